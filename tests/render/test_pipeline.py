"""The new pipeline against oracles: a textured quad gives its image back, a sphere's silhouette has
area πr², visibility agrees with trimesh's ray test, shading gradients pass ``check_grads``,
mip-mapping removes aliasing, Y-up meshes stand upright; cameras, figures, turntables, errors."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh
from jax.test_util import check_grads
from PIL import Image

from jmeshtex import InputError, Mesh
from jmeshtex.data import icosphere, torus
from jmeshtex.render import (
    Lighting,
    figure,
    look_at,
    orbit_cameras,
    rasterize,
    render,
    render_views,
    sample_mipmapped,
    shade,
    turntable,
    up_vector,
)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0**2 / mse)


def _quad():
    """The unit square in z = 0 as two triangles, uv = (x, y)."""
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, f, v[:, :2].copy()


def _astronaut(n: int) -> np.ndarray:
    import skimage.data

    img = skimage.data.astronaut()  # 512 x 512 x 3 uint8
    k = 512 // n
    return img.reshape(n, k, n, k, 3).mean(axis=(1, 3)).round().astype(np.uint8)


def _head_on(n: int, **kwargs):
    return look_at((0.5, 0.5, 3.0), (0.5, 0.5, 0.0), up="y", half_height=0.5, size=(n, n), **kwargs)


# -------------------------------------------------------------------------------------------------
# oracles
# -------------------------------------------------------------------------------------------------


def test_textured_quad_head_on_gives_the_image_back():
    v, f, uv = _quad()
    tex = _astronaut(64)
    img = render(Mesh(v, f, uv=uv, texture=tex), _head_on(64), shading="unlit", supersample=1)
    assert _psnr(img, tex) >= 40.0  # measured: exact (float32 bilinear at texel centres)
    # the oracle can fail: a texture upside down (v flipped) is far from the image
    flipped = render(
        Mesh(v, f, uv=uv * [1.0, -1.0] + [0.0, 1.0], texture=tex),
        _head_on(64),
        shading="unlit",
        supersample=1,
    )
    assert _psnr(flipped, tex) < 20.0
    # 2x2 supersampling averages four samples a quarter texel off each centre: a slight blur, still close
    ss = render(Mesh(v, f, uv=uv, texture=tex), _head_on(64), shading="unlit", supersample=2)
    assert _psnr(ss, tex) >= 28.0


@pytest.mark.parametrize("fov_deg", [None, 35.0])
def test_sphere_silhouette_area_is_pi_r_squared(fov_deg):
    r = 1.3
    v, f = icosphere(5)
    v = v * r
    n, s = 192, 2
    dist = 6.0
    if fov_deg is None:
        cam = look_at((0.0, -dist, 0.0), (0.0, 0.0, 0.0), half_height=1.5, size=(n, n))
        expected = np.pi * r**2 / (2 * 1.5) ** 2  # fraction of the image
    else:
        cam = look_at((0.0, -dist, 0.0), (0.0, 0.0, 0.0), fov_deg=fov_deg, size=(n, n))
        tan_a = np.tan(np.arcsin(r / dist))  # the silhouette cone's half angle
        expected = np.pi * tan_a**2 / (2 * np.tan(np.radians(fov_deg) / 2)) ** 2
    img = render((v, f), cam, background="transparent", supersample=s)
    coverage = img[..., 3].astype(np.float64).sum() / 255.0 / n**2
    # the inscribed icosphere(5) loses ~0.05 % of the area; pixel quantisation at 384² samples ~0.1 %
    assert abs(coverage / expected - 1.0) < 0.01
    # the oracle can fail: a sphere 2 % larger in radius is off by 4 %
    big = render((v * 1.02, f), cam, background="transparent", supersample=s)
    assert abs(big[..., 3].astype(np.float64).sum() / 255.0 / n**2 / expected - 1.0) > 0.03


def _pixel_rays(cam, rows, cols, width, height):
    r, u, w = cam.frame()
    x = ((cols + 0.5) / width * 2.0 - 1.0) * cam.half_height * width / height
    y = (1.0 - (rows + 0.5) / height * 2.0) * cam.half_height
    if cam.orthographic:
        origins = cam.eye + x[:, None] * r + y[:, None] * u
        dirs = np.broadcast_to(w, origins.shape).copy()
    else:
        t = np.tan(np.radians(cam.fov_deg) / 2) / cam.half_height  # image plane at unit distance
        dirs = w + (t * x)[:, None] * r + (t * y)[:, None] * u
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        origins = np.broadcast_to(cam.eye, dirs.shape).copy()
    return origins, dirs


class _BoxTree:
    """The two methods of an rtree index trimesh's ray test uses: ``bounds`` and ``intersection``."""

    def __init__(self, triangles):
        self.lo, self.hi = triangles.min(axis=1), triangles.max(axis=1)
        self.bounds = np.concatenate([self.lo.min(axis=0), self.hi.max(axis=0)])

    def intersection(self, box):
        box = np.asarray(box)
        return np.nonzero(((self.hi >= box[:3]) & (self.lo <= box[3:])).all(axis=1))[0]


@pytest.mark.parametrize("fov_deg", [None, 40.0])
def test_visibility_agrees_with_trimesh_ray_test(fov_deg, key):
    v, f = torus(32, 16)
    cams = orbit_cameras(
        (v, f), azimuths=[30.0], elevations=(35.0,), size=(96, 80), fov_deg=fov_deg
    )
    vis = rasterize(v, f, cams[0], supersample=1)
    rng = np.random.default_rng(int(jax.random.randint(key, (), 0, 2**31 - 1)))
    rows, cols = rng.integers(0, 80, 1500), rng.integers(0, 96, 1500)
    origins, dirs = _pixel_rays(cams[0], rows, cols, 96, 80)
    # trimesh's ray/triangle test (RayMeshIntersector without embree), with a brute-force broad
    # phase in place of its rtree index (rtree is not installed)
    tri_idx, ray_idx, hits = trimesh.ray.ray_triangle.ray_triangle_id(
        v[f], origins, dirs, tree=_BoxTree(v[f]), multiple_hits=True
    )
    near = np.full(len(rows), np.inf)
    point = np.zeros((len(rows), 3))
    dist = np.einsum("ij,ij->i", hits - origins[ray_idx], dirs[ray_idx])
    for i in np.argsort(-dist):  # the nearest hit of each ray is written last
        near[ray_idx[i]], point[ray_idx[i]] = dist[i], hits[i]
    ours = vis.face[rows, cols] >= 0
    theirs = np.isfinite(near)
    assert theirs.sum() > 300 and (~theirs).sum() > 100  # both cases are exercised
    assert (ours == theirs).mean() >= 0.995  # rays grazing the silhouette may differ
    both = ours & theirs
    seen = (vis.bary[rows, cols][..., None] * v[f[vis.face[rows, cols]]]).sum(axis=1)  # Σ b_i v_i
    err = np.linalg.norm(seen - point, axis=1)[both]
    assert (
        err < 1e-6
    ).mean() >= 0.995  # the same surface point: nearest face, perspective-correct b


def test_shading_gradients_pass_check_grads():
    v, f, uv = _quad()
    cam = _head_on(16)
    vis = rasterize(v, f, cam, supersample=2)
    face, bary = jnp.asarray(vis.face), jnp.asarray(vis.bary)
    normals = jnp.tile(jnp.array([0.0, 0.0, 1.0]), (2, 3, 1))
    lighting = Lighting(jnp.array([0.3, 0.4, 0.866]), jnp.array([0.0, 0.0, 1.0]))
    rng = np.random.default_rng(0)
    tex = jnp.asarray(0.1 + 0.5 * rng.random((6, 5, 3)))
    colors = jnp.asarray(0.1 + 0.5 * rng.random((4, 3)))

    def from_texture(t):
        return shade(
            face,
            bary,
            normals,
            lighting,
            uv=jnp.asarray(uv)[jnp.asarray(f)],
            texture=t,
            lod=jnp.array([0.7, 1.4]),
            supersample=2,
        )

    def from_vertex_colors(c):
        return shade(
            face,
            bary,
            normals,
            lighting,
            corner_colors=c[jnp.asarray(f)],
            supersample=2,
            background="transparent",
        )

    check_grads(from_texture, (tex,), order=1, modes=["fwd", "rev"])
    check_grads(from_vertex_colors, (colors,), order=1, modes=["fwd", "rev"])
    g = jax.grad(lambda t: from_texture(t).sum())(tex)
    assert float(jnp.abs(g).sum()) > 0  # the texture does reach the image


def test_mip_mapping_removes_aliasing():
    # a one-texel checker shown at an eighth of its resolution averages to grey with mip levels
    checker = (np.indices((256, 256)).sum(axis=0) % 2).astype(np.float64)
    tex = np.repeat(checker[..., None], 3, axis=2)
    v, f, uv = _quad()
    n = 37  # not a divisor of 256: pixel centres fall on both colours of the checker
    img = render(Mesh(v, f, uv=uv, texture=tex), _head_on(n), shading="unlit", supersample=1)
    img = img.astype(float)
    assert abs(img.mean() - 127.5) < 3 and img.std() < 3
    # without mip levels (plain bilinear lookups at the texels under the pixel centres) it aliases
    centres = (np.floor((np.arange(n) + 0.5) * 256 / n) + 0.5) / 256
    y, x = np.meshgrid(centres, centres, indexing="ij")
    plain = np.asarray(sample_mipmapped(tex, np.stack([x, 1.0 - y], axis=-1)))
    assert plain.std() > 0.4


def test_y_up_mesh_stands_upright():
    cone = trimesh.creation.cone(radius=0.3, height=2.0, sections=32)  # apex on +z
    v = np.asarray(cone.vertices)[:, [1, 2, 0]]  # now the apex points to +y (a Y-up file)
    f = np.asarray(cone.faces)
    img = render((v, f), up="y", size=(96, 96))
    ys, xs = np.nonzero((img < 250).any(axis=2))
    assert np.ptp(ys) > 2.5 * np.ptp(xs)  # tall and thin
    top = (img[ys.min() + 5] < 250).any(axis=1).sum()
    bottom = (img[ys.max() - 5] < 250).any(axis=1).sum()
    assert top < 0.5 * bottom  # the apex is at the top
    lying = render((v, f), up="z", size=(96, 96))
    ys, xs = np.nonzero((lying < 250).any(axis=2))
    assert np.ptp(xs) > np.ptp(ys)  # with z up the same mesh lies on its side


# -------------------------------------------------------------------------------------------------
# shading behaviour
# -------------------------------------------------------------------------------------------------


def test_smooth_shading_is_smoother_than_flat():
    v, f = icosphere(2)
    smooth = render((v, f), size=(96, 96)).astype(float)
    flat = render((v, f), shading="flat", size=(96, 96)).astype(float)
    mask = (flat < 250).any(axis=2)
    inner = mask[1:-1, 1:-1] & mask[2:, 1:-1] & mask[:-2, 1:-1] & mask[1:-1, 2:] & mask[1:-1, :-2]

    def roughness(img):
        lap = 4 * img[1:-1, 1:-1] - img[2:, 1:-1] - img[:-2, 1:-1] - img[1:-1, 2:] - img[1:-1, :-2]
        return np.abs(lap.mean(axis=2))[inner].mean()

    assert roughness(smooth) < 0.5 * roughness(flat)


def test_no_colour_source_renders_grey_and_mesh_appearance_is_used():
    v, f = icosphere(2)
    grey = render((v, f), size=(64, 64)).astype(int)
    lit = grey[(grey < 250).any(axis=2)]
    assert np.abs(lit[:, 0] - lit[:, 2]).max() < 40 and lit.std() > 10  # grey-blue, shaded
    red = np.tile([1.0, 0.0, 0.0], (len(v), 1)).astype(np.float32)
    own = render(Mesh(v, f, vertex_colors=red), size=(64, 64))
    assert own[32, 32, 0] > 150 and own[32, 32, 1] < 60  # the mesh's own colours are shown
    # face colours or scalars replace them
    blue = np.tile([0.0, 0.0, 1.0], (len(f), 1))
    other = render(Mesh(v, f, vertex_colors=red), face_colors=blue, size=(64, 64))
    assert other[32, 32, 2] > 150 and other[32, 32, 0] < 60


def test_transparent_background_has_coverage_alpha():
    v, f = icosphere(2)
    img = render((v, f), background="transparent", size=(64, 64))
    assert img.shape == (64, 64, 4)
    assert img[0, 0, 3] == 0 and img[32, 32, 3] == 255
    edge = (img[..., 3] > 0) & (img[..., 3] < 255)
    assert edge.sum() > 20  # antialiased rim


def test_render_views_compiles_once():
    mesh = torus(16, 8)
    cams = orbit_cameras(mesh, azimuths=3, elevations=(20.0,), size=(48, 48))
    render_views(mesh, cams[:1], scalars=mesh.vertices[:, 2])
    before = shade._cache_size()
    views = render_views(mesh, cams, scalars=mesh.vertices[:, 2])
    assert shade._cache_size() == before
    assert views.shape == (3, 48, 48, 3)
    assert not np.array_equal(views[0], views[1])


# -------------------------------------------------------------------------------------------------
# cameras
# -------------------------------------------------------------------------------------------------


def test_look_at_frame_and_orbit_rig():
    cam = look_at((1.0, 2.0, 3.0), (0.0, 0.0, 0.0), up="z", fov_deg=30.0)
    r, u, w = cam.frame()
    np.testing.assert_allclose(np.stack([r, u, w]) @ np.stack([r, u, w]).T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.cross(r, u), -w, atol=1e-12)  # right-handed, looking down -w
    assert u[2] > 0 and cam.size == (512, 512)
    v, f = torus(16, 8)
    cams = orbit_cameras((v, f), azimuths=4, elevations=(20.0, -10.0), up="y", size=(64, 64))
    assert len(cams) == 8
    dists = [np.linalg.norm(c.eye - c.target) for c in cams]
    np.testing.assert_allclose(dists, dists[0])
    for c in cams:  # framed: nothing touches the border, the silhouette is large
        img = render((v, f), c, supersample=1)
        mask = (img < 250).any(axis=2)
        assert not (mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())
        assert mask.mean() > 0.1
    np.testing.assert_array_equal(up_vector("-x"), [-1.0, 0.0, 0.0])


def test_top_view_has_x_right_and_y_up():
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    f = np.array([[0, 1, 2]])
    colors = np.eye(3)  # x corner green, y corner blue
    from jmeshtex.render import render_mesh

    img = render_mesh(
        Mesh(v, f, vertex_colors=colors), view=(90.0, -90.0), size=(64, 64), shading="unlit"
    ).astype(int)
    ys, xs = np.nonzero((img < 250).any(axis=2))
    right = img[ys.max() - 2, xs.max() - 4]
    top = img[ys.min() + 4, xs.min() + 2]
    assert right[1] > right[0] and right[1] > right[2]
    assert top[2] > top[0] and top[2] > top[1]


# -------------------------------------------------------------------------------------------------
# figures and turntables
# -------------------------------------------------------------------------------------------------


def test_figure_layout(tmp_path):
    a = np.zeros((32, 40, 3), np.uint8)
    b = np.ones((32, 40, 4))
    fig = figure(
        [("exemplar", a), ("result", b), ("baseline", a)], title="t", path=tmp_path / "f.png"
    )
    assert fig.shape == (28 + 20 + 32, 3 * 40, 3)
    assert fig[28 + 20 + 2 : -2, 2:38].max() < 10 and fig[28 + 20 + 2 : -2, 42:78].min() > 245
    assert (fig[28 : 28 + 20, :40] < 128).any()  # a label is written
    assert (tmp_path / "f.png").exists()
    with pytest.raises(InputError, match="at least one"):
        figure([])
    with pytest.raises(InputError, match=r"panels\[0\] must be a \(label, image\) pair"):
        figure([a])


def test_turntable_writes_a_strip_and_a_gif(tmp_path):
    mesh = torus(12, 6)
    path = tmp_path / "tt" / "torus.png"
    strip = turntable(mesh, path, n=4, size=(32, 32), gif=True)
    assert strip.shape == (32, 4 * 32, 3)
    assert sorted(p.name for p in path.parent.iterdir()) == ["torus.gif", "torus.png"]
    with Image.open(path.with_suffix(".gif")) as gif:
        assert gif.n_frames == 4


# -------------------------------------------------------------------------------------------------
# bad input
# -------------------------------------------------------------------------------------------------


def test_a_mesh_in_the_frame_that_covers_no_pixel_renders_as_background():
    # a flat square seen exactly edge-on, and a triangle far thinner than a pixel: in the frame,
    # nothing drawn; the image is the background, not an error (the mesh is not out of view)
    square = (
        np.array([[-1.0, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]]),
        np.array([[0, 1, 2], [0, 2, 3]]),
    )
    edge_on = look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up="y", half_height=2.0, size=(32, 32))
    sliver = (np.array([[0.0, 0, 0], [1e-6, 0, 0], [0, 1e-6, 0]]), np.array([[0, 1, 2]]))
    for mesh in (square, sliver):
        vis = rasterize(*mesh, edge_on)
        assert not vis.mask.any() and (vis.face == -1).all()
        img = np.asarray(render(mesh, edge_on))  # white background
        assert img.shape[:2] == (32, 32) and np.allclose(img[..., :3], img[..., :3].max())
    # the same square seen from above is drawn
    above = look_at((0.0, 5.0, 0.0), (0.0, 0.0, 0.0), up="z", half_height=2.0, size=(32, 32))
    assert rasterize(*square, above).mask.mean() > 0.2


def test_a_mesh_of_any_scale_is_framed_and_drawn_alike():
    v, f = icosphere(2)
    ref = np.asarray(render((v, f), orbit_cameras((v, f), azimuths=1, size=(48, 48))[0]))
    for scale in (1e-30, 1e30):
        cam = orbit_cameras((v * scale, f), azimuths=1, size=(48, 48))[0]
        np.testing.assert_allclose(np.asarray(render((v * scale, f), cam)), ref, atol=2.0)


def test_bad_input_raises_typed_errors():
    v, f = icosphere(1)
    away = look_at(
        (0.0, 0.0, 5.0), (0.0, 0.0, 10.0), up="y", fov_deg=30.0
    )  # looks away from the mesh
    with pytest.raises(InputError, match="the camera sees nothing"):
        render((v, f), away)
    off = look_at((50.0, 0.0, 5.0), (50.0, 0.0, 0.0), up="y", half_height=1.0)  # looks beside it
    with pytest.raises(InputError, match="the camera sees nothing"):
        render((v, f), off)
    with pytest.raises(InputError, match="zero-size image"):
        render((v, f), size=(0, 512))
    with pytest.raises(InputError, match="zero-size image"):
        look_at((0, 0, 1), (0, 0, 0), up="y", size=(512, 0))
    bad = v.copy()
    bad[3] = np.nan
    with pytest.raises(
        InputError, match=r"NaN or infinite vertices cannot be rendered: 1 vertices \(3\)"
    ):
        render((bad, f))
    with pytest.raises(InputError, match="up must be one of"):
        render((v, f), up="w")
    with pytest.raises(InputError, match="parallel to the viewing direction"):
        look_at((0, 0, 1), (0, 0, 0), up="z")
    with pytest.raises(InputError, match="shading must be one of"):
        render((v, f), shading="phong")
    with pytest.raises(InputError, match="background must be one of"):
        render((v, f), background="black")
    with pytest.raises(InputError, match="supersample must be an integer"):
        render((v, f), supersample=0)

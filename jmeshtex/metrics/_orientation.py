"""Orientation of a mesh texture across UV chart seams: do straight structures run straight over them?

A colour seam measure does not see stripes that meet at an angle with matching colours. This one
reads the *direction* of the texture on every face and compares it with the faces across each edge.

**Per face.** The texture's luminance gradient ``g`` (Sobel, in texel coordinates ``(x, y) = (u S,
(1 − v) S)``) is taken at every texel whose 3×3 stencil lies inside one UV chart and carried to 3D
through the map ``M`` of the texel's own face (``dP = M dT``, a 3×2 matrix): ``G = M (MᵀM)⁻¹ g``,
the surface gradient. Over the texels of the face's chart within ``radius`` texels of the face's UV
centroid, the structure tensor ``S_f = Σ G Gᵀ``, projected on the face's plane, has the stripe normal as dominant eigenvector
``ν_f`` (a line, sign-free) and the coherence ``(λ₁ − λ₂) / (λ₁ + λ₂)``.

**Per edge.** Across an edge with unit direction ``e`` shared by faces ``f`` and ``g``, ``ν_g`` is
unfolded onto ``f``'s plane (its components along ``e`` and along ``n × e`` are kept) and the
alignment is ``|⟨ν_f, ν_g⟩|``: 1 for structures that continue straight, 0 for a right-angle turn,
``2/π ≈ 0.64`` on average for unrelated directions (a random line field). Edges whose two faces
give them different UVs are *seam* edges, all other interior edges *interior* ones.

A texture's numbers are read against two references baked into the same atlas: the interior
alignment (how straight the structure is inside charts) and a seamless control,
:func:`stripe_texture`, a 3D-continuous stripe field whose seam alignment is what the atlas itself
allows (the disks of faces at a seam are half disks; their texels are fewer).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from jaxtyping import Float, Int

from .._errors import InputError
from .._mesh import Mesh, as_mesh
from .._triangles import face_normals
from ..geometry import rasterize_uv
from ._surface_patches import uv_charts

#: random line fields in a plane: E|cos θ| for θ uniform
RANDOM_ALIGNMENT = 2.0 / np.pi


class SeamOrientation(NamedTuple):
    """The texture's orientation per face and its alignment across seam and interior edges.

    Attributes:
      seam: mean alignment ``|⟨ν_f, ν_g⟩|`` over seam edges whose faces both have a direction.
      interior: the same over interior (non-seam) edges.
      seam_edges: how many seam edges entered ``seam``.
      interior_edges: how many interior edges entered ``interior``.
      normal: ``[F, 3]`` unit stripe normal of every face (zeros where it has none).
      coherence: ``[F]`` coherence of every face's structure tensor (0 where it has none).
      edge_faces: ``[E, 2]`` the two faces of every interior edge.
      edge_alignment: ``[E]`` alignment per interior edge (NaN where a face has no direction).
      edge_seam: ``[E]`` bool, True on seam edges.
      edge_dihedral: ``[E]`` angle between the two faces' normals, degrees (0 on a flat sheet;
        the control's alignment drops over creases, where level lines kink).
    """

    seam: float
    interior: float
    seam_edges: int
    interior_edges: int
    normal: Float[np.ndarray, "F 3"]
    coherence: Float[np.ndarray, " F"]
    edge_faces: Int[np.ndarray, "E 2"]
    edge_alignment: Float[np.ndarray, " E"]
    edge_seam: np.ndarray
    edge_dihedral: Float[np.ndarray, " E"]

    def seam_at(self, low: float, high: float) -> float:
        """Mean seam alignment over seam edges with a dihedral angle in ``[low, high)`` degrees."""
        keep = self.edge_seam & (self.edge_dihedral >= low) & (self.edge_dihedral < high)
        keep &= np.isfinite(self.edge_alignment)
        return float(self.edge_alignment[keep].mean()) if keep.any() else float("nan")


def _luminance(texture: np.ndarray) -> np.ndarray:
    t = np.asarray(texture, np.float64)
    if t.dtype.kind in "ui" or t.max(initial=0) > 1.0 + 1e-6:
        t = t / 255.0
    if t.ndim == 2:
        return t
    return t[..., :3] @ np.array([0.299, 0.587, 0.114])


def _interior_edge_faces(faces: np.ndarray, uv: np.ndarray):
    """``(face pairs [E, 2], vertex pairs [E, 2], seam [E])`` of every edge two faces share."""
    F = len(faces)
    a, b = [0, 1, 2], [1, 2, 0]
    va, vb = faces[:, a].ravel(), faces[:, b].ravel()
    lo, hi = np.minimum(va, vb), np.maximum(va, vb)
    key = lo * (int(faces.max()) + 1) + hi
    face = np.repeat(np.arange(F), 3)
    # UVs of the edge's lower and higher vertex, per face side
    ua, ub = uv[:, a].reshape(-1, 2), uv[:, b].reshape(-1, 2)
    swap = (va > vb)[:, None]
    ulo, uhi = np.where(swap, ub, ua), np.where(swap, ua, ub)
    order = np.argsort(key, kind="stable")
    k = key[order]
    pair = np.nonzero(k[1:] == k[:-1])[0]
    i, j = order[pair], order[pair + 1]
    seam = (np.abs(ulo[i] - ulo[j]).max(axis=1) > 1e-9) | (
        np.abs(uhi[i] - uhi[j]).max(axis=1) > 1e-9
    )
    return np.stack([face[i], face[j]], 1), np.stack([lo[i], hi[i]], 1), seam


def _sobel(lum: np.ndarray, chart_px: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sobel gradients ``(gx, gy)`` (per texel, x right, y down) and where the 3×3 stencil stays in
    one chart."""
    H, W = lum.shape
    p = np.pad(lum, 1, mode="edge")
    c = np.pad(chart_px, 1, mode="constant", constant_values=-1)
    win = lambda a, dr, dc: a[1 + dr : 1 + dr + H, 1 + dc : 1 + dc + W]  # noqa: E731
    gx = (
        win(p, -1, 1)
        + 2 * win(p, 0, 1)
        + win(p, 1, 1)
        - win(p, -1, -1)
        - 2 * win(p, 0, -1)
        - win(p, 1, -1)
    ) / 8.0
    gy = (
        win(p, 1, -1)
        + 2 * win(p, 1, 0)
        + win(p, 1, 1)
        - win(p, -1, -1)
        - 2 * win(p, -1, 0)
        - win(p, -1, 1)
    ) / 8.0
    ok = chart_px >= 0
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            ok &= win(c, dr, dc) == chart_px
    return gx, gy, ok


def seam_orientation(
    mesh: Mesh,
    texture: Float[np.ndarray, "H W C"] | None = None,
    *,
    radius: float = 6.0,
    min_texels: int = 12,
) -> SeamOrientation:
    """Alignment of the texture's stripe directions across UV seam edges and interior edges.

    .. math:: a_{fg} = \\big|\\langle \\nu_f,\\ \\mathrm{unfold}_{g\\to f}(\\nu_g)\\rangle\\big|,
       \\qquad \\nu_f = \\arg\\max_{\\lVert\\nu\\rVert = 1} \\nu^\\top
       \\Big(\\textstyle\\sum_{x \\in D_f} G_x G_x^\\top\\Big) \\nu

    with ``G_x`` the surface gradient of the luminance at texel ``x`` and ``D_f`` the texels of
    ``f``'s chart within ``radius`` of ``f``'s UV centroid (module docstring). Random line fields
    give ``2/π``; a texture whose structure continues across seams gives the control's value
    (:func:`stripe_texture` baked into the same atlas).

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``uv`` ``[F, 3, 2]``.
      texture: ``[H, W, 3]`` (or ``[H, W]``) image in the mesh's UV layout, row 0 at ``v = 1``;
        default ``mesh.texture``. Values in [0, 1] (uint8 is rescaled).
      radius: disk radius in texels (cover at least one period of the structure).
      min_texels: faces with fewer usable gradient texels in their disk have no direction.

    Returns:
      :class:`SeamOrientation`.

    Raises:
      InputError: no UVs or texture, a non-square texture, bad ``radius``.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(4)
      >>> mesh = Mesh(v, f, uv=v[f][..., :2])
      >>> r = seam_orientation(mesh, stripe_texture(mesh, 64, direction=(1, 1, 0), period=0.2))
      >>> r.seam_edges, round(r.interior, 3)
      (0, 1.0)
    """
    mesh = as_mesh(mesh)
    lum = _checked_luminance(mesh, texture, radius)
    S = lum.shape[0]
    V = np.asarray(mesh.vertices, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
    uv = np.asarray(mesh.uv, np.float64)
    chart = uv_charts(faces, uv)
    raster = rasterize_uv(uv, S, coverage="center")
    chart_px = np.full((S, S), -1, np.int64)
    chart_px[raster.row, raster.col] = chart[raster.face]
    gx, gy, ok = _sobel(lum, chart_px)
    tex = np.stack([uv[..., 0] * S, (1.0 - uv[..., 1]) * S], axis=-1)  # [F, 3, 2] in texels
    Q, good = _gradient_maps(V, faces, tex)

    # every usable texel's surface gradient, through its own face's map
    face_px = np.full((S, S), -1, np.int64)
    face_px[raster.row, raster.col] = raster.face
    ok &= face_px >= 0
    ok &= good[np.maximum(face_px, 0)]
    Qp = Q[np.maximum(face_px, 0)]  # [S, S, 3, 2]
    G = Qp[..., 0] * gx[..., None] + Qp[..., 1] * gy[..., None]  # [S, S, 3]
    G = np.where(ok[..., None], G, 0.0)
    outer = G[..., :, None] * G[..., None, :]  # [S, S, 3, 3]

    S3, count = _disk_sums(outer, ok, chart_px, chart, tex, radius)
    fn = face_normals(V, faces)
    proj = np.eye(3) - fn[:, :, None] * fn[:, None, :]  # onto the face's plane
    S3 = proj @ S3 @ proj  # [F, 3, 3] surface structure tensor
    w, vec = np.linalg.eigh(S3)
    normal = vec[:, :, 2]
    lam1, lam2 = w[:, 2], w[:, 1]
    coherence = np.where(lam1 + lam2 > 0, (lam1 - lam2) / np.maximum(lam1 + lam2, 1e-300), 0.0)
    has = good & (count >= min_texels) & (lam1 > 1e-12 * max(float(lam1.max(initial=0)), 1e-300))
    normal = np.where(has[:, None], normal, 0.0)
    coherence = np.where(has, coherence, 0.0)

    pairs, verts, seam = _interior_edge_faces(faces, uv)
    f, g = pairs[:, 0], pairs[:, 1]
    align = _unfolded_alignment(V[verts[:, 1]] - V[verts[:, 0]], fn[f], fn[g], normal[f], normal[g])
    valid = has[f] & has[g]
    align = np.where(valid, np.minimum(align, 1.0), np.nan)
    s, i = valid & seam, valid & ~seam
    return SeamOrientation(
        seam=float(align[s].mean()) if s.any() else float("nan"),
        interior=float(align[i].mean()) if i.any() else float("nan"),
        seam_edges=int(s.sum()),
        interior_edges=int(i.sum()),
        normal=normal,
        coherence=coherence,
        edge_faces=pairs,
        edge_alignment=align,
        edge_seam=seam,
        edge_dihedral=np.degrees(np.arccos(np.clip(np.sum(fn[f] * fn[g], axis=1), -1.0, 1.0))),
    )


def _checked_luminance(mesh: Mesh, texture, radius: float) -> np.ndarray:
    """``[S, S]`` the luminance of ``texture`` (default ``mesh.texture``), checked: the mesh has
    UVs, the texture is square, ``radius`` at least one texel."""
    if mesh.uv is None:
        raise InputError("seam_orientation: the mesh has no UVs")
    texture = mesh.texture if texture is None else texture
    if texture is None:
        raise InputError("seam_orientation: give a texture (the mesh has none)")
    lum = _luminance(texture)
    H, W = lum.shape
    if H != W:
        raise InputError(f"seam_orientation: the texture must be square, got {H}×{W}")
    if not (np.isfinite(radius) and radius >= 1.0):
        raise InputError(f"seam_orientation: radius must be >= 1 texel, got {radius!r}")
    return lum


def _gradient_maps(V: np.ndarray, faces: np.ndarray, tex: np.ndarray):
    """``([F, 3, 2], [F])`` per face the map ``Q`` taking a texel-space gradient ``g`` to the
    surface gradient ``G = Q g`` (from the face's texel corners ``tex`` ``[F, 3, 2]``), and where
    it exists (the face's UV and 3D triangles are not degenerate)."""
    T = np.stack([tex[:, 1] - tex[:, 0], tex[:, 2] - tex[:, 0]], axis=2)  # [F, 2, 2]
    P = np.stack([V[faces[:, 1]] - V[faces[:, 0]], V[faces[:, 2]] - V[faces[:, 0]]], axis=2)
    det = np.linalg.det(T)
    usable = np.abs(det) > 1e-12
    M = P @ np.linalg.inv(np.where(usable[:, None, None], T, np.eye(2)))  # [F, 3, 2]
    MtM = np.swapaxes(M, 1, 2) @ M
    good = usable & (np.abs(np.linalg.det(MtM)) > 1e-300)
    Q = M @ np.linalg.inv(np.where(good[:, None, None], MtM, np.eye(2)))  # G = Q g
    return Q, good


def _disk_sums(outer, ok, chart_px, chart, tex, radius: float):
    """``([F, 3, 3], [F])`` per face the sum of the texels' gradient outer products ``outer``
    ``[S, S, 3, 3]`` over the usable (``ok``) texels of the face's chart within ``radius`` of its
    UV centroid, and their count."""
    S = outer.shape[0]
    centre = tex.mean(axis=1) - 0.5  # texel-centre coordinates (col, row)
    r = int(np.ceil(radius))
    off = np.arange(-r, r + 1)
    dc, dr = np.meshgrid(off, off)
    base_c = np.round(centre[:, 0]).astype(np.int64)
    base_r = np.round(centre[:, 1]).astype(np.int64)
    S3 = np.zeros((len(tex), 3, 3))
    count = np.zeros(len(tex))
    for ddr, ddc in zip(dr.ravel(), dc.ravel(), strict=True):
        rr, cc = base_r + ddr, base_c + ddc
        inside = (rr >= 0) & (rr < S) & (cc >= 0) & (cc < S)
        rr, cc = np.clip(rr, 0, S - 1), np.clip(cc, 0, S - 1)
        near = (cc - centre[:, 0]) ** 2 + (rr - centre[:, 1]) ** 2 <= radius**2
        use = inside & near & ok[rr, cc] & (chart_px[rr, cc] == chart)
        S3 += np.where(use[:, None, None], outer[rr, cc], 0.0)
        count += use
    return S3, count


def _unfolded_alignment(edge, nf, ng, vf, vg) -> np.ndarray:
    """``|<v_f, unfold(v_g)>|`` per interior edge: face g's direction ``vg`` unfolded about the
    shared ``edge`` into face f's plane (normals ``nf``, ``ng``), against f's direction ``vf``."""
    e = edge / np.maximum(np.linalg.norm(edge, axis=1, keepdims=True), 1e-300)
    bf, bg = np.cross(nf, e), np.cross(ng, e)
    unfolded = np.sum(vg * e, 1)[:, None] * e + np.sum(vg * bg, 1)[:, None] * bf
    return np.abs(np.sum(vf * unfolded, axis=1))


def stripe_texture(
    mesh: Mesh,
    size: int,
    *,
    direction=(1.0, 0.0, 0.0),
    period: float,
    colors=((0.15, 0.1, 0.05), (0.9, 0.85, 0.7)),
) -> Float[np.ndarray, "S S 3"]:
    """A 3D-continuous stripe field baked into the mesh's UV atlas: the seamless control.

    .. math:: c(p) = c_0 + (c_1 - c_0)\\,\\tfrac12\\big(1 + \\cos(2\\pi\\,\\langle p, k\\rangle / T)\\big),
       \\qquad k = \\text{direction} / \\lVert\\text{direction}\\rVert

    evaluated at the surface point of every texel that overlaps a UV triangle (chart borders
    included); texels outside every chart stay 0.

    Args:
      mesh: a :class:`~jmeshtex.Mesh` with ``uv``.
      size: texture resolution.
      direction: the world vector the stripes vary along (their normal, before projection).
      period: stripe period ``T`` in world units.
      colors: the two stripe colours.

    Returns:
      ``[size, size, 3]`` float64 image, row 0 at ``v = 1``.

    Example:
      >>> from jmeshtex import Mesh
      >>> from jmeshtex.data import grid
      >>> v, f = grid(1)
      >>> stripe_texture(Mesh(v, f, uv=v[f][..., :2]), 4, period=0.5).shape
      (4, 4, 3)
    """
    mesh = as_mesh(mesh)
    if mesh.uv is None:
        raise InputError("stripe_texture: the mesh has no UVs")
    if not (np.isfinite(period) and period > 0):
        raise InputError(f"stripe_texture: period must be > 0, got {period!r}")
    k = np.asarray(direction, np.float64)
    k = k / np.linalg.norm(k)
    raster = rasterize_uv(np.asarray(mesh.uv, np.float64), int(size), coverage="overlap")
    V = np.asarray(mesh.vertices, np.float64)
    p = np.einsum("nk,nkd->nd", raster.bary, V[np.asarray(mesh.faces)[raster.face]])
    s = 0.5 * (1.0 + np.cos(2.0 * np.pi * (p @ k) / period))
    c0, c1 = (np.asarray(c, np.float64) for c in colors)
    out = np.zeros((int(size), int(size), 3))
    out[raster.row, raster.col] = c0 + (c1 - c0) * s[:, None]
    return out

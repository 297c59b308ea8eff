"""Benchmarks of MeshMatch: speed at 16K and 64K target vertices, and quality between shapes.

``--suite speed`` (default):

Source: a bumpy torus (10K vertices) with a procedural colour field; target: the same surface
at 16K / 64K vertices. Reports preprocessing (hierarchies, HKS, tracer
tables; fans are traced per level inside the transfer and reported apart), compile time, the time
of one PatchMatch iteration at the finest level (E-step + M-step: the median of that level's
iterations after its first, from the per-iteration times in ``Match.stats``),
the total transfer time and the self-transfer PSNR, next to the targets (≤ 0.65 s per iteration at
64K, ≤ 60 s total) and the paper's figures (6.5 s per iteration, ~100 s + 160 s preprocessing).

Every row carries the 1-minute load average when it was taken (the machine is shared: figures
taken under load are inflated; re-run on a quiet machine for clean numbers); the iteration row also
gives the process CPU seconds (all threads), which load inflates less than wall time.

``--suite cross``: transfer between *different* shapes with ground truth (results in
``results/meshmatch_cross.{json,md}``). Each pair's colours are one smooth field given in
coordinates both shapes share through a known map (the direction from the centre for the bumpy
spheres, the two angles for the tori, the position before a non-uniform stretch for the cow), so
the target's true colours are known. Rows (``VARIANTS``): PSNR against them of the default
configuration (aligned: HKS, the whole normal and per-axis standardised positions), of its
shape-only match (colour weight 0), of the pose-free intrinsic features (``Config.intrinsic()``:
HKS and ``n · up``, the previous default) with and without colours and with the shape weights
(3, 30), of shape weight 3 at every level, of the paper's search options (exact rotation search
for every candidate; candidates from the whole star of each neighbour's match, alone and with 8
exact candidates; sequential breadth-first propagation, aligned and intrinsic), of one
propagation sweep per iteration, of the HKS from 96 eigenpairs, of the whole normal without
positions, of position weights 4 and 2, of the intrinsic ``n · side`` feature (``Config.side``:
the cow's left/right axis, x elsewhere); and three diagnosis rows that start the finest level
alone from the truth
(``initial_nnf``) at shape weights 0, 0.3 and 3 (what its iterations lose). Each row gives the
final colours' PSNR and the finest vote's (``Match.voted``), the median placement
error (distance from the true source point, in source mean edges), the total seconds and the
finest level's seconds per iteration; next to the nearest-3D copy after alignment through the
known map (the ceiling the source's resolution sets), the unaligned nearest-3D copy, the
nearest-3D copy after matching per-axis means and standard deviations (what the ``aligned``
position feature can reach on its own) and the source colours permuted (right statistics, no
structure).

``--suite real``: self-transfer on the real meshes of ``../shared/data`` (results in
``results/meshmatch_real.{json,md}``): each mesh as stored (cheburashka 6.7K and fandisk 6.5K
vertices, the "6K user case"; the cow 2.9K; Spot 2.9K with its own texture read with the area
prefilter) → ``remesh`` of the same surface at about 5K and 20K vertices (``--large``: also 60K;
``--real-sizes`` to choose). Colours of the untextured meshes: a smooth function of position
(the cross suite's cow field, about three periods across the bounding box). Rows: the nearest-3D
copy (the ceiling), the default and ``Config.intrinsic()`` (``--variants`` selects further rows of
``EXTRA_REAL``: the fan-footprint vote, offset upsampling); each with the final and the voted PSNR,
its gap to the ceiling and where the error comes from (the share of vertices matched more than 3
source edges from the true point, how many of those at a mirror image, their share of the error).

Usage::

    python benchmarks/meshmatch.py                 # 16K and 64K
    python benchmarks/meshmatch.py --sizes 16      # 16K only
    python benchmarks/meshmatch.py --suite cross [--small] [--variants TEXT ...]
    python benchmarks/meshmatch.py --suite figure  # results/meshmatch_cross.png
    python benchmarks/meshmatch.py --suite real [--large] [--meshes cow ...] [--variants TEXT ...]

The speed suite with other ``Config`` fields (the fan vote's, sequential propagation's cost) is a
study: ``studies/meshmatch_options.py``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time
import warnings

import jax
import numpy as np
from _harness import Report, Size, size_label
from scipy.spatial import cKDTree

from jmeshtex import Mesh
from jmeshtex.data import icosphere, torus
from jmeshtex.geometry import mean_edge_length, prepare_mesh, remesh
from jmeshtex.meshmatch import Config, meshmatch
from jmeshtex.meshmatch.core import prepare_side
from jmeshtex.metrics import psnr


def _torus(n_major, n_minor):
    """A bumpy torus: the minor radius varies smoothly with both angles (no symmetry left)."""
    v, f = torus(n_major, n_minor)
    theta = np.arctan2(v[:, 1], v[:, 0])
    ring = np.hypot(v[:, 0], v[:, 1]) - 1.0
    phi = np.arctan2(v[:, 2], ring)
    r = 0.35 * (1 + 0.2 * np.sin(3 * theta + 0.5) * np.cos(2 * phi) + 0.1 * np.cos(theta))
    centre = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], 1)
    normal = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], 1)
    colour = np.stack(
        [
            0.5 + 0.4 * np.sin(7 * theta) * np.cos(2 * phi),
            0.5 + 0.4 * np.sin(5 * theta + 2 * phi + 1),
            0.5 + 0.3 * np.cos(3 * phi + theta),
        ],
        axis=1,
    )
    return Mesh(centre + r[:, None] * normal, f), colour


def _moment_aligned(x, reference):
    """Points ``x`` moved so that their per-axis mean and standard deviation match ``reference``'s."""
    return (x - x.mean(axis=0)) / x.std(axis=0) * reference.std(axis=0) + reference.mean(axis=0)


#: the cross suite's variants: label -> Config fields over the pair's own
VARIANTS = {
    "default": {},
    "shape-only (colour weight 0)": {"color_weight": 0.0},
    "intrinsic (Config.intrinsic(): HKS + n·up, pose-free; the previous default)": {
        "aligned": False
    },
    "intrinsic, shape-only (colour weight 0)": {"aligned": False, "color_weight": 0.0},
    "intrinsic, shape weight 3 at the finest level, 30 above": {
        "aligned": False,
        "shape_weight": (3.0, 30.0),
    },
    "shape weight 3 at every level": {"shape_weight": 3.0},
    "exact rotation search for every candidate (paper)": {"exact_candidates": 64},
    "candidates from the whole star of NNF(q) (paper)": {"star_candidates": True},
    "whole star + 8 exact candidates": {"star_candidates": True, "exact_candidates": 8},
    "1 propagation sweep per iteration (Jacobi)": {"sweeps": 1},
    "sequential propagation (Gauss-Seidel wavefronts, alternating direction; paper)": {
        "propagation": "sequential"
    },
    "intrinsic, sequential propagation": {"aligned": False, "propagation": "sequential"},
    "HKS from 96 eigenpairs": {"hks_eigenpairs": 96},
    "whole normal only (normal weight 4, no positions)": {
        "normal_weight": 4.0,
        "position_weight": 0.0,
    },
    "position weight 4": {"position_weight": 4.0},
    "position weight 2": {"position_weight": 2.0},
    "fan-footprint vote (paper)": {"vote": "fan"},
    "fan-footprint vote, vote sigma 2": {"vote": "fan", "vote_sigma": 2.0},
    "offset upsampling + re-vote (paper)": {"upsample": "offset"},
    "fan vote + offset upsampling (paper)": {"vote": "fan", "upsample": "offset"},
}


def _finest_steps(r) -> int:
    """Iterations the finest level ran (it stops early when few matches change)."""
    return int(next(s for s in r.stats["levels"] if s["level"] == 0)["steps"])


def _finest_iteration(r) -> float:
    finest = next(s for s in r.stats["levels"] if s["level"] == 0)
    runs = finest["iteration_seconds"][1:] or finest["iteration_seconds"]
    return round(float(np.median(runs)), 3)


def _add_run(report, case, label, cfg, **kw) -> None:
    """Run one configuration on one pair and add its row."""
    name, s, sc, t, truth, to_src, edge, base = case
    t0 = time.perf_counter()
    r = meshmatch(s, sc, t, key=jax.random.key(0), config=cfg, **kw)
    seconds = time.perf_counter() - t0
    err = float(np.median(np.linalg.norm(to_src(t.vertices) - s.vertices[r.nnf], axis=1)) / edge)
    load = round(os.getloadavg()[0], 1)
    report.add(
        **base,
        method=label,
        psnr_db=round(psnr(np.clip(r.colors, 0, 1), truth), 2),
        voted_psnr_db=round(psnr(np.clip(r.voted, 0, 1), truth), 2),
        placement_error_edges=round(err, 2),
        seconds=round(seconds, 1),
        finest_iteration_s=_finest_iteration(r),
        finest_steps=_finest_steps(r),
        load=load,
    )
    print(f"{name} | {label}: {report.rows[-1]['psnr_db']} dB", flush=True)


def cross(args) -> None:
    """The cross-shape suite (module docstring)."""
    report = Report("meshmatch_cross", ceilings=False)
    for name, s, sc, t, truth, to_src, fields in pairs(args.small):
        side = {"aligned": False, "side": SIDE_AXIS.get(name, "x")}
        variants_here = {**VARIANTS, f"intrinsic + side axis {side['side']} (n·side feature)": side}
        edge = mean_edge_length(*s)
        tree = cKDTree(s.vertices)
        gt = tree.query(to_src(t.vertices))[1]
        near = sc[gt]
        raw = sc[tree.query(t.vertices)[1]]
        moments = sc[tree.query(_moment_aligned(t.vertices, s.vertices))[1]]
        perm = sc[np.random.default_rng(0).integers(0, len(sc), len(truth))]
        size = f"{s.num_vertices}->{t.num_vertices}"
        base = {"pair": name, "size": size}
        report.add(
            **base,
            method="nearest-3D copy, aligned by the known map (ceiling)",
            psnr_db=round(psnr(near, truth), 2),
        )
        report.add(**base, method="nearest-3D copy, unaligned", psnr_db=round(psnr(raw, truth), 2))
        report.add(
            **base,
            method="nearest-3D copy after moment alignment (per-axis mean and std)",
            psnr_db=round(psnr(moments, truth), 2),
        )
        report.add(**base, method="permuted source colours", psnr_db=round(psnr(perm, truth), 2))

        case = (name, s, sc, t, truth, to_src, edge, base)
        for label, extra in variants_here.items():
            # a text that is a whole label selects that row only; any other text every label containing it
            if args.variants and not any(
                v == label if v in variants_here else v in label for v in args.variants
            ):
                continue
            _add_run(report, case, label, Config.from_dict({**fields, **extra}))
        # where the dB go: start the finest level from the truth (true matches, their colours) and
        # see how far its iterations move it at each finest-level shape weight
        for w in () if args.variants else (0.0, 0.3, 3.0):
            _add_run(
                report,
                case,
                f"finest level only, started from the truth, shape weight {w:g}",
                Config.from_dict({**fields, "levels": 1, "coarse_steps": 6, "shape_weight": w}),
                initial_nnf=gt,
            )
    report.notes.append(
        "psnr_db: the final colours (each vertex copies its match's colour); voted_psnr_db: the "
        "finest level's vote (Match.voted). seconds include compiling the PatchMatch "
        "steps (no persistent cache) and preprocessing; finest_iteration_s: median wall time of "
        "the finest level's iterations after the first; the machine is shared (load = 1-minute "
        "load average)."
    )
    report.notes.append(
        "'started from the truth' rows: one level (the finest), initial_nnf = the nearest source "
        "vertex of the known map, 6 iterations: the iterations can only lose what the truth has."
    )
    report.write(pathlib.Path(args.out) if args.out else None)


def figure(args) -> None:
    """``results/meshmatch_cross.png``: the torus and stretched-sphere pairs, the pose-free
    intrinsic features next to the aligned default, colours and nearest-neighbour fields."""
    from jmeshtex import render
    from jmeshtex.meshmatch.core import nnf_colors

    wanted = ("torus r 0.3 -> torus r 0.36", "bumpy sphere -> stretched (1.15, 1, 0.9)")
    rows, titles = [], []
    size = (300, 260)
    for name, s, sc, t, truth, to_src, fields in pairs(args.small, with_cow=False):
        if name not in wanted:
            continue
        gt = cKDTree(s.vertices).query(to_src(t.vertices))[1]

        def shot(mesh, colors):
            return render.render_mesh(
                Mesh(mesh.vertices, mesh.faces, vertex_colors=np.clip(colors, 0, 1)), size=size
            )

        cells = [
            (shot(s, sc), f"source ({name.split(' ->')[0]})"),
            (shot(t, truth), "target truth"),
        ]
        for label, cfg in (
            ("intrinsic", Config.intrinsic(**fields)),
            ("default (aligned)", Config.from_dict(fields)),
        ):
            r = meshmatch(s, sc, t, key=jax.random.key(0), config=cfg)
            cells.append(
                (shot(t, r.colors), f"{label} {psnr(np.clip(r.colors, 0, 1), truth):.1f} dB")
            )
            cells.append((shot(t, nnf_colors(s, r.nnf)), f"{label} NNF"))
        cells.append((shot(t, nnf_colors(s, gt)), "true NNF"))
        rows += [c for c, _ in cells]
        titles += [label for _, label in cells]
    out = (
        pathlib.Path(args.out) if args.out else pathlib.Path(__file__).resolve().parent / "results"
    )
    render.render_grid(rows, out / "meshmatch_cross.png", titles=titles, columns=7)
    print(f"wrote {out / 'meshmatch_cross.png'}", flush=True)


# ---- cross-shape pairs with ground truth -------------------------------------------------------

#: the side axis of each pair's n·side variant (the cow's left/right axis; "x" elsewhere)
SIDE_AXIS = {"cow -> remeshed, stretched (1.15, 1, 0.9)": "z"}

DATA = pathlib.Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def sphere_bumps(u, amp):
    """Radius of an asymmetric bumpy sphere at unit directions ``u`` (low-frequency, no symmetry)."""
    return 1 + amp * (
        np.sin(3 * u[:, 0] + 1) * np.cos(2 * u[:, 1] + 0.7) + 0.6 * np.sin(4 * u[:, 2] + 0.5)
    )


def _sphere_colors(u):
    return np.stack(
        [
            0.5 + 0.4 * np.sin(4 * u[:, 0]) * np.cos(3 * u[:, 1]),
            0.5 + 0.4 * np.sin(5 * u[:, 2] + 1),
            0.5 + 0.3 * np.cos(3 * u[:, 0] + 2 * u[:, 1]),
        ],
        axis=1,
    )


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def sphere_pair(subdivisions: int):
    """The first cross-shape pair: a bumpy sphere and a bumpier one of another tessellation (the
    same icosphere turned), coloured by one smooth field of the direction from the centre.

    Returns ``(source, source colours, target, true target colours, u, tu)``, ``u`` and ``tu`` the
    unit directions of the source's and the target's vertices (``tests/meshmatch/test_cross_shape.py``
    runs the small one, ``subdivisions=3``).
    """
    v, f = icosphere(subdivisions)
    u = _unit(v)
    q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((3, 3)))
    tu = _unit(v @ q.T)  # the same icosphere turned: another tessellation of the directions
    source = Mesh(u * sphere_bumps(u, 0.15)[:, None], f)
    target = Mesh(tu * sphere_bumps(tu, 0.22)[:, None], f)
    return source, _sphere_colors(u), target, _sphere_colors(tu), u, tu


def _angled_torus(n_major, n_minor, minor):
    """A bumpy torus of minor radius ``minor`` (asymmetric modulation) and its angles."""
    v, f = torus(n_major, n_minor)
    theta = np.arctan2(v[:, 1], v[:, 0])
    phi = np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1]) - 1.0)
    r = minor * (1 + 0.2 * np.sin(3 * theta + 0.5) * np.cos(2 * phi) + 0.1 * np.cos(theta))
    centre = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], 1)
    normal = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], 1)
    return Mesh(centre + r[:, None] * normal, f), theta, phi


def _torus_colors(theta, phi):
    return np.stack(
        [
            0.5 + 0.4 * np.sin(3 * theta) * np.cos(phi),
            0.5 + 0.4 * np.sin(2 * theta + phi + 1),
            0.5 + 0.3 * np.cos(2 * phi + theta),
        ],
        axis=1,
    )


def _cow_colors(p):
    return np.stack(
        [
            0.5 + 0.4 * np.sin(0.6 * p[:, 0]) * np.cos(0.8 * p[:, 1]),
            0.5 + 0.4 * np.sin(0.9 * p[:, 2] + 0.5 * p[:, 0]),
            0.5 + 0.3 * np.cos(0.7 * p[:, 1] + 1),
        ],
        axis=1,
    )


def pairs(small: bool = False, *, with_cow: bool = True):
    """The benchmark's pairs; ``small`` halves the resolution (the test's size)."""
    out = []
    # 1. bumpy sphere -> bumpier sphere, another tessellation (a rotated icosphere)
    source, source_colors, target, target_colors, u, tu = sphere_pair(3 if small else 4)
    out.append(
        (
            "bumpy sphere -> bumpier sphere",
            source,
            source_colors,
            target,
            target_colors,
            lambda x: _unit(x) * sphere_bumps(_unit(x), 0.15)[:, None],
            {},
        )
    )
    # 2. bumpy sphere -> the same bumpy sphere stretched non-uniformly (1.3, 1, 0.8), rotated tessellation
    stretch = np.array([1.15, 1.0, 0.9])
    target2 = Mesh(tu * sphere_bumps(tu, 0.15)[:, None] * stretch, target.faces)
    out.append(
        (
            "bumpy sphere -> stretched (1.15, 1, 0.9)",
            source,
            source_colors,
            target2,
            target_colors,
            lambda x: x / stretch,
            {},
        )
    )
    # 3. bumpy torus (minor 0.3) -> bumpy torus of other proportions (minor 0.36) and resolution
    n = (48, 24) if small else (96, 48)
    s_t, s_theta, s_phi = _angled_torus(*n, 0.3)
    t_t, t_theta, t_phi = _angled_torus(int(n[0] * 1.1), int(n[1] * 1.2), 0.36)
    out.append(
        (
            "torus r 0.3 -> torus r 0.36",
            s_t,
            _torus_colors(s_theta, s_phi),
            t_t,
            _torus_colors(t_theta, t_phi),
            lambda x: _torus_map(x, 0.3),
            {},
        )
    )
    # 4. cow (Y-up) -> remeshed cow stretched (1.15, 1, 0.9) about its centre
    path = DATA / "cow.obj"
    if with_cow and path.exists():
        from jmeshtex.io import load_mesh

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cow, _ = prepare_mesh(load_mesh(path).replace(uv=None, texture=None), repair=True)
            re = remesh(cow, n_vertices=1500 if small else 2500, key=jax.random.key(1))
        c = cow.vertices.mean(axis=0)
        k = np.array([1.15, 1.0, 0.9])
        target4 = Mesh((re.vertices - c) * k + c, re.faces)
        out.append(
            (
                "cow -> remeshed, stretched (1.15, 1, 0.9)",
                cow,
                _cow_colors(cow.vertices),
                target4,
                _cow_colors(re.vertices),
                lambda x: (x - c) / k + c,
                {"up": "y"},
            )
        )
    return out


def _torus_map(x, minor):
    """Target torus points -> the source torus point of the same angles."""
    theta = np.arctan2(x[:, 1], x[:, 0])
    phi = np.arctan2(x[:, 2], np.hypot(x[:, 0], x[:, 1]) - 1.0)
    r = minor * (1 + 0.2 * np.sin(3 * theta + 0.5) * np.cos(2 * phi) + 0.1 * np.cos(theta))
    centre = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], 1)
    normal = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], 1)
    return centre + r[:, None] * normal


# ---- real meshes: self-transfer to another tessellation of the same surface --------------------

#: the real suite's meshes: name -> (file under DATA, up axis); Spot carries its own texture
REAL_MESHES = {
    "cheburashka": ("cheburashka.obj", "y"),
    "fandisk": ("fandisk.obj", "y"),
    "cow": ("cow.obj", "y"),
    "spot": ("spot/spot_triangulated.obj", "y"),
}


def _smooth_colors(p, centre, scale):
    """A smooth colour field of position: the cross suite's cow field in coordinates centred on the
    mesh and scaled so that the bounding-box diagonal spans 18 units (about three periods across the shape)."""
    return _cow_colors((p - centre) * (18.0 / scale))


def _load_real(name: str):
    """A real mesh of ``DATA`` as (mesh for remeshing, source colours, colour function or None)."""
    from jmeshtex.io import load_mesh
    from jmeshtex.meshmatch import vertex_colors_from_texture

    file, _ = REAL_MESHES[name]
    path = DATA / file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if name == "spot":
            raw = load_mesh(path, texture=path.parent / "spot_texture.png")
            mesh, _ = prepare_mesh(raw, repair=True)
            return mesh, vertex_colors_from_texture(mesh, prefilter="area"), None
        mesh, _ = prepare_mesh(load_mesh(path).replace(uv=None, texture=None), repair=True)
    v = np.asarray(mesh.vertices, np.float64)
    centre, scale = v.mean(axis=0), float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))

    def field(p):
        return _smooth_colors(np.asarray(p, np.float64), centre, scale)

    return mesh, field(v), field


def _mirror_diagnosis(s, t, nnf, truth_index, sc, truth, edge) -> dict:
    """Where the error comes from: the share of target vertices matched more than 3 source edges
    from the true point, the share of those within 3 edges of the true point's mirror image across
    a principal plane through the centroid (the best of the three), their share of the squared
    error and the PSNR had they matched the true point."""
    sv = np.asarray(s.vertices, np.float64)
    tv = np.asarray(t.vertices, np.float64)
    off = np.linalg.norm(sv[nnf] - sv[truth_index], axis=1) / edge
    far = off > 3
    err = np.sum((np.clip(sc[nnf], 0, 1) - truth) ** 2, axis=1)
    centre = sv.mean(axis=0)
    _, _, axes = np.linalg.svd(sv - centre, full_matrices=False)
    mirrored = np.zeros(len(tv), bool)
    for n in axes:
        refl = tv - 2 * ((tv - centre) @ n)[:, None] * n
        mirrored |= np.linalg.norm(sv[nnf] - refl, axis=1) / edge <= 3
    return {
        "far_pct": round(100 * float(far.mean()), 1),
        "far_mirrored_pct": round(100 * float((far & mirrored).sum() / max(far.sum(), 1)), 1),
        "far_error_pct": round(100 * float(err[far].sum() / max(err.sum(), 1e-30)), 1),
        "median_offset_edges": round(float(np.median(off)), 2),
        # the PSNR if the far vertices had their true match (what the far ones cost)
        "psnr_far_fixed_db": round(
            psnr(np.clip(np.where(far[:, None], sc[truth_index], sc[nnf]), 0, 1), truth), 2
        ),
    }


#: the real suite's variants: label -> Config fields
REAL_VARIANTS = {
    "default (aligned)": {},
    "Config.intrinsic() (up z: the previous default, as a new user ran it)": {"aligned": False},
}


def real(args) -> None:
    """The real-mesh suite: each mesh of ``../shared/data`` (cheburashka, fandisk, cow, Spot with its
    texture) → ``remesh`` of the same surface at about 5K, 20K (and with ``--large`` 60K) vertices."""
    report = Report("meshmatch_real", ceilings=False)
    sizes = [5000, 20000] + ([60000] if args.large else [])
    if args.real_sizes:
        sizes = [int(x) for x in args.real_sizes.split(",")]
    names = args.meshes or list(REAL_MESHES)
    variants = {
        k: v
        for k, v in {**REAL_VARIANTS, **EXTRA_REAL}.items()
        if (not args.variants and k in REAL_VARIANTS)
        or (args.variants and any(x in k for x in args.variants))
    }
    for name in names:
        if not (DATA / REAL_MESHES[name][0]).exists():
            print(f"skip {name}: {DATA / REAL_MESHES[name][0]} not found", flush=True)
            continue
        s, sc, field = _load_real(name)
        edge = mean_edge_length(s.vertices, s.faces)
        tree = cKDTree(s.vertices)
        for n in sizes:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                try:
                    t = remesh(s, n_vertices=n, key=jax.random.key(7))
                except Exception as err:  # noqa: BLE001
                    report.add(
                        mesh=name,
                        size=f"{s.num_vertices}->{n}",
                        method="remesh",
                        error=f"{type(err).__name__}: {str(err)[:160]}",
                    )
                    continue
                remesh_s = time.perf_counter() - t0
            truth = np.clip(
                field(t.vertices) if field is not None else np.asarray(t.vertex_colors)[:, :3], 0, 1
            )
            t = Mesh(t.vertices, t.faces)
            gt = tree.query(t.vertices)[1]
            base = {"mesh": name, "size": f"{s.num_vertices}->{t.num_vertices}"}
            ceiling = round(psnr(np.clip(sc[gt], 0, 1), truth), 2)
            report.add(
                **base,
                method="nearest-3D copy (ceiling)",
                psnr_db=ceiling,
                remesh_s=round(remesh_s, 1),
            )
            print(
                f"{name} {base['size']}: ceiling {ceiling} dB (remesh {remesh_s:.1f} s)", flush=True
            )
            for label, extra in variants.items():
                cfg = Config.from_dict(extra)
                t0 = time.perf_counter()
                try:
                    r = meshmatch(s, sc, t, key=jax.random.key(0), config=cfg)
                except Exception as err:  # noqa: BLE001 -- a failed case is a result too; keep the others
                    report.add(
                        **base, method=label, error=f"{type(err).__name__}: {str(err)[:160]}"
                    )
                    print(
                        f"{name} {base['size']} | {label}: {type(err).__name__}: {err}", flush=True
                    )
                    continue
                seconds = time.perf_counter() - t0
                diag = _mirror_diagnosis(s, t, r.nnf, gt, sc, truth, edge)
                final = psnr(np.clip(r.colors, 0, 1), truth)
                report.add(
                    **base,
                    method=label,
                    psnr_db=round(final, 2),
                    voted_psnr_db=round(psnr(np.clip(r.voted, 0, 1), truth), 2),
                    gap_db=round(ceiling - final, 2),
                    **diag,
                    seconds=round(seconds, 1),
                    finest_iteration_s=_finest_iteration(r),
                    finest_steps=_finest_steps(r),
                    load=round(os.getloadavg()[0], 1),
                )
                row = report.rows[-1]
                print(
                    f"{name} {base['size']} | {label}: {row['psnr_db']} dB (voted {row['voted_psnr_db']}), "
                    f"far {row['far_pct']} % ({row['far_mirrored_pct']} % mirrored), {seconds:.0f} s",
                    flush=True,
                )
            report.write(pathlib.Path(args.out) if args.out else None)  # keep what is done
    report.notes.append(
        "Source: the mesh as stored (after prepare_mesh); target: remesh of it (key 7) at the size; "
        "colours: a smooth function of position (untextured meshes) or Spot's texture (source: "
        "area prefilter; target truth: the remesh's point samples of the texture)."
    )
    report.notes.append(
        "psnr_db: final colours (copy of the match); voted_psnr_db: the finest vote; gap_db: ceiling "
        "minus psnr_db; far_pct: target vertices matched > 3 source edges from the nearest source "
        "vertex; far_mirrored_pct: of those, matched within 3 edges of the mirror image across a "
        "principal plane; far_error_pct: their share of the squared error; seconds: the whole "
        "transfer incl. compiles; finest_iteration_s: median wall time of the finest level's "
        "iterations after the first (shared 2-core machine, load = 1-minute load average)."
    )
    report.write(pathlib.Path(args.out) if args.out else None)


#: further real-suite rows, run only when named by --variants
EXTRA_REAL = {
    "fan-footprint vote (paper)": {"vote": "fan"},
    "offset upsampling + re-vote (paper)": {"upsample": "offset"},
    "fan vote + offset upsampling (paper)": {"vote": "fan", "upsample": "offset"},
    "intrinsic + fan vote + offset upsampling": {
        "aligned": False,
        "vote": "fan",
        "upsample": "offset",
    },
    "Config.intrinsic(up='y') (the model's up axis)": {"aligned": False, "up": "y"},
    "Config.intrinsic(up='y', side='z') (the cow's left/right axis)": {
        "aligned": False,
        "up": "y",
        "side": "z",
    },
    "Config.intrinsic(up='y', side='x') (Spot's left/right axis)": {
        "aligned": False,
        "up": "y",
        "side": "x",
    },
}


def speed(report: Report, cfg: Config, sizes: list[int]) -> None:
    """The speed suite (module docstring) with ``cfg``, at each of ``sizes`` (16 and/or 64: K target
    vertices)."""
    source, source_colors = _torus(128, 80)  # 10240 vertices
    print(f"source {source.num_vertices} vertices")
    for size in sizes:
        n_major = {16: 128, 64: 256}[size]
        target, truth = _torus(n_major, n_major)
        tv = target.vertices
        print(f"target {len(tv)} vertices")
        t0 = time.perf_counter()
        s_side = prepare_side(source, cfg)
        t_side = prepare_side(target, cfg, hks_times=s_side.hks_times)
        prep = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = meshmatch(
            source,
            source_colors,
            target,
            key=jax.random.key(0),
            config=cfg,
            prepared=(s_side, t_side),
            progress=print,
        )
        total = time.perf_counter() - t0
        levels = r.stats["levels"]
        # one compiled step per padded shape (levels padded to a group's shape share one)
        compiles = len({(s["padded_vertices"], s["padded_source_vertices"]) for s in levels})
        finest = next(s for s in levels if s["level"] == 0)
        # the finest level's iterations after its first (which may include compiling the step)
        runs = finest["iteration_seconds"][1:] or finest["iteration_seconds"]
        cpu = finest["iteration_cpu_seconds"][1:] or finest["iteration_cpu_seconds"]
        it = float(np.median(runs))
        it_cpu = float(np.median(cpu))
        quality = psnr(r.colors, truth)
        per_level = {s["level"]: round(s["seconds"], 2) for s in levels}
        iters = {s["level"]: s["steps"] for s in levels}
        print(
            f"{len(tv)} V: preprocessing {prep:.1f} s, fans {r.stats['fans_s']:.1f} s, iteration {it:.3f} s, "
            f"(CPU {it_cpu:.3f} s), total {total:.1f} s (+ preprocessing), PSNR {quality:.1f} dB, {compiles} compiled step shapes, "
            f"per level s {per_level}, iterations {iters}"
        )
        label = Size(size_label(len(tv)), vertices=len(tv))
        load = round(os.getloadavg()[0], 1)
        report.add(
            name="preprocessing (hierarchies, HKS, tracer tables)",
            size=label,
            seconds=prep,
            load=load,
        )
        report.add(
            name="fans traced + uploaded (all levels)",
            size=label,
            seconds=r.stats["fans_s"],
            load=load,
        )
        # estimated float32 words read per target vertex: fan samples (R·A·3 corners·C) + smoothing,
        # per sweep the bound pre-score (13 candidates × 27), exact rows ((P+1) × 190) and propagation
        # stars, and the vote
        words = (
            3 * 18 * 3 * 3
            + 36
            + cfg.sweeps * (13 * 27 + (cfg.experimental.exact_candidates + 1) * 190 + 168)
            + 252
        )
        bytes_moved = len(tv) * 4 * words
        report.add(
            name="PatchMatch iteration, finest level (target 0.65 s at 64K)",
            size=label,
            seconds=it,
            bytes=bytes_moved,
            bound="bandwidth",
            load=load,
            cpu_seconds=round(it_cpu, 3),
        )
        report.add(
            name=f"transfer incl. fans + {compiles} compiles (target 60 s)",
            size=label,
            seconds=total,
            load=load,
        )
        report.add(name="preprocessing + transfer", size=label, seconds=prep + total, load=load)
        report.add(
            name="self-transfer PSNR (dB, >= 20 asked)",
            size=label,
            seconds=0.0,
            psnr_db=round(quality, 2),
            load=load,
        )
        # the ceiling: each target vertex copies the nearest source vertex (the 16K target shares the
        # source's 128 columns around the ring, the 64K one puts every second column between them)
        near = source_colors[cKDTree(source.vertices).query(tv)[1]]
        report.add(
            name="nearest-3D copy PSNR (ceiling of the copied output)",
            size=label,
            seconds=0.0,
            psnr_db=round(psnr(near, truth), 2),
            load=load,
        )
        report.add(
            name="self-transfer PSNR of the finest vote",
            size=label,
            seconds=0.0,
            psnr_db=round(psnr(np.clip(r.voted, 0, 1), truth), 2),
            load=load,
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "--suite",
        choices=("speed", "cross", "figure", "real"),
        default="speed",
        help="figure: results/meshmatch_cross.png (intrinsic vs the aligned default, two pairs)",
    )
    ap.add_argument(
        "--small", action="store_true", help="cross suite at half resolution (the test's sizes)"
    )
    ap.add_argument("--sizes", default="16,64", help="target sizes in K vertices (16 and/or 64)")
    ap.add_argument("--out", default=None)
    ap.add_argument(
        "--variants",
        nargs="*",
        default=None,
        metavar="TEXT",
        help="cross suite: run only the variants whose label contains one of these (no diagnosis rows)",
    )
    ap.add_argument("--large", action="store_true", help="real suite: also the 60K targets")
    ap.add_argument("--real-sizes", default=None, help="real suite: target sizes, e.g. 5000,20000")
    ap.add_argument("--meshes", nargs="*", default=None, help="real suite: only these meshes")
    args = ap.parse_args()
    if args.suite == "real":
        real(args)
        return
    if args.suite == "cross":
        cross(args)
        return
    if args.suite == "figure":
        figure(args)
        return
    report = Report("meshmatch")
    speed(report, Config(), [int(s) for s in args.sizes.split(",")])
    report.write(pathlib.Path(args.out) if args.out else None)


if __name__ == "__main__":
    main()

"""Study: coherent field latents on Spot (``fldm.Config.experimental.phase_sync``; beyond the paper).

Run::

    python studies/fldm_phase_sync.py                   # 3,000-vertex copies (~3 CPU-min)
    python studies/fldm_phase_sync.py --vertices 10000 --name fldm_phase_sync_10k

Writes ``studies/results/fldm_phase_sync.{json,md}``. Two re-triangulated copies of Spot
(``fldm.core`` ``copy_mesh`` with the FLDM data key) are encoded with the shipped FL-VAE pair (the
log decoder and its barycentric ablation), and each encoding's phases are left as they are
(``none``), synchronised on flat rings (``flat``: textured rings, colour spread ≥ ``flat_spread``,
pinned) or on every ring (``all``). Per row:

- ``flat_frac``: the fraction of free (turned) vertices;
- ``coh``, ``coh_flat``, ``coh_textured``: transported phase coherence of neighbouring latents
  (``fldm.core.transported_phase_coherence``) over all, flat and textured vertices;
- ``psnr``: decoded colours at 100,000 random surface points of copy 0 against Spot's texture read
  at the same points; ``dpsnr``: its change from the same codec's ``none`` row (what the turn costs);
- ``lin_err_a50``, ``lin_err_a15``: the best gauge-equivariant linear denoiser's relative error
  ``Σ|x̂₀ − x₀|² / Σ|x₀|²`` at ``ᾱ = 0.5`` and ``0.15`` (latents scaled per channel to unit power,
  unit complex noise; ``x̂₀ = A z_t + B m_t`` with ``m_t`` the mean of the transported k-NN
  neighbours, complex ``A, B`` fitted by least squares on copy 1 and scored on copy 0): where
  neighbour sums cancel (phase noise), ``B`` cannot help, and a trained denoiser has the same
  handicap (DESIGN.md, "latent structure before budget").

Rows ``flat_spread=…`` sweep the flat-ring threshold for the log codec.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import jax
import numpy as np
from _study import Report, Size, size_label

from jmeshtex import fl, fldm
from jmeshtex.fldm.core import (
    denoiser_geometry,
    ring_color_spread,
    synchronize_phases,
    transported_phase_coherence,
)

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _spot():
    from jmeshtex.io import load_mesh

    d = pathlib.Path(os.environ.get("JMESHTEX_SHARED_DATA", ROOT / ".." / "shared" / "data"))
    d = d / "spot"
    return load_mesh(d / "spot_triangulated.obj", texture=d / "spot_texture.png")


def _linear_denoiser_error(fit, test, alpha_bar: float, *, seed: int = 0) -> float:
    """Relative x̂₀ error of the least-squares ``x̂₀ = A z_t + B m_t`` (module docstring)."""
    rng = np.random.default_rng(seed)

    def features(z, nb):
        zt = np.sqrt(alpha_bar) * z + np.sqrt(1 - alpha_bar) * (
            rng.standard_normal(z.shape) + 1j * rng.standard_normal(z.shape)
        ) / np.sqrt(2)
        idx, mask = np.asarray(nb.index), np.asarray(nb.mask).astype(bool)
        mask &= idx != np.arange(len(idx))[:, None]
        m = (np.asarray(nb.transport)[..., None] * zt[idx] * mask[..., None]).sum(1)
        m /= np.maximum(mask.sum(1), 1)[:, None]
        return np.concatenate([zt, m], axis=1)

    (zf, nbf), (zs, nbs) = fit, test
    X = np.concatenate([features(zf, nbf) for _ in range(3)])
    Y = np.concatenate([zf] * 3)
    W = np.linalg.lstsq(X, Y, rcond=None)[0]
    pred = features(zs, nbs) @ W
    return float(np.sum(np.abs(pred - zs) ** 2) / np.sum(np.abs(zs) ** 2))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=3000)
    ap.add_argument("--name", default="fldm_phase_sync")
    ap.add_argument("--out", type=pathlib.Path, default=None)
    args = ap.parse_args(argv)
    report = Report(args.name, ceilings=False)
    spot = _spot()
    colors = fl.core.surface_colors(spot)
    cfg = fldm.Config.cpu(copy_vertices=args.vertices)
    copies = [fldm.core.copy_mesh(spot, cfg, i, key=jax.random.key(0)) for i in range(2)]
    geos = [denoiser_geometry(c, knn=cfg.knn, pool_ratio=cfg.pool_ratio).fine for c in copies]
    spreads = [ring_color_spread(c, colors) for c in copies]
    rng = np.random.default_rng(0)
    c0 = copies[0]
    face = rng.integers(0, len(c0.faces), 100_000)
    bary = rng.dirichlet(np.ones(3), 100_000)
    truth = colors.at_points(np.einsum("nk,nkd->nd", bary, c0.vertices[c0.faces[face]]))
    size = Size(size_label(c0.num_vertices), vertices=c0.num_vertices)

    def psnr(vae, mu):
        x = np.clip(fl.decode_points_in_faces(vae, c0, mu, face, bary), 0, 1)
        return float(10 * np.log10(1.0 / np.mean((x - truth) ** 2)))

    def row(name, vae, mus, pinned, base):
        t = time.perf_counter()
        synced = [
            m if p is False else synchronize_phases(m, nb, pinned=None if p is None else p)
            for m, nb, p in zip(mus, geos, pinned, strict=True)
        ]
        seconds = (time.perf_counter() - t) / 2
        free = np.ones(c0.num_vertices, bool) if pinned[0] is None else ~np.asarray(pinned[0])
        if pinned[0] is False:
            free = (
                spreads[0] < cfg.experimental.flat_spread
            )  # report the flat rings' coherence all the same

        def coh(mask):
            return (
                float(transported_phase_coherence(synced[0], geos[0], mask)) if mask.any() else None
            )

        scaled = [s * fldm.core.latent_scale(synced[1]) for s in synced]
        p = psnr(vae, synced[0])
        return report.add(
            name=name,
            size=size,
            flat_frac=float(free.mean()) if pinned[0] is not False else 0.0,
            coh=float(transported_phase_coherence(synced[0], geos[0])),
            coh_flat=coh(free),
            coh_textured=coh(~free),
            psnr=p,
            dpsnr=None if base is None else p - base,
            lin_err_a50=_linear_denoiser_error((scaled[1], geos[1]), (scaled[0], geos[0]), 0.5),
            lin_err_a15=_linear_denoiser_error((scaled[1], geos[1]), (scaled[0], geos[0]), 0.15),
            sync_seconds=seconds,
        )

    for decoder in ("log", "barycentric"):
        vae = fl.load_pretrained(decoder=decoder)
        mus = [
            np.asarray(
                fl.encode(vae, c, colors=colors, key=jax.random.key(1 + i)).mu, np.complex128
            )
            for i, c in enumerate(copies)
        ]
        base = row(f"{decoder} none", vae, mus, [False, False], None)["psnr"]
        flat = [s >= cfg.experimental.flat_spread for s in spreads]
        row(f"{decoder} flat", vae, mus, flat, base)
        row(f"{decoder} all", vae, mus, [None, None], base)
        if decoder == "log":
            for thr in (0.005, 0.08):
                row(f"log flat_spread={thr}", vae, mus, [s >= thr for s in spreads], base)
    report.notes += [
        "Beyond the paper: `fldm.Config.experimental.phase_sync`; see the module docstring of "
        "`studies/fldm_phase_sync.py` for the columns. `dpsnr` is the change of the decoded "
        "colours' PSNR against the same codec's `none` row; `lin_err_*` the best local "
        "gauge-equivariant linear denoiser's relative x̂₀ error (lower: more structure a denoiser "
        "can use)."
    ]
    report.config = dict(
        vertices=args.vertices, flat_spread=cfg.experimental.flat_spread, knn=cfg.knn
    )
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The surface-CNN stage of ``jmeshtex demo``: a small texture synthesised on a torus."""

from __future__ import annotations

import time

import numpy as np

from ._views import Progress, folder, say, view

#: the Gram layers of the quick demo (the first three VGG blocks: fast to compile on a CPU)
QUICK_LAYERS = ("relu1_1", "relu1_2", "pool1", "relu2_1", "relu2_2", "pool2", "relu3_1")


def demo_exemplar(size: int = 64) -> np.ndarray:
    """A furry exemplar from scikit-image's bundled ``chelsea`` photo (no download), ``[size, size, 3]``.

    Example:
      >>> demo_exemplar(32).shape
      (32, 32, 3)
    """
    import skimage.data
    import skimage.transform

    crop = skimage.data.chelsea()[100:260, 150:310]
    return skimage.transform.resize(crop, (size, size), anti_aliasing=True).astype(np.float64)


def demo_stage(out_dir, *, quick: bool, progress: Progress = None) -> dict:
    """Synthesise a 128² texture on an xatlas-unwrapped torus; write the figure and summarise.

    Args:
      out_dir: folder for ``surfacecnn.png`` (the figure, :func:`jmeshtex.render.figure`: the
        exemplar, two textured views, the texture atlas, and the protocol's baselines on the same
        UVs: the exemplar's mean colour (:func:`~jmeshtex.metrics.flat_baseline`) and its texels
        shuffled (:func:`~jmeshtex.metrics.permuted_baseline`)) and ``result/`` (the result folder
        of :func:`jmeshtex.surfacecnn.save`: ``texture.png``, ``textured.obj``, ``result.npz``).
      quick: 40 steps on the first three VGG-16 blocks (< 30 s on 2 cores); otherwise 150 steps on
        every ReLU and pool output.
      progress: called with status lines, or None; with a hook, the optimisation shows its own
        tqdm bar.

    Returns:
      ``{"summary": str, "loss_drop": float, "seconds": float, "files": [...]}``.
    """
    import jax

    from ... import surfacecnn
    from ...data import torus
    from ...metrics import flat_baseline, permuted_baseline
    from ...render import figure

    out = folder(out_dir)
    t0 = time.perf_counter()
    exemplar = demo_exemplar()
    config = surfacecnn.Config(size=128, steps=40 if quick else 150)
    say(progress, f"synthesis, {config.steps} steps")
    result = surfacecnn.synthesize(
        torus(48, 24),
        exemplar,
        config,
        key=jax.random.key(0),
        layers=QUICK_LAYERS if quick else None,
        progress=progress is not None,
    )
    say(progress, "saving and rendering")
    saved = surfacecnn.save(result, out / "result")
    m = result.mesh
    reps = -(-config.size // exemplar.shape[0])
    shuffled = np.tile(permuted_baseline(exemplar, key=jax.random.key(1)), (reps, reps, 1))[
        : config.size, : config.size
    ]
    flat = flat_baseline(exemplar)[:1, :1] * np.ones((config.size, config.size, 1))

    def torus_view(texture, azimuth=-60.0):
        return view(
            (m.vertices, m.faces), uv=m.uv, texture=texture, azimuth=azimuth, elevation=35.0
        )

    figure(
        [
            ("exemplar", np.kron(exemplar, np.ones((4, 4, 1)))),
            ("synthesised (front)", torus_view(result.texture)),
            ("synthesised (back)", torus_view(result.texture, 120.0)),
            ("texture atlas", np.kron(result.texture, np.ones((2, 2, 1)))),
            ("baseline: flat", torus_view(flat)),
            ("baseline: shuffled texels", torus_view(shuffled)),
        ],
        columns=6,
        title="Surface CNN: VGG-16 Gram statistics of a photo matched on a torus's texels",
        path=out / "surfacecnn.png",
    )
    seconds = time.perf_counter() - t0
    drop = float(result.losses[0] / max(result.final_loss, 1e-30))
    return {
        "summary": (
            f"surface CNN: {result.stats['texels']} texels at 128² on a torus, Gram loss "
            f"{result.losses[0]:.3g} → {result.final_loss:.3g} ({drop:.0f}× lower) in "
            f"{config.steps} steps, {seconds:.1f} s"
        ),
        "loss_drop": drop,
        "seconds": seconds,
        "files": [str(out / "surfacecnn.png"), *(str(p) for p in sorted(saved.iterdir()))],
    }

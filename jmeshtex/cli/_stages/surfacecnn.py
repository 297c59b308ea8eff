"""The surface-CNN stage of ``jmeshtex demo``: a small texture synthesised on a torus."""

from __future__ import annotations

import pathlib
import time

import numpy as np

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


def demo_stage(out_dir, *, quick: bool) -> dict:
    """Synthesise a 128² texture on an xatlas-unwrapped torus; write renders and summarise.

    Args:
      out_dir: the result folder of :func:`jmeshtex.surfacecnn.save` (``texture.png``,
        ``textured.obj``, the renders, ``surfacecnn.png``, ``result.npz``).
      quick: 40 steps on the first three VGG-16 blocks (< 30 s on 2 cores); otherwise 150 steps on
        every ReLU and pool output.

    Returns:
      ``{"summary": str, "loss_drop": float, "seconds": float, "files": [...]}``.

    Example:
      >>> import tempfile
      >>> out = demo_stage(tempfile.mkdtemp(), quick=True)  # doctest: +SKIP
    """
    import jax

    from ... import surfacecnn
    from ...data import torus

    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    exemplar = demo_exemplar()
    config = surfacecnn.Config(size=128, steps=40 if quick else 150)
    result = surfacecnn.synthesize(torus(48, 24), exemplar, config, key=jax.random.key(0),
                                   layers=QUICK_LAYERS if quick else None, progress=False)
    summary = surfacecnn.save(result, out, exemplar=exemplar, title="surface CNN")
    seconds = time.perf_counter() - t0
    drop = float(result.losses[0] / max(result.final_loss, 1e-30))
    return {
        "summary": (f"surface CNN: {result.stats['texels']} texels at 128² on a torus, Gram loss "
                    f"{result.losses[0]:.3g} → {result.final_loss:.3g} ({drop:.0f}× lower) in "
                    f"{config.steps} steps, {seconds:.1f} s"),
        "loss_drop": drop,
        "seconds": seconds,
        "files": summary["files"],
    }

"""A PNG of a training run's loss curve (raw per-step values and a moving average, log scale)."""

from __future__ import annotations

import io
import os

import numpy as np

from .._errors import InputError


def plot_losses(
    losses: dict, path: str | os.PathLike, *, title: str = "FL-VAE training", window: int = 100
) -> None:
    """Write a loss-curve PNG: every named series per step (faint) and its moving average (solid).

    Args:
      losses: ``{name: [steps] values}`` (e.g. :attr:`~jmeshtex.TrainResult.losses`).
      path: output ``.png`` (written atomically; parent folders created).
      title: figure title.
      window: moving-average window in steps (shortened for short runs).

    Raises:
      InputError: no series, or every series empty.

    Example:
      >>> import numpy as np, tempfile, pathlib
      >>> p = pathlib.Path(tempfile.mkdtemp()) / "loss.png"
      >>> plot_losses({"loss": np.linspace(1, 0.1, 50)}, p)
      >>> p.read_bytes()[:4] == b"\\x89PNG"
      True
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..io import atomic_write

    series = {k: np.asarray(v, np.float64) for k, v in losses.items() if len(v)}
    if not series:
        raise InputError("plot_losses: no non-empty loss series")
    fig = Figure(figsize=(7, 4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for i, (name, y) in enumerate(series.items()):
        color = f"C{i}"
        x = np.arange(1, len(y) + 1)
        ax.plot(x, y, color=color, alpha=0.25, linewidth=0.6)
        w = max(1, min(int(window), len(y) // 5 or 1))
        avg = np.convolve(y, np.ones(w) / w, mode="valid")
        ax.plot(
            x[w - 1 :],
            avg,
            color=color,
            linewidth=1.5,
            label=f"{name} (mean of {w}; last {avg[-1]:.4g})",
        )
    if all((y > 0).all() for y in series.values()):
        ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("loss")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())

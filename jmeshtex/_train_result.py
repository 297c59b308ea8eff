"""The result of every method's ``train``: one type, the same fields everywhere.

Example:
  >>> r = TrainResult(model="m", losses={"loss": [1.0, 0.5]}, steps=2, seconds=0.1)
  >>> r.final_loss("loss"), r.resumed_from is None
  (0.5, True)
"""

from __future__ import annotations

import dataclasses
from typing import Any, Generic, TypeVar

import numpy as np

M = TypeVar("M")


@dataclasses.dataclass(frozen=True)
class TrainResult(Generic[M]):
    """What ``dgts.train``, ``fl.train`` and ``fldm.train`` return.

    Attributes:
      model: the method's ``Model`` (parameters bundled with their config), ready for ``save`` and
        the task verbs.
      losses: per-step histories by name (``"loss"``, ``"generator"``, ...), each a 1-D float array
        over every step done so far, resumed steps included.
      steps: optimiser steps done in total (resumed ones included).
      seconds: wall time of the whole ``train`` call (data, initialisation and compilation
        included).
      compile_seconds: the part of ``seconds`` spent compiling the training step.
      resumed_from: the checkpoint step this call resumed from, or None for a fresh run.
      extra: method-specific records (per-level reports for DGTS, ...).
    """

    model: M
    losses: dict[str, Any]
    steps: int
    seconds: float
    resumed_from: int | None = None
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)
    compile_seconds: float = 0.0

    def final_loss(self, name: str = "loss") -> float:
        """The last recorded value of loss ``name`` (NaN when none was recorded)."""
        values = np.asarray(self.losses.get(name, ()), dtype=np.float64).reshape(-1)
        return float(values[-1]) if values.size else float("nan")

"""The smooth-isometry verdict's notes: the exclusion cap applies at the finest resolution, and a
failure's hint never asks for what the entry already sets."""

from __future__ import annotations

from jmeshtex.testing import MAX_EXCLUDED, Convergence, Entry, Field
from jmeshtex.testing._registry import _order_detail


def _entry(hops):
    return Entry(
        "t", lambda s, p, x: Field("vertex_tangent", x), {"x": ("vertex_tangent", 1)},
        ("cylinder",), selection=lambda s: None, hops=hops,
    )  # fmt: skip


def _conv(excluded):
    return Convergence((8, 16, 32, 64), (1e-2, 2e-3, 5e-4, 1e-4), (5, 4, 5), (2.3, 2, 2.3), False,
                       excluded)  # fmt: skip


def test_the_note_gives_the_coarsest_and_finest_exclusions():
    text = _order_detail(_conv((0.3, 0.1, 0.02, 0.005)), _entry(3), True)
    assert "30.0% → 0.5%" in text and "within 3 hops" in text and "set Entry" not in text


def test_a_failure_with_hops_set_does_not_ask_for_hops():
    failed = (0.5, 0.4, 0.3, 2 * MAX_EXCLUDED)
    text = _order_detail(_conv(failed), _entry(3), False)
    assert "finest resolution" in text and "hops=" not in text
    text = _order_detail(_conv(failed), _entry(1), False)
    assert "Entry(hops=<layers>)" in text

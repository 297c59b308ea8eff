"""The fault campaign through the Python API: bad meshes and numerical extremes into every public
mesh-taking entry.

Each case is a ``(vertices, faces)`` pair: the bad-mesh generator's kinds
(:func:`jmeshtex.testing.bad_meshes`, two draws per kind of ``BAD_MESH_KINDS``), a valid icosphere
scaled by 1e30, 1e12 and 1e-3 or moved by 1e8, and the valid icosphere itself (the control: every
entry must run on it). Every entry, with a tiny configuration, must either raise a typed error (a
subclass of :class:`jmeshtex.JmeshtexError`) or return only finite numbers, within
``CASE_SECONDS``; never a raw ``IndexError``/``ValueError``, never NaN. The per-entry counts of each
outcome class are printed (``-s``) and kept in ``SUMMARY`` for whoever reads them.
"""

from __future__ import annotations

import collections
import dataclasses
import time
import warnings

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from jmeshtex import JmeshtexError, Mesh, dgts, fl, fldm, geometry, meshmatch, metrics, surfacecnn
from jmeshtex.data import icosahedron, icosphere, torus
from jmeshtex.testing import BAD_MESH_KINDS, bad_meshes
from tests._presets import FLDM_MICRO

#: seconds one case may take in one entry (a refusal takes milliseconds; the control runs a tiny
#: configuration of each method, whose first call compiles)
CASE_SECONDS = 20.0
#: draws per bad-mesh kind
DRAWS = 4

SUMMARY: dict[str, collections.Counter] = {}
"""``{entry: Counter(outcome class)}`` of the last run (outcome: ``finite``, ``typed <Error>``, or
one of the failures ``untyped <Error>``, ``non-finite``, ``slow``)."""


def _draw_bad_cases() -> list[tuple[str, object, object]]:
    cases: list[tuple[str, object, object]] = []

    @settings(
        max_examples=DRAWS,
        derandomize=True,
        database=None,
        deadline=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(st.data())
    def collect(data):
        for kind in BAD_MESH_KINDS:
            v, f = data.draw(bad_meshes(kind, max_vertices=30), label=kind)
            cases.append((kind, v, f))

    collect()
    return cases


def _extreme_cases() -> list[tuple[str, object, object]]:
    v, f = icosphere(1)
    return [
        ("valid", v, f),
        ("scale 1e30", v * 1e30, f),
        ("scale 1e12", v * 1e12, f),
        ("scale 1e-3", v * 1e-3, f),
        ("offset 1e8", v + 1e8, f),
    ]


def _colored(v, f) -> Mesh:
    """A Mesh with vertex colours (the faces as given: a bad list stays a bad list)."""
    v = np.asarray(v)
    n = len(v) if v.ndim >= 1 else 0
    colors = np.random.default_rng(0).uniform(0.2, 0.8, (n, 3)).astype(np.float32)
    return Mesh(v, f, vertex_colors=colors)


def _textured(v, f) -> Mesh:
    """A Mesh with a small UV texture (random corner UVs, one per face row given)."""
    rows = len(f) if hasattr(f, "__len__") else 0
    rng = np.random.default_rng(0)
    texture = rng.uniform(0.2, 0.8, (8, 8, 3)).astype(np.float32)
    return Mesh(np.asarray(v), f, uv=rng.uniform(0, 1, (rows, 3, 2)), texture=texture)


def _half_mask(v) -> np.ndarray:
    """The painted region of paint_by_example: the vertices with x above the median."""
    v = np.asarray(v, np.float64)
    if v.ndim != 2 or not len(v) or v.shape[1] < 1:
        return np.zeros(len(v) if v.ndim else 0, bool)
    with np.errstate(invalid="ignore"):
        return v[:, 0] > np.median(v[:, 0])


def _colour_latents(mesh: Mesh) -> np.ndarray:
    """A tiny analytic codec: two complex channels from the vertex colours (no FL-VAE needed)."""
    c = np.asarray(mesh.vertex_colors, np.float64)
    return np.stack([c[:, 0] + 1j * c[:, 1], c[:, 2] - 0.5 + 0.3j], axis=1)


_KEY = jax.random.key(0)
_EXEMPLAR = np.random.default_rng(0).uniform(size=(8, 8, 3))
_FLDM = FLDM_MICRO.replace(n_copies=1, batch_size=1)
_VIEWS = metrics.Protocol(azimuths=2, elevations=(20.0,), size=16, supersample=1)
_MESHMATCH = meshmatch.Config(levels=1, steps=1, coarse_steps=2, hks_eigenpairs=8)


def _meshmatch_source() -> Mesh:
    sphere = icosphere(1)
    colors = 0.5 + 0.4 * np.sin(5 * sphere.vertices)
    return sphere.replace(vertex_colors=colors.astype(np.float32))


@pytest.fixture(scope="module")
def models():
    """The trained pieces the entries need: the shipped FL-VAE, an untrained two-level DGTS model."""
    c = dgts.Config(num_layers=3, start_features=4, min_features=4, max_features=4)
    gs = tuple(dgts.core.init_level(c, i, generator=True, key=jax.random.key(i)) for i in range(2))
    return {
        "fl": fl.load_pretrained(),
        "dgts": dgts.Model(c, gs, gs, np.zeros((12, 3), np.float32)),
    }


def _entries(models) -> dict:
    """``{name: call(vertices, faces)}``: every public entry that takes a mesh, tiny settings."""
    vae, dgts_model = models["fl"], models["dgts"]
    return {
        "geometry.validate_mesh": lambda v, f: geometry.validate_mesh(v, f),
        "geometry.prepare_mesh": lambda v, f: geometry.prepare_mesh((v, f)),
        "geometry.prepare_mesh(repair)": lambda v, f: geometry.prepare_mesh((v, f), repair=True),
        "dgts.training_meshes": lambda v, f: dgts.training_meshes(
            (v, f),
            icosahedron(),
            key=_KEY,
            config=dgts.PrepareConfig(levels=1, steps=2, samples_per_level=50),
            progress=False,
        ),
        "dgts.transfer": lambda v, f: dgts.transfer(dgts_model, (v, f), key=_KEY),
        "fl.encode": lambda v, f: fl.encode(vae, _colored(v, f), key=_KEY),
        "fl.reconstruct": lambda v, f: fl.reconstruct(
            vae, _textured(v, f), key=_KEY, size=16, lpips=False
        ),
        "fldm.build_dataset": lambda v, f: fldm.build_dataset(
            _colored(v, f), _FLDM, encode=_colour_latents, key=_KEY, progress=False
        ),
        "meshmatch.transfer (source)": lambda v, f: meshmatch.transfer(
            _colored(v, f), torus(6, 3), key=_KEY, config=_MESHMATCH, texture_size=16
        ),
        "meshmatch.transfer (target)": lambda v, f: meshmatch.transfer(
            _meshmatch_source(), (v, f), key=_KEY, config=_MESHMATCH, texture_size=16
        ),
        "meshmatch.transfer_displacement (target)": lambda v, f: meshmatch.transfer_displacement(
            _meshmatch_source(), (v, f), key=_KEY, config=_MESHMATCH, smoothing_steps=1
        ),
        "meshmatch.paint_by_example": lambda v, f: meshmatch.paint_by_example(
            _colored(v, f), _half_mask(v), key=_KEY, config=_MESHMATCH
        ),
        "surfacecnn.prepare_surface": lambda v, f: surfacecnn.prepare_surface(
            Mesh(np.asarray(v), f), size=8, levels=1
        ),
        "surfacecnn.synthesize": lambda v, f: surfacecnn.synthesize(
            Mesh(np.asarray(v), f),
            _EXEMPLAR,
            surfacecnn.Config(size=8, steps=1),
            key=_KEY,
            layers=("relu1_1",),
            progress=False,
        ),
        "metrics.protocol_views": lambda v, f: metrics.protocol_views(
            _colored(v, f), protocol=_VIEWS
        ),
    }


def _non_finite(value, depth: int = 0) -> bool:
    """Whether ``value`` (arrays, tuples, dicts, dataclasses, nested) holds a NaN or an infinity."""
    if depth > 6 or value is None or isinstance(value, (str, bytes, bool)):
        return False
    if isinstance(value, (float, complex, np.floating, np.complexfloating)):
        return not np.isfinite(value)
    if isinstance(value, (np.ndarray, jax.Array)):
        a = np.asarray(value)
        return np.issubdtype(a.dtype, np.inexact) and not np.isfinite(a).all()
    if isinstance(value, dict):
        return any(_non_finite(x, depth + 1) for x in value.values())
    if isinstance(value, (tuple, list)):
        return any(_non_finite(x, depth + 1) for x in value)
    if dataclasses.is_dataclass(value):
        return any(
            _non_finite(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)
        )
    return False


def _outcome(call, v, f) -> tuple[str, float]:
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # repair notes are not failures here
        try:
            result = call(v, f)
        except JmeshtexError as error:
            outcome = f"typed {type(error).__name__}"
        except Exception as error:  # noqa: BLE001 - classified and reported below
            outcome = f"untyped {type(error).__name__}: {str(error)[:200]}"
        else:
            outcome = "non-finite" if _non_finite(result) else "finite"
    return outcome, time.perf_counter() - start


@pytest.mark.unchecked  # bad pairs on purpose: the entries' own typed errors are under test
def test_every_entry_refuses_bad_meshes_with_a_typed_error_or_returns_finite_output(models):
    cases = _draw_bad_cases() + _extreme_cases()
    assert len(cases) == DRAWS * len(BAD_MESH_KINDS) + 5
    problems = []
    SUMMARY.clear()
    for entry, call in _entries(models).items():
        counts = SUMMARY.setdefault(entry, collections.Counter())
        for name, v, f in cases:
            outcome, seconds = _outcome(call, v, f)
            counts[outcome.split(":")[0]] += 1
            if seconds > CASE_SECONDS:
                counts["slow"] += 1
                problems.append(f"{entry} / {name}: {seconds:.1f} s")
            if not (outcome == "finite" or outcome.startswith("typed ")):
                problems.append(f"{entry} / {name}: {outcome}")
            if name == "valid" and outcome != "finite":
                problems.append(f"{entry} / the valid control: {outcome}")
            if name in BAD_MESH_KINDS and entry == "geometry.validate_mesh":
                if outcome != f"typed {BAD_MESH_KINDS[name].__name__}":
                    problems.append(f"validate_mesh / {name}: {outcome}")
    width = max(map(len, SUMMARY))
    print()
    for entry, counts in SUMMARY.items():
        print(f"{entry:<{width}}  " + ", ".join(f"{k} {n}" for k, n in sorted(counts.items())))
    assert not problems, "\n".join(problems)


def test_the_classifier_sees_untyped_errors_and_nan():
    def raw(v, f):
        raise IndexError("index 3 is out of bounds")

    assert _outcome(raw, None, None)[0].startswith("untyped IndexError")
    assert _outcome(lambda v, f: {"x": (np.array([1.0, np.nan]),)}, None, None)[0] == "non-finite"
    assert _outcome(lambda v, f: Mesh(np.full((3, 3), np.inf), None), None, None)[0] == "non-finite"
    assert _outcome(lambda v, f: np.ones(3), None, None)[0] == "finite"

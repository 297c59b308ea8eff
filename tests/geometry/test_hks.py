"""Heat kernel signature and Laplacian eigenpairs: isometry invariance, sphere, positivity, errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jmeshtex import FaceIndexError, InputError
from jmeshtex.data import grid, icosphere, torus
from jmeshtex.geometry import heat_kernel_signature, hks_times, laplacian_eigenpairs


def _sheared_sheet(nx: int = 12, ny: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """A flat sheet whose triangulation is strictly Delaunay (no cocircular quads).

    Shearing x by -0.3 y makes each cell's mesh diagonal the short one, so the intrinsic Delaunay
    flips inside ``robust_laplacian`` never face a tie that round-off could decide differently. The
    aspect ratio avoids the square's degenerate eigenvalues.
    """
    v, f = grid(nx, ny, size=(1.0, 0.8), diagonals="uniform")
    v[:, 0] -= 0.3 * v[:, 1]
    return v, f


def _fold(v: np.ndarray, row_y: float, angle: float) -> np.ndarray:
    """Rotate the part of a z = 0 sheet above the mesh line y = row_y about that line (an isometry)."""
    w = v.copy()
    up = v[:, 1] > row_y + 1e-12
    d = v[up, 1] - row_y
    w[up, 1] = row_y + np.cos(angle) * d
    w[up, 2] = np.sin(angle) * d
    return w


def test_invariant_under_a_fold_of_a_flat_sheet():
    v, f = _sheared_sheet()
    row_y = np.unique(v[:, 1])[4]
    w = _fold(v, row_y, angle=1.1)
    # the fold is an exact isometry of the mesh: edge lengths agree to round-off
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    length = lambda x: np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)  # noqa: E731
    np.testing.assert_allclose(length(w), length(v), rtol=1e-14)
    assert np.ptp(w[:, 2]) > 0.3  # and it really is folded
    h_flat = heat_kernel_signature(v, f, k=60)
    h_fold = heat_kernel_signature(w, f, k=60)
    # The Laplacian only sees edge lengths, so the two matrices agree to ~1e-16 relative; eigsh with
    # tol=0 (machine precision) then returns eigenvalues to ~1e-13 relative and eigenvectors whose
    # squares, summed over the spectrum, agree to ~1e-15 (measured). 1e-8 leaves room for a
    # different LAPACK/ARPACK build while still catching any extrinsic (angle-based) quantity,
    # which moves by ~1e-4 under this fold.
    np.testing.assert_allclose(h_fold, h_flat, rtol=1e-8)
    # control: a 1 % stretch of the same part (not an isometry) moves the signature well above that
    up = v[:, 1] > row_y + 1e-12
    stretched = w.copy()
    stretched[up, 1] = row_y + 1.01 * (w[up, 1] - row_y)
    stretched[up, 2] = 1.01 * w[up, 2]
    h_stretched = heat_kernel_signature(stretched, f, k=60)
    assert np.max(np.abs(h_stretched - h_flat) / h_flat) > 1e-4


def test_invariant_under_rigid_motion(rng):
    v, f = icosphere(2)
    # radial bumps break the icosahedral symmetry: no degenerate eigenvalue straddles k
    v = v * (1.0 + 0.1 * rng.uniform(-1, 1, size=(len(v), 1)))
    R = Rotation.random(random_state=rng).as_matrix()
    w = v @ R.T + rng.normal(size=3) * 5.0
    ev = laplacian_eigenpairs(v, f, k=30)
    ew = laplacian_eigenpairs(w, f, k=30)
    assert np.min(np.diff(ev.values)) > 1e-6 * ev.values[-1], (
        "test mesh has a degenerate eigenvalue"
    )
    np.testing.assert_allclose(ew.values, ev.values, rtol=1e-9, atol=1e-10)
    h_v = heat_kernel_signature(v, f, eigenpairs=ev)
    h_w = heat_kernel_signature(w, f, eigenpairs=ew)
    # same argument as the fold test: the matrices agree to round-off
    np.testing.assert_allclose(h_w, h_v, rtol=1e-8)


def test_constant_on_a_sphere_and_converges_with_refinement():
    # k = 36 = (5 + 1)^2 holds complete clusters l = 0..5; by the addition theorem
    # sum_m Y_lm(x)^2 = (2l + 1) / 4π, so the continuous HKS is constant over the sphere.
    variation = []
    for s in (2, 3):
        v, f = icosphere(s)
        h = heat_kernel_signature(v, f, k=36)
        variation.append(np.max(np.std(h, axis=0) / np.mean(h, axis=0)))
    assert variation[0] < 1e-2  # measured 4.5e-3 at 162 vertices
    assert variation[1] < 2e-3  # measured 1.0e-3 at 642 vertices
    # discretisation error of a second-order Laplacian: ~4× smaller per halving of h (measured 4.4)
    assert variation[0] / variation[1] > 3.0


def test_sphere_spectrum_and_orthonormality():
    v, f = icosphere(3)
    ev = laplacian_eigenpairs(v, f, k=9)
    # l(l+1) with multiplicity 2l + 1, to discretisation accuracy at 642 vertices
    np.testing.assert_allclose(ev.values, [0, 2, 2, 2, 6, 6, 6, 6, 6], atol=0.05)
    gram = ev.vectors.T @ (ev.mass[:, None] * ev.vectors)
    np.testing.assert_allclose(gram, np.eye(9), atol=1e-10)
    assert np.isclose(ev.mass.sum(), 4 * np.pi, rtol=1e-2)
    # the zero mode is the constant 1/sqrt(area): the HKS at t -> infinity is 1/area
    np.testing.assert_allclose(np.abs(ev.vectors[:, 0]), 1 / np.sqrt(ev.mass.sum()), rtol=1e-8)


def test_positive_and_decreasing_in_time():
    v, f = torus(12, 8)
    h = heat_kernel_signature(v, f, k=40, times=np.geomspace(1e-3, 1e2, 12))
    assert h.shape == (len(v), 12)
    assert (h > 0).all()
    assert (np.diff(h, axis=1) < 0).all()
    # long times: only the constant mode is left
    ev = laplacian_eigenpairs(v, f, k=40)
    np.testing.assert_allclose(
        heat_kernel_signature(v, f, eigenpairs=ev, times=[1e4]), 1 / ev.mass.sum(), rtol=1e-8
    )


def test_matches_a_loop_over_eigenpairs():
    v, f = torus(10, 6)
    ev = laplacian_eigenpairs(v, f, k=20)
    times = np.array([0.05, 0.5])
    expected = np.zeros((len(v), 2))
    for i in range(20):
        for j, t in enumerate(times):
            expected[:, j] += np.exp(-ev.values[i] * t) * ev.vectors[:, i] ** 2
    np.testing.assert_allclose(
        heat_kernel_signature(v, f, eigenpairs=ev, times=times), expected, rtol=1e-13
    )


def test_default_times_follow_sun_et_al():
    v, f = torus(10, 6)
    ev = laplacian_eigenpairs(v, f, k=20)
    t = hks_times(ev.values)
    assert len(t) == 8
    assert np.isclose(t[0], 4 * np.log(10) / ev.values[-1])
    assert np.isclose(t[-1], 4 * np.log(10) / ev.values[1])  # λ_0 = 0 is skipped
    np.testing.assert_allclose(np.diff(np.log(t)), np.log(t[1] / t[0]))  # log-spaced
    np.testing.assert_allclose(
        heat_kernel_signature(v, f, k=20), heat_kernel_signature(v, f, times=t, k=20)
    )


def test_disconnected_mesh_skips_every_zero_eigenvalue():
    v1, f1 = torus(8, 6)
    v = np.concatenate([v1, v1 + 5.0])
    f = np.concatenate([f1, f1 + len(v1)])
    ev = laplacian_eigenpairs(v, f, k=6)
    assert np.all(ev.values[:2] < 1e-8) and ev.values[2] > 0.1
    assert np.isclose(hks_times(ev.values)[-1], 4 * np.log(10) / ev.values[2])


def test_deterministic():
    v, f = torus(10, 6)
    np.testing.assert_array_equal(
        heat_kernel_signature(v, f, k=10), heat_kernel_signature(v, f, k=10)
    )


def test_errors():
    v, f = icosphere(0)  # 12 vertices
    with pytest.raises(InputError, match=r"1 <= k < V"):
        heat_kernel_signature(v, f, k=12)
    with pytest.raises(InputError, match=r"1 <= k < V"):
        laplacian_eigenpairs(v, f, k=0)
    with pytest.raises(InputError, match="positive"):
        heat_kernel_signature(v, f, k=4, times=[1.0, -1.0])
    with pytest.raises(InputError, match="same mesh"):
        heat_kernel_signature(*icosphere(1), eigenpairs=laplacian_eigenpairs(v, f, k=4))
    with pytest.raises(InputError, match="larger k"):
        hks_times(np.zeros(3))
    with pytest.raises(FaceIndexError):
        heat_kernel_signature(v, np.array([[0, 1, 12]]), k=2)

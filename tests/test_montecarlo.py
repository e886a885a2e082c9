"""tests/montecarlo.py: the Cramér–Rao bounds it computes, and the full benchmark (1000 trials, ~4 s).

The bounds are checked against closed forms worked out by hand from ``m_k = A·reference·u_k + b +
e_k``, ``e_k ~ N(0, σ²/n)``; the Jacobian behind them against finite differences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests import montecarlo as mc
from tumblecal_cli.core import methods
from tumblecal_cli.core import model as core

SIX = np.array([core.FACES[f] for f in methods.SIX_FACES])
THREE = np.array([core.FACES[f] for f in ("+x", "+y", "+z")])
# deliberately not the benchmark's values, so that every factor of σ, n and reference shows
SIGMA, N, REF = 0.03, 50, 2.5
DIAGONAL = np.diag([1.1, 0.9, 1.05])
FULL = DIAGONAL + np.array([[0.0, 0.02, -0.01], [0.015, 0.0, 0.03], [-0.02, 0.01, 0.0]])


def bound(model: mc.Model, a: np.ndarray, directions: np.ndarray) -> dict[int, float]:
    return mc.crb(model, a, directions, reference=REF, sigma=SIGMA, samples=N)


def test_one_pose_crb_is_sigma_over_root_n() -> None:
    got = bound(mc.Model("rigid", mc.OFFSET), np.eye(3), THREE[2:])
    assert [got[i] for i in mc.OFFSET] == pytest.approx([SIGMA / math.sqrt(N)] * 3, rel=1e-12)


def test_three_pose_crb() -> None:
    """Per axis: two horizontal readings give b, the vertical one A_ii·ref + b."""
    got = bound(mc.Model("rigid", mc.OFFSET + mc.GAIN), DIAGONAL, THREE)
    offset = SIGMA / math.sqrt(2 * N)
    gain = math.sqrt(SIGMA**2 / N + SIGMA**2 / (2 * N)) / REF
    assert [got[i] for i in mc.OFFSET] == pytest.approx([offset] * 3, rel=1e-12)
    assert [got[i] for i in mc.GAIN] == pytest.approx([gain] * 3, rel=1e-12)


def test_six_faces_rigid_crb() -> None:
    """Rigid model: the ML offset is the mean of all six poses, each A_ij the Ferraris difference."""
    got = bound(mc.Model("rigid", mc.ALL), FULL, SIX)
    assert [got[i] for i in mc.OFFSET] == pytest.approx([SIGMA / math.sqrt(6 * N)] * 3, rel=1e-12)
    assert [got[i] for i in range(3, 12)] == pytest.approx([SIGMA / math.sqrt(2 * N) / REF] * 9, rel=1e-12)


def test_six_faces_tilt_crb_is_the_ferraris_one() -> None:
    """Under tilt only the vertical readings inform b and diag(A): b_i = (m[+i]_i + m[-i]_i) / 2,
    √3 above the rigid bound; the gains keep theirs."""
    tilt = mc.Model("tilt", mc.OFFSET + mc.GAIN, angles=True)
    got = bound(tilt, DIAGONAL, SIX)
    assert [got[i] for i in mc.OFFSET] == pytest.approx([SIGMA / math.sqrt(2 * N)] * 3, rel=1e-12)
    assert [got[i] for i in mc.GAIN] == pytest.approx([SIGMA / math.sqrt(2 * N) / REF] * 3, rel=1e-12)
    rigid = bound(mc.Model("rigid", mc.OFFSET + mc.GAIN), DIAGONAL, SIX)
    assert got[0] / rigid[0] == pytest.approx(math.sqrt(3.0), rel=1e-12)
    # with cross-axis terms (held known) the tilt leaks into the vertical readings a little
    with_cross = bound(tilt, FULL, SIX)
    assert [with_cross[i] / got[i] for i in mc.OFFSET + mc.GAIN] == pytest.approx([1.0] * 6, abs=0.01)


def test_least_squares_crb_is_the_linear_regression_one() -> None:
    """Each raw axis is a linear regression on [ref·u, 1]: cov = σ²/n · inv(DᵀD)."""
    directions = np.vstack([SIX, np.array([(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)]) / math.sqrt(3.0)])
    design = np.column_stack([REF * directions, np.ones(len(directions))])
    sd = SIGMA / math.sqrt(N) * np.sqrt(np.diag(np.linalg.inv(design.T @ design)))  # A_i0, A_i1, A_i2, b_i
    got = bound(mc.Model("rigid", mc.ALL), FULL, directions)
    for i in range(3):
        assert got[i] == pytest.approx(sd[3], rel=1e-12)
        assert [got[3 + 3 * i + j] for j in range(3)] == pytest.approx(sd[:3], rel=1e-12)


def test_unknown_directions_only_add_uncertainty() -> None:
    directions = mc.fibonacci_directions(24)
    upper = DIAGONAL + np.triu(FULL - DIAGONAL, 1)
    params = mc.OFFSET + mc.GAIN + mc.UPPER_CROSS
    free = bound(mc.Model("free-dir", params, angles=True), upper, directions)
    rigid = bound(mc.Model("rigid", params), upper, directions)
    assert all(free[p] > rigid[p] for p in params)


def test_jacobian_matches_finite_differences() -> None:
    """The analytic Jacobian against the exact model, each direction turned through small angles."""
    directions = mc.fibonacci_directions(7)
    model = mc.Model("x", mc.ALL, angles=True)
    b = np.array([0.1, -0.2, 0.05])

    def means(theta: np.ndarray) -> np.ndarray:
        p = np.concatenate([b, FULL.ravel()])
        p[list(model.params)] += theta[: len(model.params)]
        angles = theta[len(model.params) :].reshape(-1, 2)
        out = []
        for u, (d1, d2) in zip(directions, angles, strict=True):
            w1, w2 = mc.perpendicular(u)
            turned = u + d1 * w1 + d2 * w2
            out.append(p[3:].reshape(3, 3) @ (REF * turned / np.linalg.norm(turned)) + p[:3])
        return np.concatenate(out)

    size = len(model.params) + 2 * len(directions)
    numeric = np.empty((3 * len(directions), size))
    for c in range(size):
        step = np.zeros(size)
        step[c] = 1e-6
        numeric[:, c] = (means(step) - means(-step)) / 2e-6
    assert mc.jacobian(model, FULL, directions, REF) == pytest.approx(numeric, abs=1e-8)


def test_tilt_with_free_cross_terms_identifies_the_offsets_only() -> None:
    model = mc.Model("tilt", mc.ALL, angles=True)
    ok = mc.identifiable(model, FULL, SIX)
    assert [ok[i] for i in mc.OFFSET] == [True] * 3
    assert not any(ok[i] for i in mc.GAIN + mc.CROSS)  # a tilt moves a vertical reading by ref·A_ij·δ
    diagonal = mc.identifiable(model, DIAGONAL, SIX)
    assert all(diagonal[i] for i in mc.OFFSET + mc.GAIN)
    with pytest.raises(ValueError, match="not identifiable: A_xx"):
        bound(model, FULL, SIX)


def test_a_group_off_its_bound_fails() -> None:
    check = mc.Check("offset", mc.OFFSET, mc.Model("rigid", mc.OFFSET))
    crb = np.full(3, 1e-3)
    row = mc.Row("x", check, rms=crb * np.array([1.0, 1.05, 1.12]), bound=crb, reported=None, tolerance=0.1)
    assert row.worst == pytest.approx(0.12)
    assert not row.passed
    assert mc.Row("x", check, rms=crb * 0.95, bound=crb, reported=None, tolerance=0.1).passed


@pytest.mark.slow
def test_benchmark_1000_trials(capsys: pytest.CaptureFixture[str]) -> None:
    """The whole benchmark, at its default 1000 trials (about 4 s): every solver within tolerance."""
    status = mc.main([])
    out = capsys.readouterr().out
    assert status == 0, out
    for solver in ("one-pose", "three-pose", "three-pose -x +y -z", "six-pose", "six-pose-diagonal", "least-squares"):
        assert f"\n{solver} " in out
    assert "\nsphere " in out
    assert "FAIL" not in out

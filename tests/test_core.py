"""Known-answer and property tests of the numeric core (tumblecal_cli/core/model.py).

Every capture here is synthetic (tests/synth.py), so the truth is known: the solvers must recover
it within the standard errors they report, and those standard errors must be the statistical
limit of the capture, no better and no worse.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from tests.synth import FloatArray, Truth, pose_samples
from tumblecal_cli.core import model as core
from tumblecal_cli.errors import CaptureRejected, InputError

G = 9.80665  # m/s^2 per g
THREE = ("+x", "+y", "+z")


# One unit, described in four unit systems (ids say raw units -> corrected units).
UNIT_SYSTEMS = {
    "g": Truth(1.0, (0.02, -0.015, 0.03), (1.01, 0.98, 1.02), 0.002),
    "m/s2": Truth(G, (0.02 * G, -0.015 * G, 0.03 * G), (1.01, 0.98, 1.02), 0.002 * G),
    "counts->g": Truth(1.0, (200.0, -150.0, 250.0), (16548.0, 16056.0, 16712.0), 30.0),
    "counts": Truth(16384.0, (200.0, -150.0, 250.0), (1.01, 0.98, 1.02), 30.0),
}


def capture(
    rng: np.random.Generator,
    truth: Truth,
    faces: Sequence[str],
    n: int,
    *,
    cross: FloatArray | None = None,
    tilt_deg: float = 0.0,
) -> list[core.PoseStats]:
    """One synthetic pose per face, reduced to its statistics."""
    return [
        core.pose_stats(
            pose_samples(
                rng,
                core.FACES[face],
                offset=truth.offset,
                gain=truth.gain,
                reference=truth.reference,
                noise=truth.noise,
                n=n,
                cross=cross,
                tilt_deg=tilt_deg,
            )
        )
        for face in faces
    ]


def assert_within_se(estimate: FloatArray, truth: ArrayLike, se: FloatArray, k: float = 4.0) -> None:
    err = np.abs(estimate - np.asarray(truth))
    assert np.all(err <= k * se), f"error {err} exceeds {k} x SE {se}"


# --- 3-pose known answers ------------------------------------------------------------------------


@pytest.mark.parametrize("units", list(UNIT_SYSTEMS))
def test_three_pose_recovers_truth_within_noise(units: str) -> None:
    truth = UNIT_SYSTEMS[units]
    n = 2000
    sol = core.solve_three_pose(capture(np.random.default_rng(0), truth, THREE, n), truth.reference)

    assert sol.method == "three-pose"
    assert_within_se(sol.offset, truth.offset, sol.offset_se)
    assert_within_se(sol.gain, truth.gain, sol.gain_se)
    np.testing.assert_allclose(sol.matrix, np.diag(1.0 / sol.gain), rtol=1e-12)
    assert sol.matrix[~np.eye(3, dtype=bool)].tolist() == [0.0] * 6  # no cross-axis terms

    # The reported errors are the statistical limit: each offset averages two pose means
    # (se = σ/√n · √2/2); each gain is a third mean minus that offset, over the reference.
    mean_se = truth.noise / math.sqrt(n)
    np.testing.assert_allclose(sol.offset_se, mean_se * math.sqrt(2) / 2, rtol=0.10)
    np.testing.assert_allclose(sol.gain_se, mean_se * math.sqrt(1.5) / truth.reference, rtol=0.10)


def test_three_pose_needs_a_positive_reference() -> None:
    poses = capture(np.random.default_rng(1), UNIT_SYSTEMS["g"], THREE, 10)
    with pytest.raises(InputError, match=r"^the 3-pose solver needs a positive --reference"):
        core.solve_three_pose(poses, 0.0)


# --- 1-pose known answers ------------------------------------------------------------------------

# 1-pose fixes M = I, so the raw data must already be in the units of the reference (gain 1).
ONE_POSE_UNITS = {
    "g": Truth(1.0, (0.02, -0.015, 0.03), (1.0, 1.0, 1.0), 0.002),
    "counts": Truth(16384.0, (200.0, -150.0, 250.0), (1.0, 1.0, 1.0), 30.0),
}


@pytest.mark.parametrize("units", list(ONE_POSE_UNITS))
@pytest.mark.parametrize("face", list(core.FACES))
def test_one_pose_recovers_offset_on_every_face(face: str, units: str) -> None:
    truth = ONE_POSE_UNITS[units]
    n = 1000
    [pose] = capture(np.random.default_rng(2), truth, [face], n)
    sol = core.solve_one_pose(pose, face, truth.reference)

    assert sol.method == "one-pose"
    assert_within_se(sol.offset, truth.offset, sol.offset_se)
    np.testing.assert_allclose(sol.offset_se, truth.noise / math.sqrt(n), rtol=0.10)
    assert sol.matrix.tolist() == np.eye(3).tolist()
    assert sol.gain.tolist() == [1.0, 1.0, 1.0]
    assert sol.gain_se.tolist() == [0.0, 0.0, 0.0]


# --- the reported uncertainty is honest ------------------------------------------------------------


def test_three_pose_standard_errors_match_the_scatter() -> None:
    """Over 400 captures of one truth, the spread of the estimates is the SE the solver reports."""
    truth = UNIT_SYSTEMS["counts->g"]
    rng = np.random.default_rng(3)
    sols = [core.solve_three_pose(capture(rng, truth, THREE, 16), truth.reference) for _ in range(400)]
    offsets = np.array([s.offset for s in sols])
    gains = np.array([s.gain for s in sols])
    np.testing.assert_allclose(offsets.std(axis=0, ddof=1), np.mean([s.offset_se for s in sols], axis=0), rtol=0.25)
    np.testing.assert_allclose(gains.std(axis=0, ddof=1), np.mean([s.gain_se for s in sols], axis=0), rtol=0.25)
    # and the estimator is unbiased: the mean of 400 estimates sits within 4 SE of the mean
    assert_within_se(offsets.mean(axis=0), truth.offset, offsets.std(axis=0, ddof=1) / math.sqrt(400))
    assert_within_se(gains.mean(axis=0), truth.gain, gains.std(axis=0, ddof=1) / math.sqrt(400))


MIXED = (("-x", "+y", "-z"), ("-x", "-y", "-z"), ("+x", "-y", "+z"))


@pytest.mark.parametrize("faces", MIXED, ids=["-x+y-z", "-x-y-z", "+x-y+z"])
@pytest.mark.parametrize("units", list(UNIT_SYSTEMS))
def test_three_pose_of_mixed_signs_recovers_truth_within_noise(units: str, faces: tuple[str, ...]) -> None:
    """One face per axis of either sign (a driver that reads -1 g up gives -x -y -z): the same
    offsets as +x +y +z, each gain from its face's sign, the same 1-sigma."""
    truth = UNIT_SYSTEMS[units]
    n = 2000
    sol = core.solve_three_pose(capture(np.random.default_rng(0), truth, faces, n), truth.reference, faces=faces)
    assert_within_se(sol.offset, truth.offset, sol.offset_se)
    assert_within_se(sol.gain, truth.gain, sol.gain_se)
    assert np.all(sol.gain > 0)
    mean_se = truth.noise / math.sqrt(n)
    np.testing.assert_allclose(sol.offset_se, mean_se * math.sqrt(2) / 2, rtol=0.10)
    np.testing.assert_allclose(sol.gain_se, mean_se * math.sqrt(1.5) / truth.reference, rtol=0.10)


def test_three_pose_of_plus_faces_is_unchanged_by_naming_them() -> None:
    """faces=+x +y +z is the default, bit for bit (calibration files compare equal)."""
    poses = capture(np.random.default_rng(11), UNIT_SYSTEMS["counts->g"], THREE, 50)
    plain, named = core.solve_three_pose(poses, 1.0), core.solve_three_pose(poses, 1.0, faces=THREE)
    for field in ("offset", "matrix", "offset_se", "gain_se"):
        assert getattr(plain, field).tobytes() == getattr(named, field).tobytes()


@pytest.mark.parametrize("faces", MIXED[:2], ids=["-x+y-z", "-x-y-z"])
def test_three_pose_of_mixed_signs_z_scores(faces: tuple[str, ...]) -> None:
    """Over 2000 captures the errors over their stated 1-sigma (z-scores) have mean 0 and RMS 1:
    the stated uncertainty of mixed signs is the honest one, not a copy of the + faces' formula
    that happens to pass on them."""
    truth = UNIT_SYSTEMS["counts->g"]
    rng = np.random.default_rng(12)
    z = []
    for _ in range(2000):
        sol = core.solve_three_pose(capture(rng, truth, faces, 16), truth.reference, faces=faces)
        errors = np.concatenate([sol.offset - truth.offset, sol.gain - truth.gain])
        z.append(errors / np.concatenate([sol.offset_se, sol.gain_se]))
    scores = np.array(z)
    rms = np.sqrt((scores**2).mean(axis=0))
    assert np.all((rms > 0.9) & (rms < 1.1)), rms  # RMS of 2000 z-scores: 1 ± 0.016 (1 sigma) and the se's own scatter
    assert np.all(np.abs(scores.mean(axis=0)) < 0.1), scores.mean(axis=0)  # unbiased: 1/sqrt(2000) = 0.022


def test_one_pose_standard_errors_match_the_scatter() -> None:
    truth = ONE_POSE_UNITS["g"]
    rng = np.random.default_rng(4)
    sols = [core.solve_one_pose(capture(rng, truth, ["-z"], 16)[0], "-z", truth.reference) for _ in range(400)]
    offsets = np.array([s.offset for s in sols])
    np.testing.assert_allclose(offsets.std(axis=0, ddof=1), np.mean([s.offset_se for s in sols], axis=0), rtol=0.25)


# --- known weaknesses of 3-pose, pinned as known answers ----------------------------------------------


def test_three_pose_offsets_shift_to_first_order_with_fixture_tilt() -> None:
    """Vitali 2018 notes / docs/reference/model.md: 3-pose offsets come from horizontal readings.

    In tests/synth.py each pose leans towards the next axis (+x towards +y, +y towards +z, +z
    towards +x), so each axis is tilted into in exactly one of its two horizontal poses, and
    its offset (the mean of the two) moves by gain·reference·sin θ / 2: 1° → 17 mg / 2 ≈ 8.7 mg.
    The gain inherits that error (vertical reading minus offset), plus the second-order
    gain·(1 − cos θ) of the vertical reading. Noise alone would move them by ~20 µg.
    """
    truth = Truth(1.0, (0.02, -0.015, 0.03), (1.0, 1.0, 1.0), 0.0005)
    theta = math.radians(1.0)
    sol = core.solve_three_pose(capture(np.random.default_rng(5), truth, THREE, 2000, tilt_deg=1.0), 1.0)

    offset_error = sol.offset - np.asarray(truth.offset)
    assert np.all(np.abs(offset_error) > 100 * sol.offset_se)  # not noise
    assert np.all((offset_error > 8.0e-3) & (offset_error < 9.5e-3))  # ≈ 17 mg / 2
    expected = np.asarray(truth.gain) * math.sin(theta) / 2
    assert_within_se(offset_error, expected, sol.offset_se)

    gain_error = sol.gain - np.asarray(truth.gain)
    expected_gain = -np.asarray(truth.gain) * (math.sin(theta) / 2 + 1 - math.cos(theta))
    assert_within_se(gain_error, expected_gain, sol.gain_se)


def test_three_pose_cross_axis_terms_bias_offsets_and_gains() -> None:
    """With A = diag(gain) + C, axis i reads C[i, j]·reference in the pose where j is up.

    So offset_i = b_i + (C[i, j] + C[i, k])·reference / 2 over the two other axes j, k, and
    gain_i = A[i, i] − (C[i, j] + C[i, k]) / 2: 3-pose cannot see cross-axis terms (Vitali
    2018 points to ST DT0053's 6-point method for them).
    """
    truth = UNIT_SYSTEMS["m/s2"]
    cross = np.array([[0.0, 0.010, -0.004], [0.006, 0.0, 0.003], [-0.002, 0.008, 0.0]])
    sol = core.solve_three_pose(capture(np.random.default_rng(6), truth, THREE, 2000, cross=cross), truth.reference)

    row_sums = cross.sum(axis=1)  # C[i, j] + C[i, k] (the diagonal of C is zero)
    assert_within_se(sol.offset, np.asarray(truth.offset) + row_sums * truth.reference / 2, sol.offset_se)
    assert_within_se(sol.gain, np.asarray(truth.gain) - row_sums / 2, sol.gain_se)
    assert np.all(np.abs(sol.offset - np.asarray(truth.offset)) > 10 * sol.offset_se)  # a real bias


# --- wrong poses are rejected, naming the file ---------------------------------------------------------

NAMES = ("caps/unit7-x.csv", "caps/unit7-y.csv", "caps/unit7-z.csv")


@pytest.mark.parametrize(
    ("faces", "index"),
    [
        (("-x", "+y", "+z"), 0),  # +x file captured with x pointing down
        (("+x", "-y", "+z"), 1),
        (("+x", "+y", "-z"), 2),
        (("+y", "+x", "+z"), 0),  # files given in the wrong order: x is reported first
    ],
    ids=["x-down", "y-down", "z-down", "x-y-swapped"],
)
def test_three_pose_solves_a_negative_gain_for_the_gate_to_judge(faces: tuple[str, ...], index: int) -> None:
    """The solver reports what the data says; rejecting it (pose.upside_down) is the gate's job."""
    poses = capture(np.random.default_rng(7), UNIT_SYSTEMS["g"], faces, 100)
    solution = core.solve_three_pose(poses, 1.0, names=NAMES)
    assert solution.gain[index] < 0
    assert np.isfinite(solution.matrix).all()


def test_three_pose_cannot_determine_a_zero_gain() -> None:
    """A +y pose that reads exactly what the horizontal poses read on y leaves no gain to invert:
    exit 3 even with --no-checks, naming the file."""
    level = core.PoseStats(mean=np.array([0.0, 0.0, 1.0]), std=np.zeros(3), samples=10)
    x = core.PoseStats(mean=np.array([1.0, 0.0, 0.0]), std=np.zeros(3), samples=10)
    with pytest.raises(CaptureRejected) as caught:
        core.solve_three_pose([x, level, level], 1.0, names=NAMES)
    assert caught.value.file == NAMES[1]
    assert caught.value.code == "pose.upside_down"
    assert caught.value.exit_code == 3
    assert "its gain on y cannot be determined" in str(caught.value)


# --- units mistakes -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("mean", "reference", "suggested"),
    [
        ((0.2, -0.1, G + 0.3), 1.0, G),  # m/s^2 data, reference left at 1
        ((200.0, -150.0, 16384.0 + 250.0), 1.0, 16384.0),  # ±2 g int16 counts
        ((-12.0, 4.0, -1000.0 - 3.0), 1.0, 1000.0),  # mg (near 1024 counts it would say 1024)
        ((0.02, -0.01, 1.0 + 0.03), 1.0, None),  # already in g
        ((0.02, -0.98, 0.03), 1.0, None),  # any face
        ((200.0, -150.0, 16384.0 + 250.0), 16384.0, None),  # counts with a counts reference
        ((0.5, -0.2, 0.1), 0.0, None),  # gyroscope at rest: nothing to compare
    ],
    ids=["m/s2", "counts", "mg", "g", "g-y-down", "counts-ref", "reference-0"],
)
def test_units_mistake(mean: tuple[float, float, float], reference: float, suggested: float | None) -> None:
    assert core.units_mistake(np.array(mean), reference) == suggested


# --- face names ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "face"),
    [
        ("+x", "+x"),
        ("-x", "-x"),
        ("+y", "+y"),
        ("-y", "-y"),
        ("+z", "+z"),
        ("-z", "-z"),
        ("xp", "+x"),
        ("xn", "-x"),
        ("yp", "+y"),
        ("yn", "-y"),
        ("zp", "+z"),
        ("zn", "-z"),
        (" +Z ", "+z"),
        ("XN", "-x"),
    ],
)
def test_parse_face_accepts_faces_and_aliases(text: str, face: str) -> None:
    assert core.parse_face(text) == face


@pytest.mark.parametrize("text", ["x", "+w", "", "++x", "x+", "−x", "px"])  # "−x": a Unicode minus
def test_parse_face_rejects_others(text: str) -> None:
    message = f"unknown face {text!r}: use one of +x -x +y -y +z -z (or xp xn yp yn zp zn)"
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        core.parse_face(text)


# --- pose statistics ----------------------------------------------------------------------------


def test_pose_stats_of_one_sample_has_zero_std() -> None:
    stats = core.pose_stats(np.array([[0.1, -0.2, 1.05]]))
    assert stats.samples == 1
    assert stats.mean.tolist() == [0.1, -0.2, 1.05]
    assert stats.std.tolist() == [0.0, 0.0, 0.0]
    assert stats.stderr.tolist() == [0.0, 0.0, 0.0]


def test_pose_stats_std_is_the_sample_std() -> None:
    stats = core.pose_stats(np.array([[0.0, 0.0, 0.0], [2.0, 4.0, -2.0]]))
    np.testing.assert_allclose(stats.std, [math.sqrt(2), math.sqrt(8), math.sqrt(2)])  # ddof=1, not 1, 2, 1
    np.testing.assert_allclose(stats.stderr, stats.std / math.sqrt(2))

    samples = np.random.default_rng(8).normal(size=(50, 3))
    np.testing.assert_allclose(core.pose_stats(samples).std, samples.std(axis=0, ddof=1), rtol=1e-12)


def test_pose_stats_rejects_no_samples() -> None:
    with pytest.raises(InputError, match=r"^no samples in this pose$"):
        core.pose_stats(np.empty((0, 3)))


# --- properties -----------------------------------------------------------------------------------

REFERENCES = st.sampled_from([1.0, G, 16384.0])
unit_vectors = (
    st.tuples(*[st.floats(-1.0, 1.0)] * 3)
    .map(np.array)
    .filter(lambda v: float(np.linalg.norm(v)) > 0.1)
    .map(lambda v: v / np.linalg.norm(v))
)


@pytest.mark.slow
@given(
    reference=REFERENCES,
    offset=st.tuples(*[st.floats(-100.0, 100.0)] * 3),
    gain=st.tuples(*[st.floats(0.5, 2.0)] * 3),
    cross=st.tuples(*[st.floats(-0.05, 0.05)] * 6),
    directions=st.lists(unit_vectors, min_size=1, max_size=8),
)
def test_apply_inverts_the_model_on_ideal_readings(
    reference: float,
    offset: tuple[float, float, float],
    gain: tuple[float, float, float],
    cross: tuple[float, ...],
    directions: list[FloatArray],
) -> None:
    a = np.diag(gain)
    a[~np.eye(3, dtype=bool)] = cross
    b = np.array(offset)
    v = reference * np.array(directions)  # (n, 3) true stimuli, |v| = reference
    raw = v @ a.T + b  # raw = A · v + b, row by row
    corrected = core.apply(raw, offset=b, matrix=np.linalg.inv(a))
    assert corrected.shape == v.shape
    np.testing.assert_allclose(corrected, v, rtol=0, atol=1e-9 * reference)


# (reference, raw units per reference unit): g, m/s^2, counts -> g, counts -> counts
SCALES = st.sampled_from([(1.0, 1.0), (G, 1.0), (1.0, 16384.0), (16384.0, 1.0)])


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=SCALES,
    offset=st.tuples(*[st.floats(-0.1, 0.1)] * 3),
    gain=st.tuples(*[st.floats(0.5, 2.0)] * 3),
    noise=st.floats(1e-4, 1e-2),
    n=st.integers(200, 1000),
)
def test_three_pose_recovers_random_truths(
    seed: int,
    scale: tuple[float, float],
    offset: tuple[float, float, float],
    gain: tuple[float, float, float],
    noise: float,
    n: int,
) -> None:
    reference, counts = scale
    truth = Truth(
        reference,
        (offset[0] * counts * reference, offset[1] * counts * reference, offset[2] * counts * reference),
        (gain[0] * counts, gain[1] * counts, gain[2] * counts),
        noise * counts * reference,
    )
    sol = core.solve_three_pose(capture(np.random.default_rng(seed), truth, THREE, n), reference)
    assert_within_se(sol.offset, truth.offset, sol.offset_se, k=5.0)
    assert_within_se(sol.gain, truth.gain, sol.gain_se, k=5.0)


@pytest.mark.parametrize(
    ("name", "face"),
    [("x", "+x"), ("+y", "+y"), ("-z", "-z"), ("xp", "+x"), ("XN", "-x"), ("y_p", "+y"), ("z_n", "-z"),
     ("xplus", "+x"), ("zminus", "-z"), ("y-neg", "-y"), ("pose", None), ("x_rot", None), ("xx", None)],
)  # fmt: skip
def test_face_of_name(name: str, face: str | None) -> None:
    """File stems and column headers that name a face (batch's folders and manifests)."""
    assert core.face_of_name(name) == face

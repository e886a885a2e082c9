"""The production-test gate (tumblecal_cli/core/gate.py) on numbers: quality checks, limits, verdict.

Every capture is synthetic (tests/synth.py), so each check is driven across its bound by a known
cause (noise, drift, tilt, clipping, a short pose, a pose captured upside down) and must fire on
that cause alone. The last sections check that the solution's reported uncertainty and tilt
sensitivity (tumblecal_cli/core/model.py) are what the scatter of many synthetic captures shows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import ArrayLike

from tests.synth import FloatArray, Truth, pose_samples
from tumblecal_cli.core import gate
from tumblecal_cli.core import model as core

THREE = ("+x", "+y", "+z")
NAMES = ("caps/unit7-x.csv", "caps/unit7-y.csv", "caps/unit7-z.csv")


# in g; a +x pose reads (1.03, -0.034, 0.047)
G_UNIT = Truth(1.0, (0.02, -0.034, 0.047), (1.01, 0.98, 1.02), 0.002)
# the same unit as int16 counts at ±2 g, calibrated to g (the 3-pose gains carry the unit change)
COUNTS = Truth(1.0, (200.0, -150.0, 250.0), (16548.0, 16056.0, 16712.0), 30.0)


def samples(
    rng: np.random.Generator,
    truth: Truth,
    face: str,
    n: int = 300,
    *,
    tilt_deg: float = 0.0,
    noise: float | None = None,
) -> FloatArray:
    """(n, 3) raw readings of one pose with ``face`` up (tests/synth.py)."""
    return pose_samples(
        rng,
        core.FACES[face],
        offset=truth.offset,
        gain=truth.gain,
        reference=truth.reference,
        noise=truth.noise if noise is None else noise,
        n=n,
        tilt_deg=tilt_deg,
    )


def run_gate(
    values: Sequence[FloatArray],
    solution: core.Solution,
    options: gate.Options,
    *,
    faces: Sequence[str] = THREE,
    names: Sequence[str] = NAMES,
) -> tuple[list[gate.Finding], list[gate.Finding]]:
    """measure -> orient -> check, as `tumblecal solve` does: (rejections, warnings)."""
    measured = gate.orient(
        [
            gate.measure(name, face, v, core.pose_stats(v), options)
            for name, face, v in zip(names, faces, values, strict=True)
        ],
        options.nominal_offset,
    )
    return gate.check(measured, solution, options)


def three_pose(values: Sequence[FloatArray], reference: float = 1.0) -> core.Solution:
    return core.solve_three_pose([core.pose_stats(v) for v in values], reference, names=NAMES)


def codes(findings: Sequence[gate.Finding]) -> list[str]:
    return [f.code for f in findings]


def of(findings: Sequence[gate.Finding], code: str) -> list[gate.Finding]:
    return [f for f in findings if f.code == code]


# --- pose.moved ---------------------------------------------------------------------------------

NOISE_BOUND = 0.02  # g: --max-noise 0.02 with --reference 1


def moved_capture(noise_y: float | None = None, ramp_z: float = 0.0) -> tuple[list[FloatArray], core.Solution]:
    """A counts capture (3-pose, corrected to g) with a noisier +y pose and/or a ramp on the +z pose."""
    rng = np.random.default_rng(10)
    values = [samples(rng, COUNTS, "+x"), samples(rng, COUNTS, "+y", noise=noise_y), samples(rng, COUNTS, "+z")]
    values[2][:, 2] += np.linspace(0.0, ramp_z, values[2].shape[0])
    return values, three_pose(values)


def test_moved_still_poses_pass_in_output_units() -> None:
    """30 counts of noise is 0.0018 g through the solved matrix: far under 0.02 g (raw 30 > 0.02)."""
    values, solution = moved_capture()
    rejected, warned = run_gate(values, solution, gate.Options(noise_bound=NOISE_BOUND))
    assert rejected == []
    assert warned == []


def test_moved_noisy_pose_is_rejected() -> None:
    noise = 1.5 * NOISE_BOUND * COUNTS.gain[1]  # 1.5 x the bound on y once divided by y's gain
    values, solution = moved_capture(noise_y=noise)
    rejected, warned = run_gate(values, solution, gate.Options(noise_bound=NOISE_BOUND))

    [finding] = rejected
    assert finding.code == "pose.moved"
    assert (finding.file, finding.pose) == (NAMES[1], "+y")
    output_std = core.pose_stats(values[1]).std / solution.gain  # diagonal M: std / gain
    worst = int(np.argmax(output_std))
    assert finding.value == pytest.approx(output_std[worst], rel=1e-12)
    assert 1.3 * NOISE_BOUND < finding.value < 1.7 * NOISE_BOUND
    assert finding.bound == NOISE_BOUND
    assert finding.message == (
        f"standard deviation {output_std[worst]:.3g} on {'xyz'[worst]}, above 0.02 (--max-noise): the unit moved"
    )
    assert warned == []


def test_moved_drifting_pose_is_rejected_for_its_drift() -> None:
    """A ramp of R moves the last third's mean by 2R/3 from the first's, while its std is only R/√12:
    the drift, not the spread, crosses the bound."""
    ramp = 0.045 * COUNTS.gain[2]  # counts: drift 0.03 g, std ≈ 0.013 g
    values, solution = moved_capture(ramp_z=ramp)
    stats = core.pose_stats(values[2])
    assert float(np.max(stats.std / solution.gain)) < NOISE_BOUND  # the spread alone would pass

    rejected, _ = run_gate(values, solution, gate.Options(noise_bound=NOISE_BOUND))
    [finding] = rejected
    assert (finding.code, finding.file, finding.pose) == ("pose.moved", NAMES[2], "+z")
    third = values[2].shape[0] // 3
    drift = (values[2][-third:, 2].mean() - values[2][:third, 2].mean()) / solution.gain[2]
    assert finding.value == pytest.approx(drift, rel=1e-9)
    assert finding.value == pytest.approx(2 / 3 * 0.045, rel=0.05)
    assert "drifts" in finding.message
    assert finding.message.startswith(f"drifts by {drift:.3g} on z (first vs last third), above 0.02 (--max-noise)")


def test_moved_just_under_the_bound_is_a_narrow_pass() -> None:
    noise = 0.9 * NOISE_BOUND * COUNTS.gain[1]
    values, solution = moved_capture(noise_y=noise)
    rejected, warned = run_gate(values, solution, gate.Options(noise_bound=NOISE_BOUND))

    assert rejected == []
    [finding] = warned
    assert (finding.code, finding.file) == ("pose.moved", NAMES[1])
    assert gate.NARROW * NOISE_BOUND < finding.value < NOISE_BOUND
    assert finding.message.endswith(f", close to {NOISE_BOUND:.3g} (--max-noise)")
    assert "above" not in finding.message


def test_moved_is_off_without_a_noise_bound() -> None:
    values, solution = moved_capture(noise_y=5 * NOISE_BOUND * COUNTS.gain[1])
    assert run_gate(values, solution, gate.Options(noise_bound=None)) == ([], [])


# --- pose.orientation -----------------------------------------------------------------------------


def test_orientation_swapped_files_name_the_order() -> None:
    """The +x and +y files given in the wrong order: each reads like the other's face."""
    rng = np.random.default_rng(20)
    x, y, z = (samples(rng, G_UNIT, face, noise=0.0002) for face in THREE)
    names = (NAMES[1], NAMES[0], NAMES[2])  # unit7-y.csv given first, declared +x
    values = [y, x, z]
    solution = three_pose(values)
    assert solution.gain[0] < 0  # what pose.upside_down would judge
    assert solution.gain[1] < 0

    rejected, _ = run_gate(values, solution, gate.Options(), names=names)

    # one reason per pose: the misread poses are not also reported upside down
    assert codes(rejected) == ["pose.orientation", "pose.orientation"]
    declared_x, declared_y = rejected
    assert declared_y.render() == (
        "caps/unit7-x.csv: declared +y but reads like +x (mean 1.03, -0.034, 0.047); "
        "were the files given in the order x y z?"
    )
    assert (declared_y.file, declared_y.pose) == ("caps/unit7-x.csv", "+y")
    assert declared_y.hint == "give the pose files in the order +x +y +z"
    assert declared_y.value == pytest.approx(90.0, abs=5.0)
    assert declared_y.bound == 25.0
    assert declared_x.message.startswith("declared +x but reads like +y (mean ")
    assert declared_x.file == "caps/unit7-y.csv"


@pytest.mark.parametrize(
    ("tilt", "rejected_codes", "warned_codes"),
    [(30.0, ["pose.orientation"], []), (22.0, [], ["pose.orientation"]), (10.0, [], [])],
    ids=["30deg-rejected", "22deg-narrow", "10deg-passes"],
)
def test_orientation_tilted_pose(tilt: float, rejected_codes: list[str], warned_codes: list[str]) -> None:
    """A +z pose tilted by ``tilt`` towards +x, judged against --max-tilt 25 (narrow above 20)."""
    truth = replace(G_UNIT, gain=(1.0, 1.0, 1.0))
    rng = np.random.default_rng(21)
    values = [samples(rng, truth, "+x"), samples(rng, truth, "+y"), samples(rng, truth, "+z", tilt_deg=tilt)]
    options = gate.Options(max_tilt_deg=25.0, nominal_offset=np.array(truth.offset))
    rejected, warned = run_gate(values, three_pose(values), options)

    assert codes(rejected) == rejected_codes
    assert codes(warned) == warned_codes
    for finding in rejected + warned:
        assert (finding.file, finding.pose) == (NAMES[2], "+z")
        assert finding.value == pytest.approx(tilt, abs=0.05)
    for finding in rejected:
        assert finding.message.startswith(f"declared +z but is {tilt:.1f}° from it (mean ")
        assert finding.message.endswith("), more than --max-tilt 25°")
    for finding in warned:  # a warning says how close, not that it failed
        assert finding.message == f"{tilt:.1f}° from +z, close to --max-tilt 25°"
    if rejected:
        assert "is 30.0° from it" in rejected[0].message


def test_orientation_upside_down_pose() -> None:
    """The +x file captured with x pointing down: the orientation check finds it on the opposite
    face and says so with the upside-down code, and the negative gain it solves to is not
    reported a second time."""
    rng = np.random.default_rng(22)
    values = [samples(rng, G_UNIT, "-x"), samples(rng, G_UNIT, "+y"), samples(rng, G_UNIT, "+z")]
    solution = three_pose(values)
    assert solution.gain[0] < 0
    rejected, _ = run_gate(values, solution, gate.Options())

    [finding] = rejected
    assert (finding.code, finding.file, finding.pose) == ("pose.upside_down", NAMES[0], "+x")
    assert finding.message.startswith("declared +x but reads like -x (mean -0.99, ")
    assert finding.message.endswith(": upside down")
    assert finding.hint is not None
    assert finding.hint.startswith("turn the unit over so that its x axis points up")
    assert finding.value == pytest.approx(180.0, abs=5.0)


def test_orientation_one_pose_upside_down() -> None:
    truth = replace(G_UNIT, gain=(1.0, 1.0, 1.0))
    values = samples(np.random.default_rng(23), truth, "-z")
    solution = core.solve_one_pose(core.pose_stats(values), "+z", 1.0)
    rejected, _ = run_gate([values], solution, gate.Options(), faces=["+z"], names=["z.csv"])
    [finding] = rejected
    assert finding.render().startswith("z.csv: declared +z but reads like -z (mean ")
    assert finding.render().endswith(": upside down")


# An unsigned 16-bit ADC at ±2 g: zero stimulus reads 32768 (+ the unit's own offset).
UNSIGNED = replace(COUNTS, offset=(32768.0 + 200.0, 32768.0 - 150.0, 32768.0 + 250.0))


@pytest.mark.parametrize("method", ["three-pose", "one-pose"])
def test_orientation_unsigned_counts_need_a_nominal_offset(method: str) -> None:
    rng = np.random.default_rng(24)
    if method == "three-pose":
        faces: Sequence[str] = THREE
        values = [np.round(samples(rng, UNSIGNED, face)) for face in THREE]
        solution = three_pose(values)
    else:  # 1-pose: no gains, so the data stays in counts (reference 16384)
        truth = replace(UNSIGNED, reference=16384.0, gain=(1.0, 1.0, 1.0))
        faces = ["-z"]
        values = [np.round(samples(rng, truth, "-z"))]
        solution = core.solve_one_pose(core.pose_stats(values[0]), "-z", truth.reference)
    names = NAMES[: len(faces)]

    centred = gate.Options(noise_bound=NOISE_BOUND, nominal_offset=np.full(3, 32768.0))
    if method == "one-pose":
        centred = replace(centred, noise_bound=NOISE_BOUND * 16384.0)
    assert run_gate(values, solution, centred, faces=faces, names=names) == ([], [])

    rejected, _ = run_gate(values, solution, gate.Options(), faces=faces, names=names)
    assert codes(rejected) == ["pose.orientation"] * len(faces)
    for finding, name in zip(rejected, names, strict=True):
        assert finding.file == name
        assert finding.value > 25.0
        assert "raw counts around a common centre need --nominal-offset (e.g. 32768)" in finding.message


def test_orient_centres_each_axis_on_its_two_opposite_faces() -> None:
    """Six faces of unsigned counts: with both faces of an axis present, the centre on that axis is
    their midpoint, whatever nominal_offset says; an axis with one face uses nominal_offset."""
    rng = np.random.default_rng(25)
    faces = list(core.FACES)
    values = {face: samples(rng, UNSIGNED, face) for face in faces}
    options = gate.Options()
    checks = {face: gate.measure(face, face, v, core.pose_stats(v), options) for face, v in values.items()}
    means = {face: c.stats.mean for face, c in checks.items()}
    midpoint = np.array([0.5 * (means[f"+{a}"][i] + means[f"-{a}"][i]) for i, a in enumerate("xyz")])

    oriented = gate.orient(list(checks.values()), np.zeros(3))  # nominal_offset 0: overridden on every axis
    for p in oriented:
        d = means[str(p.face)] - midpoint
        np.testing.assert_allclose(p.direction, d / np.linalg.norm(d), rtol=0, atol=1e-12)
        assert p.looks_like == p.face
        assert p.angle_deg is not None
        assert p.angle_deg < 0.1

    # without -z, z falls back to nominal_offset: right when it is the unit's centre, wrong at 0
    five = [c for c in checks.values() if c.face != "-z"]
    right = gate.orient(five, np.array([0.0, 0.0, UNSIGNED.offset[2]]))
    assert all(p.angle_deg is not None and p.angle_deg < 0.1 for p in right)
    wrong = {p.face: p for p in gate.orient(five, np.zeros(3))}
    assert wrong["+x"].angle_deg is not None
    assert wrong["+x"].angle_deg > 40.0  # centred on (mid x, mid y, 0): (16548, ~0, 33018), 63° off
    d = means["+x"] - np.array([midpoint[0], midpoint[1], 0.0])
    np.testing.assert_allclose(wrong["+x"].direction, d / np.linalg.norm(d), rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("given", "wrong"),
    [
        pytest.param(["+x", "-x", "+y", "-y", "+z", "+z"], {"-z": "+z"}, id="a +z capture given for -z"),
        pytest.param(["+x", "-x", "+z", "-y", "+y", "-z"], {"+y": "+z", "+z": "+y"}, id="+y and +z swapped"),
    ],
)
def test_six_faces_one_wrong_file_is_the_only_one_rejected(given: list[str], wrong: dict[str, str]) -> None:
    """A pair of opposite faces whose difference does not point along its axis (one of them is
    some other pose) gives no centre: the other poses still read right, and each wrong file is
    named with what it really is (not every pose, as a centre from the bad pair would)."""
    rng = np.random.default_rng(26)
    values = [samples(rng, G_UNIT, face) for face in given]
    faces = list(core.FACES)
    names = [f"{face}.csv" for face in faces]
    solution = core.solve_one_pose(core.pose_stats(values[4]), "+z", 1.0)  # the checks here need no gains
    options = gate.Options(skip=frozenset({"moved", "upside_down"}))
    rejected, _ = run_gate(values, solution, options, faces=faces, names=names)
    assert {f.pose: f.message.split(" (mean")[0] for f in rejected} == {
        face: f"declared {face} but reads like {looks}" for face, looks in wrong.items()
    }


def test_a_swapped_pair_keeps_its_midpoint_as_the_centre() -> None:
    """The +x and -x files exchanged, in unsigned counts: the pair's midpoint is the centre all
    the same, so the other four poses still read right and only the two swapped are named."""
    rng = np.random.default_rng(27)
    given = ["-x", "+x", "+y", "-y", "+z", "-z"]
    values = [samples(rng, UNSIGNED, face) for face in given]
    faces = list(core.FACES)
    names = [f"{face}.csv" for face in faces]
    solution = core.solve_one_pose(core.pose_stats(values[4]), "+z", 1.0)
    options = gate.Options(skip=frozenset({"moved", "upside_down"}))
    rejected, _ = run_gate(values, solution, options, faces=faces, names=names)
    assert sorted((f.pose, f.message.split(" (mean")[0]) for f in rejected) == [
        ("+x", "declared +x but reads like -x"),
        ("-x", "declared -x but reads like +x"),
    ]


# --- pose.saturated --------------------------------------------------------------------------------


def saturation(values: FloatArray, full_scale: float | None) -> tuple[list[gate.Finding], list[gate.Finding]]:
    """The saturation check alone on one +z pose (1-pose)."""
    solution = core.solve_one_pose(core.pose_stats(values), "+z", float(np.median(values[:, 2])))
    rails = gate.integer_rails([values])  # as `tumblecal solve` does, here over its one pose
    options = gate.Options(full_scale=full_scale, skip=frozenset(gate.CHECKS) - {"saturated"}, rails=rails)
    return run_gate([values], solution, options, faces=["+z"], names=["z.csv"])


def test_saturated_at_the_full_scale() -> None:
    values = samples(np.random.default_rng(30), G_UNIT, "+z")
    assert saturation(values, 2.0) == ([], [])  # peak 1.07 / 1.96

    values[10] = [0.1, 0.0, 1.96]  # exactly CLIP_FRACTION x 2 g
    values[20] = [-1.97, 1.99, 1.0]  # two axes clipped in one sample: counted once
    rejected, warned = saturation(values, 2.0)
    [finding] = rejected
    assert (finding.code, finding.file, finding.pose) == ("pose.saturated", "z.csv", "+z")
    assert finding.value == 2
    assert finding.bound == 0
    assert finding.message == f"2 samples clipped at 98% of --full-scale 2 (peak {1.99 / 1.96:.0%} of that)"
    assert warned == []


def test_saturated_just_under_the_full_scale_is_a_narrow_pass() -> None:
    values = samples(np.random.default_rng(31), G_UNIT, "+z")
    values[10, 2] = 0.9799 * 2.0
    rejected, warned = saturation(values, 2.0)
    assert rejected == []
    [finding] = warned
    assert finding.code == "pose.saturated"
    assert finding.value == 0


def int_counts(rng: np.random.Generator, offset: float = 0.0) -> FloatArray:
    """A +z pose of whole counts (±2 g, 16384 per g), shifted by ``offset`` (32768: unsigned)."""
    truth = replace(COUNTS, reference=16384.0, gain=(1.0, 1.0, 1.0))
    return np.round(samples(rng, truth, "+z")) + offset


@pytest.mark.parametrize("rail", [32767.0, -32768.0])
def test_saturated_int16_rails(rail: float) -> None:
    values = int_counts(np.random.default_rng(32))
    assert saturation(values, None) == ([], [])  # peak ≈ 16634 / 32767: no warning either

    values[5, 0] = rail
    rejected, _ = saturation(values, None)
    [finding] = rejected
    assert finding.code == "pose.saturated"
    assert finding.value == 1
    assert finding.message.startswith("1 sample clipped at the limit of its integer type")


@pytest.mark.parametrize("rail", [65535.0, 0.0])
def test_saturated_uint16_rails(rail: float) -> None:
    values = int_counts(np.random.default_rng(33), offset=32768.0)
    assert float(values.max()) > 32767  # so read as unsigned
    assert saturation(values, None) == ([], [])  # 32768 is the middle, not a rail

    values[5, 1] = rail
    values[6, 1] = rail
    rejected, _ = saturation(values, None)
    [finding] = rejected
    assert finding.code == "pose.saturated"
    assert finding.value == 2
    assert finding.message.startswith("2 samples clipped at the limit of its integer type")


def test_the_integer_type_is_judged_over_the_whole_unit() -> None:
    """An unsigned ADC centred a few counts under 32768: its -x pose reads below 32768 on every
    axis and may touch 32767; the unit's other poses (above 32767) show the type is unsigned, so
    32767 is the middle, not a rail (seen on a real raw-count log)."""
    rng = np.random.default_rng(35)
    below = np.round(np.array([32760.0 - 4700.0, 32760.0, 32760.0]) + rng.normal(0.0, 1.5, (200, 3)))
    below = np.minimum(below, 32766.0)
    below[5, 1] = 32767.0
    above = int_counts(np.random.default_rng(36), offset=32768.0)
    assert float(below.max()) <= 32767 < float(above.max())
    assert gate.integer_rails([below]) == (-32768.0, 32767.0, 0.0)  # alone, it reads as signed
    assert gate.integer_rails([below, above]) == (0.0, 65535.0, 32768.0)
    check = gate.measure("zn.csv", "-z", below, core.pose_stats(below), gate.Options(rails=(0.0, 65535.0, 32768.0)))
    assert check.clipped == 0
    assert check.peak_fraction is not None
    assert check.peak_fraction < 0.6
    assert gate.integer_rails([below + 0.5, above]) is None  # not whole numbers: no known type
    assert gate.integer_rails([below - 40000.0, above]) is None  # no 16-bit type holds both


def test_saturated_float_data_without_a_full_scale_is_not_judged() -> None:
    values = samples(np.random.default_rng(34), COUNTS, "+z")  # counts, but not whole numbers
    values[5] = [40000.5, -70000.25, 65535.5]
    options = gate.Options()
    check = gate.measure("z.csv", "+z", values, core.pose_stats(values), options)
    assert (check.clipped, check.peak_fraction) == (0, None)
    assert saturation(values, None) == ([], [])


# --- pose.short --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("n", "rejected", "warned"), [(5, True, False), (9, True, False), (12, False, True), (13, False, False)]
)
def test_short_pose(n: int, rejected: bool, warned: bool) -> None:
    """--min-samples 10: fewer is rejected; under 10 / NARROW = 12.5 is a narrow pass."""
    values = samples(np.random.default_rng(40), G_UNIT, "+z", n)
    solution = core.solve_one_pose(core.pose_stats(values), "+z", 1.0)
    found = run_gate([values], solution, gate.Options(min_samples=10), faces=["+z"], names=["z.csv"])
    assert (of(found[0], "pose.short") != [], of(found[1], "pose.short") != []) == (rejected, warned)
    assert codes(found[0]) == codes(of(found[0], "pose.short"))  # nothing else
    for finding in found[0] + found[1]:
        assert (finding.value, finding.bound, finding.file) == (n, 10, "z.csv")
    for finding in found[0]:
        assert finding.message == f"{n} samples, fewer than --min-samples 10"
    for finding in found[1]:
        assert finding.message == f"only {n} samples, close to --min-samples 10"


def test_one_sample_pose_passes_with_min_samples_one() -> None:
    values = np.array([[0.02, -0.034, 1.067]])
    stats = core.pose_stats(values)
    options = gate.Options(noise_bound=NOISE_BOUND, min_samples=1)
    check = gate.measure("z.csv", "+z", values, stats, options)
    assert check.stats.std.tolist() == [0.0, 0.0, 0.0]
    assert check.drift.tolist() == [0.0, 0.0, 0.0]

    solution = core.solve_one_pose(stats, "+z", 1.0)
    rejected, warned = run_gate([values], solution, options, faces=["+z"], names=["z.csv"])
    assert rejected == []
    assert warned == []  # one row is what --min-samples 1 asks for: nothing to warn about


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_drift_needs_a_third(n: int) -> None:
    """The drift compares the first and last n // 3 samples: none for n < 3."""
    values = np.arange(3.0 * n).reshape(n, 3)
    check = gate.measure("f.csv", "+z", values, core.pose_stats(values), gate.Options())
    third = n // 3
    expected = np.zeros(3) if third == 0 else values[-third:].mean(axis=0) - values[:third].mean(axis=0)
    assert check.drift.tolist() == expected.tolist()


# --- pose.upside_down ----------------------------------------------------------------------------------


def test_upside_down_negative_gain_names_the_file() -> None:
    """With the orientation check skipped, a +y file captured y-down still cannot pass: its gain is
    negative."""
    rng = np.random.default_rng(50)
    values = [samples(rng, G_UNIT, "+x"), samples(rng, G_UNIT, "-y"), samples(rng, G_UNIT, "+z")]
    solution = three_pose(values)
    assert solution.gain[1] < 0 < min(solution.gain[0], solution.gain[2])

    rejected, warned = run_gate(values, solution, gate.Options(skip=frozenset({"orientation"})))
    [finding] = rejected
    assert (finding.code, finding.file, finding.pose) == ("pose.upside_down", NAMES[1], "+y")
    assert finding.value == solution.gain[1]
    assert finding.bound == 0.0
    assert finding.render().startswith(f"{NAMES[1]}: gain {solution.gain[1]:.4g} on y (mean ")
    assert finding.message.endswith("its y axis was not pointing up (upside down, or the files out of order)")
    assert warned == []

    # both checks on: the orientation check gives the reason, once, with the upside-down code
    rejected, _ = run_gate(values, solution, gate.Options())
    assert [(f.code, f.file) for f in rejected] == [("pose.upside_down", NAMES[1])]
    assert rejected[0].message.startswith("declared +y but reads like -y (mean ")
    # the orientation check alone off or the upside-down check alone off: still rejected
    only = gate.Options(skip=frozenset({"upside_down"}))
    assert [f.code for f in run_gate(values, solution, only)[0]] == ["pose.upside_down"]
    # both off: nothing left to say
    skip_both = gate.Options(skip=frozenset({"orientation", "upside_down"}))
    assert run_gate(values, solution, skip_both) == ([], [])


# --- options.skip ---------------------------------------------------------------------------------------


def every_check_fails() -> tuple[list[FloatArray], core.Solution, gate.Options]:
    """A 3-pose capture with a short +x pose, a noisy +y pose and a +z pose 30° off that clipped once."""
    rng = np.random.default_rng(60)
    values = [
        samples(rng, G_UNIT, "+x", 5),
        samples(rng, G_UNIT, "+y", noise=0.05),
        samples(rng, G_UNIT, "+z", tilt_deg=30.0),
    ]
    values[2][7, 2] = 1.99
    options = gate.Options(noise_bound=NOISE_BOUND, nominal_offset=np.array(G_UNIT.offset), full_scale=2.0)
    return values, three_pose(values), options


@pytest.mark.parametrize("skipped", ["short", "saturated", "orientation", "moved"])
def test_skip_removes_exactly_that_checks_findings(skipped: str) -> None:
    values, solution, options = every_check_fails()
    rejected, _ = run_gate(values, solution, options)
    # one reason per pose, the first in the order of CHECKS: the clipped +z pose is not also
    # reported as tilted
    assert [(f.code, f.file) for f in rejected] == [
        ("pose.short", NAMES[0]),
        ("pose.saturated", NAMES[2]),
        ("pose.moved", NAMES[1]),
    ]

    after, after_warned = run_gate(values, solution, replace(options, skip=frozenset({skipped})))
    code = f"pose.{skipped}"
    assert code not in codes(after) + codes(after_warned)
    kept = [f for f in rejected if f.code != code]
    if skipped == "saturated":
        # the +z pose's next reason comes forward, and a pose that is not what it claims spoils
        # the solved matrix the moved check judges through: +y is no longer judged
        assert [(f.code, f.file) for f in after] == [("pose.short", NAMES[0]), ("pose.orientation", NAMES[2])]
    else:
        assert [f for f in after if f.file in {k.file for k in kept}] == kept


def test_skip_every_check_leaves_nothing() -> None:
    values, solution, options = every_check_fails()
    assert run_gate(values, solution, replace(options, skip=frozenset(gate.CHECKS))) == ([], [])


def test_findings_come_in_the_order_of_the_checks() -> None:
    values, solution, options = every_check_fails()
    rejected, _ = run_gate(values, solution, options)
    order = [gate.CHECKS.index(c.removeprefix("pose.")) for c in codes(rejected)]
    assert order == sorted(order)


# --- the reported uncertainty is honest -------------------------------------------------------------

RUNS = 400
N = 300
# realistic: 2 mg noise, 300 samples a pose, gains ~1 %, offsets ~30 mg
HONEST = Truth(1.0, (0.03, -0.025, 0.035), (1.01, 0.99, 1.012), 0.002)


def scatter_ratios(sols: Sequence[core.Solution]) -> tuple[FloatArray, FloatArray]:
    """Empirical standard deviation over the mean reported standard error, offsets and gains."""
    offsets = np.array([s.offset for s in sols])
    gains = np.array([s.gain for s in sols])
    offset_ratio: FloatArray = offsets.std(axis=0, ddof=1) / np.mean([s.offset_se for s in sols], axis=0)
    gain_ratio: FloatArray = gains.std(axis=0, ddof=1) / np.mean([s.gain_se for s in sols], axis=0)
    return offset_ratio, gain_ratio


@pytest.mark.slow
def test_three_pose_reported_errors_match_the_scatter() -> None:
    rng = np.random.default_rng(70)
    sols = [
        core.solve_three_pose([core.pose_stats(samples(rng, HONEST, f, N)) for f in THREE], HONEST.reference)
        for _ in range(RUNS)
    ]
    offset_ratio, gain_ratio = scatter_ratios(sols)
    np.testing.assert_allclose(offset_ratio, 1.0, atol=0.25)
    np.testing.assert_allclose(gain_ratio, 1.0, atol=0.25)


@pytest.mark.parametrize("face", ["+x", "-z"])
def test_one_pose_reported_errors_match_the_scatter(face: str) -> None:
    truth = replace(HONEST, gain=(1.0, 1.0, 1.0))  # the 1-pose solver fixes the gains at 1
    rng = np.random.default_rng(71 + list(core.FACES).index(face))
    sols = [
        core.solve_one_pose(core.pose_stats(samples(rng, truth, face, N)), face, truth.reference) for _ in range(RUNS)
    ]
    offset_ratio, _ = scatter_ratios([replace(s, gain_se=np.ones(3)) for s in sols])
    np.testing.assert_allclose(offset_ratio, 1.0, atol=0.25)
    # gains are not estimated: they do not scatter, and none is claimed
    assert all(s.gain.tolist() == [1.0, 1.0, 1.0] and s.gain_se.tolist() == [0.0, 0.0, 0.0] for s in sols)


# --- the tilt bound ---------------------------------------------------------------------------------------


def tilted(face: str, reference: float, theta_deg: float, phi: float) -> FloatArray:
    """The stimulus of ``face`` tilted by ``theta_deg`` towards azimuth ``phi`` (radians, measured
    from the next axis, x -> y -> z -> x, towards the one after): |v| = reference."""
    up = np.asarray(core.FACES[face])
    axis = int(np.argmax(np.abs(up)))
    e1, e2 = np.zeros(3), np.zeros(3)
    e1[(axis + 1) % 3] = 1.0
    e2[(axis + 2) % 3] = 1.0
    theta = math.radians(theta_deg)
    v: FloatArray = reference * (math.cos(theta) * up + math.sin(theta) * (math.cos(phi) * e1 + math.sin(phi) * e2))
    return v


def raw_pose(rng: np.random.Generator, truth: Truth, v: ArrayLike, n: int = N) -> core.PoseStats:
    """Statistics of n readings of the stimulus v: diag(gain) · v + offset + noise."""
    ideal = np.asarray(truth.gain) * np.asarray(v) + np.asarray(truth.offset)
    return core.pose_stats(ideal + rng.normal(0.0, truth.noise, size=(n, 3)))


def test_tilted_stimulus_keeps_its_magnitude() -> None:
    rng = np.random.default_rng(80)
    for face in core.FACES:
        theta, phi = float(rng.uniform(0, 30)), float(rng.uniform(0, 2 * math.pi))
        v = tilted(face, 9.80665, theta, phi)
        assert float(np.linalg.norm(v)) == pytest.approx(9.80665, rel=1e-12)
        cosine = float(v @ np.asarray(core.FACES[face])) / 9.80665
        assert math.degrees(math.acos(min(1.0, cosine))) == pytest.approx(theta, abs=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("tolerance", [1.0, 2.0])
def test_random_tilts_stay_within_the_tilt_sensitivity(tolerance: float) -> None:
    """Each pose off its face by a random angle up to the tolerance, in a random direction: every
    estimate is within core.tilt_sensitivity + 4 SE of the truth, for both solvers."""
    rng = np.random.default_rng(81)
    one_truth = replace(HONEST, gain=(1.0, 1.0, 1.0))  # 1-pose: raw units = reference units
    worst = 0.0
    for _ in range(150):
        stats = [
            raw_pose(rng, HONEST, tilted(f, 1.0, rng.uniform(0, tolerance), rng.uniform(0, 2 * math.pi))) for f in THREE
        ]
        sol = core.solve_three_pose(stats, 1.0)
        d_offset, d_gain = core.tilt_sensitivity(sol.method, sol.gain, 1.0, THREE, tolerance)
        offset_error = np.abs(sol.offset - HONEST.offset)
        gain_error = np.abs(sol.gain - HONEST.gain)
        assert np.all(offset_error <= d_offset + 4 * sol.offset_se), (offset_error, d_offset)
        assert np.all(gain_error <= d_gain + 4 * sol.gain_se), (gain_error, d_gain)
        worst = max(worst, float(np.max(offset_error / d_offset)))

        face = str(rng.choice(list(core.FACES)))
        v = tilted(face, 1.0, rng.uniform(0, tolerance), rng.uniform(0, 2 * math.pi))
        one = core.solve_one_pose(raw_pose(rng, one_truth, v), face, 1.0)
        d_offset, d_gain = core.tilt_sensitivity(one.method, one.gain, 1.0, [face], tolerance)
        assert np.all(np.abs(one.offset - one_truth.offset) <= d_offset + 4 * one.offset_se)
        assert np.all(np.abs(one.gain - 1.0) <= d_gain)
    assert worst > 0.5  # the random tilts do come near the bound


@pytest.mark.parametrize("tolerance", [1.0, 2.0])
def test_tilt_sensitivity_is_reached_in_the_worst_case(tolerance: float) -> None:
    """Both horizontal poses of x (+y and +z) tilted towards +x by the tolerance: the x offset moves
    by the whole sensitivity, so the bound is not vacuous. Likewise a 1-pose +z tilted towards +x."""
    rng = np.random.default_rng(82)
    toward_x = {"+y": math.pi / 2, "+z": 0.0}  # +y: e1 = z, e2 = x; +z: e1 = x
    stats = [
        raw_pose(rng, HONEST, tilted(f, 1.0, tolerance if f in toward_x else 0.0, toward_x.get(f, 0.0))) for f in THREE
    ]
    sol = core.solve_three_pose(stats, 1.0)
    d_offset, _ = core.tilt_sensitivity(sol.method, sol.gain, 1.0, THREE, tolerance)
    error = sol.offset[0] - HONEST.offset[0]
    assert error > 100 * sol.offset_se[0]  # tilt, not noise
    assert error >= 0.9 * d_offset[0]
    # and it stays a bound here too, though the same tilt also shrinks the solved gain it scales by
    assert error <= d_offset[0] + 4 * sol.offset_se[0]

    one_truth = replace(HONEST, gain=(1.0, 1.0, 1.0))
    one = core.solve_one_pose(raw_pose(rng, one_truth, tilted("+z", 1.0, tolerance, 0.0)), "+z", 1.0)
    d_offset, _ = core.tilt_sensitivity(one.method, one.gain, 1.0, ["+z"], tolerance)
    assert one.offset[0] - one_truth.offset[0] >= 0.9 * d_offset[0]


# --- limits and the verdict ----------------------------------------------------------------------------


def corrected_poses(
    values: Sequence[FloatArray], solution: core.Solution, reference: float = 1.0
) -> list[tuple[str, str, gate.Corrected]]:
    out = []
    for name, face, v in zip(NAMES, THREE, values, strict=True):
        stats = core.pose_stats(v)
        out.append(
            (name, face, gate.corrected(stats.mean, stats.std, face, solution.offset, solution.matrix, reference))
        )
    return out


def g_capture(seed: int = 90) -> tuple[list[FloatArray], core.Solution]:
    rng = np.random.default_rng(seed)
    values = [samples(rng, G_UNIT, face) for face in THREE]
    return values, three_pose(values)


def test_verdict_passes_within_every_limit() -> None:
    values, solution = g_capture()
    limits = gate.Limits(
        offset=np.full(3, 0.05), gain_error=np.full(3, 0.03), cross_axis=0.01, noise=0.003, residual=0.003
    )
    assert (
        gate.verdict(solution.method, solution.offset, solution.matrix, corrected_poses(values, solution), limits) == []
    )


@pytest.mark.parametrize("axis", range(3))
def test_verdict_offset_limit_per_axis(axis: int) -> None:
    """|offset| is (0.02, 0.034, 0.047): a bound of 0.05 passes, one just under |offset| fails that axis."""
    values, solution = g_capture()
    bound = np.full(3, 0.05)
    bound[axis] = 0.9 * abs(G_UNIT.offset[axis])
    limits = gate.Limits(offset=bound)
    failures = gate.verdict(
        solution.method, solution.offset, solution.matrix, corrected_poses(values, solution), limits
    )

    [finding] = failures
    assert finding.code == f"limit.offset.{'xyz'[axis]}"
    assert finding.value == solution.offset[axis]
    assert finding.bound == bound[axis]
    assert finding.file is None
    assert finding.message == f"offset {solution.offset[axis]:.6g} on {'xyz'[axis]} is outside ±{bound[axis]:g}"


def test_verdict_gain_limit_against_a_nominal_gain_in_counts() -> None:
    """±16 g int16 counts: 2048 counts per g nominal; the unit is +1 %, -2 %, +2 % off."""
    truth = Truth(1.0, (20.0, -15.0, 25.0), (2048 * 1.01, 2048 * 0.98, 2048 * 1.02), 4.0)
    rng = np.random.default_rng(91)
    values = [samples(rng, truth, face) for face in THREE]
    solution = three_pose(values)
    limits = gate.Limits(gain_error=np.full(3, 0.015), nominal_gain=np.full(3, 2048.0))
    failures = gate.verdict(
        solution.method, solution.offset, solution.matrix, corrected_poses(values, solution), limits
    )

    assert codes(failures) == ["limit.gain.y", "limit.gain.z"]
    y, z = failures
    assert y.value == pytest.approx(-0.02, abs=5e-4)
    assert z.value == pytest.approx(0.02, abs=5e-4)
    assert y.bound == 0.015
    assert y.message.startswith(f"gain {solution.gain[1]:.6g} on y is -2.0")
    assert y.message.endswith("from nominal 2048, outside ±1.500%")

    wide = gate.Limits(gain_error=np.full(3, 0.025), nominal_gain=np.full(3, 2048.0))
    assert gate.verdict(solution.method, solution.offset, solution.matrix, [], wide) == []


def test_verdict_never_judges_the_one_pose_gain() -> None:
    """1-pose fixes the gains at 1: 1 count per count is -99.95 % from 2048, and not judged."""
    values = samples(np.random.default_rng(92), replace(COUNTS, gain=(1.0, 1.0, 1.0), reference=2048.0), "+z")
    stats = core.pose_stats(values)
    solution = core.solve_one_pose(stats, "+z", 2048.0)
    limits = gate.Limits(gain_error=np.full(3, 0.01), nominal_gain=np.full(3, 2048.0))
    fixed = gate.corrected(stats.mean, stats.std, "+z", solution.offset, solution.matrix, 2048.0)
    assert gate.verdict("one-pose", solution.offset, solution.matrix, [("z.csv", "+z", fixed)], limits) == []
    # the same matrix under a method with gains is judged
    failures = gate.verdict("three-pose", solution.offset, solution.matrix, [], limits)
    assert codes(failures) == ["limit.gain.x", "limit.gain.y", "limit.gain.z"]


@pytest.mark.parametrize(("term", "fails"), [(0.008, True), (-0.008, True), (0.004, False)])
def test_verdict_cross_axis_limit(term: float, fails: bool) -> None:
    """A[x, y] / A[x, x] = term against a bound of 0.5 %."""
    a = np.diag([1.01, 0.98, 1.02])
    a[0, 1] = term * a[0, 0]
    matrix = np.linalg.inv(a)
    failures = gate.verdict("six-pose", np.zeros(3), matrix, [], gate.Limits(cross_axis=0.005))
    if fails:
        [finding] = failures
        assert finding.code == "limit.cross.xy"
        assert finding.value == pytest.approx(term, rel=1e-9)
        assert finding.bound == 0.005
        assert finding.message == f"cross-axis term xy is {finding.value:+.3%}, outside ±0.500%"
    else:
        assert failures == []


@pytest.mark.parametrize("method", ["one-pose", "three-pose", "six-pose-diagonal", "minmax", "gyro-bias"])
def test_limits_a_method_cannot_be_judged_by_are_dropped_with_the_reason(method: str) -> None:
    limits = gate.Limits(gain_error=np.full(3, 0.01), cross_axis=0.005, noise=0.01, residual=0.01)
    dropped = limits.not_applying(method)
    assert "cross_axis" in dropped
    assert dropped["cross_axis"] == "estimates no cross-axis terms"
    kept = limits.for_method(method)
    for name in ("gain_error", "cross_axis", "noise", "residual"):
        assert (getattr(kept, name) is None) == (name in dropped), name
    assert limits.for_method("six-pose") == limits  # every one applies


def test_verdict_cross_axis_is_not_judged_on_a_diagonal_matrix() -> None:
    _, solution = g_capture()
    assert np.count_nonzero(solution.matrix - np.diag(np.diag(solution.matrix))) == 0
    limits = gate.Limits(cross_axis=0.0)  # any non-zero term would fail
    assert gate.verdict(solution.method, solution.offset, solution.matrix, [], limits) == []
    a = np.linalg.inv(solution.matrix)
    a[2, 0] = 1e-6
    assert codes(gate.verdict(solution.method, solution.offset, np.linalg.inv(a), [], limits)) == ["limit.cross.zx"]


def test_verdict_noise_limit_names_the_pose() -> None:
    """Noise is judged per pose in output units: 2 mg passes 3 mg, the +y pose at 4 mg does not."""
    rng = np.random.default_rng(93)
    values = [samples(rng, G_UNIT, "+x"), samples(rng, G_UNIT, "+y", noise=0.004), samples(rng, G_UNIT, "+z")]
    solution = three_pose(values)
    poses = corrected_poses(values, solution)
    failures = gate.verdict(solution.method, solution.offset, solution.matrix, poses, gate.Limits(noise=0.003))

    [finding] = failures
    assert (finding.code, finding.file, finding.pose) == ("limit.noise", NAMES[1], "+y")
    worst = int(np.argmax(poses[1][2].std))
    assert finding.value == poses[1][2].std[worst]
    assert finding.value == pytest.approx(0.004 / G_UNIT.gain[worst], rel=0.15)
    assert finding.message == f"noise {finding.value:.3g} on {'xyz'[worst]} is above 0.003"
    assert gate.verdict(solution.method, solution.offset, solution.matrix, poses, gate.Limits(noise=0.005)) == []


@pytest.mark.parametrize("shift", [0.004, -0.004])
def test_verdict_residual_limit_per_pose(shift: float) -> None:
    """Re-test captures against a stored calibration (as `tumblecal check` does): the unit's z gain has
    since moved by ``shift``, so its +z pose reads ``shift`` off the reference, outside ±0.003; its +x
    and +y poses, where z is horizontal, stay inside."""
    values, solution = g_capture()
    assert all(abs(c.norm_error) < 3e-4 for _, _, c in corrected_poses(values, solution))
    moved = replace(G_UNIT, gain=(G_UNIT.gain[0], G_UNIT.gain[1], G_UNIT.gain[2] * (1.0 + shift)))
    rng = np.random.default_rng(94)
    poses = corrected_poses([samples(rng, moved, face) for face in THREE], solution)

    failures = gate.verdict(solution.method, solution.offset, solution.matrix, poses, gate.Limits(residual=0.003))
    [finding] = failures
    assert (finding.code, finding.file, finding.pose) == ("limit.residual", NAMES[2], "+z")
    assert finding.value == pytest.approx(shift, rel=0.05)
    assert finding.bound == 0.003
    assert finding.message == f"reads {finding.value:+.3g} from the reference after calibration, outside ±0.003"


def test_corrected_reads_the_pose_in_output_units() -> None:
    offset = np.array([0.02, -0.034, 0.047])
    matrix = np.diag([1 / 1.01, 1 / 0.98, 1 / 1.02])
    mean = offset + np.array([0.0, 0.0, 1.02 * 1.003])  # 0.3 % too long on z
    c = gate.corrected(mean, np.array([0.00202, 0.00196, 0.00408]), "+z", offset, matrix, 1.0)
    assert c.norm_error == pytest.approx(0.003, abs=1e-12)
    assert c.vector_error == pytest.approx(0.003, abs=1e-12)
    np.testing.assert_allclose(c.std, [0.002, 0.002, 0.004], rtol=1e-12)
    sideways = gate.corrected(offset + np.array([0.0, 0.98, 0.0]), np.zeros(3), "+z", offset, matrix, 1.0)
    assert sideways.norm_error == pytest.approx(0.0, abs=1e-12)
    assert sideways.vector_error == pytest.approx(math.sqrt(2), rel=1e-12)


# --- findings as data ----------------------------------------------------------------------------------


def test_finding_as_dict() -> None:
    pose = gate.Finding("pose.short", "5 samples, fewer than --min-samples 10", 5, 10, file="x.csv", pose="+x")
    assert pose.as_dict() == {
        "code": "pose.short",
        "value": 5,
        "bound": 10,
        "pose": "+x",
        "file": "x.csv",
        "message": "5 samples, fewer than --min-samples 10",
    }
    assert list(pose.as_dict()) == ["code", "value", "bound", "pose", "file", "message"]
    assert pose.render() == "x.csv: 5 samples, fewer than --min-samples 10"

    limit = gate.Finding("limit.offset.y", "offset -0.034 on y is outside ±0.01", -0.034, 0.01)
    assert limit.as_dict() == {
        "code": "limit.offset.y",
        "value": -0.034,
        "bound": 0.01,
        "message": "offset -0.034 on y is outside ±0.01",
    }
    assert limit.render() == "offset -0.034 on y is outside ±0.01"
    assert type(gate.Finding("c", "m", 2.0, 0.5).as_dict()["value"]) is int  # whole numbers as integers


def test_verdict_findings_as_dict() -> None:
    values, solution = g_capture()
    limits = gate.Limits(offset=np.full(3, 0.01), noise=0.001)
    failures = gate.verdict(
        solution.method, solution.offset, solution.matrix, corrected_poses(values, solution), limits
    )
    assert codes(failures) == ["limit.offset.x", "limit.offset.y", "limit.offset.z"] + ["limit.noise"] * 3
    for f in failures:
        d = f.as_dict()
        assert (d["code"], d["value"], d["bound"], d["message"]) == (f.code, f.value, f.bound, f.message)
        if f.code == "limit.noise":
            assert (d["file"], d["pose"]) == (f.file, f.pose)
        else:
            assert "file" not in d
            assert "pose" not in d


def test_every_check_of_the_catalog_has_its_judge_and_its_choice() -> None:
    """core.catalog lists the quality checks once: the gate judges each pose under each of them
    (and under no other), and ``--no-check`` offers each by its name."""
    from tumblecal_cli.cli.flags import CheckName
    from tumblecal_cli.core import catalog
    from tumblecal_cli.pipeline.options import CHECK_NAMES

    assert tuple(gate.JUDGES) == catalog.CHECKS == gate.CHECKS
    assert tuple(c.value for c in CheckName) == catalog.check_names() == CHECK_NAMES
    assert set(catalog.check_names()) == {c.replace("_", "-") for c in (*catalog.CHECKS, *catalog.FIT_CHECKS)}

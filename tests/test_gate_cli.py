"""CLI tests of the production-test gate: quality checks (exit 3), limits (exit 1), --json,
traceability, ``show``, ``check`` and the gate's effect on ``apply`` (docs/reference/exit-status.md).

Poses are synthetic with a known truth (tests/synth.py, the sample set's offset and gain), written
to tmp_path; bad limits files live in tests/data/bad/. Every run is in-process.
"""

from __future__ import annotations

import gzip
import json
import math
import re
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tests.conftest import (
    BAD,
    POSES_3,
    ROOT,
    SAMPLE,
    Result,
    assert_one_error,
    assert_untouched,
    precious,
    run,
    unnamed,
    write,
)
from tests.synth import FloatArray, pose_samples
from tumblecal_cli.core import model as core
from tumblecal_cli.core.model import FACES

#: the truth of the synthetic poses: the sample set's (sample_data/README.md)
OFFSET = (0.021, -0.034, 0.047)
GAIN = (1.012, 0.987, 1.005)
LIMITS = SAMPLE / "limits.yaml"
SAMPLE_LIMITS = {
    "offset": [0.05, 0.05, 0.05],
    "gain_error": [0.02, 0.02, 0.02],
    "nominal_gain": [1.0, 1.0, 1.0],
    "cross_axis": 0.01,
    "noise": 0.005,
    "residual": 0.002,
}
# sample_data/limits.yaml as a three-pose unit is judged by it: no cross-axis terms to judge
THREE_POSE_LIMITS = {k: v for k, v in SAMPLE_LIMITS.items() if k != "cross_axis"}
SAMPLE_JUDGED = "limits: offset, gain_error, noise, residual"
RULE = "--max-noise 0.02 × reference 1"  # how the moved check's bound was made, as its messages say
CROSS_AXIS_NOTE = "note: the three-pose solver estimates no cross-axis terms, so the cross-axis limit does not apply"
HINT = {
    "pose.moved": "hold the unit still and capture the pose again, or raise --max-noise; a capture turned through "
    "orientations on purpose is a log: solve --log FILE finds its still stretches",
    "pose.short": "log the pose for longer, or lower --min-samples (1 for loggers that store one averaged row)",
    "pose.saturated": "the pose reaches the sensor's limits: use a wider range, or give the real one with --full-scale",
    "pose.upside_down": "give the files in the order +x +y +z, each with that axis pointing up",
}
EPOCH = "1700000000"  # 2023-11-14T22:13:20Z


# -- helpers -------------------------------------------------------------------------------


def pose_values(
    face: str,
    *,
    n: int = 200,
    noise: float = 0.002,
    seed: int = 0,
    offset: Sequence[float] = OFFSET,
    gain: Sequence[float] = GAIN,
    tilt_deg: float = 0.0,
) -> FloatArray:
    """(n, 3) raw readings of one static pose, ``diag(gain) v + offset + noise`` (|v| = 1)."""
    rng = np.random.default_rng(seed)
    return pose_samples(rng, FACES[face], offset=offset, gain=gain, reference=1.0, noise=noise, n=n, tilt_deg=tilt_deg)


def write_capture(
    path: Path,
    values: FloatArray,
    *,
    fmt: str = "%.6f",
    header: str = "t,ax,ay,az",
    extra: FloatArray | None = None,
) -> Path:
    """``t`` at 100 Hz, the three values, then the ``extra`` column if given (named in ``header``)."""
    n = values.shape[0]
    columns = [np.arange(n) / 100.0, values[:, 0], values[:, 1], values[:, 2]]
    formats = ["%.2f", fmt, fmt, fmt]
    if extra is not None:
        columns.append(extra)
        formats.append("%.3f")
    return write(path, np.column_stack(columns), header=header, fmt=formats)


def three_poses(folder: Path, *, n: int = 200, noise: float = 0.002) -> list[Path]:
    """x.csv, y.csv, z.csv: the +x, +y, +z poses of the synthetic unit."""
    return [
        write_capture(folder / f"{face[1]}.csv", pose_values(face, n=n, noise=noise, seed=seed))
        for seed, face in enumerate(("+x", "+y", "+z"), start=1)
    ]


def ramp(n: int, axis: int, rise: float) -> FloatArray:
    """A drift of ``rise`` over the capture on one axis (the unit slowly moving)."""
    out = np.zeros((n, 3))
    out[:, axis] = np.linspace(0.0, rise, n)
    return out


def third_drift(values: FloatArray) -> FloatArray:
    """What the gate calls drift: the mean of the last third minus the mean of the first third."""
    third = values.shape[0] // 3
    drift: FloatArray = values[-third:].mean(axis=0) - values[:third].mean(axis=0)
    return drift


def file_values(path: Path) -> FloatArray:
    values: FloatArray = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)[:, 1:4]
    return values


def vec(values: Sequence[float] | FloatArray) -> str:
    """A mean as the gate prints it."""
    return ", ".join(f"{v:.3g}" for v in values)


def solve(capsys: pytest.CaptureFixture[str], *args: str | Path) -> Result:
    return run(capsys, "solve", *args)


def lines(result: Result, prefix: str) -> list[str]:
    return [ln for ln in result.err.splitlines() if ln.startswith(prefix)]


def assert_rejected(result: Result, expected: list[str], hint: str, *, json_out: bool = False) -> None:
    """Exit 3: exactly these ``error:`` lines (one per rejected pose), then one hint."""
    assert result.code == 3, result.err
    assert "Traceback" not in result.err
    assert lines(result, "error:") == [f"error: {e}" for e in expected]
    assert lines(result, "hint:") == [f"hint: {hint}"]
    assert result.err.rstrip("\n").endswith(f"hint: {hint}"), "the hint comes last"
    if json_out:
        summary = json.loads(result.out)
        assert (summary["status"], summary["exit_status"], summary["file"]) == ("rejected", 3, None)
        assert summary["verdict"] is None
    else:
        assert result.out == ""


def codes(items: list[dict[str, Any]]) -> list[str]:
    return [str(item["code"]) for item in items]


def solved(capsys: pytest.CaptureFixture[str], out: Path, *args: str | Path, code: int = 0) -> dict[str, Any]:
    """Solve the sample set into ``out`` and return the document."""
    r = solve(capsys, "-q", "-p", *POSES_3, "-o", out, *args)
    assert r.code == code, r.err
    doc: dict[str, Any] = yaml.safe_load(out.read_text()) if out.suffix == ".yaml" else json.loads(out.read_text())
    return doc


def solved_files(capsys: pytest.CaptureFixture[str], files: list[Path], out: Path) -> dict[str, Any]:
    """Solve ``files`` into ``out`` (exit 0, nothing on stderr) and return the document."""
    r = solve(capsys, "-q", "-p", *files, "-o", out)
    assert (r.code, r.err) == (0, "")
    doc: dict[str, Any] = json.loads(out.read_text())
    return doc


# -- exit 0: a good unit ---------------------------------------------------------------------


def test_good_poses_pass_and_write_the_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = three_poses(tmp_path)
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *poses, "-o", out)
    assert r.code == 0, r.err
    assert r.out == ""
    assert lines(r, "error:") == lines(r, "warning:") == lines(r, "hint:") == []
    assert "verdict: PASS (no limits judged)\n" in r.err
    assert r.err.endswith(f"wrote {out}\n")
    doc = json.loads(out.read_text())
    assert doc["verdict"] == {"pass": True, "failures": [], "limits": {}}
    np.testing.assert_allclose(doc["offset"], OFFSET, atol=1e-3)
    np.testing.assert_allclose(doc["gain"], GAIN, atol=1e-3)


# -- exit 3: quality checks ----------------------------------------------------------------


def test_a_pose_that_drifts_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y, z = three_poses(tmp_path)
    moving = ramp(200, axis=1, rise=0.2)
    write_capture(y, pose_values("+y", seed=2) + moving)
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", x, y, z, "-o", out, "--json")
    summary = json.loads(r.out)
    [moved] = summary["rejections"]
    assert {k: moved[k] for k in ("code", "bound", "pose", "file")} == {
        "code": "pose.moved",
        "bound": 0.02,
        "pose": "+y",
        "file": str(y),
    }
    # the drift on y in output units: the ramp's (last third - first third) over the solved gain
    assert moved["value"] == pytest.approx(third_drift(moving)[1] / summary["gain"][1], rel=0.02)
    assert_rejected(
        r,
        [f"{y}: drifts by {moved['value']:.3g} on y (first vs last third), above 0.02 ({RULE}): the unit moved"],
        HINT["pose.moved"],
        json_out=True,
    )
    assert_untouched(out)
    # the drift is 0.12 g: a bound of 0.2 g lets it through
    r = solve(capsys, "-q", "-p", x, y, z, "-o", out, "--max-noise", "0.2")
    assert (r.code, r.err) == (0, "")
    assert json.loads(out.read_text())["poses"][1]["drift"][1] == pytest.approx(third_drift(moving)[1], abs=1e-3)


def test_a_noisy_pose_is_rejected_for_its_standard_deviation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    x, y, z = three_poses(tmp_path)
    write_capture(y, pose_values("+y", seed=2, noise=0.05))
    r = solve(capsys, "-q", "-p", x, y, z, "-o", tmp_path / "cal.json", "--json")
    summary = json.loads(r.out)
    [moved] = summary["rejections"]
    # the standard deviation through M, on the worst axis
    std = np.abs(np.diag(summary["matrix"])) * np.array(summary["poses"][1]["std"])
    assert moved["value"] == pytest.approx(std.max(), rel=1e-9)
    assert moved["value"] == pytest.approx(0.05, rel=0.15)
    axis = "xyz"[int(np.argmax(std))]
    assert_rejected(
        r,
        [f"{y}: standard deviation {moved['value']:.3g} on {axis}, above 0.02 ({RULE}): the unit moved"],
        HINT["pose.moved"],
        json_out=True,
    )
    assert not (tmp_path / "cal.json").exists()


def test_a_narrow_pass_warns_and_exits_0(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y, z = three_poses(tmp_path)
    write_capture(y, pose_values("+y", seed=2, noise=0.017))  # within 80-100 % of --max-noise 0.02
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", x, y, z, "-o", out, "--json")
    assert r.code == 0, r.err
    assert lines(r, "error:") == lines(r, "hint:") == []
    summary = json.loads(r.out)
    assert (summary["status"], summary["exit_status"]) == ("pass", 0)
    [close] = summary["warnings"]
    assert (close["code"], close["bound"], close["file"]) == ("pose.moved", 0.02, str(y))
    assert 0.8 * 0.02 < close["value"] <= 0.02
    message = f"standard deviation {close['value']:.3g} on y, close to 0.02 ({RULE})"
    assert close["message"] == message  # not "above ...: the unit moved": it passed
    assert lines(r, "warning:") == [f"warning: {y}: {message} (pose.moved)"]
    assert json.loads(out.read_text())["verdict"]["pass"] is True


def test_swapped_files_are_named_with_the_order_question(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # files not named for their faces: their order gives the faces, here +x and +y swapped
    x, y, z = unnamed(three_poses(tmp_path), tmp_path / "unnamed")
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", y, x, z, "-o", out)
    assert_rejected(
        r,
        [
            f"{y}: declared +x but reads like +y (mean {vec(file_values(y).mean(axis=0))}); "
            "were the files given in the order x y z?",
            f"{x}: declared +y but reads like +x (mean {vec(file_values(x).mean(axis=0))}); "
            "were the files given in the order x y z?",
        ],
        "give the pose files in the order +x +y +z",
    )
    assert_untouched(out)


def test_a_pose_past_the_full_scale_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y, z = three_poses(tmp_path)
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", x, y, z, "-o", out, "--full-scale", "1.07")  # z reads 1.052: past 0.98 x 1.07
    level = 0.98 * 1.07
    peaks = np.abs(file_values(z)).max(axis=1)
    clipped = int((peaks >= level).sum())
    assert 0 < clipped < 200
    assert_rejected(
        r,
        [f"{z}: {clipped} samples clipped at 98% of --full-scale 1.07 (peak {peaks.max() / level:.0%} of that)"],
        HINT["pose.saturated"],
    )
    assert_untouched(out)


def write_counts(folder: Path, gain_z: float) -> list[Path]:
    """The three poses in signed 16-bit counts (about 16400 per g); +z reads gain_z + 700, clipped."""
    paths = []
    for seed, face in enumerate(("+x", "+y", "+z"), start=1):
        values = pose_values(face, seed=seed, noise=30, offset=(300, -500, 700), gain=(16500, 16200, gain_z))
        counts = np.clip(np.round(values), -32768, 32767)
        paths.append(write_capture(folder / f"c{face[1]}.csv", counts, fmt="%d"))
    return paths


def test_integer_counts_at_the_int16_rail_are_clipped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cx, cy, cz = write_counts(tmp_path, gain_z=32400)  # +z would read 33100: the ADC stops at 32767
    assert (file_values(cz)[:, 2] == 32767).all()
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", cx, cy, cz, "-o", out)
    assert_rejected(
        r, [f"{cz}: 200 samples clipped at the limit of its integer type (peak 100% of that)"], HINT["pose.saturated"]
    )
    assert_untouched(out)
    # a sensor whose real full scale is wider than the data: not clipped
    r = solve(capsys, "-q", "-p", cx, cy, cz, "-o", out, "--full-scale", "40000")
    assert (r.code, r.err) == (0, "")
    assert [p["clipped"] for p in json.loads(out.read_text())["poses"]] == [0, 0, 0]


def test_counts_below_the_rail_pass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", *write_counts(tmp_path, gain_z=16400), "-o", out, "--input-units", "counts")
    assert (r.code, r.err) == (0, "")
    doc = json.loads(out.read_text())
    np.testing.assert_allclose(doc["gain"], [16500, 16200, 16400], rtol=1e-3)  # counts per g
    assert [p["clipped"] for p in doc["poses"]] == [0, 0, 0]


def test_one_row_poses_are_short_unless_min_samples_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = three_poses(tmp_path, n=1)
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *poses, "-o", out)
    assert_rejected(r, [f"{p}: 1 sample, fewer than --min-samples 10" for p in poses], HINT["pose.short"])
    assert_untouched(out)
    r = solve(capsys, "-q", "-p", *poses, "-o", out, "--min-samples", "1")
    assert (r.code, r.err) == (0, "")
    doc = json.loads(out.read_text())
    assert [p["samples"] for p in doc["poses"]] == [1, 1, 1]
    assert [p["std"] for p in doc["poses"]] == [[0.0, 0.0, 0.0]] * 3
    assert [p["drift"] for p in doc["poses"]] == [[0.0, 0.0, 0.0]] * 3


def test_one_row_one_pose_with_min_samples_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = write_capture(tmp_path / "z.csv", pose_values("+z", n=1))
    assert solve(capsys, "-q", "-p", pose).code == 3
    r = solve(capsys, "-q", "-p", pose, "--min-samples", "1")
    assert (r.code, r.err) == (0, "")
    assert json.loads(r.out)["method"] == "one-pose"


def test_upside_down_pose_then_negative_gain(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "upside_down_x.csv"
    files: list[str | Path] = [pose, *POSES_3[1:]]
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *files, "-o", out, "--json", "-q")
    assert r.code == 3
    assert codes(json.loads(r.out)["rejections"]) == ["pose.upside_down"]  # found by its direction
    # without the orientation check the solved gain on x is negative: the upside-down check says so
    r = solve(capsys, "-p", *files, "-o", out, "--json", "-q", "--no-check", "orientation")
    summary = json.loads(r.out)
    assert codes(summary["rejections"]) == ["pose.upside_down"]
    means = [file_values(Path(f)).mean(axis=0) for f in files]
    gain_x = summary["gain"][0]
    assert gain_x == pytest.approx(means[0][0] - (means[1][0] + means[2][0]) / 2, abs=1e-9)
    assert gain_x < 0
    assert_rejected(
        r,
        [
            f"{pose}: gain {gain_x:.4g} on x (mean {vec(means[0])}): "
            "its x axis was not pointing up (upside down, or the files out of order)"
        ],
        HINT["pose.upside_down"],
        json_out=True,
    )
    assert_untouched(out)
    r = solve(capsys, "-q", "-p", *files, "-o", out, "--no-check", "orientation", "--no-check", "upside-down")
    assert (r.code, r.err) == (0, "")
    assert json.loads(out.read_text())["gain"][0] < 0


def test_one_pose_upside_down(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = write_capture(tmp_path / "z.csv", pose_values("-z"))  # logged with z down, declared +z (the default)
    r = solve(capsys, "-q", "-p", pose)
    assert_rejected(
        r,
        [f"{pose}: declared +z but reads like -z (mean {vec(file_values(pose).mean(axis=0))}): upside down"],
        "turn the unit over so that its z axis points up (a sensor that reads -1 g on the axis pointing up is "
        "declared as the opposite face)",
    )
    r = solve(capsys, "-q", "-p", pose, "--up", "-z")
    assert (r.code, r.err) == (0, "")


def scenario(name: str, folder: Path) -> tuple[list[Path], list[str]]:
    """Pose files and options that one quality check rejects."""
    x, y, z = three_poses(folder)
    if name == "moved":
        write_capture(y, pose_values("+y", seed=2) + ramp(200, axis=1, rise=0.2))
        return [x, y, z], []
    if name == "swapped":  # not named for their faces: their order gives the faces
        return unnamed([y, x, z], folder / "unnamed"), []
    if name == "saturated":
        return [x, y, z], ["--full-scale", "1.07"]
    if name == "int16-rail":
        return write_counts(folder, gain_z=32400), []
    if name == "short":
        return three_poses(folder, n=1), []
    assert name == "upside-down"
    return [BAD / "upside_down_x.csv", *map(Path, POSES_3[1:])], []


SCENARIOS = ["moved", "swapped", "saturated", "int16-rail", "short", "upside-down"]


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENARIOS)
def test_no_checks_turns_every_check_off(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files, options = scenario(name, tmp_path)
    out = precious(tmp_path / "cal.json")
    assert solve(capsys, "-q", "-p", *files, "-o", out, *options).code == 3
    assert_untouched(out)
    r = solve(capsys, "-q", "-p", *files, "-o", out, *options, "--no-checks", "--json")
    assert r.code == 0, r.err
    assert r.err == ""
    summary = json.loads(r.out)
    assert (summary["status"], summary["rejections"]) == ("pass", [])
    # a negative gain is still said, whatever checks are off (a mirrored axis is never right)
    mirrored = {"swapped": ["x", "y"], "upside-down": ["x"]}.get(name, [])
    assert [w["code"] for w in summary["warnings"]] == ["pose.upside_down"] * len(mirrored)
    assert [w["message"].split(" is negative")[0].split()[-1] for w in summary["warnings"]] == mirrored
    assert json.loads(out.read_text())["verdict"]["pass"] is True


@pytest.mark.parametrize(
    ("name", "checks"),
    [
        ("moved", ["moved"]),
        ("saturated", ["saturated"]),
        ("int16-rail", ["saturated"]),
        ("short", ["short"]),
        # a swapped pair also solves to negative gains: two checks say so
        ("swapped", ["orientation", "upside-down"]),
        ("upside-down", ["orientation", "upside-down"]),
    ],
)
def test_no_check_turns_one_check_off(
    name: str, checks: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files, options = scenario(name, tmp_path)
    out = tmp_path / "cal.json"
    others = [c for c in ("moved", "orientation", "saturated", "short", "upside-down") if c not in checks]
    skip_others = [arg for c in others for arg in ("--no-check", c)]
    r = solve(capsys, "-q", "-p", *files, "-o", out, *options, *skip_others)
    assert r.code == 3, "the other checks do not turn this one off"
    assert not out.exists()
    skip = [arg for c in checks for arg in ("--no-check", c)]
    r = solve(capsys, "-q", "-p", *files, "-o", out, *options, *skip)
    assert (r.code, r.err) == (0, "")
    assert out.exists()


def test_no_check_needs_a_known_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--no-check", "noise")
    assert_one_error(
        r,
        "Invalid value for '--no-check': 'noise' is not one of 'moved', 'orientation', 'saturated', "
        "'short', 'upside-down', 'coverage'.",
        hint="see 'tumblecal solve --help'",
    )
    assert_untouched(out)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--max-noise", "0"], "--max-noise must be positive, got 0"),
        (["--max-tilt", "0"], "--max-tilt must be positive, got 0"),
        (["--full-scale", "0"], "--full-scale must be positive, got 0"),
        (["--nominal-offset", "1,2"], "--nominal-offset takes one number or three (X,Y,Z), got '1,2'"),
        (["--max-offset", "0"], "--max-offset must be positive, got '0'"),
        (["--max-offset", "0.1,0.1"], "--max-offset takes one number or three (X,Y,Z), got '0.1,0.1'"),
        (["--max-gain-error", "2%"], "--max-gain-error takes one number or three (X,Y,Z), got '2%'"),
        (["--nominal-gain", "0,1,1"], "--nominal-gain must be positive, got '0,1,1'"),
        (["--nominal-gain", "1e308"], "--nominal-gain must be a number up to 1e100, got '1e308'"),  # overflow warnings
        (["--json"], "--json prints the summary on stdout, so the calibration needs -o FILE"),
        (["--json", "-o", "-"], "--json prints the summary on stdout, so the calibration needs -o FILE"),
    ],
)
def test_bad_gate_options_are_usage_errors(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert_one_error(solve(capsys, "-p", *POSES_3, *args), message, json_out="--json" in args)


def test_gyroscope_noise_is_judged_only_with_max_noise(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rates = pose_values("+z", noise=1.0, offset=(0.5, -0.3, 0.2), gain=(0.0, 0.0, 0.0))  # deg/s at rest
    pose = write_capture(tmp_path / "gyro.csv", rates, header="t,gyr_x,gyr_y,gyr_z")
    r = solve(capsys, "-q", "-p", pose, "--sensor", "gyroscope")
    assert r.code == 0, r.err
    assert json.loads(r.out)["reference"] == 0.0
    r = solve(capsys, "-q", "-p", pose, "--sensor", "gyroscope", "--max-noise", "0.5")
    assert r.code == 3
    [error] = lines(r, "error:")
    assert error.startswith(f"error: {pose}: standard deviation ")
    assert error.endswith("above 0.5 (--max-noise 0.5): the unit moved")  # in deg/s, not x reference


# -- exit status order: 2 > 3 > 1 > 0 ------------------------------------------------------


def moving_poses(folder: Path) -> list[Path]:
    files, _ = scenario("moved", folder)
    return files


def test_a_units_mistake_is_2_even_when_a_check_fails(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # m/s^2 read as g: one row (pose.short) or a drift (pose.moved) would be rejected, but the units come first
    one_row = write_capture(tmp_path / "one_row_ms2.csv", 9.80665 * pose_values("+z", n=1))
    drifting = write_capture(
        tmp_path / "drifting_ms2.csv", 9.80665 * pose_values("+z", noise=0.01) + ramp(200, axis=2, rise=0.6)
    )
    out = precious(tmp_path / "cal.json")
    for pose in (one_row, drifting):
        r = solve(capsys, "-p", pose, "-o", out, "--json")
        magnitude = np.linalg.norm(file_values(pose).mean(axis=0))
        assert_one_error(
            r,
            f"{pose}: the pose reads {magnitude:.4g} in magnitude but --reference is 1: a units mistake?",
            hint="run with --reference 9.80665",
            json_out=True,
        )
        assert_untouched(out)
    # with its reference the drifting pose is judged, and rejected
    r = solve(capsys, "-q", "-p", drifting, "-o", out, "--reference", "9.80665")
    assert r.code == 3
    assert lines(r, "error:")[0].startswith(f"error: {drifting}: drifts by ")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--limits", str(BAD / "limits_unknown_key.yaml")], "unknown limit 'gain'"),
        (["--meta", "lot"], "--meta takes KEY=VALUE, got 'lot'"),
        (["--max-noise", "0"], "--max-noise must be positive, got 0"),
    ],
    ids=["bad-limits-file", "bad-meta", "bad-option"],
)
def test_an_input_error_is_2_even_when_a_pose_moved(
    extra: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *moving_poses(tmp_path), "-o", out, "--json", *extra)
    assert r.code == 2
    assert json.loads(r.out)["status"] == "error", "no JSON summary for a usage error: an error object"
    [error] = lines(r, "error:")
    assert message in error
    assert_untouched(out)


@pytest.mark.parametrize("where", ["missing-folder", "a-folder"])
def test_an_output_that_cannot_be_written_is_2_even_when_a_pose_moved(
    where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    poses = moving_poses(tmp_path)
    if where == "missing-folder":
        out, message = tmp_path / "no" / "cal.json", "the output folder does not exist"
    else:
        out, message = tmp_path / "cals", "is a folder: -o takes a file name"
        out.mkdir()
    r = solve(capsys, "-p", *poses, "-o", out, "--json")
    assert_one_error(r, f"{out}: {message}", json_out=True)
    r = solve(capsys, "-p", *poses, "-o", out, "--no-checks")  # and when there is nothing else wrong
    assert_one_error(r, f"{out}: {message}")
    assert not (tmp_path / "no").exists()
    assert not out.is_dir() or list(out.iterdir()) == []
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == [], "no temporary file is left"


def test_apply_to_a_folder(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "corrected"
    folder.mkdir()
    r = run(capsys, "apply", "--cal", unit_cal, SAMPLE / "capture.csv", "-o", folder)
    assert_one_error(r, f"{folder}: is a folder: -o takes a file name")
    assert list(folder.iterdir()) == []


def test_a_bad_capture_is_2_even_when_another_pose_moved(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y, _ = moving_poses(tmp_path)
    bad = BAD / "non_numeric_cell.csv"
    r = solve(capsys, "-p", x, y, bad)
    assert_one_error(r, f"{bad}: not a number: 'oops' (line 3, column ay)")


def test_a_rejection_is_3_even_when_a_limit_fails(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-q", "-p", *moving_poses(tmp_path), "-o", out, "--json", "--max-offset", "0.001")
    summary = json.loads(r.out)
    assert (r.code, summary["status"], summary["exit_status"], summary["verdict"]) == (3, "rejected", 3, None)
    assert codes(summary["rejections"]) == ["pose.moved"]
    assert "verdict:" not in r.err
    assert_untouched(out)


# -- exit 1: limits ------------------------------------------------------------------------


def test_sample_set_passes_the_sample_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--limits", LIMITS)
    assert r.code == 0, r.err
    assert f"verdict: PASS ({SAMPLE_JUDGED})\n" in r.err
    assert CROSS_AXIS_NOTE in r.err.splitlines()
    assert json.loads(out.read_text())["verdict"] == {"pass": True, "failures": [], "limits": THREE_POSE_LIMITS}


def test_a_limit_exceeded_exits_1_and_writes_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--limits", LIMITS, "--max-offset", "0.04")
    assert r.code == 1, r.err
    assert r.out == ""
    assert lines(r, "error:") == []
    err = r.err.splitlines()
    assert f"verdict: FAIL ({SAMPLE_JUDGED})" in err
    assert "  limit.offset.z: offset 0.0469971 on z is outside ±0.04" in err
    assert err[-1] == f"wrote {out}"
    verdict = json.loads(out.read_text())["verdict"]  # the failing unit is archived too
    assert verdict["pass"] is False
    assert verdict["failures"] == [
        {
            "code": "limit.offset.z",
            "value": pytest.approx(0.0469971, abs=1e-7),
            "bound": 0.04,
            "message": "offset 0.0469971 on z is outside ±0.04",
        }
    ]
    assert verdict["limits"] == THREE_POSE_LIMITS | {"offset": [0.04, 0.04, 0.04]}  # the flag overrides the file


@pytest.mark.parametrize(
    ("args", "failing", "limits"),
    [
        pytest.param(
            ["--max-offset", "0.025,0.03,0.05"], ["limit.offset.y"], {"offset": [0.025, 0.03, 0.05]}, id="per-axis"
        ),
        pytest.param(
            ["--max-gain-error", "0.01"],
            ["limit.gain.x", "limit.gain.y"],  # +1.19 %, -1.31 %; z is -0.50 % off
            {"gain_error": [0.01] * 3, "nominal_gain": [1.0] * 3},
            id="gain-error",
        ),
        pytest.param(
            ["--max-gain-error", "0.01", "--nominal-gain", "1.01"],
            ["limit.gain.y"],  # against 1.01: x +0.19 %, y -2.29 %, z -0.50 %
            {"gain_error": [0.01] * 3, "nominal_gain": [1.01] * 3},
            id="nominal-gain",
        ),
        pytest.param(
            ["--limits", LIMITS, "--nominal-gain", "1.1"],
            ["limit.gain.x", "limit.gain.y", "limit.gain.z"],
            THREE_POSE_LIMITS | {"nominal_gain": [1.1] * 3},
            id="nominal-gain-overrides-file",
        ),
    ],
)
def test_limit_flags(
    args: list[str | Path],
    failing: list[str],
    limits: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "cal.json"
    verdict = solved(capsys, out, *args, code=1)["verdict"]
    assert codes(verdict["failures"]) == failing
    assert verdict["limits"] == limits


def test_limits_file_in_json_with_per_pose_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    limits = tmp_path / "limits.json"
    limits.write_text(json.dumps({"version": 1, "gain_error": [0.02, 0.005, 0.02], "noise": 0.001}))
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--limits", limits)
    assert r.code == 1
    failures = json.loads(out.read_text())["verdict"]["failures"]
    assert codes(failures) == ["limit.gain.y", "limit.noise", "limit.noise", "limit.noise"]
    # a per-pose failure names the pose and its file
    assert [(f.get("pose"), f.get("file")) for f in failures] == [
        (None, None),
        *zip(("+x", "+y", "+z"), POSES_3, strict=True),
    ]
    for f in failures[1:]:
        assert f"  limit.noise: {f['file']}: noise " in r.err


def test_output_onto_the_limits_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    limits = tmp_path / "limits.yaml"
    limits.write_bytes(LIMITS.read_bytes())
    r = solve(capsys, "-p", *POSES_3, "--limits", limits, "-o", limits)
    assert_one_error(r, f"{limits}: -o would overwrite the input {limits}", hint="write the output to a new file")
    assert limits.read_bytes() == LIMITS.read_bytes()


def test_one_pose_gains_are_not_judged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", SAMPLE / "z.csv", "-o", out, "--max-gain-error", "0.001")
    assert (r.code, r.err) == (0, "")  # the 1-pose solver fixes its gains at 1


BAD_LIMITS = [
    pytest.param(
        "limits_unknown_key.yaml",
        "unknown limit 'gain' (known: offset, gain_error, nominal_gain, cross_axis, noise, residual, nominal_offset, "
        "noise_density, bias_instability, random_walk, offset_drift, offset_drift_per_degc, imu_consistency, "
        "gyro_consistency, current_interference, dip_angle)",
        id="unknown-key",
    ),
    pytest.param("limits_negative_offset.yaml", "limit 'offset' must be positive, got -0.05", id="negative"),
    pytest.param(
        "limits_zero_gain_error.json", "limit 'gain_error' must be positive, got [0.02, 0, 0.02]", id="zero-on-one-axis"
    ),
    pytest.param("limits_offset_two_values.yaml", "field 'offset' must be a list of 3 numbers", id="two-values"),
    pytest.param("limits_noise_per_axis.yaml", "field 'noise' must be a finite number", id="list-for-one-number"),
    pytest.param(
        "limits_ini_not_yaml.yaml",
        "not valid YAML: expected '<document start>', but found '<scalar>' (line 2, column 1)",
        id="not-yaml",
    ),
    pytest.param(
        "limits_truncated.json",
        "not valid JSON: Expecting property name enclosed in double quotes (line 4, column 1)",
        id="not-json",
    ),
    pytest.param(
        "limits_version_2.yaml", "unsupported limits version 2 (this tumblecal reads version 1)", id="version-2"
    ),
    pytest.param(
        "limits_version_true.yaml",
        "unsupported limits version True (this tumblecal reads version 1)",
        id="version-true",
    ),
    pytest.param(
        "limits_list_not_mapping.yaml", "not a limits file: expected a JSON/YAML object at the top", id="not-a-mapping"
    ),
    pytest.param("does_not_exist.yaml", "no such limits file", id="missing-file"),
]


@pytest.mark.parametrize(("name", "message"), BAD_LIMITS)
def test_solve_bad_limits_file(name: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--limits", BAD / name, "--json")
    assert_one_error(r, f"{BAD / name}: {message}", json_out=True)
    assert_untouched(out)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "message"), BAD_LIMITS)
def test_check_bad_limits_file(name: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    solved(capsys, cal)
    before = cal.read_bytes()
    assert_one_error(run(capsys, "check", cal, "--limits", BAD / name), f"{BAD / name}: {message}")
    assert cal.read_bytes() == before


# -- --json --------------------------------------------------------------------------------

SUMMARY_KEYS = [
    "status",
    "exit_status",
    "file",
    "rejections",
    "verdict",
    "warnings",
    "notes",
    "sensor",
    "method",
    "reference",
    "units",
    "columns",
    "offset",
    "matrix",
    "gain",
    "uncertainty",
    "tilt_sensitivity",
    "residuals",
    "coverage",
    "coverage_gaps",
    "outliers",
    "poses",
    "unit",
]
POSE_DIAGNOSTICS = ["angle_deg", "clipped", "drift", "norm_error", "vector_error"]


def test_json_summary_on_pass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--json", "--serial", "A17")
    assert r.code == 0, r.err
    summary = json.loads(r.out)  # stdout is one JSON document and nothing else
    assert r.out.startswith("{")
    assert r.out.endswith("}\n")
    assert "verdict: PASS" in r.err  # people's summary still goes to stderr
    assert list(summary) == SUMMARY_KEYS
    assert (summary["status"], summary["exit_status"], summary["file"]) == ("pass", 0, str(out))
    assert (summary["rejections"], summary["warnings"]) == ([], [])
    doc = json.loads(out.read_text())
    assert summary["verdict"] == doc["verdict"] == {"pass": True, "failures": [], "limits": {}}
    for key in SUMMARY_KEYS[7:]:
        assert summary[key] == doc.get(key), key
    assert summary["unit"]["serial"] == "A17"
    assert list(summary["uncertainty"]) == ["offset", "gain"]
    assert list(summary["tilt_sensitivity"]) == ["offset", "gain", "tolerance_deg"]
    for pose in summary["poses"]:
        assert [k for k in pose if k in POSE_DIAGNOSTICS] == POSE_DIAGNOSTICS
    assert summary["notes"] == [ln.removeprefix("note: ") for ln in lines(r, "note: ")]


def test_json_summary_on_fail(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", *POSES_3, "-o", out, "--json", "--max-offset", "0.04")
    assert (r.code, r.err) == (1, "")
    summary = json.loads(r.out)
    assert (summary["status"], summary["exit_status"], summary["file"]) == ("fail", 1, str(out))
    assert summary["verdict"]["pass"] is False
    assert codes(summary["verdict"]["failures"]) == ["limit.offset.z"]
    assert summary["verdict"] == json.loads(out.read_text())["verdict"]


def test_json_summary_on_rejection_has_the_parameters(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", *three_poses(tmp_path, n=1), "-o", out, "--json")
    assert r.code == 3
    summary = json.loads(r.out)
    assert list(summary) == SUMMARY_KEYS
    assert (summary["status"], summary["exit_status"], summary["file"], summary["verdict"]) == (
        "rejected",
        3,
        None,
        None,
    )
    assert codes(summary["rejections"]) == ["pose.short"] * 3
    assert [found["bound"] for found in summary["rejections"]] == [10, 10, 10]
    np.testing.assert_allclose(summary["offset"], OFFSET, atol=0.01)  # solved, but not written
    assert not out.exists()


def test_json_summary_when_a_gain_cannot_be_solved(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Three copies of one pose: the +x pose reads on x what the others do, so its gain is 0."""
    same = write_capture(tmp_path / "same.csv", pose_values("+z", seed=4))
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-q", "-p", same, same, same, "-o", out, "--json", "--no-checks")
    assert r.code == 3
    summary = json.loads(r.out)
    # the head every summary has; no parameters follow, as there are none
    assert summary == {
        "status": "rejected",
        "exit_status": 3,
        "file": None,
        "rejections": [{"code": "pose.upside_down", "file": str(same), "message": summary["rejections"][0]["message"]}],
        "verdict": None,
        "warnings": [],
        "notes": [],
    }
    [error] = lines(r, "error:")
    assert error.startswith(f"error: {same}: the +x pose reads the same on x as the poses where x is horizontal")
    assert_untouched(out)


# -- the calibration file ------------------------------------------------------------------


@pytest.mark.parametrize("tolerance", [1.0, 2.5])
def test_tilt_sensitivity_follows_fixture_tolerance(
    tolerance: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--fixture-tolerance", str(tolerance))
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    tilt = doc["tilt_sensitivity"]
    assert list(tilt) == ["offset", "gain", "tolerance_deg"]
    assert tilt["tolerance_deg"] == tolerance
    expected = core.tilt_sensitivity("three-pose", np.array(doc["gain"]), 1.0, ["+x", "+y", "+z"], tolerance)
    np.testing.assert_allclose(tilt["offset"], expected[0], rtol=1e-12)
    np.testing.assert_allclose(tilt["gain"], expected[1], rtol=1e-12)
    # first order in the tilt: about 17 mg per degree on a gain near 1
    np.testing.assert_allclose(tilt["offset"], math.sin(math.radians(tolerance)), rtol=0.1)
    assert f"± tilt: worst-case shift if each pose is {tolerance:g}° off level\n" in r.err


def test_tilt_sensitivity_bounds_a_real_fixture_tilt(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Poses tilted by 1° (tests/synth.py) move the parameters by no more than the 1° tilt_sensitivity."""
    docs = []
    for tilt_deg in (0.0, 1.0):
        folder = tmp_path / f"tilt{tilt_deg:g}"
        folder.mkdir()
        files = [
            write_capture(folder / f"{face[1]}.csv", pose_values(face, noise=1e-7, tilt_deg=tilt_deg), fmt="%.9f")
            for face in ("+x", "+y", "+z")
        ]
        docs.append(solved_files(capsys, files, folder / "cal.json"))
    level, tilted = docs
    tilt = level["tilt_sensitivity"]
    moved_offset = np.abs(np.subtract(tilted["offset"], level["offset"]))
    moved_gain = np.abs(np.subtract(tilted["gain"], level["gain"]))
    assert (moved_offset <= np.array(tilt["offset"])).all()
    assert (moved_gain <= np.array(tilt["gain"])).all()
    assert moved_offset.max() > 0.25 * max(tilt["offset"]), "the bound is not loose by orders of magnitude"


def test_tilt_sensitivity_of_one_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = solve(capsys, "-q", "-p", SAMPLE / "xn.csv", "--up", "-x", "--fixture-tolerance", "2")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    tilt = doc["tilt_sensitivity"]
    expected = core.tilt_sensitivity("one-pose", np.array(doc["gain"]), 1.0, ["-x"], 2.0)
    # the up axis x also holds the default --gain-tolerance 0.02 x reference 1 (below)
    np.testing.assert_allclose(tilt["offset"], expected[0] + [0.02, 0, 0], rtol=1e-12)
    # x is vertical (second order, under 1 mg at 2°); y and z horizontal (first order, sin 2°); no gains
    assert tilt["offset"][0] - 0.02 < 1e-3
    np.testing.assert_allclose(tilt["offset"][1:], math.sin(math.radians(2)), rtol=0.1)
    assert tilt["gain"] == [0.0, 0.0, 0.0]


@pytest.mark.parametrize(("given", "tolerance"), [([], 0.02), (["--gain-tolerance", "0.05"], 0.05)])
@pytest.mark.parametrize("method", ["one-pose", "one-pose-tilt"])
def test_one_pose_up_offset_holds_the_gain_tolerance(
    given: list[str], tolerance: float, method: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One pose cannot tell the up axis's gain error from its offset: a unit whose z gain is 3 %
    high reads an up offset 0.03 x reference off, and the up offset's tilt_sensitivity holds
    --gain-tolerance x reference for it (reference 16384: the raw units the 1-pose solver keeps)."""
    reference = 16384.0
    rng = np.random.default_rng(7)
    values = pose_samples(
        rng, FACES["+z"], offset=(20, -30, 40), gain=(1, 1, 1.03), reference=reference, noise=2.0, n=200
    )
    pose = write_capture(tmp_path / "z.csv", values, fmt="%.3f")
    out = tmp_path / "cal.json"
    r = solve(capsys, "-p", pose, "--reference", "16384", "--method", method, "-o", out, *given)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    tilt = doc["tilt_sensitivity"]
    assert tilt["gain_tolerance"] == tolerance
    assert doc["offset"][2] == pytest.approx(40 + 0.03 * reference, abs=5)  # the gain error, in the offset
    level = 1 - math.cos(math.radians(1))  # the up axis's own (second-order) tilt term, 1°
    if method == "one-pose":
        assert tilt["offset"][2] == pytest.approx(tolerance * reference + level * reference, rel=1e-12)
    else:  # the tilt term is bounded by --bias-spread instead; the gain part is the same
        assert tolerance * reference < tilt["offset"][2] < tolerance * reference + 0.01 * reference
    np.testing.assert_allclose(tilt["offset"][:2], reference * math.sin(math.radians(1)), rtol=1e-12)
    said = f"± tilt of the z offset (up axis +z) includes ±{tolerance * reference:.4g} (--gain-tolerance {tolerance:g}"
    assert [ln for ln in r.err.splitlines() if ln.startswith("± tilt of the z offset")] == [
        f"{said} × reference 16384) for an unknown gain error of ±{tolerance:.2%}: one pose cannot tell it from "
        "an offset"
    ]
    # the note on fixture tilt speaks of the tilt alone, not of the gain tolerance added to it
    assert f"moves the offsets by up to {reference * math.sin(math.radians(1)):.2g}" in r.err


def test_three_pose_records_no_gain_tolerance(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = solved(capsys, tmp_path / "cal.json", "--gain-tolerance", "0.05")
    assert "gain_tolerance" not in doc["tilt_sensitivity"]


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("-0.01", "Invalid value for '--gain-tolerance'"),
        ("nan", "--gain-tolerance is a fraction from 0 to below 1 (0.02: ±2 %), got nan"),
        ("1e308", "--gain-tolerance is a fraction from 0 to below 1 (0.02: ±2 %), got 1e+308"),
    ],
)
def test_gain_tolerance_is_checked(value: str, expected: str, capsys: pytest.CaptureFixture[str]) -> None:
    r = solve(capsys, "-p", SAMPLE / "z.csv", "--gain-tolerance", value)
    assert r.code == 2
    assert r.out == ""
    assert expected in r.err


def test_pose_diagnostics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A perfect unit (offset 0, gain 1): +x tilted 5° towards +y, +z drifting slowly."""

    def perfect(face: str, seed: int, tilt_deg: float = 0.0) -> FloatArray:
        return pose_values(face, seed=seed, offset=(0, 0, 0), gain=(1, 1, 1), noise=0.001, tilt_deg=tilt_deg)

    x = write_capture(tmp_path / "x.csv", perfect("+x", 1, tilt_deg=5.0))
    y = write_capture(tmp_path / "y.csv", perfect("+y", 2))
    slow = ramp(200, axis=2, rise=0.01)
    z = write_capture(tmp_path / "z.csv", perfect("+z", 3) + slow)
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", x, y, z, "-o", out)
    assert (r.code, r.err) == (0, "")
    doc = json.loads(out.read_text())
    poses = doc["poses"]
    angles = [p["angle_deg"] for p in poses]
    assert angles == [pytest.approx(5.0, abs=0.05), pytest.approx(0, abs=0.1), pytest.approx(0, abs=0.1)]
    assert [p["clipped"] for p in poses] == [0, 0, 0]
    assert poses[2]["drift"][2] == pytest.approx(third_drift(slow)[2], abs=5e-4)
    for k, face in enumerate(("+x", "+y", "+z")):
        # the errors left after calibration, recomputed from the file's own parameters
        c = np.array(doc["matrix"]) @ (np.array(poses[k]["mean"]) - np.array(doc["offset"]))
        assert poses[k]["norm_error"] == pytest.approx(np.linalg.norm(c) - 1.0, abs=1e-12)
        assert poses[k]["vector_error"] == pytest.approx(np.linalg.norm(c - FACES[face]), abs=1e-12)
        assert poses[k]["file"] == str((x, y, z)[k])
    assert poses[0]["vector_error"] > 0.03  # the tilted pose does not read +x after calibration


def test_unit_block(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    meta = ["--meta", "lot=42", "--meta", "note=a=b", "--meta", "empty="]
    doc = solved(capsys, out, "--serial", "A17", "--station", "line-3", "--operator", "A. N. Other", *meta)
    assert doc["unit"] == {
        "serial": "A17",
        "station": "line-3",
        "operator": "A. N. Other",
        "meta": {"lot": "42", "note": "a=b", "empty": ""},
    }
    assert solved(capsys, out)["unit"] == {"serial": None, "station": None, "operator": None, "meta": {}}


@pytest.mark.parametrize("item", ["lot", "=42", " =42"])
def test_bad_meta(item: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out, "--meta", "ok=1", "--meta", item)
    assert_one_error(r, f"--meta takes KEY=VALUE, got {item!r}")
    assert_untouched(out)


@pytest.mark.parametrize("column", ["temp", "temperature", "temp_c", "Temp_C"])
def test_temperature_column_mean_per_pose(column: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = []
    for k, face in enumerate(("+x", "+y", "+z")):
        temperature: FloatArray = 21.0 + k + 0.5 * (np.arange(200, dtype=np.float64) % 5)  # mean 22.0 + k
        files.append(
            write_capture(
                tmp_path / f"{face[1]}.csv",
                pose_values(face, seed=k),
                header=f"t,ax,ay,az,{column}",
                extra=temperature,
            )
        )
    out = tmp_path / "cal.json"
    doc = solved_files(capsys, files, out)
    assert [p["temperature"] for p in doc["poses"]] == [pytest.approx(22.0 + k, abs=1e-9) for k in range(3)]
    assert doc["columns"] == ["ax", "ay", "az"]  # the temperature is not a sensor column


def test_no_temperature_without_the_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = solved(capsys, tmp_path / "cal.json")
    assert all("temperature" not in p for p in doc["poses"])


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_source_date_epoch_makes_files_byte_identical(
    suffix: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)
    first, second = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    args = ["--limits", str(LIMITS), "--serial", "A17", "--meta", "lot=42"]
    doc = solved(capsys, first, *args)
    solved(capsys, second, *args)
    assert first.read_bytes() == second.read_bytes()
    assert doc["created"] == "2023-11-14T22:13:20Z"


def test_created_is_now_without_source_date_epoch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    created = solved(capsys, tmp_path / "cal.json")["created"]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", created)
    when = datetime.strptime(created, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=UTC)
    assert abs((datetime.now(UTC) - when).total_seconds()) < 300


def test_source_date_epoch_out_of_range(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "99999999999999")
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out)
    assert_one_error(r, "SOURCE_DATE_EPOCH=99999999999999 is out of range for a date")
    assert_untouched(out)


@pytest.mark.parametrize("epoch", ["abc", "-5", "1.5e9"])
def test_source_date_epoch_malformed(
    epoch: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """reproducible-builds.org: a SOURCE_DATE_EPOCH that is not a whole number is an error, not ignored."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", epoch)
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, "-o", out)
    assert_one_error(r, f"SOURCE_DATE_EPOCH={epoch!r} is not a whole number of seconds since 1970")
    assert_untouched(out)


# -- show ----------------------------------------------------------------------------------


@pytest.fixture
def unit_cal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> Path:
    """The sample set solved with a serial, station, operator and meta (created at EPOCH)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)
    out = tmp_path / "cal.json"
    solved(capsys, out, "--serial", "A17", "--station", "line-3", "--operator", "bob", "--meta", "lot=42")
    return out


def test_show_prints_for_people_on_stdout(unit_cal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "show", unit_cal)
    assert (r.code, r.err) == (0, "")
    out = r.out.splitlines()
    assert out[:5] == [
        f"file:        {unit_cal}",
        "sensor:      accelerometer, three-pose, reference 1 g",
        "unit:        serial A17, station line-3, operator bob",
        "meta:        lot=42",
        "created:     2023-11-14T22:13:20Z by tumblecal 0.1.0",
    ]
    assert "three-pose calibration" in r.out
    for word in ("ax", "ay", "az", "+x", "+y", "+z", "x.csv"):
        assert word in r.out
    assert out[-1] == "verdict: PASS (no limits judged)"
    assert "\x1b[" not in r.out


def test_show_json_prints_the_document(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "show", unit_cal, "--json")
    assert (r.code, r.err) == (0, "")
    assert json.loads(r.out) == json.loads(unit_cal.read_text())
    as_yaml = tmp_path / "cal.yaml"
    as_yaml.write_text(yaml.safe_dump(json.loads(unit_cal.read_text()), sort_keys=False))
    r = run(capsys, "show", as_yaml, "--json")
    assert (r.code, r.err) == (0, "")
    assert json.loads(r.out) == json.loads(unit_cal.read_text())


def test_show_a_failed_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.yaml"
    solved(capsys, cal, "--max-offset", "0.04", code=1)
    r = run(capsys, "show", cal)
    assert (r.code, r.err) == (0, "")  # showing a failed unit is not an error
    assert r.out.splitlines()[-2:] == [
        "verdict: FAIL (limits: offset)",
        "  limit.offset.z: offset 0.0469971 on z is outside ±0.04",
    ]


def mutate(cal: Path, change: str, out: Path) -> Path:
    """A copy of ``cal`` with one field changed: ``change`` is ``dotted.path=JSON`` or ``-dotted.path``."""
    doc = json.loads(cal.read_text())
    path, _, value = change.lstrip("-").partition("=")
    *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
    target: Any = doc
    for key in parents:
        target = target[key]
    if change.startswith("-"):
        del target[last]
    else:
        target[last] = json.loads(value)
    out.write_text(json.dumps(doc))
    return out


INVALID_FIELDS = [
    pytest.param("-matrix", "missing field 'matrix'", id="no-matrix"),
    pytest.param("offset=[0.1, 0.2]", "field 'offset' must be a list of 3 numbers", id="offset-length"),
    pytest.param("method=5", "field 'method' must be a string", id="method"),
    pytest.param('unit="A17"', "field 'unit' must be an object (serial, station, operator, meta)", id="unit"),
    pytest.param('unit.meta=["lot=42"]', "field 'unit.meta' must be an object (KEY: VALUE)", id="unit-meta"),
    pytest.param("uncertainty=0.1", "field 'uncertainty' must be an object with 'offset' and 'gain'", id="uncertainty"),
    pytest.param(
        "-uncertainty.gain", "field 'uncertainty' must be an object with 'offset' and 'gain'", id="uncertainty-gain"
    ),
    pytest.param(
        "tilt_sensitivity.gain=[1, 2]", "field 'tilt_sensitivity.gain' must be a list of 3 numbers", id="tilt-gain"
    ),
    pytest.param(
        'tilt_sensitivity.tolerance_deg="1°"',
        "field 'tilt_sensitivity.tolerance_deg' must be a finite number",
        id="tilt-tolerance",
    ),
    pytest.param("poses={}", "field 'poses' must be a list of pose objects", id="poses"),
    pytest.param(
        "-poses.1.samples", "field 'poses[1]' must be an object with pose, mean and samples", id="pose-samples-missing"
    ),
    pytest.param("poses.2.samples=0", "field 'poses[2].samples' must be a positive integer", id="pose-samples"),
    pytest.param(
        'poses.0.pose="up"',
        "field 'poses[0].pose' must be a face (+x -x +y -y +z -z), a direction X,Y,Z or null",
        id="pose-face",
    ),
    pytest.param("poses.0.mean=[1]", "field 'poses[0].mean' must be a list of 3 numbers", id="pose-mean"),
    pytest.param('poses.0.angle_deg="3°"', "field 'poses[0].angle_deg' must be a finite number", id="pose-angle"),
    pytest.param(
        'verdict={"pass": "no", "failures": []}',
        "field 'verdict' must be an object with 'pass' (true/false) and 'failures' (a list)",
        id="verdict-pass",
    ),
    pytest.param(
        'verdict={"pass": false, "failures": ["limit.offset.z"]}',
        "field 'verdict.failures[0]' must be an object with a 'code'",
        id="verdict-failure",
    ),
    pytest.param("verdict.limits=[0.05]", "field 'verdict.limits' must be an object", id="verdict-limits"),
    pytest.param("reference=-1", "field 'reference' must be positive (0 only for a gyroscope), got -1", id="reference"),
    pytest.param("units=5", "field 'units' must be a string or null", id="units"),
    pytest.param("residuals=[0.1]", "field 'residuals' must be an object with rms, max and count", id="residuals"),
    pytest.param(
        'columns=["ax", "AX", "az"]',
        "field 'columns' must name three different columns, got ax, AX, az",
        id="columns-repeated",
    ),
    pytest.param(
        'verdict={"pass": true, "failures": [{"code": "limit.offset.x", "value": 1, "bound": 0.1}]}',
        "field 'verdict' passes with 1 failures: the file was altered",
        id="verdict-pass-with-failures",
    ),
    pytest.param(
        'verdict={"pass": false, "failures": []}',
        "field 'verdict' fails with 0 failures: the file was altered",
        id="verdict-fail-without-failures",
    ),
]


@pytest.mark.slow
@pytest.mark.parametrize(("change", "message"), INVALID_FIELDS)
def test_show_an_invalid_file_names_the_field(
    change: str, message: str, unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = mutate(unit_cal, change, tmp_path / "bad.json")
    assert_one_error(run(capsys, "show", bad), f"{bad}: {message}")
    assert_one_error(run(capsys, "show", bad, "--json"), f"{bad}: {message}", json_out=True)


@pytest.mark.slow
@pytest.mark.parametrize(
    "change", ["tilt_sensitivity=null", "-tilt_sensitivity", "-uncertainty", "unit=null", "verdict=null", "-poses"]
)
def test_show_a_file_without_optional_fields(
    change: str, unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Fields a later version added may be absent (or null) in an older file."""
    r = run(capsys, "show", mutate(unit_cal, change, tmp_path / "old.json"))
    assert (r.code, r.err) == (0, ""), r.err
    assert "three-pose calibration" in r.out


def test_show_a_pose_without_std(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "show", mutate(unit_cal, "-poses.0.std", tmp_path / "old.json"))
    assert (r.code, r.err) == (0, "")


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("cal_missing_matrix.json", "missing field 'matrix'"),
        ("cal_unknown_version.json", "unsupported calibration version 2 (this tumblecal reads version 1)"),
        ("does_not_exist.json", "no such calibration file"),
    ],
)
def test_show_bad_calibration_files(name: str, message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert_one_error(run(capsys, "show", BAD / name), f"{BAD / name}: {message}")


# -- check ---------------------------------------------------------------------------------


def test_check_pass_and_fail_leave_the_file_alone(unit_cal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before, stat = unit_cal.read_bytes(), unit_cal.stat()
    r = run(capsys, "check", unit_cal, "--limits", LIMITS)
    assert (r.code, r.out) == (0, "")
    assert r.err.splitlines()[-1] == f"verdict: PASS ({SAMPLE_JUDGED})"
    r = run(capsys, "check", unit_cal, "--limits", LIMITS, "--max-offset", "0.04")
    assert (r.code, r.out) == (1, "")
    assert r.err.splitlines()[-2:] == [
        f"verdict: FAIL ({SAMPLE_JUDGED})",
        "  limit.offset.z: offset 0.0469971 on z is outside ±0.04",
    ]
    assert lines(r, "error:") == []
    assert unit_cal.read_bytes() == before
    assert unit_cal.stat().st_mtime_ns == stat.st_mtime_ns
    assert sorted(p.name for p in unit_cal.parent.iterdir()) == ["cal.json"]


def test_check_json(unit_cal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "check", "-q", unit_cal, "--max-offset", "0.04", "--json")
    assert (r.code, r.err) == (1, "")
    summary = json.loads(r.out)
    doc = json.loads(unit_cal.read_text())
    # the same summary as solve --json: parameters, uncertainties and per-pose diagnostics too
    for key in ("sensor", "method", "reference", "units", "columns", "offset", "matrix", "gain", "uncertainty"):
        assert summary.pop(key) == doc[key], key
    for key in ("tilt_sensitivity", "residuals", "coverage", "coverage_gaps", "outliers", "poses", "unit"):
        assert summary.pop(key) == doc.get(key), key
    assert summary == {
        "status": "fail",
        "exit_status": 1,
        "file": str(unit_cal),
        "rejections": [],
        "warnings": [],
        "notes": [],
        "verdict": {
            "pass": False,
            "failures": [
                {
                    "code": "limit.offset.z",
                    "value": pytest.approx(0.0469971, abs=1e-7),
                    "bound": 0.04,
                    "message": "offset 0.0469971 on z is outside ±0.04",
                }
            ],
            "limits": {"offset": [0.04, 0.04, 0.04]},
        },
    }
    r = run(capsys, "check", unit_cal, "--limits", LIMITS, "--json")
    assert r.code == 0
    summary = json.loads(r.out)
    assert (summary["status"], summary["exit_status"], summary["verdict"]["pass"]) == ("pass", 0, True)
    assert "verdict: PASS" in r.err


def test_check_judges_as_solve_did(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    limits = ["--limits", str(LIMITS), "--max-offset", "0.04", "--max-gain-error", "0.01"]
    verdict = solved(capsys, out, *limits, code=1)["verdict"]
    r = run(capsys, "check", out, *limits, "--json", "-q")
    assert r.code == 1
    assert json.loads(r.out)["verdict"] == verdict


def test_check_a_failed_unit_against_looser_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    solved(capsys, out, "--max-offset", "0.04", code=1)
    before = out.read_bytes()
    r = run(capsys, "check", "-q", out, "--max-offset", "0.05")
    assert (r.code, r.out, r.err) == (0, "", "")
    assert out.read_bytes() == before  # still says it failed: check does not rewrite the verdict


def test_check_without_limits(unit_cal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    expected = "no limits to judge against"
    assert_one_error(
        run(capsys, "check", unit_cal), expected, hint="give --limits FILE, --max-offset or --max-gain-error"
    )
    assert_one_error(run(capsys, "check", unit_cal, "--nominal-gain", "2"), expected)  # a nominal is not a bound


def test_check_needs_the_poses(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = mutate(unit_cal, "-poses", tmp_path / "bad.json")
    r = run(capsys, "check", bad, "--limits", LIMITS)  # noise and residual limits: judged on the poses
    assert_one_error(r, f"{bad}: has no poses to judge the noise and residual limits by")
    r = run(capsys, "check", bad, "--max-offset", "0.05")  # the parameters alone can still be judged
    assert r.code == 0, r.err


# -- apply and the verdict, apply and the columns --------------------------------------------


def test_apply_refuses_a_failed_unit_unless_forced(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    solved(capsys, cal, "--limits", LIMITS, "--max-offset", "0.04", "--max-gain-error", "0.01", code=1)
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out)
    assert_one_error(
        r,
        f"{cal}: this unit failed its limits (limit.offset.z, limit.gain.x, limit.gain.y): refusing to correct with it",
        hint="pass --force to apply it anyway",
    )
    assert_untouched(out)
    r = run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out, "--force")
    assert r.code == 0, r.err
    assert f"note: {cal}: this unit failed its limits; correcting with it as --force asks\n" in r.err
    assert out.read_text().startswith("t,ax,ay,az\n")
    assert len(out.read_text().splitlines()) == 3001


def test_apply_accepts_a_passed_unit(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "apply", "-q", "--cal", unit_cal, SAMPLE / "capture.csv", "-o", tmp_path / "out.csv")
    assert (r.code, r.out, r.err) == (0, "", "")


def test_apply_refuses_other_named_columns(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "other.csv"
    src.write_text("t,acc_x,acc_y,acc_z\n0,0.1,0.2,1.0\n")
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", unit_cal, src, "-o", out)
    assert_one_error(
        r,
        f"{src}: the capture's accelerometer columns are acc_x, acc_y, acc_z, "
        f"but {unit_cal} calibrates accelerometer columns ax, ay, az",
        hint="if they are the same sensor, name them: --columns acc_x,acc_y,acc_z",
    )
    assert_untouched(out)
    r = run(capsys, "apply", "--cal", unit_cal, src, "-o", out, "--columns", "acc_x,acc_y,acc_z")
    assert r.code == 0, r.err
    assert f"note: {src}: correcting columns acc_x, acc_y, acc_z (the calibration was made from ax, ay, az)" in r.err
    assert out.read_text().splitlines()[0] == "t,acc_x,acc_y,acc_z"


def test_apply_accepts_a_headerless_capture(unit_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "headerless.csv"
    src.write_text("0.00,0.1,0.2,1.0\n0.01,0.1,0.2,1.0\n")
    r = run(capsys, "apply", "--cal", unit_cal, src)
    assert r.code == 0, r.err
    assert f"note: {src}: correcting columns x, y, z (the calibration was made from ax, ay, az)" in r.err
    assert [ln.split(",")[0] for ln in r.out.splitlines()] == ["0.00", "0.01"]


# -- help and colour -----------------------------------------------------------------------

SOLVE_OPTIONS = [
    "--max-noise",
    "--max-tilt",
    "--nominal-offset",
    "--full-scale",
    "--min-samples",
    "--fixture-tolerance",
    "--no-checks",
    "--no-check",
    "--limits",
    "--max-offset",
    "--max-gain-error",
    "--nominal-gain",
    "--json",
    "--serial",
    "--station",
    "--operator",
    "--meta",
]


def test_solve_help_lists_the_gate_options(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--help-all")  # --help names them by panel, --help-all describes each
    assert (r.code, r.err) == (0, "")
    listed = set(re.findall(r"^\s+(?:-\w, )?(--[\w-]+)", r.out, flags=re.MULTILINE))
    assert set(SOLVE_OPTIONS) <= listed
    text = " ".join(r.out.split())
    for words in (
        "Quality checks (exit 3)",
        "Limits (exit 1)",
        "moved, orientation, saturated, short, upside-down or coverage",
    ):
        assert words in text


@pytest.mark.parametrize(
    ("command", "statuses"),
    [
        ("show", "Exit status: 0 a valid calibration file; 2 an invalid one (the error names the field)."),
        ("check", "Exit status: 0 within the limits; 1 outside them; 2 usage or input error."),
    ],
)
def test_show_and_check_help(command: str, statuses: str, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, command, "--help")
    assert (r.code, r.err) == (0, "")
    assert r.out.startswith(f"Usage: tumblecal {command} [OPTIONS] {{CAL}}\n")  # Typer's braces: required
    assert statuses in " ".join(r.out.split())
    assert "--json" in r.out


def test_top_level_help_lists_show_and_check(capsys: pytest.CaptureFixture[str]) -> None:
    out = run(capsys, "--help").out
    assert re.search(r"^\s+show\s", out, flags=re.MULTILINE)
    assert re.search(r"^\s+check\s", out, flags=re.MULTILINE)


SGR = re.compile(r"\x1b\[([0-9;]*)m")


def colour_codes(text: str) -> list[str]:
    """The SGR sequences that set a colour (30-49, 90-107); bold or italic alone are not colour."""
    found = []
    for params in SGR.findall(text):
        numbers = [int(p) for p in params.split(";") if p]
        if any(30 <= n <= 49 or 90 <= n <= 107 for n in numbers):
            found.append(params)
    return found


def coloured_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Result:
    """A solve that prints a warning (yellow), a failed verdict and its failures (red)."""
    x, y, z = three_poses(tmp_path)
    write_capture(y, pose_values("+y", seed=2, noise=0.017))
    return solve(capsys, "-p", x, y, z, "-o", tmp_path / "cal.json", "--max-offset", "0.04")


@pytest.fixture
def plain_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in ("FORCE_COLOR", "NO_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "COLORTERM"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("TERM", "xterm-256color")
    return monkeypatch


def test_no_colour_when_stderr_is_not_a_terminal(
    plain_env: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = coloured_run(tmp_path, capsys)
    assert r.code == 1, r.err
    assert lines(r, "warning:")
    assert "verdict: FAIL" in r.err
    assert "\x1b[" not in r.err


def test_no_colour_with_no_color_on_a_terminal(
    plain_env: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain_env.setenv("FORCE_COLOR", "1")  # Rich: behave as on a terminal
    assert colour_codes(coloured_run(tmp_path, capsys).err), "the terminal run is coloured (the test's premise)"
    plain_env.setenv("NO_COLOR", "1")
    r = coloured_run(tmp_path, capsys)
    assert r.code == 1
    assert "verdict: FAIL" in r.err
    assert colour_codes(r.err) == []


def test_one_pose_gain_limit_does_not_apply(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The 1-pose solver fixes its gains at 1: a gain limit is not judged, nor recorded as judged."""
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", SAMPLE / "z.csv", "--max-gain-error", "0.001", "-o", out)
    assert r.code == 0, r.err
    assert "verdict: PASS (no limits judged)\n" in r.err
    assert json.loads(out.read_text())["verdict"] == {"pass": True, "failures": [], "limits": {}}


# -- found in review: nothing meaningless passes --------------------------------------------


@pytest.mark.parametrize("reference", ["nan", "inf", "0", "-1"])
def test_reference_must_be_a_positive_number(
    reference: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, f"--reference={reference}", "-o", out)
    assert_one_error(r, f"--reference must be a positive number, got {float(reference):g}", hint="--sensor gyroscope")
    assert_untouched(out)


@pytest.mark.parametrize("reference", ["1e-320", "5e-324"])
def test_reference_too_small_to_divide_by(reference: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A subnormal --reference made every gain overflow (a numpy warning, then an internal error): exit 2."""
    out = precious(tmp_path / "cal.json")
    r = solve(capsys, "-p", *POSES_3, f"--reference={reference}", "-o", out)
    assert_one_error(
        r, f"--reference {float(reference):g} is too small to divide by (the smallest is 2.23e-308)", hint="16384"
    )
    assert "Warning" not in r.err
    assert_untouched(out)


@pytest.mark.parametrize("reference", ["2048", "1"])
def test_a_gyroscope_reference_other_than_0_is_refused(
    reference: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It was taken and written into the calibration (reference 2048 for a zero-rate bias)."""
    out = precious(tmp_path / "cal.json")
    gyroscope = ["--sensor", "gyroscope", "--columns", "ax,ay,az"]
    r = solve(capsys, "-p", SAMPLE / "z.csv", *gyroscope, "--reference", reference, "-o", out)
    assert_one_error(r, f"--reference is a gyroscope's reading at rest, which is 0, got {reference}", hint="leave")
    assert_untouched(out)


def test_gyroscope_at_rest_has_reference_zero_and_no_angle(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", SAMPLE / "z.csv", "--sensor", "gyroscope", "--columns", "ax,ay,az", "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["reference"] == 0.0
    assert doc["poses"][0]["angle_deg"] is None  # orientation is not judged, so not recorded


def test_one_pose_unsigned_counts_with_their_nominal_offset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Unsigned 16-bit counts at 16384 LSB/g sit around 32768: --nominal-offset makes --reference 16384 right."""
    counts = np.round(32768 + 16384 * pose_values("+z", offset=(0.01, -0.02, 0.03), gain=(1, 1, 1)))
    pose = write_capture(tmp_path / "z.csv", counts, fmt="%d")
    out = tmp_path / "cal.json"
    r = solve(capsys, "-q", "-p", pose, "--reference", "16384", "--nominal-offset", "32768", "-o", out)
    assert r.code == 0, r.err
    offset = json.loads(out.read_text())["offset"]
    np.testing.assert_allclose(offset, [32768 + 164, 32768 - 328, 32768 + 492], atol=10)


def test_the_offset_limit_of_unsigned_counts_is_around_their_nominal_offset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """|offset| <= 1000 can never hold for counts around 32768: the limit is judged from
    --nominal-offset (or the limits file's nominal_offset), and the file records the centre."""
    counts = np.round(32768 + 16384 * pose_values("+z", offset=(0.01, -0.02, 0.03), gain=(1, 1, 1)))
    pose = write_capture(tmp_path / "z.csv", counts, fmt="%d")
    out = tmp_path / "cal.json"
    base: list[str | Path] = ["-q", "-p", pose, "--reference", "16384", "-o", out]
    r = solve(capsys, *base, "--nominal-offset", "32768", "--max-offset", "1000")
    assert r.code == 0, r.err
    assert json.loads(out.read_text())["verdict"]["limits"] == {"offset": [1000.0] * 3, "nominal_offset": [32768.0] * 3}
    r = solve(capsys, *base, "--nominal-offset", "32768", "--max-offset", "400")  # z is 492 off 32768
    assert r.code == 1, r.err
    [failure] = json.loads(out.read_text())["verdict"]["failures"]
    assert failure["code"] == "limit.offset.z"
    assert failure["message"].endswith("on z is outside 32768 ±400")
    limits = tmp_path / "limits.yaml"
    limits.write_text("offset: 1000\nnominal_offset: 32768\n")
    r = solve(capsys, *base, "--nominal-offset", "32768", "--limits", limits)
    assert r.code == 0, r.err
    r = run(capsys, "check", out, "--limits", limits)
    assert r.code == 0, r.err
    r = run(capsys, "check", out, "--max-offset", "1000")  # the centre solve recorded is used
    assert r.code == 0, r.err


def test_a_dead_sensor_is_not_a_units_mistake(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = write_capture(tmp_path / "z.csv", np.zeros((50, 3)), fmt="%d")
    r = solve(capsys, "-p", pose, "-o", tmp_path / "cal.json")
    assert_one_error(
        r,
        f"{pose}: the pose reads 0 in magnitude but --reference is 1",
        hint="a pose at rest reads the reference: is the sensor working, and are these its columns?",
    )


def test_a_duplicated_pose_blames_only_that_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """y.csv is a copy of x.csv: the solved matrix is nonsense, so x.csv and z.csv are not judged through it."""
    x, y, z = three_poses(tmp_path)
    y.write_bytes(x.read_bytes())
    r = solve(capsys, "-p", x, y, z, "-o", tmp_path / "cal.json")
    assert r.code == 3
    assert [ln.split(":")[1].strip() for ln in lines(r, "error:")] == [str(y)]
    assert "declared +y but reads like +x" in lines(r, "error:")[0]


def test_one_row_poses_say_their_noise_is_unknown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = [write_capture(tmp_path / f"{f[1]}.csv", pose_values(f, n=1)) for f in ("+x", "+y", "+z")]
    r = solve(capsys, "-p", *poses, "--min-samples", "1", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert "note: x.csv has 1 sample: its noise is unknown, so its uncertainty reads 0" in r.err


def test_fixture_tolerance_beyond_the_tilt_model_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = solve(capsys, "-p", *POSES_3, "--fixture-tolerance", "45", "-o", tmp_path / "cal.json")
    assert r.code == 2
    assert "--fixture-tolerance" in r.err
    assert not (tmp_path / "cal.json").exists()


def test_check_refuses_a_singular_matrix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    doc = solved(capsys, cal)
    doc["matrix"] = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    cal.write_text(json.dumps(doc))
    commands: list[list[str | Path]] = [["check", cal, "--max-offset", "1"], ["show", cal]]
    for command in commands:
        assert_one_error(run(capsys, *command), f"{cal}: field 'matrix' is singular (it has no inverse)")


def test_a_calibration_given_as_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    solved(capsys, cal)
    r = solve(capsys, "-p", *POSES_3, "--limits", cal, "-o", tmp_path / "other.json")
    assert_one_error(r, f"{cal}: a tumblecal-calibration file, not a limits file", hint="docs/production-test.md")


def test_check_of_a_log_calibration_names_each_block(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The six failures of a solve --log calibration named the same log six times, no block."""
    log = tmp_path / "session.csv"
    log.write_bytes(
        gzip.decompress((ROOT / "tests" / "data" / "logs" / "imucal_annotated_session.csv.gz").read_bytes())
    )
    cal, limits = tmp_path / "cal.json", tmp_path / "limits.yaml"
    limits.write_text("noise: 0.0001\n")
    assert run(capsys, "solve", "-q", "--log", log, "--reference", "9.81", "-o", cal).code == 0
    solved = [ln for ln in run(capsys, "check", cal, "--limits", limits).err.splitlines() if "limit.noise" in ln]
    assert len(solved) == 6
    assert all(re.match(rf"  limit\.noise: {re.escape(str(log))} block \d+: noise ", ln) for ln in solved), solved


@pytest.mark.parametrize("centre", [0.5, "0.5", [0.5, 0.5]])
def test_check_refuses_a_recorded_nominal_offset_that_is_not_three_numbers(
    centre: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hand-edited centre was judged as 0 (a PASS against the wrong centre): now exit 2 naming the field."""
    cal = tmp_path / "cal.json"
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    assert (
        run(capsys, "solve", "--poses", *poses, "--nominal-offset", "0.02", "--max-offset", "0.1", "-o", cal).code == 0
    )
    doc = json.loads(cal.read_text())
    doc["verdict"]["limits"]["nominal_offset"] = centre
    cal.write_text(json.dumps(doc))
    r = run(capsys, "check", cal, "--max-offset", "0.1")
    assert r.code == 2, r.err
    assert "verdict.limits.nominal_offset' must be 3 numbers" in r.err
    assert "internal error" not in r.err


def test_a_six_pose_retry_after_auto_keeps_auto_s_note(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Files named for faces, two swapped: auto's choice of six-pose-magnitude is said with the
    rejection's detail (-v; without it the rejection alone)."""
    folder = tmp_path / "swap"
    folder.mkdir()
    for name, source in {"x": "x", "xn": "y", "y": "xn", "yn": "yn", "z": "z", "zn": "zn"}.items():
        (folder / f"{name}.csv").write_bytes((SAMPLE / f"{source}.csv").read_bytes())
    order = ["zn", "z", "yn", "y", "xn", "x"]
    r = run(capsys, "solve", "--poses", *(str(folder / f"{n}.csv") for n in order), "-o", tmp_path / "o.json", "-v")
    assert r.code == 3, r.err
    assert "auto chose six-pose-magnitude" in r.err

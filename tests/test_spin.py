"""A gyroscope on a turntable or rate table (issue "A gyroscope from known rates"): solve --spin
RATE=FILE fits offset, gains and cross-axis terms to the files' steady runs (core.spin,
pipeline.solve.spins); the platter's spin-up, the handling between orientations and runs at
another rate are left out and named by rows; the stated uncertainty covers the error."""

from __future__ import annotations

import importlib.util
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import ROOT, assert_one_error, run
from tumblecal_cli.core import model, spin
from tumblecal_cli.core.arrays import FloatArray

TURNTABLE = importlib.util.spec_from_file_location("make_turntable", ROOT / "sample_data" / "make_turntable.py")
assert TURNTABLE is not None
assert TURNTABLE.loader is not None
platters = importlib.util.module_from_spec(TURNTABLE)
TURNTABLE.loader.exec_module(platters)
RPM, readings, truth, turned, write = platters.RPM, platters.readings, platters.truth, platters.turned, platters.write


def _session(rng: np.random.Generator, *, labelled: bool) -> tuple[spin.RateFit, FloatArray, FloatArray]:
    """One turntable session at 33⅓ and 45 rpm and at rest, fitted from its steady runs."""
    a, b = truth(rng, symmetric=not labelled)
    runs = []
    for rate in (45 * RPM, 100 / 3 * RPM):
        files = (
            [(f, [(model.direction(f), rate)]) for f in ("+x", "-x", "+y", "-y", "+z", "-z")]
            if labelled
            else [(None, [(turned(rng), rate) for _ in range(6)])]
        )
        for face, placements in files:
            for r in spin.steady_runs(readings(rng, a, b, placements), 25, 50):
                if abs(np.linalg.norm(r.mean) / rate - 1) < 0.1:
                    runs.append(spin.SpinRun(r.mean, r.stderr, rate, None if face is None else model.direction(face)))
    for r in spin.steady_runs(readings(rng, a, b, [(np.array([0.0, 0.0, 1.0]), 0.0)]), 25, 50):
        runs.append(spin.SpinRun(r.mean, r.stderr, 0.0))
    return spin.fit_rates(runs), a, b


def test_one_session_recovers_bias_and_gains_within_their_uncertainty() -> None:
    fit, a, b = _session(np.random.default_rng(3), labelled=False)
    assert np.all(np.abs(fit.offset - b) < 4 * fit.offset_se)
    gains = np.diag(np.linalg.inv(fit.matrix))
    assert np.all(np.abs(gains - np.diag(a)) < 4 * fit.gain_se)
    assert fit.gain_se.max() < 0.003
    assert fit.kept.all()
    assert not fit.full


@pytest.mark.slow
@pytest.mark.parametrize("labelled", [False, True])
def test_stated_uncertainty_covers_the_error_over_100_sessions(labelled: bool) -> None:
    """The bias, the gains and (labelled) the cross-axis terms, each group's z-scores: RMS 0.8-1.25,
    and beyond ±3 no more often than the Student distribution of a spread estimated from a dozen
    runs allows (3 %)."""
    rng = np.random.default_rng(5)
    groups: dict[str, list[FloatArray]] = {"bias": [], "gains": [], "cross": []}
    for _ in range(100):
        fit, a, b = _session(rng, labelled=labelled)
        groups["bias"].append((fit.offset - b) / fit.offset_se)
        groups["gains"].append((np.diag(np.linalg.inv(fit.matrix)) - np.diag(a)) / fit.gain_se)
        if labelled:
            off = ~np.eye(3, dtype=bool)
            groups["cross"].append((np.linalg.inv(fit.matrix) - a)[off] / fit.cross_se[off])
    for name, found in groups.items():
        if not found:
            continue
        z = np.array(found)
        assert 0.8 < float(np.sqrt(np.mean(z**2))) < 1.25, (name, np.sqrt(np.mean(z**2, axis=0)))
        assert float(np.mean(np.abs(z) > 3)) < 0.03, name


@pytest.fixture
def platter(tmp_path: Path) -> tuple[list[str], FloatArray, FloatArray]:
    """--spin items of a session written as files: 45 and 33⅓ rpm (six unknown placements each)
    and rest; the 45 rpm file also holds one placement run at 33⅓ rpm (the platter left at the
    other speed), which is left out."""
    rng = np.random.default_rng(11)
    a, b = truth(rng, symmetric=True)
    fast = [(turned(rng), 45 * RPM) for _ in range(6)] + [(turned(rng), 100 / 3 * RPM)]
    slow = [(turned(rng), 100 / 3 * RPM) for _ in range(6)]
    rest = [(np.array([0.0, 0.0, 1.0]), 0.0)]
    held = [(turned(rng), 45 * RPM) for _ in range(3)]
    files = [
        f"45rpm={write(tmp_path / '45rpm.csv', readings(rng, a, b, fast))}",
        f"33.333rpm={write(tmp_path / '33rpm.csv', readings(rng, a, b, slow))}",
        f"0={write(tmp_path / 'rest.csv', readings(rng, a, b, rest))}",
        f"45rpm={write(tmp_path / 'held-out.csv', readings(rng, a, b, held))}",
    ]
    return files, a, b


def test_solve_spin_from_the_command_line_names_what_it_left_out(
    platter: tuple[list[str], FloatArray, FloatArray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    items, a, b = platter
    out = tmp_path / "gyr.json"
    r = run(
        capsys, "solve", "--sensor", "gyroscope", *[x for i in items[:3] for x in ("--spin", i)], "-o", out, "--json"
    )
    assert r.code == 0, r.err
    summary = json.loads(r.out)
    doc = json.loads(out.read_text())
    assert doc["method"] == "known-rates"
    assert doc["units"] == "rad/s"
    sigma = np.array(doc["uncertainty"]["offset"])
    assert np.all(np.abs(np.array(doc["offset"]) - b) < 4 * sigma)
    assert np.all(np.abs(np.array(doc["gain"]) - np.diag(a)) < 4 * np.array(doc["uncertainty"]["gain"]))
    assert "45rpm.csv at 45rpm (4.712 rad/s): 6 steady runs used; " in r.err  # the 33⅓ rpm placement is not
    assert "rows left out (rows 0–149, 1150–1299, " in r.err  # 2 s of handling and 1 s of spin-up at 50 Hz
    assert "rest.csv at 0 (0 rad/s): 1 steady run used; 100 rows left out (rows 0–99: handling, turning)" in r.err
    left = summary["outliers"]
    assert left["count"] > 0
    assert {s["file"] for s in left["stretches"]} == {str(tmp_path / n) for n in ("45rpm.csv", "33rpm.csv", "rest.csv")}
    assert all(s["rows"] is not None for s in left["stretches"])
    assert {p["label"] for p in doc["poses"]} == {"45rpm", "33.333rpm", "0"}


def test_the_python_api_takes_spin(platter: tuple[list[str], FloatArray, FloatArray]) -> None:
    items, _, b = platter
    done = tumblecal.solve(sensor="gyroscope", spin=items[:3])
    assert done.status == 0
    assert done.calibration is not None
    assert np.allclose(done.calibration.offset, b, atol=0.002)


def test_labelled_faces_recover_the_full_matrix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(21)
    a, b = truth(rng, symmetric=False)
    items = []
    for face in ("+x", "-x", "+y", "-y", "+z", "-z"):
        for text, rate in (("45rpm", 45 * RPM), ("-33.333rpm", -100 / 3 * RPM)):
            path = write(tmp_path / f"{face}{text}.csv", readings(rng, a, b, [(model.direction(face), rate)]))
            items += ["--spin", f"{face}@{text}={path}"]
    out = tmp_path / "gyr.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    fitted = np.linalg.inv(np.array(doc["matrix"]))
    cross = np.array(doc["uncertainty"]["cross_axis"])
    off = ~np.eye(3, dtype=bool)
    assert np.all(np.abs(fitted - a)[off] < 4 * cross[off])  # the misalignment, which the magnitude cannot see
    assert "full M (faces labelled)" in r.err
    factors = doc["scale_factors"]["axes"]
    assert [f["axis"] for f in factors] == ["x", "y", "z"]
    for f, gain in zip(factors, np.diag(a), strict=True):
        assert f["least_squares"] == pytest.approx(gain, rel=3e-3)
        assert f["asymmetry_ppm"] is not None
    assert "scale factor x (raw per rad/s): " in r.err
    summary = run(capsys, "solve", "--sensor", "gyroscope", *items, "-o", tmp_path / "again.json", "--json")
    assert json.loads(summary.out)["scale_factors"] == doc["scale_factors"]


@pytest.mark.parametrize(
    ("item", "expected"),
    [
        ("45=a.csv", "--spin '45=a.csv': the rate has no unit: give RATE=FILE, the rate with its unit: 45rpm=a.csv, "
         "270deg/s=b.csv, 0=rest.csv, +z@45rpm=c.csv"),
        ("45furlongs=a.csv", "--spin '45furlongs=a.csv': 'furlongs' is not a unit of angular rate (rpm, rad/s, deg/s)"),
        ("90000rpm=a.csv", "--spin '90000rpm=a.csv': 90000 rpm is no rate table's or platter's (at most 1910 rpm)"),
        ("-45rpm=a.csv", "--spin '-45rpm=a.csv': a minus sign turns a labelled face the other way "
         "(+z@-45rpm=a.csv); without a face the fit sees only the rate's size"),
        ("45rpm", "--spin '45rpm': give RATE=FILE, the rate with its unit: 45rpm=a.csv, 270deg/s=b.csv, 0=rest.csv, "
         "+z@45rpm=c.csv"),
    ],
)  # fmt: skip
def test_a_bad_rate_is_one_line_and_nothing_written(
    item: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "gyr.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", "--spin", item, "-o", out)
    hint = "give the rate without its sign, or the face that pointed up" if item.startswith("-") else None
    assert_one_error(r, expected, hint=hint)
    assert not out.exists()


def test_a_file_that_does_not_spin_and_a_spin_for_an_accelerometer_are_refused(
    platter: tuple[list[str], FloatArray, FloatArray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    items, _, _ = platter
    rest = items[2].partition("=")[2]
    out = tmp_path / "gyr.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", "--spin", f"45rpm={rest}", "--spin", items[1], "-o", out)
    assert r.code == 3
    assert f"error: {rest}: 45rpm (4.712 rad/s): no steady stretch at that rate; its steady stretches turn at" in r.err
    assert not out.exists()
    r = run(capsys, "solve", "--spin", items[0], "-o", out)
    assert_one_error(
        r,
        "--spin spins a gyroscope at known rates, not the accelerometer's",
        hint="give --sensor gyroscope (and the gyroscope's columns)",
    )
    assert not out.exists()


def test_a_gyroscopes_reference_hint_points_to_spin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The hints went in a circle: "give the turning rate with --reference" / "leave --reference out"."""
    r = run(capsys, "solve", "--sensor", "gyroscope", "--reference", "4.7", "--poses", tmp_path / "x.csv")
    assert r.code == 2
    assert "--spin 45rpm=FILE" in r.err


def test_gyro_bias_takes_the_still_run_not_the_handling(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """gyro-bias averaged the handling at a file's start in (3.4 sigma off on a real file); the
    bias is the still run's now, its rows named, and a file still throughout is solved whole."""
    rng = np.random.default_rng(8)
    a, b = truth(rng, symmetric=True)
    handled = write(tmp_path / "rest.csv", readings(rng, a, b, [(np.array([0.0, 0.0, 1.0]), 0.0)]))
    out = tmp_path / "bias.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", "--method", "gyro-bias", "--poses", handled, "-o", out)
    assert r.code == 0, r.err
    assert f"{handled}: the gyroscope turned or was handled in it; its bias is its still run, rows 100-1149" in r.err
    doc = json.loads(out.read_text())
    assert np.all(np.abs(np.array(doc["offset"]) - b) < 4 * np.array(doc["uncertainty"]["offset"]))
    assert doc["poses"][0]["rows"] == [100, 1149]
    kept = run(capsys, "solve", "--sensor", "gyroscope", "--method", "gyro-bias", "--poses", handled, "--no-trim",
               "-o", tmp_path / "whole.json")  # fmt: skip
    assert kept.code == 0
    whole = json.loads((tmp_path / "whole.json").read_text())
    stated = np.array(doc["uncertainty"]["offset"])
    assert np.any(np.abs(np.array(whole["offset"]) - b) > 4 * stated)  # the bug: the handling moves the mean
    still = write(tmp_path / "still.csv", a @ np.zeros(3) + b + rng.normal(size=(1000, 3)) * 0.01)
    r = run(capsys, "solve", "--sensor", "gyroscope", "--method", "gyro-bias", "--poses", still, "-o", out)
    assert r.code == 0
    assert "still run" not in r.err
    assert json.loads(out.read_text())["poses"][0]["samples"] == 1000


def test_verify_judges_a_gyroscope_on_held_out_spun_files(
    platter: tuple[list[str], FloatArray, FloatArray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    items, _, _ = platter
    cal = tmp_path / "gyr.json"
    fitted = [x for i in items[:3] for x in ("--spin", i)]
    assert run(capsys, "solve", "--sensor", "gyroscope", *fitted, "-o", cal).code == 0
    r = run(capsys, "verify", "--cal", cal, "--spin", items[3], "--json")  # three placements not fitted on
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    (row,) = doc["captures"]
    assert row["rate"] == pytest.approx(45 * RPM)
    assert row["error_after"] < 0.02  # the samples' noise (0.01 rad/s) and the platter's 0.1 %
    assert row["max_error"] > row["error_after"]
    failed = run(capsys, "verify", "--cal", cal, "--spin", items[3], "--max-norm-error", "0.001")
    assert failed.code == 1
    mag = tmp_path / "mag.json"
    doc_mag = json.loads(cal.read_text()) | {"sensor": "magnetometer", "reference": 1.0}
    mag.write_text(json.dumps(doc_mag))
    r = run(capsys, "verify", "--cal", mag, "--spin", items[3])
    assert_one_error(r, f"{mag}: --spin checks a gyroscope's calibration, not the magnetometer's")


def test_solve_help_for_a_gyroscope_points_to_spin(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--help")
    assert r.code == 0
    flat = " ".join(r.out.split())
    assert "a gyroscope 0: its rates by --spin" in flat  # where --reference sent it in a circle
    full = run(capsys, "solve", "--help-all")
    assert "--spin RATE=FILE" in full.out


def _session_files(tmp_path: Path, rng: np.random.Generator, scale: float = 1.0) -> tuple[list[str], FloatArray]:
    """--spin items of a session (45 and 33⅓ rpm, six placements each, and rest), its readings
    multiplied by ``scale`` (57.3: deg/s; 7506: counts at 131 LSB per deg/s); and the true A."""
    a, b = truth(rng, symmetric=True)
    items = []
    for name, rate, n in (("45rpm", 45 * RPM, 6), ("33.333rpm", 100 / 3 * RPM, 6), ("0", 0.0, 1)):
        placements = [(turned(rng), rate) for _ in range(n)]
        path = write(tmp_path / f"s{name.replace('.', '_')}.csv", readings(rng, a, b, placements, hold=10) * scale)
        items += ["--spin", f"{name}={path}"]
    return items, a * scale


def test_what_a_stress_run_found_in_solve_spin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(31)
    items, _ = _session_files(tmp_path, rng)
    rest = items[-1].partition("=")[2]
    before = Path(rest).read_bytes()
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "-o", rest)  # -o naming an input
    assert r.code == 2
    assert "overwrite" in r.err
    assert Path(rest).read_bytes() == before
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "--json")  # two documents on stdout
    assert_one_error(r, "--json prints the summary on stdout, so the calibration needs -o FILE", json_out=True)
    twice = [*items, "--spin", items[1]]
    r = run(capsys, "solve", "--sensor", "gyroscope", *twice, "-o", tmp_path / "twice.json")
    assert r.code == 2
    assert "--spin gives this file twice" in r.err  # its runs would count twice: false precision


def test_counts_and_units_are_judged_from_the_readings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(32)
    lsb = 131 * 180 / math.pi  # 131 LSB per deg/s, per rad/s
    items, a = _session_files(tmp_path, rng, lsb)
    out = tmp_path / "counts.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "--units", "deg/s", "-o", out)
    assert r.code == 0, r.err  # refused "the runs do not determine the gains" (gain_se against M)
    doc = json.loads(out.read_text())
    assert np.allclose(doc["gain"], np.diag(a) / (180 / math.pi), rtol=0.005)  # raw per deg/s
    assert doc["units"] == "deg/s"
    items, _ = _session_files(tmp_path, rng, 180 / math.pi)  # readings in deg/s
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "--input-units", "rad/s", "-o", out)
    assert r.code == 2
    assert "times what --input-units rad/s says" in r.err
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "--units", "rad/s", "-o", out)
    assert r.code == 0, r.err  # --units names the corrected units: deg/s readings corrected into rad/s
    assert np.allclose(json.loads(out.read_text())["gain"], 180 / math.pi, rtol=0.05)


def _placed(tmp_path: Path, name: str, a: FloatArray, b: FloatArray, placements: list[tuple[FloatArray, float]]) -> str:
    seed = sum(ord(c) for c in name)  # files of their own noise (the same bytes are one file given twice)
    return str(write(tmp_path / name, readings(np.random.default_rng(seed), a, b, placements, hold=10)))


def test_runs_that_cannot_fit_are_exit_3_and_a_platter_off_its_rate_is_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(33)
    a, b = truth(rng, symmetric=True)
    up = np.array([0.0, 0.0, 1.0])
    rest = f"0={_placed(tmp_path, 'rest.csv', a, b, [(up, 0.0)])}"
    same = [f"45rpm={_placed(tmp_path, 'same45.csv', a, b, [(up, 45 * RPM)] * 6)}", rest]
    r = run(capsys, "solve", "--sensor", "gyroscope", *[x for i in same for x in ("--spin", i)], "-o", tmp_path / "s")
    assert r.code == 3, r.err  # was an internal error
    assert "internal error" not in r.err
    wrong = [f"+x@45rpm={_placed(tmp_path, f'z{k}.csv', a, b, [(up, 45 * RPM)])}" for k in range(3)]
    right = [f"{f}@45rpm={_placed(tmp_path, f'f{f}.csv', a, b, [(model.direction(f), 45 * RPM)])}"
             for f in ("-x", "+y", "-y", "-z")]  # fmt: skip
    r = run(capsys, "solve", "--sensor", "gyroscope", *[x for i in [*wrong, *right, rest] for x in ("--spin", i)],
            "-o", tmp_path / "w.json")  # fmt: skip
    assert r.code == 3
    assert "internal error" not in r.err
    fast = [(turned(rng), 45 * RPM * 1.03) for _ in range(6)]  # the whole file 3 % fast
    slow = [(turned(rng), 100 / 3 * RPM) for _ in range(6)]
    items = [
        f"45rpm={_placed(tmp_path, 'fast.csv', a, b, fast)}",
        f"33.333rpm={_placed(tmp_path, 'slow.csv', a, b, slow)}",
    ]
    r = run(capsys, "solve", "--sensor", "gyroscope", *[x for i in [*items, rest] for x in ("--spin", i)],
            "-o", tmp_path / "f.json")  # fmt: skip
    assert f"warning: {tmp_path / 'fast.csv'}'s runs read +" in r.err
    odd = [(turned(rng), 45 * RPM) for _ in range(6)] + [(turned(rng), 45 * RPM * 1.03)]  # one placement 3 % off
    items = [f"45rpm={_placed(tmp_path, 'odd.csv', a, b, odd)}", items[1]]
    r = run(capsys, "solve", "--sensor", "gyroscope", *[x for i in [*items, rest] for x in ("--spin", i)],
            "-o", tmp_path / "o.json")  # fmt: skip
    assert r.code == 0, r.err
    assert re.search(r"odd\.csv rows \d+–\d+: off the fit by", r.err)  # the 3 % placement, left out


def test_labelled_faces_with_axes_are_the_bodys(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """+x@45rpm with --axes +y,+z,+x: the body's +x is the sensor's +y; the fit took the label as
    the sensor's, and the matrix came out turned the wrong way."""
    rng = np.random.default_rng(34)
    a, b = truth(rng, symmetric=False)
    axes = "+y,+z,+x"
    p = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # body = P sensor
    items = []
    for face in ("+x", "-x", "+y", "-y", "+z", "-z"):
        sensor_up = p.T @ model.direction(face)
        items += ["--spin", f"{face}@45rpm={_placed(tmp_path, f'b{face}.csv', a, b, [(sensor_up, 45 * RPM)])}"]
    out = tmp_path / "body.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", *items, "--axes", axes, "-o", out)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert np.allclose(doc["gain"], np.diag(a), rtol=0.01)  # the sensor's gains
    body = np.array(doc["matrix"]) @ (a @ (p.T @ np.array([0.0, 45 * RPM, 0.0])))  # a turn about the body's y
    assert np.allclose(body, [0.0, 45 * RPM, 0.0], atol=0.02)


def test_gyro_bias_of_a_file_that_turns_steadily_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(35)
    a, b = truth(rng, symmetric=True)
    spun = _placed(tmp_path, "spun.csv", a, b, [(turned(rng), 45 * RPM) for _ in range(3)])
    out = tmp_path / "bias.json"
    r = run(capsys, "solve", "--sensor", "gyroscope", "--method", "gyro-bias", "--poses", spun, "-o", out)
    assert r.code == 3  # it took a spinning stretch as the bias: 4.7 rad/s, PASS
    assert "the gyroscope reads 3 different steady rates in it" in r.err
    assert not out.exists()


def test_verify_of_a_labelled_face_judges_the_rates_direction(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """verify --spin +x@45rpm=FILE of a file turned about +z passed: only the magnitude was judged."""
    rng = np.random.default_rng(36)
    a, b = truth(rng, symmetric=False)
    items = []
    for face in ("+x", "-x", "+y", "-y", "+z", "-z"):
        items += [
            "--spin",
            f"{face}@45rpm={_placed(tmp_path, f'l{face}.csv', a, b, [(model.direction(face), 45 * RPM)])}",
        ]
    cal = tmp_path / "gyr.json"
    assert run(capsys, "solve", "--sensor", "gyroscope", *items, "-o", cal).code == 0
    z_file = items[-3].partition("=")[2]  # turned about +z
    right = run(capsys, "verify", "--cal", cal, "--spin", f"+z@45rpm={z_file}", "--max-norm-error", "0.05")
    assert right.code == 0, right.err
    wrong = run(capsys, "verify", "--cal", cal, "--spin", f"+x@45rpm={z_file}", "--max-norm-error", "0.05")
    assert wrong.code == 1
    assert "|corrected − rate along +x|" in wrong.err

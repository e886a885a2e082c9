"""tumblecal current (docs/current.md): a magnetometer's offset per ampere of motor current fitted
from logs of a still vehicle running its motors up, kept as a ``current`` block, corrected by
apply row by row, and exported as the firmware's own compensation (checked against each
firmware's correction, written out here as its source has it)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import Result, assert_one_error, assert_untouched, precious, run, run_exe
from tumblecal_cli.core import current_fit
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile

DATA = Path(__file__).resolve().parent / "data" / "ardupilot"
#: A compass's truth, in gauss: its offset, its correction M (not symmetric: a small rotation
#: that ArduPilot's and PX4's symmetric matrices drop), the offset per ampere, the noise.
OFFSET = np.array([0.12, -0.05, 0.21])
M = np.array([[1.04, 0.03, -0.01], [0.01, 0.97, 0.012], [0.0, 0.008, 1.015]])
PER_AMP = np.array([0.0035, -0.0021, 0.0052])  # gauss per ampere, raw
SIGMA = 0.002
#: The field in the two attitudes the vehicle is logged in (corrected gauss).
FIELDS = (np.array([0.21, 0.03, 0.43]), np.array([-0.15, 0.2, 0.41]))


def _base(path: Path, matrix: np.ndarray = M) -> Path:
    cal = calfile.Calibration(
        sensor="magnetometer",
        method="ellipsoid",
        reference=0.5,
        columns=["mx", "my", "mz"],
        offset=OFFSET,
        matrix=matrix,
        gain=np.diag(np.linalg.inv(matrix)),
        units="gauss",
        input_units="gauss",
    )
    cal.save(path)
    return path


def _runup(seed: int, n: int = 400, field: np.ndarray = FIELDS[0]) -> tuple[np.ndarray, np.ndarray]:
    """A still vehicle's throttle run from idle to full and back: raw readings (n, 3), current (n,)."""
    rng = np.random.default_rng(seed)
    ramp = np.concatenate([np.linspace(0.5, 42.0, n // 2), np.linspace(42.0, 0.5, n - n // 2)])
    current = np.clip(ramp + rng.normal(0, 0.4, n), 0, None)
    raw = np.linalg.solve(M, field) + OFFSET + np.outer(current, PER_AMP) + rng.normal(0, SIGMA, (n, 3))
    return raw, current


def _write(path: Path, raw: np.ndarray, current: np.ndarray, name: str = "curr_a") -> Path:
    lines = [f"t,mx,my,mz,{name}"]
    lines += [
        f"{k * 0.02:.2f},{r[0]:.7f},{r[1]:.7f},{r[2]:.7f},{c:.3f}"
        for k, (r, c) in enumerate(zip(raw, current, strict=True))
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


# -- the fit ------------------------------------------------------------------------------------


@pytest.mark.slow
def test_truth_is_recovered_within_its_stated_uncertainty() -> None:
    """Monte Carlo: 400 runs of two logs (two attitudes); the errors of the offset per ampere
    and of each log's reading at 0 A over their 1-sigma are standard normal (z within ±3)."""
    z_k, z_b = [], []
    for seed in range(400):
        (raw1, i1), (raw2, i2) = _runup(seed, 300, FIELDS[0]), _runup(10_000 + seed, 200, FIELDS[1])
        group = np.r_[np.zeros(300, np.int64), np.ones(200, np.int64)]
        fit = current_fit.fit(np.vstack([raw1, raw2]), np.r_[i1, i2], group)
        z_k.append((fit.per_amp - PER_AMP) / fit.per_amp_se)
        at_zero = np.array([np.linalg.solve(M, f) + OFFSET for f in FIELDS])
        z_b.append(((fit.at_zero - at_zero) / fit.at_zero_se).ravel())
    for z in (np.array(z_k).ravel(), np.array(z_b).ravel()):
        assert abs(z.mean()) < 0.1
        assert 0.9 < z.std() < 1.1
        assert np.mean(np.abs(z) > 3) < 0.01


@pytest.mark.slow
def test_noise_that_follows_itself_widens_the_uncertainty_to_match() -> None:
    """AR(1) noise (r = 0.8, a swaying vehicle): the 1-sigma, widened by sqrt((1 + r) / (1 - r)),
    still covers the errors (z within ±3); unwidened it would be 3 times too small."""
    rng = np.random.default_rng(5)
    z, r, n = [], [], 600
    for _ in range(300):
        current = np.r_[np.linspace(0, 40, n // 2), np.linspace(40, 0, n // 2)]
        noise, step = np.zeros((n, 3)), rng.normal(0, SIGMA, (n, 3))
        for i in range(1, n):
            noise[i] = 0.8 * noise[i - 1] + step[i]
        fit = current_fit.fit(OFFSET + np.outer(current, PER_AMP) + noise, current)
        z.append((fit.per_amp - PER_AMP) / fit.per_amp_se)
        r.append(fit.autocorrelation)
    assert np.mean(r) == pytest.approx(0.8, abs=0.03)
    scores = np.array(z).ravel()
    assert abs(scores.mean()) < 0.15
    assert 0.85 < scores.std() < 1.2
    assert np.mean(np.abs(scores) > 3) < 0.01


def test_a_real_flight_log_is_fitted_and_warned_of(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """spark404's ArduCopter log (MAG and CURR, 51 s in flight, tests/data/ardupilot): the vehicle
    sways and turns, so the current explains little of the field, and the slope is not known
    better than its (widened) uncertainty says: docs/current.md shows this run."""
    code, _, err = run(
        capsys,
        "current",
        DATA / "spark404_mag_curr.csv",
        "--cal",
        DATA / "spark404_mag_as_logged.json",
        "--current-column",
        "Curr",
        "-o",
        tmp_path / "c.json",
    )
    assert code == 0, err
    block = json.loads((tmp_path / "c.json").read_text())["current"]
    np.testing.assert_allclose(block["per_amp"], [2.439, -0.899, 0.489], atol=1e-3)
    np.testing.assert_allclose(block["uncertainty"]["per_amp"], [4.3, 0.84, 0.59], rtol=0.02)
    assert block["explained_total"] == pytest.approx(0.064, abs=1e-3)
    assert "warning: the current explains only 6% of the field's variation" in err


@pytest.mark.slow
def test_interference_is_within_its_stated_uncertainty() -> None:
    """Monte Carlo: the field's change at the largest current over the reference, and its
    1-sigma (first order through |M k|), z within ±3."""
    z = []
    for seed in range(400):
        raw, current = _runup(20_000 + seed, 300)
        fit = current_fit.fit(raw, current)
        value, sigma = current_fit.interference(fit, M, 0.5)
        truth = np.linalg.norm(M @ PER_AMP) * max(abs(fit.span[0]), abs(fit.span[1])) / 0.5
        z.append((value - truth) / sigma)
    scores = np.array(z)
    assert abs(scores.mean()) < 0.15
    assert 0.85 < scores.std() < 1.15
    assert np.mean(np.abs(scores) > 3) < 0.01


def test_explained_share_is_the_current_s_over_the_noise() -> None:
    """R² per axis is k² var(I) / (k² var(I) + σ²), to the scatter of one run."""
    raw, current = _runup(7, 4000)
    fit = current_fit.fit(raw, current)
    signal = PER_AMP**2 * current.var()
    np.testing.assert_allclose(fit.explained, signal / (signal + SIGMA**2), atol=0.01)
    assert fit.span == (float(current.min()), float(current.max()))
    np.testing.assert_allclose(fit.residual_rms, SIGMA, rtol=0.05)


def test_correct_removes_the_current_s_offset_row_by_row() -> None:
    raw, current = _runup(3)
    fixed = current_fit.correct(raw, current, OFFSET, M, PER_AMP)
    np.testing.assert_allclose(fixed, (raw - OFFSET - np.outer(current, PER_AMP)) @ M.T)
    assert fixed.std(axis=0).max() < 2 * SIGMA  # the field no longer follows the current


# -- the command, the file, apply ---------------------------------------------------------------


@pytest.fixture
def fitted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, Path, np.ndarray, np.ndarray]:
    raw, current = _runup(11)
    log = _write(tmp_path / "runup.csv", raw, current)
    out = tmp_path / "mag-current.json"
    code, _, err = run(
        capsys, "current", log, "--cal", _base(tmp_path / "mag.json"), "--current-column", "curr_a", "-o", out
    )
    assert code == 0, err
    return log, out, raw, current


def test_the_block_holds_the_fit_and_show_reports_it(
    fitted: tuple[Path, Path, np.ndarray, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    _, out, _, _ = fitted
    doc = json.loads(out.read_text())
    block = doc["current"]
    assert block["column"] == "curr_a"
    se = np.array(block["uncertainty"]["per_amp"])
    assert (np.abs(np.array(block["per_amp"]) - PER_AMP) < 4 * se).all()
    np.testing.assert_allclose(block["per_amp_corrected"], M @ np.array(block["per_amp"]))
    assert block["explained_total"] > 0.95
    cal = calfile.load(out)
    assert cal.current is not None
    assert calfile.dumps(cal, str(out)) == out.read_text()  # read and written again, unchanged
    code, shown, _ = run(capsys, "show", out)
    assert code == 0
    line = next(ln for ln in shown.splitlines() if ln.startswith("current ("))
    assert "gauss/A" in line
    assert "of the field's variation" in line


def test_json_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, current = _runup(12)
    log = _write(tmp_path / "runup.csv", raw, current)
    args: list[str | Path] = ["current", log, "--cal", _base(tmp_path / "mag.json"), "--current-column", "curr_a"]
    code, out, _ = run(capsys, *args, "-o", tmp_path / "c.json", "--json", "-q")
    assert code == 0
    doc = json.loads(out)
    assert doc["status"] == "pass"
    assert doc["current"]["column"] == "curr_a"
    per_amp = np.linalg.norm(M @ np.array(doc["current"]["per_amp"]))
    assert doc["interference"] == pytest.approx(per_amp * doc["current"]["range"][1] / 0.5)


@pytest.mark.slow
def test_apply_corrects_each_row_at_its_current_from_the_installed_cli(tmp_path: Path) -> None:
    raw, current = _runup(21)
    log = _write(tmp_path / "runup.csv", raw, current)
    base = _base(tmp_path / "mag.json")
    made = run_exe(["current", log, "--cal", base, "--current-column", "curr_a", "-o", tmp_path / "c.json"], text=True)
    assert made.returncode == 0, made.stderr
    check_raw, check_current = _runup(22, 300, FIELDS[1])
    capture = _write(tmp_path / "check.csv", check_raw, check_current)
    done = run_exe(["apply", "--cal", tmp_path / "c.json", capture, "-o", tmp_path / "fixed.csv"], text=True)
    assert done.returncode == 0, done.stderr
    table = np.genfromtxt(tmp_path / "fixed.csv", delimiter=",", names=True)
    fixed = np.c_[table["mx"], table["my"], table["mz"]]
    np.testing.assert_allclose(table["curr_a"], check_current, atol=1e-3)  # other columns as they were
    per_amp = np.array(json.loads((tmp_path / "c.json").read_text())["current"]["per_amp"])
    expected = (check_raw - OFFSET - np.outer(table["curr_a"], per_amp)) @ M.T
    np.testing.assert_allclose(fixed, expected, atol=1e-6)
    np.testing.assert_allclose(fixed.mean(axis=0), FIELDS[1], atol=2e-3)
    assert fixed.std(axis=0).max() < 2 * SIGMA
    plain = (check_raw - OFFSET) @ M.T  # without the block the field follows the current
    assert plain.std(axis=0).max() > 20 * SIGMA


def test_python_api_fits_and_applies(tmp_path: Path) -> None:
    pd = pytest.importorskip("pandas")
    raw, current = _runup(31)
    log = _write(tmp_path / "runup.csv", raw, current)
    done = tumblecal.current([log], _base(tmp_path / "mag.json"), current_column="curr_a")
    assert isinstance(done, tumblecal.CurrentResult)
    cal = done.calibration
    frame = pd.DataFrame({"mx": raw[:, 0], "my": raw[:, 1], "mz": raw[:, 2], "curr_a": current})
    fixed = cal.apply(frame)
    expected = current_fit.correct(raw, current, OFFSET, M, done.fit.per_amp)
    np.testing.assert_allclose(fixed[["mx", "my", "mz"]].to_numpy(), expected)
    np.testing.assert_allclose(cal.apply(raw, temperature=current), expected)
    with pytest.raises(InputError, match="motor current"):
        cal.apply(raw)


def test_two_logs_in_two_attitudes_share_one_slope(tmp_path: Path) -> None:
    (raw1, i1), (raw2, i2) = _runup(41, 300, FIELDS[0]), _runup(42, 300, FIELDS[1])
    logs = [_write(tmp_path / "a.csv", raw1, i1), _write(tmp_path / "b.csv", raw2, i2)]
    done = tumblecal.current(logs, _base(tmp_path / "mag.json"), current_column="curr_a")
    assert (np.abs(done.fit.per_amp - PER_AMP) < 4 * done.fit.per_amp_se).all()
    assert done.fit.explained_total > 0.95  # each log's own reading at 0 A: the attitudes are not variation
    assert done.warnings == []


def test_a_vehicle_that_turned_is_warned_of(tmp_path: Path) -> None:
    raw, current = _runup(43)
    rng = np.random.default_rng(0)
    raw = raw + rng.normal(0, 0.1, raw.shape)  # the field swings far more than the current moves it
    done = tumblecal.current(
        [_write(tmp_path / "a.csv", raw, current)], _base(tmp_path / "mag.json"), current_column="curr_a"
    )
    assert any("did the vehicle move" in w for w in done.warnings)


@pytest.mark.parametrize(("bound", "code"), [(0.9, 0), (0.3, 1)])
def test_the_limits_file_judges_the_interference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bound: float, code: int
) -> None:
    """current_interference (a share of the reference): above it exit 1, the calibration written."""
    raw, current = _runup(14)
    log = _write(tmp_path / "runup.csv", raw, current)
    limits = tmp_path / "limits.yaml"
    limits.write_text(f"current_interference: {bound}\n")
    out = tmp_path / "c.json"
    args: list[str | Path] = ["current", log, "--cal", _base(tmp_path / "mag.json"), "--current-column", "curr_a"]
    result = run(capsys, *args, "--limits", limits, "-o", out, "--json", "-q")
    assert result.code == code, result.err
    assert out.exists()
    doc = json.loads(result.out)
    assert (doc["status"], doc["exit_status"]) == (("pass", 0) if code == 0 else ("fail", 1))
    assert doc["verdict"]["pass"] is (code == 0)
    truth = np.linalg.norm(M @ PER_AMP) * current.max() / 0.5  # |M k| I_max / reference
    assert doc["interference"] == pytest.approx(truth, abs=3 * doc["interference_sigma"])
    assert 0 < doc["interference_sigma"] < 0.01
    if code:
        assert doc["verdict"]["failures"][0]["code"] == "limit.current_interference"
    result = run(capsys, "current", *args[1:], "--limits", limits, "-o", out)
    assert f"verdict: {'PASS' if code == 0 else 'FAIL'} (limit: current_interference {bound:g})" in result.err


def test_solve_takes_a_limits_file_with_current_interference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    limits = tmp_path / "limits.yaml"
    limits.write_text("offset: 0.2\ncurrent_interference: 0.3\n")
    poses = [str(Path(__file__).resolve().parent.parent / "sample_data" / f"{a}.csv") for a in "xyz"]
    code, _, err = run(capsys, "solve", "--poses", *poses, "--limits", limits, "-o", tmp_path / "cal.json", "-q")
    assert code == 0, err


# -- bad input: one line, exit 2 or 3, nothing written ------------------------------------------


def _bad(tmp_path: Path, capsys: pytest.CaptureFixture[str], log: Path, *more: str) -> Result:
    out = precious(tmp_path / "out.json")
    base = _base(tmp_path / "mag.json")
    result = run(capsys, "current", log, "--cal", base, *more, "-o", out)
    assert_untouched(out)
    return result


def test_a_current_that_never_changes_is_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, _ = _runup(51)
    log = _write(tmp_path / "flat.csv", raw, np.full(len(raw), 12.0))
    result = _bad(tmp_path, capsys, log, "--current-column", "curr_a")
    assert_one_error(
        result,
        f"{log}: the current column 'curr_a' never changes at 12 A within a log: "
        "nothing to fit an offset per ampere against",
        code=3,
        hint="motors run",
    )


def test_a_missing_current_column_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, current = _runup(52)
    log = _write(tmp_path / "runup.csv", raw, current)
    result = _bad(tmp_path, capsys, log, "--current-column", "amps")
    assert_one_error(
        result, f"{log}: --current-column 'amps' not found (columns: t, mx, my, mz, curr_a)", hint="amperes"
    )


def test_a_current_column_that_is_a_sensor_column_names_the_option_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It said '--pose-column names ...', an option current does not have."""
    raw, current = _runup(52)
    log = _write(tmp_path / "runup.csv", raw, current)
    result = _bad(tmp_path, capsys, log, "--current-column", "mx")
    assert_one_error(result, f"{log}: --current-column names 'mx', one of the magnetometer columns", hint="amperes")


def test_a_nan_current_is_exit_2_naming_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, current = _runup(53)
    log = _write(tmp_path / "runup.csv", raw, current)
    lines = log.read_text().splitlines()
    lines[10] = lines[10].rsplit(",", 1)[0] + ",nan"
    log.write_text("\n".join(lines) + "\n")
    result = _bad(tmp_path, capsys, log, "--current-column", "curr_a")
    assert_one_error(result, f"{log}: current is not a finite number: 'nan' (line 11, column curr_a)", hint="amperes")


def test_a_dataflash_log_is_exit_2_saying_to_write_a_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "copter.bin"
    log.write_bytes(gzip.decompress((DATA / "spark404_copter.bin.gz").read_bytes()))
    result = _bad(tmp_path, capsys, log, "--current-column", "Curr")
    assert_one_error(
        result,
        f"{log}: an ArduPilot DataFlash log's current is in a message of its own, on its own clock: "
        "current reads CSV logs",
        hint="to a CSV",
    )


def test_an_accelerometer_calibration_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, current = _runup(54)
    log = _write(tmp_path / "runup.csv", raw, current)
    acc = tmp_path / "acc.json"
    calfile.Calibration("accelerometer", "six-pose", 1.0, ["mx", "my", "mz"], OFFSET, M, np.ones(3)).save(acc)
    result = run(capsys, "current", log, "--cal", acc, "--current-column", "curr_a", "-o", tmp_path / "o.json")
    assert_one_error(
        result,
        f"{acc}: current compensation is a magnetometer's, and this calibration is of the accelerometer",
        hint="magnetometer",
    )
    assert not (tmp_path / "o.json").exists()


def test_apply_without_the_current_column_is_exit_2(
    fitted: tuple[Path, Path, np.ndarray, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, out, raw, current = fitted
    capture = tmp_path / "no-current.csv"
    capture.write_text("mx,my,mz\n" + "".join(f"{r[0]},{r[1]},{r[2]}\n" for r in raw[:20]))
    result = run(capsys, "apply", "--cal", out, capture, "-o", tmp_path / "fixed.csv")
    assert_one_error(
        result,
        f"{capture}: the capture has no current column 'curr_a', which the calibration's current block corrects with",
        hint="columns: mx, my, mz",
    )
    bad = _write(tmp_path / "bad.csv", raw[:20], current[:20])
    bad.write_text(bad.read_text().replace(f",{current[5]:.3f}\n", ",x\n", 1))
    result = run(capsys, "apply", "--cal", out, bad, "-o", tmp_path / "fixed.csv")
    assert result.code == 2
    assert "current is not a number: 'x'" in result.err
    assert not (tmp_path / "fixed.csv").exists()


@pytest.mark.parametrize(
    ("block", "says"),
    [
        ({"column": "i", "per_amp": [1, 2], "range": [0, 30]}, "field 'current.per_amp' must be a list of 3 numbers"),
        ({"column": "i", "per_amp": [1, 2, 3], "range": [30, 0]}, "field 'current.range' [30, 0] must be"),
        ({"per_amp": [1, 2, 3], "range": [0, 30]}, "field 'current' has no 'column'"),
    ],
)
def test_a_malformed_block_names_its_field(tmp_path: Path, block: dict[str, object], says: str) -> None:
    doc = json.loads(_base(tmp_path / "mag.json").read_text())
    doc["current"] = block
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=says.replace("[", r"\[").replace("]", r"\]")):
        calfile.load(tmp_path / "bad.json")


# -- export: the firmware's own correction reproduces ours --------------------------------------


def _params(text: str, sep: str) -> dict[str, float]:
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            cells = line.split(sep)
            name, value = (cells[0], cells[1]) if sep == "," else (cells[2], cells[3])
            out[name] = float(value)
    return out


def _symmetric_fit(tmp_path: Path) -> tuple[calfile.Calibration, np.ndarray, np.ndarray]:
    raw, current = _runup(61)
    sym = (M + M.T) / 2  # what both firmwares hold whole: their correction is then ours exactly
    base = _base(tmp_path / "sym.json", sym)
    done = tumblecal.current([_write(tmp_path / "r.csv", raw, current)], base, current_column="curr_a")
    return done.calibration, raw, current


def test_ardupilot_compass_mot_reproduces_our_correction(tmp_path: Path) -> None:
    """AP_Compass_Backend::correct_field, mGauss: mag += COMPASS_OFS; mag = DIA/ODI * mag (COMPASS_SCALE
    1); mag += COMPASS_MOT * current (COMPASS_MOTCT 2, amperes)."""
    cal, raw, current = _symmetric_fit(tmp_path)
    p = _params(tumblecal.export(cal, "ardupilot"), ",")
    assert p["COMPASS_MOTCT"] == 2
    ofs = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"])
    dia, odi = (np.array([p[f"COMPASS_{k}_{a}"] for a in "XYZ"]) for k in ("DIA", "ODI"))
    mat = np.array([[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]])
    mot = np.array([p[f"COMPASS_MOT_{a}"] for a in "XYZ"])
    firmware = (raw * 1000 + ofs) @ mat.T * p["COMPASS_SCALE"] + np.outer(current, mot)
    np.testing.assert_allclose(firmware, cal.apply(raw, temperature=current) * 1000, rtol=1e-6, atol=1e-4)
    assert np.sign(mot) @ np.sign(cal.matrix @ PER_AMP) == -3  # it opposes the field's change


def test_px4_power_compensation_reproduces_our_correction(tmp_path: Path) -> None:
    """PX4 calibration::Magnetometer::Correct, gauss: S ((raw + power * xCOMP) - xOFF), power =
    battery_status.current_a * 0.001 (kA) with CAL_MAG_COMP_TYP 2 (VehicleMagnetometer.cpp)."""
    cal, raw, current = _symmetric_fit(tmp_path)
    p = _params(tumblecal.export(cal, "px4"), "\t")
    assert p["CAL_MAG_COMP_TYP"] == 2
    off = np.array([p[f"CAL_MAG0_{a}OFF"] for a in "XYZ"])
    sc = np.array([p[f"CAL_MAG0_{a}SCALE"] for a in "XYZ"])
    od = np.array([p[f"CAL_MAG0_{a}ODIAG"] for a in "XYZ"])
    s = np.array([[sc[0], od[0], od[1]], [od[0], sc[1], od[2]], [od[1], od[2], sc[2]]])
    comp = np.array([p[f"CAL_MAG0_{a}COMP"] for a in "XYZ"])
    power = current * 0.001
    firmware = ((raw + np.outer(power, comp)) - off) @ s.T
    np.testing.assert_allclose(firmware, cal.apply(raw, temperature=current), rtol=1e-6, atol=1e-7)
    assert cal.current is not None
    np.testing.assert_allclose(comp, -1000 * cal.current.per_amp)


@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
def test_with_a_rotation_dropped_the_firmware_field_still_ignores_the_current(tmp_path: Path, fmt: str) -> None:
    """M not symmetric: the firmware keeps its symmetric part, and its field, for a still vehicle,
    no longer moves with the current."""
    raw, current = _runup(62)
    done = tumblecal.current(
        [_write(tmp_path / "r.csv", raw, current)], _base(tmp_path / "m.json"), current_column="curr_a"
    )
    text = tumblecal.export(done.calibration, fmt)
    if fmt == "ardupilot":
        p = _params(text, ",")
        dia, odi = (np.array([p[f"COMPASS_{k}_{a}"] for a in "XYZ"]) for k in ("DIA", "ODI"))
        mat = np.array([[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]])
        ofs, mot = (np.array([p[f"COMPASS_{k}_{a}"] for a in "XYZ"]) for k in ("OFS", "MOT"))
        field = ((raw * 1000 + ofs) @ mat.T + np.outer(current, mot)) / 1000
    else:
        p = _params(text, "\t")
        sc, od = (np.array([p[f"CAL_MAG0_{a}{k}"] for a in "XYZ"]) for k in ("SCALE", "ODIAG"))
        s = np.array([[sc[0], od[0], od[1]], [od[0], sc[1], od[2]], [od[1], od[2], sc[2]]])
        off, comp = (np.array([p[f"CAL_MAG0_{a}{k}"] for a in "XYZ"]) for k in ("OFF", "COMP"))
        field = ((raw + np.outer(current / 1000, comp)) - off) @ s.T
    assert field.std(axis=0).max() < 2 * SIGMA
    slope = np.polyfit(current, field, 1)[0]
    assert np.abs(slope).max() < 4 * done.fit.per_amp_se.max() * 1.1


def test_other_formats_say_the_block_is_not_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    raw, current = _runup(63)
    done = tumblecal.current(
        [_write(tmp_path / "r.csv", raw, current)], _base(tmp_path / "m.json"), current_column="curr_a"
    )
    done.calibration.save(tmp_path / "c.json")
    code, _, err = run(capsys, "export", tmp_path / "c.json", "--format", "c-header")
    assert code == 0
    assert "the current block (offset per ampere) is NOT written" in err

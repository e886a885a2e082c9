"""tumblecal thermal and the apply of a thermal block: known truth (sample_data/make_thermal.py's
chamber run), the refusals, the file block, and each row corrected at its own temperature."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tests.conftest import SAMPLE, run
from tumblecal_cli.core import drift
from tumblecal_cli.core.model import FACES
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile

THERMAL = SAMPLE / "thermal"
FACE_FILES = {"+x": "up_xp", "-x": "down_xn", "+y": "up_yp", "-y": "down_yn", "+z": "up_zp", "-z": "down_zn"}
ITEMS = [f"{face}={THERMAL / f'sweep_{name}.csv'}" for face, name in FACE_FILES.items()]


def _truth() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_thermal", SAMPLE / "make_thermal.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_thermal"] = module
    spec.loader.exec_module(module)
    return module


mt = _truth()


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The base calibration: six-pose from the room-temperature poses (25 °C)."""
    out = tmp_path_factory.mktemp("thermal") / "base.json"
    from tumblecal_cli.cli import main

    poses = [str(THERMAL / f"{n}.csv") for n in ("xp", "xn", "yp", "yn", "zp", "zn")]
    assert main(["solve", "--poses", *poses, "-o", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def fitted(base: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tumblecal_cli.cli import main

    out = tmp_path_factory.mktemp("thermal") / "base-thermal.json"
    assert main(["thermal", *ITEMS, "--cal", str(base), "-o", str(out), "--quiet"]) == 0
    return out


def _sweeps(seed: int) -> list[drift.Sweep]:
    runs = mt.chamber(seed)
    return [drift.Sweep(r[:, 1:], r[:, 0], np.array(FACES[f], dtype=float)) for f, r in runs.items()]


# -- core: known truth --------------------------------------------------------------------------


def test_fit_recovers_the_chamber_truth_within_a_few_standard_errors() -> None:
    fit = drift.fit(_sweeps(18), gain_scale=mt.GAIN * 1.0, t_ref=mt.T_REF, order=2)
    fitted = fit.drift
    for got, se, truth in (
        (fitted.offset[:, 0], fit.offset_se[:, 0], mt.OFFSET_DRIFT1),
        (fitted.offset[:, 1], fit.offset_se[:, 1], mt.OFFSET_DRIFT2),
        (fitted.gain[:, 0], fit.gain_se[:, 0], mt.GAIN_DRIFT1),
        (fitted.gain[:, 1], fit.gain_se[:, 1], np.zeros(3)),
    ):
        assert np.all(np.abs(got - truth) < 4 * se), (got, truth, se)
    assert fit.gain_drift == ("separate", "separate", "separate")


def test_order_auto_picks_the_true_order_on_most_seeds() -> None:
    picked = [
        drift.fit(_sweeps(seed), gain_scale=mt.GAIN * 1.0, t_ref=mt.T_REF, order=None).drift.order for seed in range(10)
    ]
    assert picked.count(2) >= 8, picked


def test_one_face_folds_its_vertical_axis_gain_drift_into_the_offset() -> None:
    runs = mt.chamber(3)
    sweep = drift.Sweep(runs["+z"][:, 1:], runs["+z"][:, 0], np.array(FACES["+z"], dtype=float))
    fit = drift.fit([sweep], gain_scale=mt.GAIN * 1.0, t_ref=mt.T_REF, order=2)
    assert fit.gain_drift == ("unobserved", "unobserved", "folded")
    # the folded z drift is offset + gain x reference: what +z reads
    assert fit.drift.offset[2, 0] == pytest.approx(mt.OFFSET_DRIFT1[2] + mt.GAIN[2] * mt.GAIN_DRIFT1[2], rel=0.05)


def test_correct_clamps_to_the_range_and_counts_the_rows() -> None:
    model = drift.Drift(25.0, 0.0, 50.0, np.array([[1.0], [0.0], [0.0]]), np.zeros((3, 1)))
    raw = np.zeros((3, 3))
    out, outside = drift.correct(raw, np.array([25.0, 60.0, -5.0]), np.zeros(3), np.eye(3), model)
    assert outside == 2
    assert out[:, 0].tolist() == [0.0, -25.0, 25.0]  # at 60 °C the drift of 50 °C, at -5 that of 0 °C


# -- the command ----------------------------------------------------------------------------------


def test_thermal_writes_the_base_calibration_plus_a_thermal_block(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    code, stdout, err = run(capsys, "thermal", *ITEMS, "--cal", base, "-o", out)
    assert code == 0, err
    assert stdout == ""
    assert "order 2 (chosen by cross-validation over temperature" in err
    doc = json.loads(out.read_text())
    old = json.loads(base.read_text())
    assert {k: v for k, v in doc.items() if k != "thermal"} == old
    block = doc["thermal"]
    assert block["column"] == "temp"
    assert block["order"] == 2
    assert block["reference_temperature"] == pytest.approx(25.0, abs=0.01)
    assert block["range"][0] < -9.9
    assert block["range"][1] > 59.9
    assert block["gain_drift"] == ["separate"] * 3
    assert list(doc).index("thermal") == list(doc).index("poses") - 1
    assert len(block["sweeps"]) == 6


def test_thermal_json_summary_gives_the_drift_over_the_range(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, stdout, _ = run(capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "c.json", "--json", "--order", "1")
    assert code == 0
    doc = json.loads(stdout)
    assert doc["status"] == "pass"
    assert doc["thermal"]["order"] == 1
    assert doc["thermal"]["order_choice"]["method"] == "given"
    assert [row["axis"] for row in doc["drift"]] == ["x", "y", "z"]


def _sweep_file(path: Path, temps: np.ndarray, face: str = "+z", text_at: int | None = None) -> Path:
    rng = np.random.default_rng(1)
    v = np.tile(np.array(FACES[face], dtype=float), (len(temps), 1))
    rows = mt.reading(v, temps, rng)
    lines = ["temp,ax,ay,az"]
    for k, (t, r) in enumerate(zip(temps, rows, strict=True)):
        cell = "warm" if k == text_at else f"{t:.2f}"
        lines.append(f"{cell},{r[0]:.6f},{r[1]:.6f},{r[2]:.6f}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("temps", "code", "message"),
    [
        (np.full(400, 25.0), "temperature.constant", "is constant at 25 °C"),
        (25 + np.random.default_rng(2).uniform(-8, 8, 400), "temperature.noise", "does not trend"),
        (np.linspace(20, 26, 400), "temperature.swing", "order 1 (the least) needs at least 10 °C"),
    ],
)
def test_a_temperature_that_cannot_carry_a_fit_is_rejected(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], temps: np.ndarray, code: str, message: str
) -> None:
    sweep = _sweep_file(tmp_path / "sweep.csv", temps)
    out = tmp_path / "out.json"
    result = run(capsys, "thermal", f"+z={sweep}", "--cal", base, "-o", out)
    assert result.code == 3, result.err
    assert message in result.err
    assert not out.exists()
    result = run(capsys, "thermal", f"+z={sweep}", "--cal", base, "-o", out, "--json")
    assert result.code == 3


def test_a_swing_too_small_for_the_order_names_the_order(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep = _sweep_file(tmp_path / "sweep.csv", np.linspace(20, 32, 600))
    assert run(capsys, "thermal", f"+z={sweep}", "--cal", base, "-o", tmp_path / "a.json", "--order", "1").code == 0
    code, _, err = run(capsys, "thermal", f"+z={sweep}", "--cal", base, "-o", tmp_path / "b.json", "--order", "3")
    assert code == 3
    assert "order 3 needs at least 20 °C" in err


def test_a_text_temperature_cell_is_exit_2_naming_its_line_and_column(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep = _sweep_file(tmp_path / "sweep.csv", np.linspace(0, 40, 400), text_at=10)
    code, _, err = run(capsys, "thermal", f"+z={sweep}", "--cal", base, "-o", tmp_path / "o.json")
    assert code == 2
    assert "temperature is not a number: 'warm' (line 12, column temp)" in err


def test_a_sweep_without_the_temperature_column_is_exit_2(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(capsys, "thermal", f"+x={SAMPLE / 'x.csv'}", "--cal", base, "-o", tmp_path / "o.json")
    assert code == 2
    assert "no temperature column" in err
    assert "--temperature-column" in err
    code, _, err = run(
        capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "o.json", "--temperature-column", "heat"
    )
    assert code == 2
    assert "heat" in err


def test_a_sweep_that_moved_is_rejected_after_the_drift_is_removed(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = mt.chamber(18)
    rows = runs["+z"].copy()
    half = len(rows) // 2
    tilt = np.radians(5)
    rows[half:, 1] += np.sin(tilt)  # knocked over by 5° halfway
    path = tmp_path / "moved.csv"
    path.write_text("temp,ax,ay,az\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows) + "\n")
    items = [i for i in ITEMS if not i.startswith("+z=")] + [f"+z={path}"]
    code, _, err = run(capsys, "thermal", *items, "--cal", base, "-o", tmp_path / "o.json")
    assert code == 3
    assert "moved.csv" in err
    assert "the unit moved" in err
    assert "after removing the fitted drift" in err


def test_a_base_without_a_temperature_needs_the_reference_temperature(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = tmp_path / "base.json"
    poses = [str(SAMPLE / n) for n in ("x.csv", "y.csv", "z.csv")]
    assert run(capsys, "solve", "--poses", *poses, "-o", base, "-q").code == 0
    code, _, err = run(capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "o.json")
    assert code == 2
    assert "--reference-temperature" in err
    code, _, err = run(
        capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "o.json", "--reference-temperature", "25"
    )
    assert code == 0, err


# -- apply ----------------------------------------------------------------------------------------


def _segment_errors(rows: np.ndarray, directions: np.ndarray) -> np.ndarray:
    means = rows.reshape(len(directions), -1, 3).mean(axis=1)
    errors: np.ndarray = np.linalg.norm(means - directions, axis=1)
    return errors


def test_apply_corrects_each_row_at_its_temperature(
    base: Path, fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    directions, _, _ = mt.check_capture()
    errors = {}
    for name, cal in (("base", base), ("thermal", fitted)):
        out = tmp_path / f"{name}.csv"
        code, _, err = run(capsys, "apply", "--cal", cal, THERMAL / "check.csv", "-o", out)
        assert code == 0, err
        data = np.loadtxt(out, delimiter=",", skiprows=1)
        errors[name] = _segment_errors(data[:, 1:], directions)
    noise = mt.NOISE / np.sqrt(100) * np.sqrt(3)  # a segment mean's vector error from noise alone
    assert np.sqrt(np.mean(errors["thermal"] ** 2)) < 2 * noise
    assert np.sqrt(np.mean(errors["base"] ** 2)) > 10 * noise


def test_apply_without_the_temperature_column_is_exit_2_naming_it(
    fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "apply", "--cal", fitted, SAMPLE / "x.csv", "-o", out)
    assert code == 2
    assert "no temperature column 'temp'" in err
    assert not out.exists()


def test_apply_clamps_rows_outside_the_range_with_one_warning(
    fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = _sweep_file(tmp_path / "hot.csv", np.array([20.0] * 5 + [75.0] * 3 + [-30.0] * 2))
    code, _, err = run(capsys, "apply", "--cal", fitted, capture, "-o", tmp_path / "o.csv")
    assert code == 0
    assert err.count("warning:") == 1
    assert "5 rows outside the calibrated temperature range" in err
    assert "clamped" in err


def test_calibration_apply_uses_the_dataframes_temperature_column(fitted: Path) -> None:
    pd = pytest.importorskip("pandas")
    cal = calfile.load(fitted)
    directions, _, rows = mt.check_capture()
    frame = pd.DataFrame(rows, columns=["temp", "ax", "ay", "az"])
    out = cal.apply(frame)
    assert list(out.columns) == ["temp", "ax", "ay", "az"]
    errors = _segment_errors(out[["ax", "ay", "az"]].to_numpy(), directions)
    assert np.sqrt(np.mean(errors**2)) < 2 * mt.NOISE / np.sqrt(100) * np.sqrt(3)
    array = cal.apply(rows[:, 1:], temperature=rows[:, 0])
    assert np.allclose(array, out[["ax", "ay", "az"]].to_numpy())
    with pytest.raises(InputError, match="give temperature="):
        cal.apply(rows[:, 1:])


# -- the file -------------------------------------------------------------------------------------


def test_the_thermal_block_round_trips_and_a_bad_one_names_its_field(fitted: Path, tmp_path: Path) -> None:
    cal = calfile.load(fitted)
    assert cal.thermal is not None
    again = tmp_path / "again.json"
    cal.save(again)
    assert json.loads(again.read_text()) == json.loads(fitted.read_text())
    doc = json.loads(fitted.read_text())
    doc["thermal"]["offset"] = [[1.0], [2.0], [3.0]]  # order 2 with one coefficient per axis
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"field 'thermal.offset' must be 3 lists of 2 numbers"):
        calfile.load(bad)


# -- show and check -------------------------------------------------------------------------------


def test_show_prints_the_drift_per_axis(fitted: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "show", fitted)
    assert code == 0
    assert "temperature drift (raw units), -10.0 to 60.1 °C against 25.00 °C" in out
    assert "offset per (T - T_ref)^2:" in out


def test_check_judges_the_offset_drift_over_the_range_and_per_degree(
    fitted: Path, base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    limits = tmp_path / "limits.yaml"
    limits.write_text("offset_drift: 0.012\n")
    code, _, err = run(capsys, "check", fitted, "--limits", limits)
    assert code == 1
    assert "limit.offset_drift.z: offset drifts by 0.0155 on z over the range, above 0.012" in err
    limits.write_text("offset_drift: 0.02\noffset_drift_per_degc: [0.001, 0.001, 0.001]\n")
    assert run(capsys, "check", fitted, "--limits", limits, "--quiet").code == 0
    code, _, err = run(capsys, "check", base, "--limits", limits)
    assert code == 2
    assert "has no thermal block to judge the offset_drift limits by" in err


# -- export ---------------------------------------------------------------------------------------


def _params(text: str, sep: str) -> dict[str, float]:
    out = {}
    for line in text.splitlines():
        if line.startswith("#"):
            continue
        cells = line.split(sep)
        name, value = (cells[0], cells[1]) if sep == "," else (cells[2], cells[3])
        out[name] = float(value)
    return out


def _drift_ms2(cal: calfile.Calibration, temps: np.ndarray) -> np.ndarray:
    """The offset drift in corrected m/s^2 (M @ drift x g) at clamped temperatures."""
    assert cal.thermal is not None
    off, _ = cal.thermal.drift().at(temps)
    drift: np.ndarray = 9.80665 * off @ cal.matrix.T
    return drift


def test_export_ardupilot_reproduces_the_drift_through_its_own_formula(
    fitted: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "export", fitted, "--format", "ardupilot", "--instance", "2")
    assert code == 0
    assert "gain drift NOT written" in out
    p = _params(out, ",")
    assert p["INS_TCAL2_ENABLE"] == 1
    cal = calfile.load(fitted)
    assert cal.thermal is not None
    assert p["INS_TCAL2_TMIN"] == pytest.approx(cal.thermal.range[0], abs=0.005)
    coeff = np.array([[p[f"INS_TCAL2_ACC{k}_{a}"] for k in (1, 2, 3)] for a in "XYZ"]) * 1e-6

    def poly(d: np.ndarray) -> np.ndarray:  # AP_InertialSensor_tempcal.cpp polynomial_eval
        value: np.ndarray = (coeff[:, 0] + (coeff[:, 1] + coeff[:, 2] * d[:, None]) * d[:, None]) * d[:, None]
        return value

    temps = np.array([-30.0, 0.0, 20.0, 45.0, 80.0])
    low, high = p["INS_TCAL2_TMIN"], p["INS_TCAL2_TMAX"]
    for caltemp in (25.0, 31.5):  # whatever temperature its own accel calibration was made at
        t = np.clip(temps, low, high)
        correction = poly(t - 35.0) - poly(np.full(len(t), np.clip(caltemp, low, high)) - 35.0)
        expected = _drift_ms2(cal, temps) - _drift_ms2(cal, np.array([caltemp]))
        assert np.allclose(correction, expected, atol=1e-6)


def test_export_px4_reproduces_the_drift_through_its_own_formula(
    fitted: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "export", fitted, "--format", "px4")
    assert code == 0
    p = _params(out, "\t")
    assert p["TC_A_ENABLE"] == 1
    assert "TC_A0_ID" not in p
    assert "set TC_A0_ID to the sensor's device id" in out
    temps = np.array([-30.0, 0.0, 20.0, 45.0, 80.0])
    d = np.clip(temps, p["TC_A0_TMIN"], p["TC_A0_TMAX"]) - p["TC_A0_TREF"]  # calc_thermal_offsets_3D
    x = np.array([[p[f"TC_A0_X{k}_{i}"] for k in range(4)] for i in range(3)])
    offset = x[:, 0] + x[:, 1] * d[:, None] + x[:, 2] * d[:, None] ** 2 + x[:, 3] * d[:, None] ** 3
    assert np.allclose(offset, _drift_ms2(calfile.load(fitted), temps), atol=1e-6)


def test_export_firmware_formats_write_the_thermal_block_where_there_is_one_and_need_known_units(
    base: Path, fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "export", base, "--format", "px4")  # no block: the offsets and scales
    assert code == 0
    assert "CAL_ACC0_XOFF" in out
    assert "TC_A0_X1_0" not in out
    assert "TC_A0_X1_0" in run(capsys, "export", fitted, "--format", "px4").out
    doc = json.loads(fitted.read_text())
    doc["units"] = "counts"
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps(doc))
    code, _, err = run(capsys, "export", odd, "--format", "ardupilot")
    assert code == 2
    assert "writes m/s^2: the calibration's corrected units are 'counts'" in err
    assert run(capsys, "export", fitted, "--format", "ardupilot", "--instance", "0").code == 2
    assert run(capsys, "export", fitted, "--format", "c-header", "--instance", "1").code == 2


@pytest.mark.slow
def test_c_header_apply_at_matches_calibration_apply(fitted: Path, tmp_path: Path) -> None:
    import shutil
    import subprocess

    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    header = tmp_path / "cal.h"
    from tumblecal_cli.cli import main

    assert main(["export", str(fitted), "--format", "c-header", "-o", str(header)]) == 0
    (tmp_path / "t.c").write_text(
        '#include <stdio.h>\n#include "cal.h"\nint main(void) {\n'
        "    float raw[3] = {0.5f, -0.2f, 1.1f}, out[3], temps[3] = {-20.0f, 40.0f, 70.0f};\n"
        "    int j;\n"
        '    for (j = 0; j < 3; j++) { tumblecal_accel_apply_at(raw, temps[j], out); printf("%.9g %.9g %.9g\\n", '
        "out[0], out[1], out[2]); }\n    return 0;\n}\n"
    )
    subprocess.run(
        ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-o", str(tmp_path / "t"), str(tmp_path / "t.c")],
        check=True,
        cwd=tmp_path,
    )
    got = np.loadtxt(
        subprocess.run([str(tmp_path / "t")], check=True, capture_output=True, text=True).stdout.splitlines()
    )
    want = calfile.load(fitted).apply(np.array([[0.5, -0.2, 1.1]] * 3), temperature=[-20.0, 40.0, 70.0])
    assert np.allclose(got, want, atol=1e-5)


# -- the Python API and a gyroscope -----------------------------------------------------------------


def test_the_api_fits_a_gyroscopes_bias_drift_from_captures_in_any_pose(tmp_path: Path) -> None:
    import tumblecal_cli as tumblecal

    rng = np.random.default_rng(4)
    drift1, drift2 = np.array([0.01, -0.02, 0.015]), np.array([2e-4, 1e-4, -3e-4])  # deg/s per °C, °C^2
    bias = np.array([0.5, -0.3, 0.2])
    files = []
    for k, (low, high) in enumerate(((0.0, 50.0), (45.0, -5.0))):
        temp = np.linspace(low, high, 3000)
        d = (temp - 20.0)[:, None]
        rate = bias + drift1 * d + drift2 * d**2 + rng.normal(0, 0.05, (len(temp), 3))
        path = tmp_path / f"gyro{k}.csv"
        lines = ["die_temp,gx,gy,gz"] + [
            f"{t:.3f},{r[0]:.5f},{r[1]:.5f},{r[2]:.5f}" for t, r in zip(temp, rate, strict=True)
        ]
        path.write_text("\n".join(lines) + "\n")
        files.append(str(path))
    base = tumblecal.solve([files[0]], sensor="gyroscope", units="deg/s").calibration
    assert base is not None
    done = tumblecal.thermal(files, base, reference_temperature=20.0)
    block = done.calibration.thermal
    assert block is not None
    assert block.column == "die_temp"
    assert block.order == 2
    assert block.gain_drift == ("unobserved", "unobserved", "unobserved")
    se = np.array(block.extra["uncertainty"]["offset"])  # type: ignore[index]
    assert np.all(np.abs(block.offset[:, 0] - drift1) < 4 * se[:, 0])
    assert np.all(np.abs(block.offset[:, 1] - drift2) < 4 * se[:, 1])
    assert "GYR1_X" in tumblecal.export(done.calibration, "ardupilot")
    # a gyroscope's sweeps labelled anyway: in any pose, so no pose is said of them anywhere
    from tests.conftest import tumblecal as tumblecal_cli_run

    base_file, moved = tmp_path / "gyro.json", tmp_path / "moved.csv"
    base.save(base_file)
    head, *rows = Path(files[1]).read_text().splitlines()
    jumped = [
        ",".join([t, *(f"{float(v) + 3.0:.5f}" for v in rest)]) for t, *rest in (r.split(",") for r in rows[1500:])
    ]
    moved.write_text("\n".join([head, *rows[:1500], *jumped]) + "\n")  # the unit moved half-way: a warning
    r = tumblecal_cli_run("thermal", f"+x={files[0]}", f"-z={moved}", "--cal", base_file, "--json",
                          "--reference-temperature", "20", "--max-noise", "1.6", "-o", tmp_path / "g.json")  # fmt: skip
    assert r.code in (0, 1), r.err
    warned = json.loads(r.out)["warnings"]
    assert [(w["code"], w["pose"]) for w in warned] == [("pose.moved", None)]
    assert [w["pose"] for w in json.loads((tmp_path / "g.json").read_text())["thermal"]["sweeps"]] == [None, None]


@pytest.mark.slow
def test_plot_draws_the_drift_and_writes_nothing_on_a_rejection(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("matplotlib")
    png = tmp_path / "drift.png"
    code, _, err = run(capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "c.json", "--plot", png, "-q")
    assert code == 0, err
    assert png.read_bytes().startswith(b"\x89PNG")
    flat = _sweep_file(tmp_path / "flat.csv", np.full(300, 25.0))
    png.unlink()
    assert run(capsys, "thermal", f"+z={flat}", "--cal", base, "-o", tmp_path / "d.json", "--plot", png).code == 3
    assert not png.exists()
    code, _, err = run(
        capsys, "thermal", *ITEMS, "--cal", base, "-o", tmp_path / "e.json", "--plot", tmp_path / "a.jpg"
    )
    assert code == 2
    assert "PNG" in err


def test_verify_reads_a_capture_at_its_own_temperature(
    base: Path, fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    hot = _sweep_file(tmp_path / "hot.csv", np.full(400, 55.0), face="+x")
    errors = {}
    for name, cal in (("base", base), ("thermal", fitted)):
        code, out, err = run(capsys, "verify", "--cal", cal, hot, "--json")
        assert code == 0, err
        errors[name] = abs(json.loads(out)["captures"][0]["error_after"])
    assert errors["thermal"] < 0.0005  # the mean of 400 samples of 2 mg noise
    assert errors["base"] > 0.005  # the drift at 55 °C: about 8 mg offset and 0.3 % gain on x


def test_a_longer_dwell_does_not_move_the_fit() -> None:
    """Every (sweep, temperature interval) counts once: dwelling 50 times longer at 25 °C leaves
    the coefficients where they were (an unweighted fit would be pulled towards that dwell)."""
    sweeps = _sweeps(5)
    longer = []
    for s in sweeps:
        near = np.abs(s.temperature - 25.0) < 0.5
        extra = np.repeat(np.flatnonzero(near), 50)
        rng = np.random.default_rng(9)
        values = s.values[extra] + rng.normal(0.0, mt.NOISE, (len(extra), 3))
        longer.append(
            drift.Sweep(np.vstack([s.values, values]), np.concatenate([s.temperature, s.temperature[extra]]), s.up)
        )
    one = drift.fit(sweeps, gain_scale=mt.GAIN * 1.0, t_ref=mt.T_REF, order=2)
    two = drift.fit(longer, gain_scale=mt.GAIN * 1.0, t_ref=mt.T_REF, order=2)
    assert np.all(np.abs(two.drift.offset - one.drift.offset) < 0.5 * one.offset_se)


def test_a_single_face_says_its_gain_drift_is_folded(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "one.json"
    code, _, err = run(capsys, "thermal", f"+z={THERMAL / 'sweep_up_zp.csv'}", "--cal", base, "-o", out)
    assert code == 0, err
    assert "note: gain drift of z folded into its offset drift" in err
    assert json.loads(out.read_text())["thermal"]["gain_drift"] == ["unobserved", "unobserved", "folded"]


def test_the_sensor_must_be_the_base_calibrations_and_the_block_survives_yaml(
    base: Path, fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(capsys, "thermal", *ITEMS, "--cal", base, "--sensor", "gyroscope", "-o", tmp_path / "g.json")
    assert code == 2
    assert "--sensor gyroscope, but the base calibration's sensor is accelerometer" in err
    cal = calfile.load(fitted)
    cal.save(tmp_path / "cal.yaml")
    again = calfile.load(tmp_path / "cal.yaml")
    assert again.thermal is not None
    assert cal.thermal is not None
    assert np.array_equal(again.thermal.offset, cal.thermal.offset)
    assert again.thermal.extra == cal.thermal.extra


@pytest.mark.parametrize("cell", ["nan", "inf"])
def test_apply_refuses_a_reading_at_no_temperature(
    fitted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], cell: str
) -> None:
    """nan and inf parse as numbers, but a row cannot be corrected at them (was: at T_ref, silently)."""
    capture = tmp_path / "c.csv"
    capture.write_text("temp,ax,ay,az\n20,0.01,0.02,1.0\n" + f"{cell},0.01,0.02,1.0\n" + "21,0.01,0.02,1.0\n" * 3000)
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "apply", "--cal", fitted, capture, "-o", out)
    assert code == 2
    assert f"temperature is not a finite number: '{cell}' (line 3, column temp)" in err
    assert not out.exists()

"""export --format ardupilot | px4 for plain calibrations (and the parameter files of a thermal
block): each firmware's own correction, written here in numpy float32 from its source, turns raw
readings into what ``Calibration.apply`` gives with the exported parameters; what a firmware
cannot hold is said with its size; units are converted; and each file is read as the tool users
load it with reads it (the parsers below are written from those tools' sources).

Sources (README "Parameters for autopilots" has them with commits):

- ArduPilot ``libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp``
  (``_rotate_and_correct_accel``, ``_rotate_and_correct_gyro``),
  ``libraries/AP_Compass/AP_Compass_Backend.cpp`` (``correct_field``).
- PX4 ``src/lib/sensor_calibration/{Accelerometer,Gyroscope,Magnetometer}.hpp`` (``Correct``)
  and ``Magnetometer.cpp`` (``set_scale``, ``set_offdiagonal``).
- Mission Planner ``ExtLibs/Utilities/ParamFile.cs`` (``loadParamFile``); pymavlink
  ``mavparm.py`` (``MAVParmDict.load``, MAVProxy's ``param load``); ArduPilot
  ``libraries/AP_Param/AP_Param.cpp`` (``parse_param_line``, ``read_param_defaults_file``);
  QGroundControl ``src/QmlControls/ParameterEditorController.cc`` (``buildDiffFromFile``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import POSES_3, ROOT, SAMPLE, assert_usage_error, run, run_exe
from tests.test_hostile_outputs import HOSTILE
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.calfiles.calfile import Calibration, Unit
from tumblecal_cli.io.export import paramfile
from tumblecal_cli.io.export.contract import Exported
from tumblecal_cli.pipeline import exchange

G = 9.80665
DATA_DIR = ROOT / "tests" / "data"
MAG_LOG = DATA_DIR / "ckexplorer_mag" / "acc_mag_every8.csv"
VEHICLES = DATA_DIR / "autopilot_params"
NCSU = {
    "+x": DATA_DIR / "ncsu_xplus_head.csv",
    **{
        f"{'+' if kind == 'plus' else '-'}{axis}": DATA_DIR / "ncsu_microstrain" / f"{axis}{kind}_head.csv"
        for axis in "xyz"
        for kind in ("plus", "minus")
        if (axis, kind) != ("x", "plus")
    },
}


# -- the firmwares' own corrections, float32 as on the vehicle -------------------------------------


def _vec(p: dict[str, float], *names: str) -> np.ndarray:
    return np.array([p[n] for n in names], dtype=np.float32)


def ardupilot_correct(sensor: str, p: dict[str, float], n: int, raw: np.ndarray) -> np.ndarray:
    """ArduPilot's correction of raw readings (m/s^2, rad/s, mGauss) with the parameters ``p``."""
    s = "" if n == 1 else str(n)
    raw = raw.astype(np.float32)
    if sensor == "accelerometer":  # _rotate_and_correct_accel: accel -= offset; accel.x *= scale.x ...
        off = _vec(p, *(f"INS_ACC{s}OFFS_{a}" for a in "XYZ"))
        scale = _vec(p, *(f"INS_ACC{s}SCAL_{a}" for a in "XYZ"))
        accel: np.ndarray = (raw - off) * scale
        return accel
    if sensor == "gyroscope":  # _rotate_and_correct_gyro: gyro -= _imu._gyro_offset(instance)
        gyro: np.ndarray = raw - _vec(p, *(f"INS_GYR{s}OFFS_{a}" for a in "XYZ"))
        return gyro
    # correct_field: mag += offsets; if (have_scale_factor) mag *= scale_factor; mag = mat * mag
    dia = _vec(p, *(f"COMPASS_DIA{s}_{a}" for a in "XYZ"))
    odi = _vec(p, *(f"COMPASS_ODI{s}_{a}" for a in "XYZ"))
    mag: np.ndarray = raw + _vec(p, *(f"COMPASS_OFS{s}_{a}" for a in "XYZ"))
    factor = np.float32(p[f"COMPASS_SCALE{s}"])
    if 1 / 1.5 <= factor <= 1.5:  # have_scale_factor: COMPASS_MIN/MAX_SCALE_FACTOR
        mag = mag * factor
    mat = np.array(
        [[dia[0], odi[0], odi[1]], [odi[0], dia[1], odi[2]], [odi[1], odi[2], dia[2]]], dtype=np.float32
    )  # Matrix3f mat(diagonals.x, offdiagonals.x, offdiagonals.y, ...)
    out: np.ndarray = mag @ mat.T
    return out


def px4_correct(sensor: str, p: dict[str, float], n: int, raw: np.ndarray) -> np.ndarray:
    """PX4's Correct() before its rotation, with the parameters ``p`` (m/s^2, rad/s, gauss)."""
    kind = {"accelerometer": "ACC", "gyroscope": "GYRO", "magnetometer": "MAG"}[sensor]
    head = f"CAL_{kind}{n}_"
    raw = raw.astype(np.float32)
    off = _vec(p, *(f"{head}{a}OFF" for a in "XYZ"))
    if sensor == "gyroscope":  # data - _thermal_offset - _offset
        gyro: np.ndarray = raw - off
        return gyro
    scale = _vec(p, *(f"{head}{a}SCALE" for a in "XYZ"))
    if sensor == "accelerometer":  # (data - _thermal_offset - _offset).emult(_scale)
        accel: np.ndarray = (raw - off) * scale
        return accel
    xy, xz, yz = _vec(p, *(f"{head}{a}ODIAG" for a in "XYZ"))  # set_offdiagonal: (0,1), (0,2), (1,2)
    matrix = np.array([[scale[0], xy, xz], [xy, scale[1], yz], [xz, yz, scale[2]]], dtype=np.float32)
    out: np.ndarray = (raw - off) @ matrix.T  # _scale * ((data + power compensation) - _offset)
    return out


def firmware_correct(fmt: str, sensor: str, p: dict[str, float], n: int, raw: np.ndarray) -> np.ndarray:
    return (ardupilot_correct if fmt == "ardupilot" else px4_correct)(sensor, p, n, raw)


# -- the loaders' parsers --------------------------------------------------------------------------


def mission_planner(text: str) -> dict[str, float]:
    """ParamFile.loadParamFile: a line starting with '#' skipped; split on ' ', ',' and tab
    (empty parts removed); exactly two parts, else skipped; double.Parse, which throws."""
    params = {}
    for line in re.split(r"\r\n|\r|\n", text.removesuffix("\n")):  # StreamReader.ReadLine
        if line.startswith("#"):
            continue
        items = [i for i in re.split(r"[ ,\t]", line) if i]
        if len(items) != 2:
            continue
        params[items[0]] = float(items[1])  # a FormatException stops the whole load
    return params


def mavproxy(text: str) -> tuple[dict[str, float], list[str]]:
    """pymavlink MAVParmDict.load: stripped; empty or '#'-first skipped; ',' made ' '; split;
    two parts, else "Invalid line" (returned); float() of the value."""
    params, invalid = {}, []
    for raw_line in text.splitlines():
        line = raw_line.strip()
        if not line or line[0] == "#":
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 2:
            invalid.append(line)
            continue
        params[parts[0]] = float(parts[1])
    return params, invalid


def ardupilot_defaults(text: str) -> dict[str, float]:
    """AP_Param::read_param_defaults_file: fgets into char line[100] with sizeof(line)-1, so a
    line is read in pieces of up to 98 bytes; parse_param_line skips a piece starting with '#'
    and takes the first two tokens split on ", =\\t\\r\\n", the value by strtof (its longest
    number prefix, else 0), as a float parameter."""
    params = {}
    data = text.encode()
    while data:
        end = data.find(b"\n")
        cut = 98 if end < 0 or end + 1 > 98 else end + 1
        piece, data = data[:cut], data[cut:]
        if piece.startswith(b"#"):
            continue
        tokens = [t for t in re.split(rb"[, =\t\r\n]", piece) if t]
        if len(tokens) < 2 or len(tokens[0]) > 16:  # AP_MAX_NAME_SIZE
            continue
        number = re.match(rb"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", tokens[1])
        params[tokens[0].decode()] = float(np.float32(float(number[0]) if number else 0.0))
    return params


def qgc(text: str) -> tuple[dict[str, float], list[tuple[int, int, int]]]:
    """ParameterEditorController::buildDiffFromFile: a line not starting with '#' split on tab;
    five fields: vehicle id, component id, name, value, MAV_PARAM_TYPE; other lines skipped."""
    params, ids = {}, []
    for line in text.splitlines():  # QTextStream::readLine on a QIODevice::Text file
        if line.startswith("#"):
            continue
        fields = line.split("\t")
        if len(fields) != 5:
            continue
        params[fields[2]] = float(fields[3])
        ids.append((int(fields[0]), int(fields[1]), int(fields[4])))
    return params, ids


def loaded(text: str, fmt: str) -> dict[str, float]:
    """The parameters every loader of ``fmt`` reads, checked to be the same."""
    if fmt == "px4":
        params, ids = qgc(text)
        assert set(ids) == {(1, 1, 9)} or set(ids) == {(1, 1, 9), (1, 1, 6)}
        return params
    mp = mission_planner(text)
    mav, invalid = mavproxy(text)
    assert invalid == []
    assert mav == mp
    defaults = ardupilot_defaults(text)
    assert defaults.keys() == mp.keys()
    assert all(defaults[k] == np.float32(v) for k, v in mp.items())
    return mp


def assert_loadable(text: str) -> None:
    """Every line is a parameter or a comment every loader skips: ASCII, at most 97 characters."""
    assert text.isascii()
    for line in text.splitlines():
        assert len(line) <= 97, line
        assert line.startswith("#") or re.fullmatch(r"[A-Z0-9_]+,[-0-9.e+]+|1\t1\t[A-Z0-9_]+\t[-0-9.e+]+\t[69]", line)


# -- calibrations ------------------------------------------------------------------------------


def calibration(
    sensor: str, units: tuple[str, str], offset: list[float], matrix: np.ndarray, **kw: object
) -> Calibration:
    """A calibration as solve writes one (raw units in ``units[0]``, corrected in ``units[1]``)."""
    method = str(
        kw.pop("method", {"accelerometer": "six-pose", "magnetometer": "ellipsoid", "gyroscope": "turns"}[sensor])
    )
    reference = float(kw.pop("reference", {"accelerometer": 1.0, "magnetometer": 50.0, "gyroscope": 0.0}[sensor]))  # type: ignore[arg-type]
    return Calibration(
        sensor=sensor,
        method=method,
        reference=reference,
        columns=["x", "y", "z"],
        offset=np.array(offset, dtype=float),
        matrix=matrix,
        gain=np.diag(np.linalg.inv(matrix)),
        units=units[1],
        input_units=units[0],
        path="cal.json",
        unit=kw.pop("unit", None),  # type: ignore[arg-type]
    )


SOFT_IRON = np.array([[1.05, 0.03, -0.02], [0.03, 0.97, 0.04], [-0.02, 0.04, 1.01]])
#: What each firmware holds exactly: a diagonal accelerometer matrix, a symmetric magnetometer
#: matrix, a gyroscope's offsets; each in units the firmware converts from.
EXACT = {
    "accelerometer": calibration(
        "accelerometer", ("g", "g"), [0.021, -0.034, 0.047], np.diag(1 / np.array([1.012, 0.987, 1.005]))
    ),
    "magnetometer": calibration("magnetometer", ("uT", "uT"), [12.0, -25.0, 30.0], np.linalg.inv(SOFT_IRON)),
    "gyroscope": calibration("gyroscope", ("deg/s", "deg/s"), [0.5, -0.3, 0.2], np.eye(3), method="gyro-bias"),
}
#: units to m/s^2, rad/s and gauss; ArduPilot's compass takes mGauss (COMPASS_OFS @Units)
TO_BASE = {"g": G, "m/s^2": 1.0, "deg/s": math.pi / 180, "rad/s": 1.0, "uT": 0.01, "mG": 0.001, "gauss": 1.0}


def to_firmware(fmt: str, sensor: str, units: str | None) -> float:
    return TO_BASE[units or ""] * (1000.0 if (fmt, sensor) == ("ardupilot", "magnetometer") else 1.0)


def raw_readings(cal: Calibration, n: int = 500, seed: int = 3) -> np.ndarray:
    """Raw readings of the calibrated unit: stimuli of the reference's size (rates up to 200
    deg/s for a gyroscope) in every direction, through A = M^-1 and the offset."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    size = cal.reference if cal.reference > 0 else rng.uniform(0, 200, (n, 1))
    raw: np.ndarray = (u * size) @ np.linalg.inv(cal.matrix).T + cal.offset
    return raw


def through_firmware(cal: Calibration, fmt: str, instance: int) -> tuple[np.ndarray, np.ndarray, Exported]:
    """(what the firmware makes of raw readings with the exported parameters, in the
    calibration's units; what Calibration.apply makes of them; the file)."""
    written = paramfile.write(cal, fmt, instance)
    params = loaded(written.text, fmt)
    k_in, k_out = (to_firmware(fmt, cal.sensor, u) for u in (cal.input_units or cal.units, cal.units))
    raw = raw_readings(cal)
    got = firmware_correct(fmt, cal.sensor, params, instance, raw * k_in).astype(np.float64) / k_out
    return got, cal.apply(raw), written


# -- the firmwares' formulas ---------------------------------------------------------------------


@pytest.mark.parametrize("sensor", ["accelerometer", "magnetometer", "gyroscope"])
@pytest.mark.parametrize(("fmt", "instance"), [("ardupilot", 1), ("ardupilot", 2), ("px4", 0), ("px4", 1)])
def test_the_firmwares_own_correction_with_the_exported_parameters_equals_apply(
    sensor: str, fmt: str, instance: int
) -> None:
    cal = EXACT[sensor]
    got, want, written = through_firmware(cal, fmt, instance)
    scale = np.abs(raw_readings(cal)).max() + np.abs(cal.offset).max()
    assert np.abs(got - want).max() <= 4e-7 * scale  # float32: 6e-8 of each term
    assert not [n for n in written.notes if n.startswith("warning:")]


def test_the_units_are_converted_to_the_firmwares() -> None:
    """g to m/s^2 (×9.80665), µT to mGauss (×10, ArduPilot) and gauss (×0.01, PX4), deg/s to rad/s."""
    acc = loaded(paramfile.write(EXACT["accelerometer"], "px4", 0).text, "px4")
    assert acc["CAL_ACC0_XOFF"] == pytest.approx(0.021 * G)
    assert acc["CAL_ACC0_YSCALE"] == pytest.approx(0.987**-1)
    ap = loaded(paramfile.write(EXACT["magnetometer"], "ardupilot", 1).text, "ardupilot")
    assert [ap[f"COMPASS_OFS_{a}"] for a in "XYZ"] == pytest.approx([-120.0, 250.0, -300.0])  # added: -b
    assert ap["COMPASS_SCALE"] == 1
    mag = loaded(paramfile.write(EXACT["magnetometer"], "px4", 0).text, "px4")
    assert [mag[f"CAL_MAG0_{a}OFF"] for a in "XYZ"] == pytest.approx([0.12, -0.25, 0.30])
    inv = np.linalg.inv(SOFT_IRON)
    assert [mag["CAL_MAG0_XODIAG"], mag["CAL_MAG0_YODIAG"], mag["CAL_MAG0_ZODIAG"]] == pytest.approx(
        [inv[0, 1], inv[0, 2], inv[1, 2]]
    )
    gyr = loaded(paramfile.write(EXACT["gyroscope"], "ardupilot", 3).text, "ardupilot")
    assert gyr["INS_GYR3OFFS_X"] == pytest.approx(math.radians(0.5))
    text = paramfile.write(EXACT["accelerometer"], "ardupilot", 1).text
    assert "# units: g in and out, x 9.80665 to m/s^2" in text
    mixed = calibration("magnetometer", ("mG", "uT"), [120.0, -250.0, 300.0], np.linalg.inv(SOFT_IRON) / 10)
    got, want, written = through_firmware(mixed, "px4", 0)
    assert np.abs(got - want).max() < 1e-4  # µT
    assert "# units: raw mG x 0.001, corrected uT x 0.01, to gauss" in written.text


# -- what a firmware cannot hold ---------------------------------------------------------------


def _rotation(degrees: float, axis: tuple[float, float, float]) -> np.ndarray:
    k = np.array(axis) / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    t = math.radians(degrees)
    out: np.ndarray = np.eye(3) + math.sin(t) * cross + (1 - math.cos(t)) * cross @ cross
    return out


@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
def test_a_magnetometer_matrix_that_is_not_symmetric_loses_its_rotation_with_a_warning(fmt: str) -> None:
    """M = R(2°) P: DIA/ODI (ODIAG) hold P; the field's length is kept, its direction turned 2°."""
    symmetric = np.linalg.inv(SOFT_IRON)
    cal = calibration("magnetometer", ("uT", "uT"), [12.0, -25.0, 30.0], _rotation(2.0, (1, 2, 3)) @ symmetric)
    got, want, written = through_firmware(cal, fmt, 1 if fmt == "ardupilot" else 0)
    (warning,) = [n for n in written.notes if n.startswith("warning:")]
    assert warning.startswith("warning: a 2 deg rotation NOT written")
    size = "17.5 mGauss at 500 mGauss" if fmt == "ardupilot" else "0.0175 gauss at 0.5 gauss"  # 2 sin(1°) of 50 µT
    assert warning.endswith(
        f"the field's direction is off by up to 2 deg, 3.490% ({size}) of it, its length not at all"
    )
    assert "# a 2 deg rotation NOT written" in written.text
    assert np.allclose(np.linalg.norm(got, axis=1), np.linalg.norm(want, axis=1), rtol=1e-5)
    cos = np.sum(got * want, axis=1) / np.linalg.norm(got, axis=1) / np.linalg.norm(want, axis=1)
    turned = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert 1.9 < turned.max() <= 2.0001


@pytest.mark.slow
def test_an_accelerometers_cross_axis_terms_are_dropped_with_their_size_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A real six-pose calibration (NCSU MicroStrain, six faces): ArduPilot and PX4 keep one
    scale per axis; the warning's bound is what the firmware's readings of a 1 g stimulus in any
    direction miss Calibration.apply by."""
    out = tmp_path / "six.json"
    poses = [f"{face}={path}" for face, path in NCSU.items()]
    r = run(capsys, "solve", "-q", "--method", "six-pose", "--max-noise", "0.05", "--poses", *poses, "-o", out)
    assert r.code == 0, r.err
    cal = calfile.load(out)
    assert np.abs(cal.matrix - np.diag(np.diag(cal.matrix))).max() > 1e-4  # real cross-axis terms
    for fmt, instance in (("ardupilot", 1), ("px4", 0)):
        r = run(capsys, "export", out, "--format", fmt)
        assert r.code == 0, r.err
        (warning,) = [ln for ln in r.err.splitlines() if ln.startswith("warning:")]
        found = re.fullmatch(
            r"warning: cross-axis terms \(the reading's length is off by up to ([0-9.]+)% \(([0-9.]+) m/s\^2 at "
            r"9.80665 m/s\^2\)\) and a ([0-9.]+) deg rotation to the poses' frame \(level the board with "
            r"(AHRS_TRIM_X/Y|SENS_BOARD_X_OFF/Y_OFF)\) NOT written \((ArduPilot|PX4) has one scale per axis\)",
            warning,
        )
        assert found, warning
        bound, degrees = float(found[1]) / 100, float(found[3])
        assert float(found[2]) == pytest.approx(bound * G, rel=2e-3)
        got, want, _ = through_firmware(cal, fmt, instance)
        length = np.abs(np.linalg.norm(got, axis=1) / np.linalg.norm(want, axis=1) - 1).max()
        assert 0.5 * bound < length <= bound * 1.001 + 1e-6
        w, _, vt = np.linalg.svd(cal.matrix)
        assert degrees == pytest.approx(np.degrees(np.arccos((np.trace(w @ vt) - 1) / 2)), rel=2e-3)


@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
def test_a_gyroscopes_scale_is_dropped_with_its_size_said(fmt: str) -> None:
    cal = calibration("gyroscope", ("rad/s", "rad/s"), [0.01, -0.02, 0.005], np.diag([1.01, 0.99, 1.0]))
    got, want, written = through_firmware(cal, fmt, 1 if fmt == "ardupilot" else 0)
    (warning,) = [n for n in written.notes if n.startswith("warning:")]
    assert "scale and cross-axis terms NOT written" in warning
    assert warning.endswith("the rate is off by up to 1.010% of it")
    missed = (np.linalg.norm(got - want, axis=1) / np.linalg.norm(want, axis=1)).max()
    assert 0.009 < missed <= 0.0102
    note = "measures INS_GYROFFS again at each boot" if fmt == "ardupilot" else "IMU_GYRO_CAL_EN"
    assert any(note in n for n in written.notes)


def test_values_outside_the_firmwares_ranges_are_warned_of() -> None:
    acc = calibration("accelerometer", ("m/s^2", "m/s^2"), [4.0, 0.0, 0.0], np.diag([1.3, 1.0, 1.0]))
    notes = paramfile.write(acc, "ardupilot", 1).notes
    assert "warning: INS_ACCOFFS_X = 4 is outside ArduPilot's range for it, -3.5 to 3.5" in notes
    assert "warning: INS_ACCSCAL_X = 1.3 is outside ArduPilot's range for it, 0.8 to 1.2" in notes
    zero = calibration("accelerometer", ("m/s^2", "m/s^2"), [0.0, 0.0, 0.0], np.diag([1.01, 1.0, 1.0]))
    (warning,) = paramfile.write(zero, "ardupilot", 1).notes
    assert warning.startswith("warning: ArduPilot reads offsets of exactly 0 as an accelerometer never calibrated")
    mag = calibration("magnetometer", ("mG", "mG"), [1500.0, 1500.0, 0.0], np.eye(3), reference=500.0)
    (warning,) = paramfile.write(mag, "ardupilot", 1).notes
    assert warning.startswith("warning: COMPASS_OFS is 2121 mGauss long, above COMPASS_OFFS_MAX's default 1800")
    wide = calibration("magnetometer", ("gauss", "gauss"), [0.1, 0.1, 0.0], np.diag([3.5, 1, 1]), reference=0.5)
    assert (
        "warning: CAL_MAG2_XSCALE = 3.5 is outside PX4's range for it, 0.1 to 3"
        in paramfile.write(wide, "px4", 2).notes
    )


# -- what cannot be exported -------------------------------------------------------------------


def test_what_cannot_be_exported_is_exit_2_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "--poses", *POSES_3, "-o", cal).code == 0
    r = run(capsys, "export", cal, "--format", "px4", "--instance", "4")
    assert_usage_error(r, "--instance for px4 is 0 to 3", "got 4")
    assert_usage_error(run(capsys, "export", cal, "--format", "ardupilot", "--instance", "0"), "1 to 3")
    counts = tmp_path / "counts.json"
    imucal = [str(SAMPLE / "imucal" / f"{f}.csv") for f in ("xp", "xn", "yp", "yn", "zp", "zn")]
    args = ["--reference", "9.81", "--units", "m/s^2", "--input-units", "counts"]
    assert run(capsys, "solve", "-q", "--poses", *imucal, *args, "-o", counts).code == 0
    r = run(capsys, "export", counts, "--format", "ardupilot")
    assert_usage_error(r, "ArduPilot corrects readings in m/s^2", "raw units are 'counts'")
    doc = calfile.load(cal).to_dict() | {"units": None, "input_units": None, "sensor": "magnetometer"}
    calfile.write(doc, str(tmp_path / "mag.json"))
    r = run(capsys, "export", tmp_path / "mag.json", "--format", "px4")
    assert_usage_error(r, "writes gauss: the calibration's corrected units are not recorded")
    mirror = calibration("accelerometer", ("g", "g"), [0, 0, 0], np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(InputError, match=r"mirrors the axes \(det M <= 0\)"):
        paramfile.write(mirror, "px4", 0)
    unknown = calibration("accelerometer", ("counts?", "g"), [0, 0, 0], np.eye(3))
    with pytest.raises(InputError, match="raw units are 'counts\\?'"):
        paramfile.write(unknown, "ardupilot", 1)
    far = calibration("accelerometer", ("", "g"), [0, 0, 0], np.eye(3) / 2048)
    with pytest.raises(InputError, match="does not say its raw units, and its gains \\(2048, 2048, 2048\\)"):
        paramfile.write(far, "ardupilot", 1)


# -- the loaders ---------------------------------------------------------------------------------


@pytest.mark.parametrize("sensor", ["accelerometer", "magnetometer", "gyroscope"])
@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_a_hostile_serial_or_file_name_adds_no_parameter(sensor: str, fmt: str, text: str) -> None:
    """Comment lines are ASCII and short, so no loader reads one as a parameter, whatever the
    serial, station, operator or file name (ArduPilot's defaults reader cuts lines at 98 bytes)."""
    clean = paramfile.write(EXACT[sensor], fmt, 1)
    hostile = calibration(
        sensor,
        (EXACT[sensor].input_units or "", EXACT[sensor].units or ""),
        list(EXACT[sensor].offset),
        EXACT[sensor].matrix,
        method=EXACT[sensor].method,
        unit=Unit(serial=text + " INS_ACCOFFS_X,9 " * 8, station=text, operator=text),
    )
    hostile = Calibration(**{**hostile.__dict__, "path": f"a{text}\n1\t1\tCAL_ACC0_XOFF\t9\t9\nINS_ACCOFFS_X,9.json"})
    written = paramfile.write(hostile, fmt, 1)
    assert_loadable(written.text)
    assert loaded(written.text, fmt) == loaded(clean.text, fmt)


def test_comment_lines_are_what_each_loader_skips() -> None:
    """A line starting with '#' is skipped by Mission Planner, MAVProxy, ArduPilot's defaults
    reader and QGroundControl; a line longer than 98 bytes is read by ArduPilot in pieces."""
    long = "# " + "x" * 96 + "INS_ACCOFFS_X,5\n"
    assert ardupilot_defaults(long) == {"INS_ACCOFFS_X": 5.0}  # why comments are kept to 97
    assert mission_planner(long) == {}
    assert mavproxy(long) == ({}, [])
    for fmt, sensor in (("ardupilot", "magnetometer"), ("px4", "accelerometer")):
        text = paramfile.write(EXACT[sensor], fmt, 1).text
        assert text.startswith("# ")
        assert_loadable(text)


# -- thermal blocks: the same loaders -------------------------------------------------------------


@pytest.fixture(scope="module")
def thermal_cal(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tumblecal_cli.cli import main

    folder = tmp_path_factory.mktemp("thermal")
    thermal = SAMPLE / "thermal"
    poses = [str(thermal / f"{n}.csv") for n in ("xp", "xn", "yp", "yn", "zp", "zn")]
    assert main(["solve", "--poses", *poses, "-o", str(folder / "base.json"), "--quiet"]) == 0
    sweeps = {"+x": "up_xp", "-x": "down_xn", "+y": "up_yp", "-y": "down_yn", "+z": "up_zp", "-z": "down_zn"}
    items = [f"{face}={thermal / f'sweep_{name}.csv'}" for face, name in sweeps.items()]
    out = folder / "warm.json"
    assert main(["thermal", *items, "--cal", str(folder / "base.json"), "-o", str(out), "--quiet"]) == 0
    return out


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["ardupilot", "px4"])
def test_a_thermal_block_exports_as_before_with_short_comments_and_a_warning(
    thermal_cal: Path, fmt: str, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "export", thermal_cal, "--format", fmt)
    assert r.code == 0, r.err
    assert_loadable(r.out)
    params = loaded(r.out, fmt)
    assert ("INS_TCAL1_ACC1_X" if fmt == "ardupilot" else "TC_A0_X1_0") in params
    assert r.err.startswith("warning: gain drift NOT written (the firmware has no temperature-dependent scale)")
    assert "# gain drift NOT written" in r.out


# -- real vehicles: the names exist, and their own calibrations come back -----------------------


def vehicle_params(name: str) -> dict[str, tuple[str, float]]:
    """A real vehicle's parameters (tests/data/autopilot_params): name -> (type, value)."""
    text = (VEHICLES / name).read_text()
    if name.endswith(".parm"):
        return {k: ("float", v) for k, v in mission_planner(text).items()}
    rows = (line.split(" ") for line in text.splitlines())
    return {n: (t, float(v)) for t, n, v in rows}


def test_the_names_written_are_parameters_of_real_vehicles() -> None:
    """A real ArduCopter's 772 parameters and a real PX4 1.12.3's (those its logger recorded)
    hold every name the export writes (but COMPASS_SCALE, which ArduPilot added later)."""
    ardupilot, px4 = vehicle_params("ardupilot_copter.parm"), vehicle_params("px4_fmu_v5.txt")
    for cal in EXACT.values():
        for n in (1, 2, 3):
            names = loaded(paramfile.write(cal, "ardupilot", n).text, "ardupilot").keys()
            assert {k for k in names if not k.startswith("COMPASS_SCALE")} <= ardupilot.keys(), (cal.sensor, n)
        for n in (0, 1):
            names = loaded(paramfile.write(cal, "px4", n).text, "px4").keys()
            assert {px4[k][0] for k in names} == {"float"}, (cal.sensor, n)


def test_a_real_vehicles_own_calibration_exports_back_as_its_parameters() -> None:
    """The vehicles' calibrations read into tumblecal's model by each firmware's formula
    (ArduPilot: M = DIA/ODI, b = -COMPASS_OFS; M = diag(INS_ACCSCAL), b = INS_ACCOFFS; PX4:
    M = S, b = CAL_MAG_xOFF) export as the numbers they came from."""
    ap = {k: v for k, (_, v) in vehicle_params("ardupilot_copter.parm").items()}
    px4 = {k: v for k, (_, v) in vehicle_params("px4_fmu_v5.txt").items()}

    def sym(d: list[float], o: list[float]) -> np.ndarray:
        return np.array([[d[0], o[0], o[1]], [o[0], d[1], o[2]], [o[1], o[2], d[2]]])

    cases = [
        (
            calibration(
                "magnetometer",
                ("mG", "mG"),
                [-ap[f"COMPASS_OFS2_{a}"] for a in "XYZ"],
                sym([ap[f"COMPASS_DIA2_{a}"] for a in "XYZ"], [ap[f"COMPASS_ODI2_{a}"] for a in "XYZ"]),
                reference=500.0,
            ),
            "ardupilot",
            2,
            {k: v for k, v in ap.items() if re.fullmatch(r"COMPASS_(OFS|DIA|ODI)2_[XYZ]", k)},
        ),
        (
            calibration(
                "accelerometer",
                ("m/s^2", "m/s^2"),
                [ap[f"INS_ACC2OFFS_{a}"] for a in "XYZ"],
                np.diag([ap[f"INS_ACC2SCAL_{a}"] for a in "XYZ"]),
                reference=G,
            ),
            "ardupilot",
            2,
            {k: v for k, v in ap.items() if re.fullmatch(r"INS_ACC2(OFFS|SCAL)_[XYZ]", k)},
        ),
        (
            calibration(
                "magnetometer",
                ("gauss", "gauss"),
                [px4[f"CAL_MAG1_{a}OFF"] for a in "XYZ"],
                sym([px4[f"CAL_MAG1_{a}SCALE"] for a in "XYZ"], [px4[f"CAL_MAG1_{a}ODIAG"] for a in "XYZ"]),
                reference=0.5,
            ),
            "px4",
            1,
            {k: v for k, v in px4.items() if re.fullmatch(r"CAL_MAG1_[XYZ](OFF|SCALE|ODIAG)", k)},
        ),
    ]
    for cal, fmt, n, theirs in cases:
        written = paramfile.write(cal, fmt, n)
        ours = loaded(written.text, fmt)
        assert {k: np.float32(ours[k]) for k in theirs} == {k: np.float32(v) for k, v in theirs.items()}
        assert not [x for x in written.notes if x.startswith("warning:")]


# -- end to end, the installed command on calibrations made from sample data -----------------------


@pytest.mark.slow
def test_the_installed_command_exports_what_apply_corrects(tmp_path: Path) -> None:
    """sample_data's three poses (g) → .parm and .params; the firmware's formula on
    sample_data/capture.csv in m/s^2 is what `tumblecal apply` writes, x 9.80665."""
    cal, corrected = tmp_path / "cal.json", tmp_path / "corrected.csv"
    assert run_exe(["solve", "-q", "--poses", *POSES_3, "-o", cal]).returncode == 0
    assert run_exe(["apply", "--cal", cal, SAMPLE / "capture.csv", "-o", corrected]).returncode == 0
    raw = np.loadtxt(SAMPLE / "capture.csv", delimiter=",", skiprows=1)[:, 1:]
    want = np.loadtxt(corrected, delimiter=",", skiprows=1)[:, 1:]
    for fmt, instance, name in (("ardupilot", 2, "imu.parm"), ("px4", 1, "imu.params")):
        done = run_exe(["export", cal, "--format", fmt, "--instance", str(instance), "-o", tmp_path / name], text=True)
        assert done.returncode == 0, done.stderr
        assert done.stderr == "note: raw units not recorded: taken as g, as the gains near 1 say\n"
        text = (tmp_path / name).read_text()
        assert_loadable(text)
        got = firmware_correct(fmt, "accelerometer", loaded(text, fmt), instance, raw * G) / G
        assert np.abs(got - want).max() < 2e-6
    mag = tmp_path / "mag.json"
    args = ["--sensor", "magnetometer", "--units", "gauss", "--input-units", "gauss", "--reference", "0.3"]
    assert run_exe(["solve", "-q", *args, "--poses", MAG_LOG, "-o", mag]).returncode == 0
    real = calfile.load(mag)
    samples = np.loadtxt(MAG_LOG, delimiter=",", skiprows=1)[:, 3:]
    for fmt, instance, k in (("ardupilot", 1, 1000.0), ("px4", 0, 1.0)):
        done = run_exe(["export", mag, "-f", fmt, "--instance", str(instance)], text=True)
        assert done.returncode == 0, done.stderr
        assert done.stderr == ""  # a real ellipsoid fit is symmetric: nothing lost
        got = firmware_correct(fmt, "magnetometer", loaded(done.stdout, fmt), instance, samples * k) / k
        assert np.abs(got - real.apply(samples)).max() < 2e-6


def test_the_api_gives_the_text_and_the_notes_apart() -> None:
    cal = calibration("gyroscope", ("rad/s", "rad/s"), [0.01, -0.02, 0.005], np.diag([1.01, 0.99, 1.0]))
    done = exchange.exported(cal, "px4", instance=3)
    assert done.text == exchange.export(cal, "px4", instance=3)
    assert done.notes[0].startswith("warning: scale and cross-axis terms NOT written (PX4 takes")
    assert "CAL_GYRO3_XOFF" in done.text


def test_a_zero_is_written_0_never_minus_0() -> None:
    """A zero offset negated (ArduPilot's offsets are added) was written `-0`."""
    assert paramfile._value(-0.0, "COMPASS_OFS_X", None) == "0"
    assert paramfile._value(-1.5, "COMPASS_OFS_X", None) == "-1.5"

"""Sensor frames (issue "Real recordings, round 3", item 2): ``--axes`` states the body's axes in the
sensor's; a calibration keeps its offsets in the sensor's raw axes and corrects into the body's;
``align`` finds a rotation of any size and names the ``--axes`` that states it; the autopilot
exports carry it as their orientation parameter. Real data: furbrain's SAP6 unit "BB"
(tests/data/furbrain_sap, Unlicense), whose magnetometer is its accelerometer turned 180° about a
diagonal (the device maps them "+X+Y-Z" and "-Y-X+Z")."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import ROOT, assert_one_error, run
from tests.test_align import FIELD, UP, poses
from tumblecal_cli.core import alignment
from tumblecal_cli.core import axes as sensor_axes
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.export.paramfile import rotation_value

SAP = Path(__file__).resolve().parent / "data" / "furbrain_sap"
SHOTS = SAP / "sap6_BB_shots.csv"
#: The device's own axes of each sensor (SOURCE.md: device X, Y, Z = these sensor axes).
DEVICE_AXES = {"accelerometer": "-y,-x,+z", "magnetometer": "+x,+y,-z"}


def _device_dip_spread() -> float:
    """The spread of the dip over the 24 shots through the instrument's own calibration
    ((axes-mapped raw - centre) @ transform; SOURCE.md)."""
    with SHOTS.open(newline="") as shots:
        rows = list(csv.DictReader(shots))
    device = json.loads((SAP / "sap6_BB_device_cal.json").read_text())["calib"]

    def calibrated(keys: tuple[str, str, str], part: str) -> FloatArray:
        raw = np.array([[float(r[k]) for k in keys] for r in rows])
        mapped = raw @ sensor_axes.parse(device[part]["axes"]).matrix.T
        out: FloatArray = (mapped - np.array(device[part]["centre"])) @ np.array(device[part]["transform"])
        unit: FloatArray = out / np.linalg.norm(out, axis=1)[:, None]
        return unit

    g, field = calibrated(("ax", "ay", "az"), "grav"), calibrated(("mx", "my", "mz"), "mag")
    return float(np.std(np.degrees(np.arcsin(np.einsum("ij,ij->i", g, field)))))


def _solved(capsys: pytest.CaptureFixture[str], out: Path, sensor: str, axes: str | None) -> Path:
    columns = "ax,ay,az" if sensor == "accelerometer" else "mx,my,mz"
    given = ["--axes", axes] if axes else []
    accel = sensor == "accelerometer"
    given += ["--units", "m/s^2", "--reference", "9.80665"] if accel else ["--units", "uT", "--reference", "43.38"]
    r = run(capsys, "solve", "--sensor", sensor, "--poses", SHOTS, "--columns", columns, *given, "-o", out, "-q")
    assert r.code == 0, r.err
    return out


def test_axes_parse_both_spellings_and_refuse_an_axis_named_twice() -> None:
    a = sensor_axes.parse("-y,-x,+z")
    assert a == sensor_axes.parse("-Y-X+Z") == sensor_axes.parse("-y -x z")
    assert a.text == "-y,-x,+z"
    assert np.array_equal(a.matrix @ np.array([1.0, 2.0, 3.0]), [-2.0, -1.0, 3.0])  # body = P sensor
    assert a.mirrors
    assert not sensor_axes.parse("-y,+x,+z").mirrors
    assert a.sensor_label("+x") == "-y"
    assert a.sensor_label("-z") == "-z"
    for bad in ("-y,-y,+z", "x,y", "+x,+q,+z"):
        with pytest.raises(ValueError, match=r"sensor axes|named twice"):
            sensor_axes.parse(bad)
    assert len(sensor_axes.every()) == 24
    assert len(sensor_axes.every(mirrored=None)) == 48


def test_every_rotation_of_the_axes_has_its_autopilot_orientation_and_no_mirror_has() -> None:
    values = [rotation_value(a) for a in sensor_axes.every()]
    assert None not in values
    assert len(set(values)) == 24
    assert rotation_value(sensor_axes.parse("-y,+x,+z")) == 2  # ROTATION_YAW_90: x = -y, y = x (ArduPilot's rotate)
    assert rotation_value(sensor_axes.parse("+x,-y,-z")) == 8  # ROTATION_ROLL_180
    assert all(rotation_value(a) is None for a in sensor_axes.every(mirrored=True))


def _six_faces(tmp_path: Path, axes: sensor_axes.Axes, offset: FloatArray) -> list[str]:
    """Six pose files named by the body's faces, read by a sensor mounted with ``axes``."""
    rng = np.random.default_rng(4)
    items = []
    for face, up in (
        ("+x", [1, 0, 0]),
        ("-x", [-1, 0, 0]),
        ("+y", [0, 1, 0]),
        ("-y", [0, -1, 0]),
        ("+z", [0, 0, 1]),
        ("-z", [0, 0, -1]),
    ):
        sensor = axes.matrix.T @ np.array(up, dtype=float) + offset
        path = tmp_path / f"pose{face}.csv"
        rows = sensor + rng.normal(size=(200, 3)) * 0.002
        path.write_text("ax,ay,az\n" + "".join(f"{a:.6f},{b:.6f},{c:.6f}\n" for a, b, c in rows))
        items.append(f"{face}={path}")
    return items


def test_solve_with_axes_keeps_offsets_in_the_sensors_axes_and_corrects_into_the_bodys(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    axes, offset = sensor_axes.parse("-y,+z,-x"), np.array([0.03, -0.02, 0.05])
    items = _six_faces(tmp_path, axes, offset)
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", *items, "--axes", "-y,+z,-x", "-o", out)
    assert r.code == 0, r.err
    assert "--axes -y,+z,-x: the faces told in the body's axes, solved in the sensor's" in r.err
    doc = json.loads(out.read_text())
    assert doc["axes"] == "-y,+z,-x"
    assert list(doc)[list(doc).index("columns") + 1] == "axes"
    assert np.allclose(doc["offset"], offset, atol=1e-3)  # the sensor's own axes, for its registers
    assert np.allclose(doc["gain"], 1.0, atol=1e-3)
    cal = calfile.load(out)
    assert np.allclose(cal.sensor_matrix, np.eye(3), atol=2e-3)
    body = cal.apply(np.array([axes.matrix.T @ np.array([0.0, 0.0, 1.0]) + offset]))[0]
    assert np.allclose(body, [0.0, 0.0, 1.0], atol=2e-3)  # the body's +z up reads +z
    # the same faces without --axes are faces the readings do not show: refused, nothing written
    refused = run(capsys, "solve", "--poses", *items, "-o", tmp_path / "no.json")
    assert refused.code == 3
    assert not (tmp_path / "no.json").exists()
    # the Python API takes it by the same name
    solved = tumblecal.solve({f.split("=")[0]: f.split("=")[1] for f in items}, axes="-y,+z,-x")
    assert solved.calibration is not None
    assert solved.calibration.axes == axes


def test_axes_given_wrong_is_one_line_naming_the_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", SHOTS, "--columns", "ax,ay,az", "--axes", "-y,-y,+z", "-o", out)
    assert_one_error(r, "--axes '-y,-y,+z': a sensor axis is named twice: name each of x, y and z once (e.g. -y,-x,+z)")
    assert not out.exists()


def test_a_calibration_file_with_bad_axes_is_refused_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = _solved(capsys, tmp_path / "acc.json", "accelerometer", "-y,-x,+z")
    doc = json.loads(cal.read_text())
    assert calfile.load(cal).to_dict()["axes"] == "-y,-x,+z"  # read and written back as it was
    doc["axes"] = "+x,+x,+z"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = run(capsys, "show", bad)
    assert_one_error(
        r, f"{bad}: field 'axes' '+x,+x,+z': a sensor axis is named twice: name each of x, y and z once (e.g. -y,-x,+z)"
    )


def test_align_finds_the_180_degree_turn_between_the_sap6_sensors_and_names_its_axes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both calibrations in their sensors' own axes: the magnetometer is the accelerometer turned
    180° about a diagonal ("-y,-x,-z"); align says so and names the --axes that states it. A plain
    Gauss-Newton from the identity stopped at 178.7° (the issue); refused on 6 of 7 units."""
    acc = _solved(capsys, tmp_path / "acc.json", "accelerometer", None)
    mag = _solved(capsys, tmp_path / "mag.json", "magnetometer", None)
    out, aligned = tmp_path / "align.json", tmp_path / "mag-aligned.json"
    r = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, SHOTS, "-o", out, "--aligned-mag", aligned)
    assert r.code == 0, r.err
    assert "axes -y,-x,-z (the first's x, y, z as the other's), then a rotation" in r.err
    assert "the accelerometer's x, y, z are the magnetometer's -y,-x,-z (a turn of 180°)" in r.err
    assert "solve the magnetometer with --axes -y,-x,-z" in r.err
    doc = json.loads(out.read_text())
    assert doc["axes"] == "-y,-x,-z"
    assert doc["mag_axes"] == "-y,-x,-z"
    assert doc["angle_deg"] < 3.0  # what is left beyond the axes: the sensors' small misalignment
    assert doc["dip_spread_deg"]["after"] <= _device_dip_spread()
    written = calfile.load(aligned)
    assert written.axes is not None
    assert written.axes.text == "-y,-x,-z"
    assert np.allclose(written.gain, calfile.load(mag).gain, rtol=0.02)  # the sensor's gains, not a permutation's
    # solved again with the --axes it named, the magnetometer needs no turn: a plain misalignment
    restated = _solved(capsys, tmp_path / "mag2.json", "magnetometer", "-y,-x,-z")
    again = run(capsys, "align", "--accel-cal", acc, "--mag-cal", restated, SHOTS, "--json")
    assert again.code == 0, again.err
    found = json.loads(again.out)
    assert "axes" not in found
    assert found["angle_deg"] < 3.0
    assert "--axes" not in again.err


def test_the_devices_own_axes_align_the_sap6_sensors_to_within_its_dip_spread(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc = _solved(capsys, tmp_path / "acc.json", "accelerometer", DEVICE_AXES["accelerometer"])
    mag = _solved(capsys, tmp_path / "mag.json", "magnetometer", DEVICE_AXES["magnetometer"])
    offsets = json.loads(mag.read_text())["offset"]
    centre = json.loads((SAP / "sap6_BB_device_cal.json").read_text())["calib"]["mag"]["centre"]
    assert np.allclose(offsets, [centre[0], centre[1], -centre[2]], atol=0.05)  # raw axes: z's sign the sensor's
    r = run(capsys, "align", "--accel-cal", acc, "--mag-cal", mag, SHOTS, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert "axes" not in doc
    assert doc["angle_deg"] < 3.0
    assert doc["dip_spread_deg"]["after"] <= _device_dip_spread()


def test_exports_carry_the_axes_as_the_autopilots_orientation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mag = _solved(capsys, tmp_path / "mag.json", "magnetometer", "-y,-x,-z")
    cal = calfile.load(mag)
    px4 = run(capsys, "export", mag, "--format", "px4", "-o", "-")
    assert px4.code == 0, px4.err
    assert re.search(r"\tCAL_MAG0_ROT\t14\t6$", px4.out, re.MULTILINE)  # ROTATION_ROLL_180_YAW_270
    xoff = float(re.search(r"CAL_MAG0_XOFF\t(\S+)", px4.out).group(1))  # type: ignore[union-attr]
    assert xoff == pytest.approx(cal.offset[0] / 100, rel=1e-6)  # PX4 corrects in the sensor's axes, in gauss
    ardupilot = run(capsys, "export", mag, "--format", "ardupilot", "-o", "-")
    assert ardupilot.code == 0, ardupilot.err
    assert "\nCOMPASS_ORIENT,14\n" in ardupilot.out
    ofs_x = float(re.search(r"COMPASS_OFS_X,(\S+)", ardupilot.out).group(1))  # type: ignore[union-attr]
    assert ofs_x == pytest.approx(cal.offset[1] * 10, rel=1e-6)  # -(P b) in the body's axes: x = -y, in mGauss
    mirrored = _solved(capsys, tmp_path / "mirror.json", "magnetometer", "+x,+y,-z")
    r = run(capsys, "export", mirrored, "--format", "px4", "-o", tmp_path / "m.params")
    assert_one_error(
        r,
        f"{mirrored}: its axes +x,+y,-z mirror the sensor's (a left-handed sensor): no px4 rotation does that",
        hint="check the signs of --axes, or export it as a matrix (c-header)",
    )
    assert not (tmp_path / "m.params").exists()


def test_a_rotation_of_any_size_is_found_and_an_unturned_axis_is_named() -> None:
    rng = np.random.default_rng(12)
    turned = sensor_axes.parse("+z,-y,+x").matrix @ alignment.exp_map(np.radians([2.0, -1.0, 0.5]))
    c = poses(rng, 12)
    g = np.array([m @ UP for m in c])
    m = np.array([r @ FIELD for r in c]) @ turned  # v_acc = turned v_mag
    s = np.full(12, 1e-4)
    fit = alignment.mag_to_accel(g + rng.normal(size=g.shape) * 1e-4, m + rng.normal(size=m.shape) * 1e-4, s, s)
    assert fit.rotation.axes is not None
    assert fit.rotation.axes.text == "+z,-y,+x"
    assert np.degrees(np.linalg.norm(alignment.log_map(fit.rotation.matrix @ turned.T))) < 0.05
    assert fit.rotation.angle_deg == pytest.approx(np.degrees(np.linalg.norm(np.radians([2.0, -1.0, 0.5]))), abs=0.05)
    # turned about the vertical alone: the rotation about the accelerometer's z is what is loose
    k = 10
    gv = np.array([alignment.exp_map(np.array([0.0, 0.0, yaw])) @ UP for yaw in np.linspace(0, 6, k)])
    mv = np.array([alignment.exp_map(np.array([0.0, 0.0, yaw])) @ FIELD for yaw in np.linspace(0, 6, k)])
    loose = alignment.mag_to_accel(gv, mv + rng.normal(size=mv.shape) * 1e-4, np.full(k, 1e-4), np.full(k, 1e-4))
    axis, sigma = loose.rotation.loosest()
    assert not loose.rotation.observable()
    assert abs(axis[2]) > 0.99
    assert sigma > 5


def test_apply_corrects_into_the_axes_of_the_calibration_or_of_axes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = _solved(capsys, tmp_path / "mag.json", "magnetometer", None)
    stated = _solved(capsys, tmp_path / "mag-axes.json", "magnetometer", "-y,-x,-z")
    given: list[str | Path] = ["--columns", "mx,my,mz", SHOTS, "-o", "-", "-q"]
    by_file = run(capsys, "apply", "--cal", stated, *given)
    by_flag = run(capsys, "apply", "--cal", plain, "--axes", "-y,-x,-z", *given)
    as_read = run(capsys, "apply", "--cal", plain, *given)
    assert by_file.code == by_flag.code == as_read.code == 0

    def fields(out: str) -> FloatArray:
        return np.array([[float(v) for v in line.split(",")[2:5]] for line in out.splitlines()[1:]])

    assert np.allclose(fields(by_file.out), fields(by_flag.out), atol=0.05)  # one calibration, the same axes
    assert np.allclose(fields(by_flag.out), fields(as_read.out) @ sensor_axes.parse("-y,-x,-z").matrix.T)
    out = tmp_path / "twice.csv"
    r = run(capsys, "apply", "--cal", stated, "--axes", "+x,+y,-z", "--columns", "mx,my,mz", SHOTS, "-o", out)
    assert_one_error(
        r,
        f"{stated}: corrects into its own axes -y,-x,-z already: --axes +x,+y,-z would turn them again",
        hint="leave --axes out (the calibration's axes apply), or solve again with the axes wanted",
    )
    assert not out.exists()


def test_apply_refuses_the_identity_over_a_calibrations_own_axes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--axes +x,+y,+z states nothing of its own, but over a calibration with axes it said nothing
    and was ignored: it is refused as another --axes is."""
    stated = _solved(capsys, tmp_path / "mag-axes.json", "magnetometer", "-y,-x,-z")
    r = run(capsys, "apply", "--cal", stated, "--axes", "+x,+y,+z", "--columns", "mx,my,mz", SHOTS, "-o", "-")
    assert r.code == 2
    assert "--axes +x,+y,+z would turn them again" in r.err


# -- --axes on segment, solve --log with a label column, noise and thermal ------------------------

AXES = "+y,-z,-x"  # (not its own inverse: a mapping taken the wrong way round fails)
SAMPLE = ROOT / "sample_data"


def _as_mounted(source: Path, target: Path, columns: tuple[str, str, str]) -> None:
    """``source``'s readings of ``columns`` as a sensor mounted with AXES reads them (its other
    columns as they are): the sensor's ``P^T v`` of each body reading v."""
    p = sensor_axes.parse(AXES).matrix
    with source.open(newline="") as f:
        rows = list(csv.reader(f))
    where = [rows[0].index(c) for c in columns]
    for row in rows[1:]:
        body = np.array([float(row[j]) for j in where])
        for j, v in zip(where, p.T @ body, strict=True):
            row[j] = repr(float(v))
    with target.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)


def _index(folder: Path) -> list[tuple[str, str, str]]:
    with (folder / "segments.csv").open(newline="") as f:
        return [(r["file"], r["face"].lstrip("'"), r["nearest_face"].lstrip("'")) for r in csv.DictReader(f)]


def test_segment_with_axes_names_the_bodys_faces_and_solve_reads_them_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log of a sensor mounted +y,-z,-x: segment --axes cuts the blocks of the log as read
    without the turn, named by the same faces; solve --poses --axes of them corrects its readings
    into the body's axes as the unturned log's calibration corrects its own."""
    log = SAMPLE / "imucal" / "session_every4th.csv"
    mounted = tmp_path / "mounted.csv"
    _as_mounted(log, mounted, ("acc_x", "acc_y", "acc_z"))
    assert run(capsys, "segment", log, "--rate", "25.6", "-d", tmp_path / "plain", "-q").code == 0
    r = run(capsys, "segment", mounted, "--rate", "25.6", "--axes", AXES, "-d", tmp_path / "turned")
    assert r.code == 0, r.err
    assert f"--axes {AXES}: the faces are the body's" in r.err
    assert _index(tmp_path / "turned") == _index(tmp_path / "plain")
    faces = [f"{a}{s}.csv" for a in "xyz" for s in "pn"]
    cals = {}
    for name, extra in (("plain", []), ("turned", ["--axes", AXES])):
        out = tmp_path / f"{name}.json"
        assert run(capsys, "solve", "-q", "--poses", *(tmp_path / name / f for f in faces), *extra, "-o", out).code == 0
        cals[name] = calfile.load(out)
    assert cals["turned"].axes == sensor_axes.parse(AXES)
    raw = np.loadtxt(log, delimiter=",", skiprows=1, usecols=(4, 5, 6))[:400]
    seen = np.loadtxt(mounted, delimiter=",", skiprows=1, usecols=(4, 5, 6))[:400]
    np.testing.assert_allclose(cals["turned"].apply(seen), cals["plain"].apply(raw), atol=1e-9)


def test_solve_log_with_a_label_column_and_axes_takes_the_labels_as_the_bodys(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import gzip

    session = tmp_path / "session.csv"
    packed = ROOT / "tests" / "data" / "logs" / "imucal_annotated_session.csv.gz"
    session.write_bytes(gzip.decompress(packed.read_bytes()))
    mounted = tmp_path / "mounted.csv"
    _as_mounted(session, mounted, ("acc_x", "acc_y", "acc_z"))
    labelled = ["--rate", "204.8", "--pose-column", "part", "--pose-map", "x_p=+x,x_a=-x,y_p=+y,y_a=-y,z_p=+z,z_a=-z"]
    plain, turned = tmp_path / "plain.json", tmp_path / "turned.json"
    assert run(capsys, "solve", "-q", "--log", session, *labelled, "-o", plain).code == 0
    r = run(capsys, "solve", "-q", "--log", mounted, *labelled, "--axes", AXES, "-o", turned)
    assert r.code == 0, r.err
    a, b = calfile.load(plain), calfile.load(turned)
    p = sensor_axes.parse(AXES).matrix
    np.testing.assert_allclose(b.offset, p.T @ a.offset, atol=1e-9)  # the sensor's own axes
    np.testing.assert_allclose(b.matrix, a.matrix @ p, atol=1e-9)  # into the body's: M_body P^T^-1
    # without --axes the labels are taken as the sensor's faces, which the turned readings do not show
    assert run(capsys, "solve", "-q", "--log", mounted, *labelled, "-o", tmp_path / "no.json").code == 3
    # a gyroscope from known turns: the turns' axes are the body's too
    both = tmp_path / "both.csv"
    _as_mounted(mounted, both, ("gyr_x", "gyr_y", "gyr_z"))
    turns = ["--sensor", "gyroscope", *labelled, "--turns", "x_rot=+x,y_rot=+y,z_rot=+z", "--turn-angle", "360"]
    gyro, gyro_turned = tmp_path / "gyro.json", tmp_path / "gyro-turned.json"
    assert run(capsys, "solve", "-q", "--log", session, *turns, "-o", gyro).code == 0
    r = run(capsys, "solve", "-q", "--log", both, *turns, "--axes", AXES, "-o", gyro_turned)
    assert r.code == 0, r.err
    np.testing.assert_allclose(calfile.load(gyro_turned).matrix, calfile.load(gyro).matrix @ p, atol=1e-9)


def test_noise_with_axes_gives_the_bodys_figures_and_refuses_to_turn_a_calibrations_axes_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    still = tmp_path / "still.csv"
    rng = np.random.default_rng(8)
    x = rng.normal(0.0, [0.001, 0.004, 0.009], size=(20_000, 3))
    still.write_text("x,y,z\n" + "".join(f"{a:.6f},{b:.6f},{c:.6f}\n" for a, b, c in x))

    def density(*extra: str | Path) -> list[float]:
        r = run(capsys, "noise", still, "--rate", "100", "--json", *extra)
        assert r.code == 0, r.err
        assert ("x, y and z are the body's axes" in r.err) == ("--axes" in extra)
        return [json.loads(r.out)["axes"][a]["noise_density"]["value"] for a in "xyz"]

    plain, turned = density(), density("--axes", AXES)
    assert turned == [plain[1], plain[2], plain[0]]  # the body's x is the sensor's +y: its noise
    cal = tmp_path / "cal.json"
    calfile.Calibration("accelerometer", "six-pose", 1.0, ["x", "y", "z"], np.zeros(3), np.eye(3), np.ones(3)).in_axes(
        sensor_axes.parse(AXES)
    ).save(cal)
    assert density("--cal", cal) == turned  # a calibration's own axes turn them the same
    refused = run(capsys, "noise", still, "--rate", "100", "--cal", cal, "--axes", "+z,+x,+y")
    assert_one_error(
        refused,
        f"{cal}: corrects into its own axes {AXES} already: --axes +z,+x,+y would turn them again",
        hint="leave --axes out (the calibration's axes apply), or solve again with the axes wanted",
    )


def test_thermal_of_a_calibration_into_the_bodys_axes_takes_the_bodys_faces(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same sweeps told by the body's faces against a calibration solved with --axes: the same
    drift (in the sensor's axes, as its offsets), the sweeps recorded by the faces told."""
    s = SAMPLE / "thermal"
    sensor_faces = {"xp": "+x", "xn": "-x", "yp": "+y", "yn": "-y", "zp": "+z", "zn": "-z"}
    turn = sensor_axes.parse(AXES)
    body = {n: turn.body_label(f) for n, f in sensor_faces.items()}  # the sensor's +x is the body's -z
    sweeps = {"xp": "sweep_up_xp", "xn": "sweep_down_xn", "yp": "sweep_up_yp", "yn": "sweep_down_yn"}
    sweeps |= {"zp": "sweep_up_zp", "zn": "sweep_down_zn"}
    base, base_turned = tmp_path / "base.json", tmp_path / "base-turned.json"
    assert run(capsys, "solve", "-q", "--poses", *(s / f"{n}.csv" for n in sensor_faces), "-o", base).code == 0
    told = [f"{body[n]}={s / (n + '.csv')}" for n in sensor_faces]
    assert run(capsys, "solve", "-q", "--poses", *told, "--axes", AXES, "-o", base_turned).code == 0
    warm, warm_turned = tmp_path / "warm.json", tmp_path / "warm-turned.json"
    plain_items = [f"{sensor_faces[n]}={s / (sweeps[n] + '.csv')}" for n in sweeps]
    body_items = [f"{body[n]}={s / (sweeps[n] + '.csv')}" for n in sweeps]
    assert run(capsys, "thermal", "-q", *plain_items, "--cal", base, "-o", warm).code == 0
    r = run(capsys, "thermal", "-q", *body_items, "--cal", base_turned, "-o", warm_turned)
    assert r.code == 0, r.err
    a, b = json.loads(warm.read_text())["thermal"], json.loads(warm_turned.read_text())["thermal"]
    assert {k: v for k, v in a.items() if k != "sweeps"} == {k: v for k, v in b.items() if k != "sweeps"}
    assert [w["pose"] for w in b["sweeps"]] == [body[n] for n in sweeps]
    assert json.loads(warm_turned.read_text())["axes"] == AXES
    # two sweeps told the wrong way round: refused, named by the faces as told (the body's)
    swapped = [f"{body['yp' if n == 'xp' else 'xp' if n == 'yp' else n]}={s / (sweeps[n] + '.csv')}" for n in sweeps]
    r = run(capsys, "thermal", "-q", *swapped, "--cal", base_turned, "-o", tmp_path / "no.json")
    assert r.code == 3
    assert f"sweep_up_xp.csv: declared {body['yp']} but reads like {body['xp']} (mean " in r.err
    assert not (tmp_path / "no.json").exists()

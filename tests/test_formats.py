"""tumblecal export / import (tumblecal_cli/io/export/formats.py): firmware headers that compile and give the
same correction, register counts that never wrap, and peer formats that round-trip to 1e-12."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import run
from tumblecal_cli.core import model as core
from tumblecal_cli.core.arrays import FloatArray
from tumblecal_cli.core.model import Solution
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.io.export import formats
from tumblecal_cli.pipeline import report as reports

ROOT = Path(__file__).resolve().parent.parent
IMUCAL_CAL = ROOT / "tests" / "data" / "imucal_session" / "example_cal.json"
SIX = [str(ROOT / "sample_data" / "imucal" / f"{f}.csv") for f in ("xp", "xn", "yp", "yn", "zp", "zn")]
#: imucal's published calibration of its annotated session as M = R_a^-1 K_a^-1 (issue 4, to 1e-6)
IMUCAL_M = np.array(
    [
        [4.7941075750e-3, -3.3657395500e-5, 5.2667296510e-5],
        [4.0523316827e-5, 4.8076518588e-3, -1.0969773274e-4],
        [-1.0191238382e-4, 5.2568900273e-5, 4.6548524031e-3],
    ]
)
IMUCAL_B = [-6.018868019671572, -48.287874016760156, -28.96636637224333]


def write_cal(
    path: Path,
    offset: Any,
    matrix: Any,
    *,
    method: str = "six-pose",
    sensor: str = "accelerometer",
    serial: str | None = "SN-7",
    reference: float = 1.0,
) -> Path:
    m = np.asarray(matrix, dtype=float)
    doc = calfile.build(
        Solution(method, np.asarray(offset, dtype=float), m, np.full(3, 1e-5), np.full(3, 1e-5)),
        calfile.Basis(sensor, reference, ["ax", "ay", "az"], None, "counts"),
        [{"pose": "+z", "file": "z.csv", "samples": 10, "mean": [0.0, 0.0, 1.0], "std": [0.0] * 3}],
        unit={"serial": serial, "station": None, "operator": None, "meta": {}},
    )
    calfile.write(doc, str(path))
    return path


def random_cal(rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
    """A unit in counts (about 2048 per g) with cross-axis terms and a few hundred counts of offset."""
    a = np.diag(rng.uniform(1900, 2200, 3)) + rng.normal(0, 20, (3, 3)) * (1 - np.eye(3))
    return rng.normal(0, 300, 3), np.asarray(np.linalg.inv(a), dtype=np.float64)


def corrected(path: Path, raw: FloatArray) -> FloatArray:
    c = calfile.load(str(path))
    return core.apply(raw, c.offset, c.matrix)


# --- imucal ---------------------------------------------------------------------------------------


def test_import_imucal_published_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """imucal's own file: M = R_a^-1 K_a^-1 and offset b_a, as the solvers issue states them."""
    out = tmp_path / "cal.json"
    code, _, err = run(capsys, "import", str(IMUCAL_CAL), "-o", str(out))
    assert code == 0, err
    cal = calfile.load(str(out))
    np.testing.assert_allclose(cal.matrix, IMUCAL_M, rtol=1e-9)
    assert cal.offset.tolist() == IMUCAL_B
    assert cal.to_dict()["method"] == "imported"
    assert cal.reference == 9.81
    assert cal.to_dict()["units"] == "m/s^2"
    assert cal.columns == ["acc_x", "acc_y", "acc_z"]
    imported = cal.to_dict()["imported"]
    assert isinstance(imported, dict)
    assert imported["format"] == "imucal-json"
    assert "reference 9.81" in err


def test_six_pose_solve_exports_what_imucal_published(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Our six-pose solve of imucal's session, exported, carries imucal's own K_a, R_a and b_a."""
    cal, exported = tmp_path / "six.json", tmp_path / "imucal.json"
    code, _, err = run(capsys, "solve", "--poses", *SIX, "--reference", "9.81", "-q", "-o", str(cal))
    assert code == 0, err
    assert run(capsys, "export", str(cal), "--format", "imucal-json", "-o", str(exported))[0] == 0
    ours, theirs = json.loads(exported.read_text()), json.loads(IMUCAL_CAL.read_text())
    assert list(ours) == [*theirs, "_format_version"]  # imucal's to_json field order, and its version key
    assert ours["_format_version"] == "2.0.0"
    assert ours["cal_type"] == "Ferraris"
    for key in ("K_a", "R_a", "b_a"):
        np.testing.assert_allclose(ours[key], theirs[key], rtol=1e-6, atol=1e-9)
    assert ours["K_g"] == np.eye(3).tolist()
    assert ours["b_g"] == [0.0, 0.0, 0.0]
    assert ours["K_ga"] == np.zeros((3, 3)).tolist()


def test_imucal_scale_and_rotation_shape() -> None:
    """K diagonal and positive, each row of R of unit length, K R = A."""
    rng = np.random.default_rng(7)
    _, m = random_cal(rng)
    k, r = formats.scale_and_rotation(m)
    assert np.all(np.diag(k) > 0)
    assert np.count_nonzero(k - np.diag(np.diag(k))) == 0
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(k @ r, np.linalg.inv(m), rtol=1e-13)


@pytest.mark.parametrize("fmt", ["imucal-json", "ros-yaml"])
@pytest.mark.parametrize("seed", range(5))
def test_export_import_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str, seed: int) -> None:
    """export -> import gives the same correction to 1e-12 (relative to the corrected magnitude)."""
    rng = np.random.default_rng(seed)
    offset, m = random_cal(rng)
    cal = write_cal(tmp_path / "cal.json", offset, m, reference=1.0)
    peer, back = tmp_path / ("peer.json" if fmt == "imucal-json" else "peer.yaml"), tmp_path / "back.json"
    assert run(capsys, "export", str(cal), "--format", fmt, "-o", str(peer))[0] == 0
    code, _, err = run(capsys, "import", str(peer), "-o", str(back))
    assert code == 0, err
    raw = offset + rng.normal(0, 2048, (200, 3))
    want, got = corrected(cal, raw), corrected(back, raw)
    assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))
    loaded = calfile.load(str(back))
    assert loaded.reference == 1.0  # carried in the export's comment
    np.testing.assert_allclose(loaded.offset, offset, rtol=1e-12, atol=1e-9)


def test_gyroscope_goes_in_imucal_gyro_slot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "g.json", [0.5, -0.2, 0.1], np.diag([0.99, 1.01, 1.0]), sensor="gyroscope", reference=0)
    code, out, _ = run(capsys, "export", str(cal), "--format", "imucal-json")
    doc = json.loads(out)
    assert code == 0
    assert doc["b_g"] == [0.5, -0.2, 0.1]
    assert doc["b_a"] == [0.0, 0.0, 0.0]
    peer = tmp_path / "peer.json"
    peer.write_text(out)
    code, out, _ = run(capsys, "import", str(peer), "--sensor", "gyroscope")
    back = json.loads(out)
    assert code == 0
    assert back["sensor"] == "gyroscope"
    assert back["reference"] == 0
    np.testing.assert_allclose(back["matrix"], np.diag([0.99, 1.01, 1.0]), rtol=1e-14)


def test_import_imucal_gyroscope_notes_dropped_g_sensitivity(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "import", str(IMUCAL_CAL), "--sensor", "gyroscope")
    assert code == 0
    assert json.loads(out)["units"] == "deg/s"
    assert "K_ga" in err
    assert "left out" in err


# --- ROS and MATLAB -------------------------------------------------------------------------------


def test_ros_yaml_is_sm_raw_minus_bias(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """imu_calib computes SM * raw - bias: that must equal tumblecal's M (raw - offset)."""
    rng = np.random.default_rng(3)
    offset, m = random_cal(rng)
    cal = write_cal(tmp_path / "cal.json", offset, m)
    code, out, _ = run(capsys, "export", str(cal), "--format", "ros-yaml")
    doc = yaml.safe_load(out)
    assert code == 0
    assert set(doc) == {"SM", "bias", "tumblecal"}  # tumblecal: the record import reads back (imu_calib ignores it)
    assert len(doc["SM"]) == 9
    assert len(doc["bias"]) == 3
    sm, bias = np.array(doc["SM"]).reshape(3, 3), np.array(doc["bias"])  # row-major, as imu_calib reads it
    raw = rng.normal(0, 2048, (50, 3))
    np.testing.assert_allclose((sm @ raw.T).T - bias, corrected(cal, raw), rtol=0, atol=1e-12)


def test_matlab_is_u_times_a_plus_b(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """accelcal's row-vector convention C = U*A + b gives tumblecal's correction."""
    rng = np.random.default_rng(4)
    offset, m = random_cal(rng)
    cal = write_cal(tmp_path / "cal.json", offset, m)
    code, out, _ = run(capsys, "export", str(cal), "--format", "matlab")
    assert code == 0
    body = out.split("A = [", 1)[1]
    a = np.array([float(v) for v in body.split("]", 1)[0].replace(";", " ").split()]).reshape(3, 3)
    b = np.array([float(v) for v in out.split("b = [", 1)[1].split("]", 1)[0].split()])
    raw = rng.normal(0, 2048, (50, 3))
    np.testing.assert_allclose(raw @ a + b, corrected(cal, raw), rtol=0, atol=1e-12)
    assert all(line.startswith("%") for line in out.splitlines() if not re.match(r"\s*(A|b) = |\s+-?\d", line))


# --- C header -------------------------------------------------------------------------------------

GCC = shutil.which("gcc")
needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed")

PROGRAM = """
#include <stdio.h>
#include "accel.h"
#include "mag.h"
int main(void) {
    float raw[3], out[3];
    while (scanf("%f %f %f", &raw[0], &raw[1], &raw[2]) == 3) {
        tumblecal_accel_apply(raw, out);
        printf("%.9g %.9g %.9g\\n", out[0], out[1], out[2]);
    }
    return 0;
}
"""


@needs_gcc
def test_c_header_compiles_cleanly_and_corrects(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """-Wall -Wextra -Werror: on the header alone, and in a program that includes two headers
    (accelerometer and magnetometer) and reproduces tumblecal's correction to float precision."""
    rng = np.random.default_rng(11)
    offset, m = random_cal(rng)
    cal = write_cal(tmp_path / "cal.json", offset, m, serial="SN */ 42 x")  # a serial that tries to end the comment
    mag = write_cal(tmp_path / "mag.json", [0.1, 0.2, 0.3], np.eye(3), method="ellipsoid", sensor="magnetometer")
    assert run(capsys, "export", str(cal), "--format", "c-header", "-o", str(tmp_path / "accel.h"))[0] == 0
    assert run(capsys, "export", str(mag), "-f", "c-header", "-o", str(tmp_path / "mag.h"))[0] == 0
    header = (tmp_path / "accel.h").read_text()
    assert "#ifndef TUMBLECAL_ACCEL_H" in header
    assert "static const float TUMBLECAL_ACCEL_MATRIX[3][3]" in header
    assert "SN * / 42 x" in header
    assert "corrected = M * (raw - offset)" in header
    flags = ["-Wall", "-Wextra", "-Werror", "-pedantic"]
    for std in ("-std=c99", "-std=c11"):
        for source in ("accel.h", "mag.h"):
            alone = subprocess.run(
                [str(GCC), std, *flags, "-x", "c", "-c", source, "-o", f"{source}.o"],
                cwd=tmp_path,
                capture_output=True,
                text=True,
                check=False,
            )
            assert alone.returncode == 0, alone.stderr
    (tmp_path / "main.c").write_text(PROGRAM)
    built = subprocess.run(
        [str(GCC), "-std=c99", *flags, "main.c", "-o", "apply"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert built.returncode == 0, built.stderr
    raw = offset + rng.normal(0, 2048, (100, 3))
    lines = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in raw)
    done = subprocess.run([str(tmp_path / "apply")], input=lines, capture_output=True, text=True, check=True)
    got = np.array([[float(v) for v in line.split()] for line in done.stdout.splitlines()])
    want = corrected(cal, raw.astype(np.float32).astype(np.float64))
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-5 * np.max(np.abs(want)))  # float arithmetic


@needs_gcc
def test_c_header_compiles_as_cpp(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gxx = shutil.which("g++")
    if gxx is None:
        pytest.skip("g++ is not installed")
    cal = write_cal(tmp_path / "cal.json", [1.0, 2.0, 3.0], np.eye(3))
    assert run(capsys, "export", str(cal), "-f", "c-header", "--prefix", "imu0", "-o", str(tmp_path / "imu.h"))[0] == 0
    (tmp_path / "t.cpp").write_text(
        '#include "imu.h"\nint f(float* o) { const float r[3] = {1, 2, 3}; imu0_apply(r, o); return 0; }\n'
    )
    done = subprocess.run(
        [gxx, "-Wall", "-Wextra", "-Werror", "-c", "t.cpp"], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr


def test_c_float_literals_are_valid() -> None:
    assert formats._c_float(1.0, "x", "f") == "1.0f"
    assert formats._c_float(-2.5e-5, "x", "f") == "-2.5e-05f"
    assert formats._c_float(16384.0, "x", "f") == "16384.0f"


def test_c_header_rejects_a_bad_prefix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.eye(3))
    code, out, err = run(capsys, "export", str(cal), "-f", "c-header", "--prefix", "9lives")
    assert code == 2
    assert out == ""
    assert "not a C identifier" in err


# --- registers ------------------------------------------------------------------------------------


def registers(out: str) -> dict[str, list[str]]:
    lines = out.splitlines()
    assert lines[0] == "register,count,hex,value,target,error"
    return {line.split(",")[0]: line.split(",")[1:] for line in lines[1:]}


def test_registers_offsets_subtract_and_add(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", [-6.0189, -48.2879, 29.4], np.eye(3))
    code, out, _ = run(capsys, "export", str(cal), "--format", "registers", "--lsb", "0.98", "--bits", "16")
    rows = registers(out)
    assert code == 0
    assert [rows[f"offset_{a}"][0] for a in "xyz"] == ["-6", "-49", "30"]
    assert rows["offset_y"][1] == "0xFFCF"
    assert rows["offset_z"][1] == "0x001E"
    assert float(rows["offset_x"][2]) == pytest.approx(-5.88)
    assert float(rows["offset_x"][4]) == pytest.approx(-0.1389)
    code, out, _ = run(capsys, "export", str(cal), "-f", "registers", "--lsb", "0.98", "--register-sign", "add")
    assert code == 0
    assert [registers(out)[f"offset_{a}"][0] for a in "xyz"] == ["6", "49", "-30"]


def test_registers_gain_trim(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Gain 2088 counts/g on x, nominal 2048: the trim must scale x by 2048/2088 (count -19 at 0.1 %)."""
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.diag(1 / np.array([2088.0, 2048.0, 2000.0])))
    args = ["export", str(cal), "-f", "registers", "--lsb", "1", "--gain-step", "0.001", "--nominal-gain", "2048"]
    code, out, err = run(capsys, *args)
    rows = registers(out)
    assert code == 0, err
    assert [rows[f"gain_{a}"][0] for a in "xyz"] == [str(round((2048 / 2088 - 1) / 0.001)), "0", "24"]
    assert float(rows["gain_x"][3]) == pytest.approx(2048 / 2088, rel=1e-12)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--lsb", "0.001"], "offset_y needs -48288 register counts"),
        (
            ["--lsb", "0.98", "--bits", "6"],
            "offset_y needs -49 register counts (offset -48.2879 / --lsb 0.98), outside",
        ),
        (["--lsb", "0"], "--lsb must be a positive number"),
        (["--lsb", "-1"], "--lsb must be a positive number"),
        (["--lsb", "nan"], "--lsb must be a positive number"),
        ([], "--format registers needs --lsb"),
        (["--lsb", "1", "--gain-step", "0"], "--gain-step must be a positive number"),
    ],
)
def test_registers_refuse_what_does_not_fit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    """A value outside the register is exit 2 naming it -- never a silent wrap-around -- and
    the existing output is left as it was."""
    cal = write_cal(tmp_path / "cal.json", [-6.0189, -48.2879, 29.4], np.eye(3))
    out = tmp_path / "regs.csv"
    out.write_text("old\n")
    code, stdout, err = run(capsys, "export", str(cal), "-f", "registers", *args, "-o", str(out))
    assert (code, stdout) == (2, ""), err
    assert message in err
    assert len(err.splitlines()) <= 2
    assert "Traceback" not in err
    assert out.read_text() == "old\n"


def test_a_nominal_gain_given_to_solve_alone_is_recorded_for_the_gain_trim(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`solve --nominal-gain 208` with no limit: the file keeps it, and export's trim uses it."""
    imucal = ROOT / "sample_data" / "imucal"
    poses = [str(imucal / f"{face}.csv") for face in ("xp", "xn", "yp", "yn", "zp", "zn")]
    cal = tmp_path / "ng.json"
    code, _, err = run(
        capsys, "solve", "-q", "-p", *poses, "--reference", "9.81", "--nominal-gain", "208", "-o", str(cal)
    )
    assert code == 0, err
    doc = json.loads(cal.read_text())
    assert doc["verdict"] == {"pass": True, "failures": [], "limits": {"nominal_gain": [208.0, 208.0, 208.0]}}
    code, out, err = run(capsys, "export", str(cal), "-f", "registers", "--lsb", "1", "--gain-step", "0.001")
    assert code == 0, err
    gain_x = float(np.linalg.inv(doc["matrix"])[0, 0])
    assert float(registers(out)["gain_x"][3]) == pytest.approx(208.0 / gain_x, rel=1e-12)


def test_registers_name_every_misfit_with_its_own_arithmetic_and_hint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = write_cal(tmp_path / "cal.json", [-6.0189, -48.2879, 29.4], np.eye(3))
    code, _, err = run(capsys, "export", str(cal), "-f", "registers", "--lsb", "1", "--bits", "2")
    assert code == 2
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert [e.split(": ")[2].split(" needs")[0] for e in errors] == ["offset_x", "offset_y", "offset_z"]
    assert "hint: check --lsb" in err
    code, _, err = run(
        capsys, "export", str(cal), "-f", "registers", "--lsb", "1", "--bits", "6", "--register-sign", "add"
    )
    assert code == 2
    assert "offset_y needs 48 register counts (-(offset -48.2879) / --lsb 1), outside the signed 6-bit range" in err
    gains = write_cal(tmp_path / "gains.json", [0, 0, 0], np.diag(1 / np.array([2088.0, 2048.0, 2000.0])))
    args = ["export", str(gains), "-f", "registers", "--lsb", "1", "--bits", "4", "--gain-step", "0.001"]
    code, _, err = run(capsys, *args, "--nominal-gain", "2048")
    assert code == 2
    assert "gain_x needs -19 register counts" in err
    assert "hint: check --gain-step (what one count adds to the factor) and --nominal-gain, or --bits" in err
    zero = write_cal(tmp_path / "zero.json", [0.0, 0.0, 0.0], np.eye(3))
    code, out, _ = run(capsys, "export", str(zero), "-f", "registers", "--lsb", "1", "--register-sign", "add")
    assert code == 0
    assert {row[2] for row in registers(out).values()} == {"0"}  # never "-0"


@pytest.mark.slow
@given(offset=st.floats(-1e4, 1e4), lsb=st.floats(0.01, 100), bits=st.integers(4, 24))
@settings(max_examples=200, deadline=None)
def test_register_counts_round_to_nearest_and_fit(offset: float, lsb: float, bits: int) -> None:
    """Every count written fits the signed range and leaves at most half a count of error."""
    doc = {"offset": [offset, 0.0, 0.0], "matrix": np.eye(3).tolist()}
    cal = calfile.Calibration(
        "magnetometer", "six-pose", 1.0, ["x", "y", "z"], np.array(doc["offset"]), np.eye(3), np.ones(3)
    )
    count = round(offset / lsb)
    if not -(2 ** (bits - 1)) <= count <= 2 ** (bits - 1) - 1:
        with pytest.raises(InputError, match="offset_x needs"):
            formats.registers(cal, lsb=lsb, bits=bits)
        return
    rows = formats.registers(cal, lsb=lsb, bits=bits)
    x = rows[0]
    assert -(2 ** (bits - 1)) <= x.count <= 2 ** (bits - 1) - 1
    assert abs(x.error) <= lsb / 2 + 1e-9 * abs(offset)
    assert int(x.hex, 16) == x.count % (1 << bits)


def test_gain_trim_needs_gains(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", [0.1, 0.2, 0.3], np.eye(3), method="one-pose")
    code, _, err = run(capsys, "export", str(cal), "-f", "registers", "--lsb", "0.01", "--gain-step", "0.001")
    assert code == 2
    assert "fixes the gains" in err


# --- usage and input errors -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-f", "c-header", "--lsb", "1"], "--lsb is for --format registers"),
        (["-f", "matlab", "--bits", "8"], "--bits and --register-sign are for --format registers"),
        (["-f", "ros-yaml", "--prefix", "x"], "--prefix is for --format c-header"),
        (["-f", "png"], "Invalid value for '--format'"),
    ],
)
def test_export_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.eye(3))
    code, out, err = run(capsys, "export", str(cal), *args)
    assert (code, out) == (2, ""), err
    assert message in err


def test_export_magnetometer_to_imucal_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "m.json", [0, 0, 0], np.eye(3), method="ellipsoid", sensor="magnetometer")
    code, _, err = run(capsys, "export", str(cal), "-f", "imucal-json")
    assert code == 2
    assert "not a magnetometer" in err
    assert str(cal) in err


def test_export_never_writes_onto_its_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.eye(3))
    before = cal.read_bytes()
    code, _, err = run(capsys, "export", str(cal), "-f", "matlab", "-o", str(cal))
    assert code == 2
    assert "would overwrite the input" in err
    assert cal.read_bytes() == before


def test_import_a_tumblecal_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.eye(3))
    code, out, err = run(capsys, "import", str(cal))
    assert code == 2
    assert out == ""
    assert "neither an imucal JSON" in err
    assert str(cal) in err


def test_import_format_mismatch_and_bad_fields(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "import", str(IMUCAL_CAL), "--from", "ros-yaml")
    assert code == 2
    assert "the file is imucal-json, not ros-yaml" in err
    bad = tmp_path / "ros.yaml"
    bad.write_text("SM: [1, 0, 0, 0, 1, 0, 0, 0]\nbias: [0, 0, 0]\n")
    code, _, err = run(capsys, "import", str(bad))
    assert code == 2
    assert "field 'SM' must be 3x3 numbers" in err
    bad.write_text("SM: [1, 0, 0, 0, 0, 0, 0, 0, 1]\nbias: [0, 0, 0]\n")
    code, _, err = run(capsys, "import", str(bad))
    assert code == 2
    assert "field 'SM' is singular" in err
    doc = json.loads(IMUCAL_CAL.read_text()) | {"_format_version": "9.0.0"}
    newer = tmp_path / "newer.json"
    newer.write_text(json.dumps(doc))
    code, _, err = run(capsys, "import", str(newer))
    assert code == 2
    assert "format version '9.0.0'" in err


def test_import_unknown_units_needs_reference(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = json.loads(IMUCAL_CAL.read_text()) | {"acc_unit": "mg"}
    peer = tmp_path / "mg.json"
    peer.write_text(json.dumps(doc))
    code, _, err = run(capsys, "import", str(peer))
    assert code == 2
    assert "give --reference" in err
    code, out, _ = run(capsys, "import", str(peer), "--reference", "1000", "--columns", "a,b,c", "--serial", "U1")
    back = json.loads(out)
    assert code == 0
    assert back["reference"] == 1000
    assert back["columns"] == ["a", "b", "c"]
    assert back["unit"]["serial"] == "U1"


def test_import_ros_file_of_another_sensor_has_no_acceleration_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """imu_calib's files are accelerometers in m/s^2; read as a gyroscope or a magnetometer (a
    file not from tumblecal), the units are unknown and a magnetometer's field must be given."""
    peer = tmp_path / "plain.yaml"
    peer.write_text("SM: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nbias: [0.1, 0.2, 0.3]\n")
    code, out, err = run(capsys, "import", str(peer), "--sensor", "gyroscope", "-q")
    assert code == 0, err
    assert (json.loads(out)["units"], json.loads(out)["reference"]) == (None, 0.0)
    code, out, err = run(capsys, "import", str(peer), "--sensor", "magnetometer", "-q")
    assert code == 2
    assert "give --reference" in err
    code, out, err = run(capsys, "import", str(peer), "--sensor", "magnetometer", "--reference", "48", "-q")
    assert code == 0, err
    assert (json.loads(out)["units"], json.loads(out)["reference"]) == (None, 48.0)
    code, out, _ = run(capsys, "import", str(peer), "-q")
    assert (json.loads(out)["units"], json.loads(out)["reference"]) == ("m/s^2", 9.80665)


def test_imported_calibration_applies_and_exports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An imported file is a calibration like any other: show, apply and export read it."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "import", str(IMUCAL_CAL), "-o", str(cal))[0] == 0
    assert run(capsys, "show", str(cal))[0] == 0
    capture = tmp_path / "c.csv"
    capture.write_text("acc_x,acc_y,acc_z\n-6.018868019671572,-48.287874016760156,2016.0\n")
    code, out, _ = run(capsys, "apply", "--cal", str(cal), str(capture))
    assert code == 0
    z = [float(v) for v in out.splitlines()[1].split(",")]
    np.testing.assert_allclose(z, IMUCAL_M @ np.array([0.0, 0.0, 2016.0 - IMUCAL_B[2]]), rtol=1e-9)
    assert run(capsys, "export", str(cal), "-f", "imucal-json")[0] == 0


def test_check_judges_an_imported_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """It has no poses: its parameters are judged, noise and residual limits cannot be."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "import", str(IMUCAL_CAL), "-o", str(cal))[0] == 0
    ok = ["check", str(cal), "--max-offset", "50", "--max-gain-error", "0.05", "--nominal-gain", "209", "-q"]
    assert run(capsys, *ok)[0] == 0
    assert run(capsys, *ok[:3], "40", *ok[4:])[0] == 1  # offset y is -48.3
    code, _, err = run(capsys, "check", str(cal), "--limits", str(ROOT / "sample_data" / "limits.yaml"))
    assert code == 2
    assert "has no poses to judge the noise and residual limits by" in err


def test_export_refuses_a_failed_calibration_unless_forced(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Firmware must not get a unit that failed its limits by accident (as apply refuses it)."""
    cal = tmp_path / "fail.json"
    three = [str(ROOT / "sample_data" / f"{f}.csv") for f in ("x", "y", "z")]
    assert run(capsys, "solve", "-q", "-p", *three, "--max-offset", "0.01", "-o", str(cal))[0] == 1
    code, out, err = run(capsys, "export", str(cal), "-f", "c-header")
    assert (code, out) == (2, "")
    assert "failed its limits (limit.offset" in err
    assert "--force" in err
    code, out, _ = run(capsys, "export", str(cal), "-f", "c-header", "--force")
    assert code == 0
    assert "verdict FAIL" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--gain-step", "0.0001", "--nominal-gain", "1"], "gain_x: the trim would scale the axis by 0.004796"),
        (["--gain-step", "0.001", "--nominal-gain", "0"], "--nominal-gain must be positive"),
        (["--gain-step", "0.001", "--nominal-gain", "208,209,-210"], "--nominal-gain must be positive"),
        (["--nominal-gain", "208"], "it needs --gain-step"),
    ],
)
def test_gain_trim_refuses_units_mistakes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    """Counts at ~208 per m/s^2 with a nominal gain of 1: a trim to 0.5 % is a units mistake."""
    cal = write_cal(tmp_path / "cal.json", [0, 0, 0], np.diag(1 / np.array([208.5, 208.0, 214.8])))
    code, out, err = run(capsys, "export", str(cal), "-f", "registers", "--lsb", "1", *args)
    assert (code, out) == (2, ""), err
    assert message in err


@pytest.mark.parametrize(
    ("fmt", "sensor", "method"),
    [
        ("imucal-json", "accelerometer", "six-pose"),
        ("ros-yaml", "magnetometer", "ellipsoid"),
        ("ros-yaml", "gyroscope", "gyro-bias"),
    ],
)
def test_round_trip_keeps_what_the_export_recorded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str, sensor: str, method: str
) -> None:
    """Sensor, serial, station, operator, date, method, units, reference and columns travel in
    a data field of the export and come back, so apply on the original capture works with the imported
    calibration and report dates it from when it was made."""
    reference = {"accelerometer": 1.0, "magnetometer": 48.0, "gyroscope": 0.0}[sensor]
    cal = write_cal(
        tmp_path / "cal.json", [0.1, 0.2, 0.3], np.eye(3) * 0.5, method=method, sensor=sensor, reference=reference
    )
    doc = json.loads(cal.read_text())
    doc["unit"] |= {"station": "line 3", "operator": "Kim Lee"}
    doc["created"] = "2026-03-04T05:06:07Z"
    cal.write_text(json.dumps(doc))
    peer = tmp_path / "peer.txt"  # any name: --from says what it is
    assert run(capsys, "export", str(cal), "-f", fmt, "-o", str(peer))[0] == 0
    code, out, err = run(capsys, "import", str(peer), "--from", fmt)
    assert code == 0, err
    back, original = json.loads(out), calfile.load(str(cal)).to_dict()
    for key in ("sensor", "reference", "units", "input_units", "columns"):
        assert back[key] == original[key], key
    assert back["unit"] | {"meta": {}} == {"serial": "SN-7", "station": "line 3", "operator": "Kim Lee", "meta": {}}
    assert back["method"] == "imported"
    assert (back["imported"]["created"], back["imported"]["method"]) == ("2026-03-04T05:06:07Z", method)
    capture = tmp_path / "c.csv"
    capture.write_text("t,ax,ay,az\n0,1.1,2.2,3.3\n")
    back_file = tmp_path / "back.json"
    back_file.write_text(out)
    assert reports.entry(calfile.load(str(back_file))).created == "2026-03-04T05:06:07Z"  # report's date for it
    code, applied, err = run(capsys, "apply", "--cal", str(back_file), str(capture))
    assert code == 0, err
    np.testing.assert_allclose([float(v) for v in applied.splitlines()[1].split(",")[1:]], [0.5, 1.0, 1.5], rtol=1e-12)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--reference", "nan"], "--reference must be a positive number"),
        (["--reference", "-1"], "--reference must be a positive number"),
        (["--columns", "a,a,b"], "--columns takes three different names"),
        (["--columns", "a,b"], "--columns takes three different names"),
    ],
)
def test_import_option_errors(capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    code, out, err = run(capsys, "import", str(IMUCAL_CAL), *args)
    assert (code, out) == (2, "")
    assert message in err


def test_imucal_comment_record_is_read_by_calibration_rules(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The record an export leaves in an imucal file's comment is JSON: a key given twice there is
    refused as in a calibration file (it was read last-wins), while a person's note that only
    starts with a brace is still no record."""
    rng = np.random.default_rng(3)
    offset, m = random_cal(rng)
    cal = write_cal(tmp_path / "cal.json", offset, m, reference=1.0)
    peer = tmp_path / "peer.json"
    assert run(capsys, "export", str(cal), "--format", "imucal-json", "-o", str(peer))[0] == 0
    doc = json.loads(peer.read_text())
    record = json.loads(doc["comment"])
    doc["comment"] = json.dumps(record)[:-1] + ', "tumblecal": {"reference": 9.81}}'  # the key again
    peer.write_text(json.dumps(doc))
    code, out, err = run(capsys, "import", str(peer), "-o", str(tmp_path / "back.json"))
    assert (code, out) == (2, "")
    assert err.startswith(f"error: {peer}: ")
    assert "tumblecal" in err.splitlines()[0]
    assert "Traceback" not in err
    assert not (tmp_path / "back.json").exists()
    doc["comment"] = "{not json, a person's note}"
    peer.write_text(json.dumps(doc))
    assert run(capsys, "import", str(peer), "-o", str(tmp_path / "back.json"))[0] == 0

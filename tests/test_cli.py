"""CLI tests: exit status, stdout and stderr checked separately (docs/reference/exit-status.md).

Most tests call ``tumblecal_cli.cli.main`` in-process (fast); a few run the installed
``tumblecal`` script and ``python -m tumblecal_cli`` as subprocesses, for stdin piping and the
entry points. Bad inputs live in ``tests/data/bad/``, one file per defect.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.typing import NDArray

from tests.conftest import (
    BAD,
    IMUCAL,
    POSES_3,
    SAMPLE,
    assert_one_error,
    assert_untouched,
    feed_stdin,
    precious,
    run,
    run_exe,
    tumblecal_exe,
    unnamed,
    write,
)
from tumblecal_cli import __version__
from tumblecal_cli.cli import main
from tumblecal_cli.core import model as core
from tumblecal_cli.errors import InputError

FloatArray = NDArray[np.float64]

#: the sample set's truth (sample_data/README.md); the 3-pose result must be this within 3e-4
TRUE_OFFSET = [0.021, -0.034, 0.047]
TRUE_GAIN = [1.012, 0.987, 1.005]

#: a calibration with cross-axis terms, so apply is checked against the full M (raw - offset)
OFFSET = np.array([0.021, -0.034, 0.047])
MATRIX = np.array(
    [
        [0.9881, 0.0123, -0.0045],
        [-0.0071, 1.0132, 0.0089],
        [0.0052, -0.0033, 0.9950],
    ]
)


# -- helpers -------------------------------------------------------------------------------


def write_pose(
    path: Path,
    mean: Sequence[float] | FloatArray,
    *,
    n: int = 200,
    noise: float = 0.002,
    seed: int = 0,
    fmt: str = "%.6f",
    header: str = "t,ax,ay,az",
) -> FloatArray:
    """A static pose capture ``t,ax,ay,az``; returns the (n, 3) values as written (re-read)."""
    rng = np.random.default_rng(seed)
    values = np.asarray(mean, dtype=np.float64) + noise * rng.standard_normal((n, 3))
    data = np.column_stack([np.arange(n) / 100.0, values])
    write(path, data, header=header, fmt=["%.2f", fmt, fmt, fmt])
    written: FloatArray = np.loadtxt(path, delimiter=",", skiprows=1)[:, 1:]
    return written


def write_cal(path: Path, columns: Sequence[str] = ("ax", "ay", "az")) -> Path:
    doc: dict[str, Any] = {
        "format": "tumblecal-calibration",
        "version": 1,
        "sensor": "accelerometer",
        "method": "three-pose",
        "reference": 1.0,
        "units": "g",
        "input_units": None,
        "columns": list(columns),
        "offset": OFFSET.tolist(),
        "matrix": MATRIX.tolist(),
        "gain": np.diag(np.linalg.inv(MATRIX)).tolist(),
    }
    path.write_text(json.dumps(doc, indent=2) + "\n")
    return path


def corrected(raw: FloatArray) -> FloatArray:
    """M (raw - offset), computed the way core.apply does (broadcast products), so bit-equal."""
    d = raw - OFFSET
    out: FloatArray = d[:, 0:1] * MATRIX[:, 0] + d[:, 1:2] * MATRIX[:, 1] + d[:, 2:3] * MATRIX[:, 2]
    return out


def cells(line: str, delimiter: str | None = ",") -> list[str]:
    return line.split() if delimiter is None else line.split(delimiter)


@pytest.fixture
def cal(tmp_path: Path) -> Path:
    return write_cal(tmp_path / "cal.json")


# -- solve: the 3-pose sample set --------------------------------------------------------


def test_solve_three_pose_json_to_stdout_table_to_stderr(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", *POSES_3)
    assert r.code == 0, r.err
    doc = json.loads(r.out)  # stdout is the calibration and nothing else
    assert doc["format"] == "tumblecal-calibration"
    assert doc["version"] == 1
    assert doc["method"] == "three-pose"
    assert doc["columns"] == ["ax", "ay", "az"]
    assert doc["units"] == "g"
    np.testing.assert_allclose(doc["offset"], TRUE_OFFSET, atol=3e-4)
    np.testing.assert_allclose(doc["gain"], TRUE_GAIN, atol=3e-4)
    np.testing.assert_allclose(doc["matrix"], np.diag(1 / np.array(doc["gain"])), rtol=1e-12)
    assert [p["pose"] for p in doc["poses"]] == ["+x", "+y", "+z"]
    assert [p["file"] for p in doc["poses"]] == POSES_3
    assert [p["samples"] for p in doc["poses"]] == [1000, 1000, 1000]
    # people's table on stderr: the method, each axis's column, offset and gain
    assert "three-pose" in r.err
    for word in ("offset", "gain", "ax", "ay", "az"):
        assert word in r.err
    assert "poses" not in r.err.split()  # the per-pose table is -v's
    assert "error" not in r.err
    assert "\x1b[" not in r.err, "no colour when stderr is not a terminal"


def test_solve_output_json_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", out)
    assert r.code == 0, r.err
    assert r.out == ""
    assert str(out) in r.err
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"
    np.testing.assert_allclose(doc["offset"], TRUE_OFFSET, atol=3e-4)


def test_solve_output_yaml_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.yaml"
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", out)
    assert r.code == 0, r.err
    assert r.out == ""
    text = out.read_text()
    assert text.startswith("format: tumblecal-calibration\n")  # YAML, not JSON
    doc = yaml.safe_load(text)
    assert doc["method"] == "three-pose"
    np.testing.assert_allclose(doc["gain"], TRUE_GAIN, atol=3e-4)


def test_solve_quiet_prints_nothing_on_stderr(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--quiet", "--poses", *POSES_3, "-o", tmp_path / "cal.json")
    assert (r.code, r.out, r.err) == (0, "", "")


def test_solve_output_replaces_an_existing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    assert run(capsys, "solve", "-q", "--poses", *POSES_3, "-o", out).code == 0
    assert json.loads(out.read_text())["method"] == "three-pose"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]


# -- solve: --poses parsing --------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "args",
    [
        pytest.param(["--poses", *POSES_3, "-o", "OUT"], id="poses-then-options"),
        pytest.param(["-o", "OUT", "--poses", *POSES_3], id="options-then-poses"),
        pytest.param(["-o", "OUT", "--poses", *POSES_3, "--reference", "1", "-q"], id="options-around"),
        pytest.param([f"--poses={POSES_3[0]}", *POSES_3[1:], "-o", "OUT"], id="poses-equals"),
        pytest.param(["-p", *POSES_3, "-o", "OUT"], id="short-p"),
        pytest.param(["--sensor", "accelerometer", "--poses", *POSES_3, "--output=OUT"], id="sensor-first"),
    ],
)
def test_solve_poses_take_every_file_after_one_flag(
    args: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", *[a.replace("OUT", str(out)) for a in args])
    assert r.code == 0, r.err
    assert r.out == ""
    doc = json.loads(out.read_text())
    assert doc["method"] == "three-pose"
    assert [p["file"] for p in doc["poses"]] == POSES_3


@pytest.mark.parametrize("up", [["--up", "-x"], ["--up=-x"], ["--up", "xn"]])
def test_solve_one_pose_up_minus_x(up: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", SAMPLE / "xn.csv", *up, "-q")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["method"] == "one-pose"
    assert doc["poses"][0]["pose"] == "-x"
    # xn reads x = -gain + offset = -1.012 + 0.021; the 1-pose offset is that + 1
    np.testing.assert_allclose(doc["offset"], [-1.012 + 0.021 + 1, -0.034, 0.047], atol=5e-4)


@pytest.mark.parametrize("files", [POSES_3[:2], [*POSES_3, str(SAMPLE / "zn.csv")]], ids=["2-files", "4-files"])
def test_solve_wrong_number_of_pose_files(files: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *unnamed(files, tmp_path / "unnamed"), "-o", out)
    assert_one_error(
        r,
        f"--poses: no solver takes {len(files)} unlabelled files: give 1 (one-pose), 3 (+x +y +z), "
        "6 (+x -x +y -y +z -z), 12+ unlabelled (sphere) or 4+ labelled (least-squares)",
        hint="label a file with its face or direction: --poses +x=a.csv -x=b.csv 0.707,0,0.707=c.csv",
    )
    assert_untouched(out)


def test_solve_wrong_number_of_files_named_for_faces_says_the_names_gave_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Files named for their faces are labelled by their names, whatever their count: the error
    names the faces and says where they came from."""
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *POSES_3[:2], "-o", out)
    assert_one_error(
        r,
        "--poses: no face on the z axis: add +z or -z (faces given: +x +y)",
        hint="the files' names gave the faces (x.csv +x, y.csv +y); every axis needs a pose with it pointing "
        "up or down: one face per axis solves as three-pose (e.g. --poses -z=a.csv -x=b.csv +y=c.csv), "
        "four or more as least-squares",
    )
    assert_untouched(out)


def test_solve_without_poses_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve")
    assert r.code == 2
    assert r.out == ""
    assert "--poses" in r.err
    assert "Traceback" not in r.err


def test_solve_poses_flag_without_files_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses")
    assert r.code == 2
    assert r.out == ""
    assert "--poses" in r.err


def test_solve_unknown_face(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", SAMPLE / "z.csv", "--up", "up")
    assert_one_error(r, "--up: unknown face 'up': use one of +x -x +y -y +z -z (or xp xn yp yn zp zn)")


# -- solve: the 1-pose solver on every face, and its units check --------------------------

FACE_VECTORS = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("up", "face"),
    [("+x", "+x"), ("-x", "-x"), ("+y", "+y"), ("-y", "-y"), ("+z", "+z"), ("-z", "-z"), ("xp", "+x"), ("zn", "-z")],
)
def test_solve_one_pose_each_face(up: str, face: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    v = np.array(FACE_VECTORS[face], dtype=np.float64)
    values = write_pose(tmp_path / "pose.csv", v + TRUE_OFFSET, seed=sum(map(ord, face)))
    r = run(capsys, "solve", "--poses", tmp_path / "pose.csv", f"--up={up}")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["method"] == "one-pose"
    assert doc["poses"][0]["pose"] == face
    assert doc["gain"] == [1.0, 1.0, 1.0]
    assert doc["matrix"] == [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    np.testing.assert_allclose(doc["offset"], values.mean(axis=0) - v, rtol=0, atol=1e-12)  # offset = mean - v
    np.testing.assert_allclose(doc["offset"], TRUE_OFFSET, atol=1e-3)  # 1e-3 ~ 7 standard errors
    np.testing.assert_allclose(doc["uncertainty"]["offset"], values.std(axis=0, ddof=1) / np.sqrt(200), rtol=1e-9)
    assert "one-pose" in r.err


def test_solve_units_mistake_ms2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "units_ms2_pose_z.csv"
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", pose, "-o", out)
    assert_one_error(
        r,
        f"{pose}: the pose reads 9.858 in magnitude but --reference is 1: a units mistake?",
        hint="--reference 9.80665",
    )
    assert_untouched(out)


def test_solve_units_mistake_counts(capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "units_counts16384_pose_z.csv"
    r = run(capsys, "solve", "--poses", pose)
    assert_one_error(
        r,
        f"{pose}: the pose reads 1.717e+04 in magnitude but --reference is 1: a units mistake?",
        hint="--reference 16384",
    )


def test_solve_counts_with_their_reference(capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "units_counts16384_pose_z.csv"
    r = run(capsys, "solve", "--poses", pose, "--reference", "16384", "--input-units", "counts", "-q")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["reference"] == 16384.0
    assert doc["input_units"] == "counts"
    assert doc["units"] is None
    np.testing.assert_allclose(doc["offset"], [344, -557, 770], atol=1.0)


def test_solve_units_mistake_on_the_opposite_face(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # m/s^2 data with -y up: the magnitude is the same, the hint too
    write_pose(tmp_path / "yn.csv", [0.2, -9.81, 0.4], noise=0.02)
    r = run(capsys, "solve", "--poses", tmp_path / "yn.csv", "--up", "-y")
    assert r.code == 2
    assert "--reference 9.80665" in r.err
    r = run(capsys, "solve", "--poses", tmp_path / "yn.csv", "--up", "-y", "--reference", "9.80665", "-q")
    assert r.code == 0, r.err
    np.testing.assert_allclose(json.loads(r.out)["offset"], [0.2, -9.81 + 9.80665, 0.4], atol=0.01)


# -- solve: the real imucal capture (accelerometer and gyroscope columns) -----------------


def test_solve_real_data_picks_accelerometer_columns(capsys: pytest.CaptureFixture[str]) -> None:
    files = [IMUCAL / "xp.csv", IMUCAL / "yp.csv", IMUCAL / "zp.csv"]
    r = run(capsys, "solve", "--poses", *files, "--reference", "9.81")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["sensor"] == "accelerometer"
    assert doc["columns"] == ["acc_x", "acc_y", "acc_z"]
    assert doc["reference"] == 9.81
    # about 2040-2110 counts per g: the gains are counts per m/s^2
    assert all(200 < g < 220 for g in doc["gain"])
    assert "acc_x" in r.err
    assert "gyr_x" not in r.err


def test_solve_real_data_gyroscope_columns(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", IMUCAL / "xp.csv", "--sensor", "gyroscope", "-q")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["sensor"] == "gyroscope"
    assert doc["columns"] == ["gyr_x", "gyr_y", "gyr_z"]
    assert doc["reference"] == 0.0  # zero rate at rest: the offset is the mean
    np.testing.assert_allclose(doc["offset"], doc["poses"][0]["mean"], rtol=0, atol=0)


def test_solve_real_data_no_magnetometer(capsys: pytest.CaptureFixture[str]) -> None:
    pose = IMUCAL / "zp.csv"
    r = run(capsys, "solve", "--poses", pose, "--sensor", "magnetometer")
    assert_one_error(
        r,
        f"{pose}: no magnetometer x,y,z columns found "
        "(columns: part, samples, acc_x, acc_y, acc_z, gyr_x, gyr_y, gyr_z)",
        hint="--columns",
    )


def test_solve_columns_option_overrides(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", IMUCAL / "zp.csv", "--columns", "acc_y,acc_x,acc_z", "--reference", "2048")
    assert r.code == 0, r.err
    assert json.loads(r.out)["columns"] == ["acc_y", "acc_x", "acc_z"]


def test_solve_upside_down_pose_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "upside_down_x.csv"
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", pose, *POSES_3[1:], "-o", out)
    assert r.code == 3, r.err
    assert r.out == ""
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert errors == [f"error: {pose}: declared +x but reads like -x (mean -0.979, -0.034, 0.047): upside down"]
    assert "hint: turn the unit over so that its x axis points up" in r.err
    assert "Traceback" not in r.err
    assert_untouched(out)


# -- apply: what it keeps, what it changes ------------------------------------------------


def _interleaved_capture(path: Path, n: int = 300) -> tuple[bytes, FloatArray, list[bool]]:
    """A capture with a CRLF '#' preamble, a zero-padded integer time, a text column and
    interleaved rows whose sensor cells are all empty. Returns the bytes, the raw values
    (NaN on empty rows) and which rows are empty."""
    rng = np.random.default_rng(7)
    head = b"# station: line 3, bay 7\r\n#   operator: A. N. Other\r\n\r\ntime,ax,ay,az,label\r\n"
    raw = rng.normal(0, 1, (n, 3)) + np.array([0.1, -0.2, 1.0])
    labels = ["at rest", "  two  spaces ", "", "x=1; y=2", "ünïcödé ✓", "say 'hi'", "tab\there"]
    empty = [i % 5 == 3 for i in range(n)]
    rows = []
    for i in range(n):
        t = f"{1000 + 10 * i:08d}"
        label = labels[i % len(labels)]
        if empty[i]:
            rows.append(f"{t},,,,gps fix {i}")
            raw[i] = np.nan
            continue
        styles = [f"{v:.6f}" for v in raw[i]]
        if i % 7 == 1:  # integers and exponents are numbers too
            styles = [str(round(v * 1000)) for v in raw[i]]
            raw[i] = [float(s) for s in styles]
        elif i % 7 == 2:
            styles = [f"{v:.3e}" for v in raw[i]]
        raw[i] = [float(s) for s in styles]
        rows.append(f"{t},{','.join(styles)},{label}")
    data = head + "\r\n".join(rows).encode() + b"\r\n"
    path.write_bytes(data)
    return data, raw, empty


def test_apply_keeps_every_other_byte(cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "capture.csv"
    data, raw, empty = _interleaved_capture(src)
    out = tmp_path / "corrected.csv"
    r = run(capsys, "apply", "--cal", cal, src, "-o", out)
    assert r.code == 0, r.err
    assert r.out == ""
    assert f"corrected 300 rows of {src}" in r.err
    result = out.read_bytes()
    head_len = data.index(b"time,ax")
    head_len = data.index(b"\r\n", head_len) + 2
    assert result[:head_len] == data[:head_len], "preamble and header are copied verbatim"
    assert result.endswith(b"\r\n")
    assert b"\n" not in result.replace(b"\r\n", b""), "CRLF is kept on every line"
    src_rows = data[head_len:].decode().split("\r\n")[:-1]
    out_rows = result[head_len:].decode().split("\r\n")[:-1]
    assert len(out_rows) == len(src_rows) == 300
    values = np.full((300, 3), np.nan)
    for i, (before, after) in enumerate(zip(src_rows, out_rows, strict=True)):
        b, a = before.split(","), after.split(",")
        assert len(a) == len(b) == 5
        assert a[0] == b[0]  # 00001000 stays 00001000
        assert a[4] == b[4]  # the text column, byte for byte
        if empty[i]:
            assert a[1:4] == ["", "", ""]
        else:
            values[i] = [float(c) for c in a[1:4]]
    keep = ~np.array(empty)
    expected = corrected(raw[keep])
    # bit for bit: the text written parses back to exactly the float64 apply computed
    np.testing.assert_array_equal(values[keep], expected)
    np.testing.assert_allclose(values[keep], (raw[keep] - OFFSET) @ MATRIX.T, rtol=0, atol=1e-12)


def test_apply_stdout_equals_file_output(cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "capture.csv"
    _interleaved_capture(src, n=40)
    out = tmp_path / "corrected.csv"
    assert run(capsys, "apply", "--cal", cal, src, "-o", out, "-q").code == 0
    capsys.readouterr()
    r = run(capsys, "apply", "--cal", cal, src)
    assert r.code == 0, r.err
    assert r.out.encode() == out.read_bytes()
    assert "-> stdout" in r.err


def test_apply_sample_capture_reads_one_g(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "--poses", *POSES_3, "-o", cal).code == 0
    out = tmp_path / "corrected.csv"
    assert run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out).code == 0
    fixed = np.loadtxt(out, delimiter=",", skiprows=1)
    assert fixed.shape == (3000, 4)
    np.testing.assert_array_equal(fixed[:, 0], np.loadtxt(SAMPLE / "capture.csv", delimiter=",", skiprows=1)[:, 0])
    segments = np.linalg.norm(fixed[:, 1:], axis=1).reshape(6, 500).mean(axis=1)
    np.testing.assert_allclose(segments, 1.0, atol=5e-4)


@pytest.mark.slow
def test_apply_stdin_to_stdout_subprocess(cal: Path, tmp_path: Path) -> None:
    src = tmp_path / "capture.csv"
    data, _, _ = _interleaved_capture(src, n=50)
    via_file = run_exe(["apply", "--cal", cal, src, "-q"])
    assert via_file.returncode == 0, via_file.stderr
    piped = run_exe(["apply", "--cal", cal], stdin=data)  # cat capture.csv | tumblecal apply --cal cal.json
    assert piped.returncode == 0, piped.stderr
    assert piped.stdout == via_file.stdout
    assert b"corrected 50 rows of <stdin>" in piped.stderr
    assert b"Traceback" not in piped.stderr
    dash = run_exe(["apply", "--cal", cal, "-", "-o", "-", "-q"], stdin=data)
    assert (dash.returncode, dash.stdout, dash.stderr) == (0, via_file.stdout, b"")


@pytest.mark.slow
def test_apply_real_pipe_from_cat(cal: Path, tmp_path: Path) -> None:
    src = tmp_path / "capture.csv"
    _interleaved_capture(src, n=30)
    cat = shutil.which("cat")
    if cat is None:
        pytest.skip("no cat")
    expected = run_exe(["apply", "--cal", cal, src, "-q"]).stdout
    with subprocess.Popen([cat, str(src)], stdout=subprocess.PIPE) as producer:
        consumer = subprocess.run(
            [tumblecal_exe(), "apply", "--cal", str(cal), "-q"],
            stdin=producer.stdout,
            capture_output=True,
            timeout=60,
            check=False,
        )
    assert consumer.returncode == 0, consumer.stderr
    assert consumer.stdout == expected


def test_apply_dash_reads_stdin_in_process(
    cal: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = b"t,ax,ay,az\n0.00,0.5,-0.25,1.0\n0.01,0.0,0.0,0.0\n"
    feed_stdin(monkeypatch, data)
    out = tmp_path / "out.csv"
    r = run(capsys, "apply", "--cal", cal, "-", "-o", out)
    assert r.code == 0, r.err
    lines = out.read_text().splitlines()
    assert lines[0] == "t,ax,ay,az"
    raw = np.array([[0.5, -0.25, 1.0], [0.0, 0.0, 0.0]])
    got = np.array([[float(c) for c in ln.split(",")[1:]] for ln in lines[1:]])
    np.testing.assert_array_equal(got, corrected(raw))
    assert [ln.split(",")[0] for ln in lines[1:]] == ["0.00", "0.01"]


RAW = np.array([[0.1, -0.2, 0.98], [1, 2, 3], [-0.5, 0.25, 33108]])


@pytest.mark.parametrize(
    ("name", "text", "delimiter"),
    [
        pytest.param("semicolon", "t;ax;ay;az\n0;0.1;-0.2;0.98\n1;1;2;3\n2;-0.5;0.25;33108\n", ";", id="semicolon"),
        pytest.param("tab", "t\tax\tay\taz\n0\t0.1\t-0.2\t0.98\n1\t1\t2\t3\n2\t-0.5\t0.25\t33108\n", "\t", id="tab"),
        pytest.param(
            "bom", "\ufefft,ax,ay,az\r\n0,0.1,-0.2,0.98\r\n1,1,2,3\r\n2,-0.5,0.25,33108\r\n", ",", id="bom-crlf"
        ),
        pytest.param("headerless", "0.1,-0.2,0.98\n1,2,3\n-0.5,0.25,33108\n", ",", id="headerless-3"),
        pytest.param("headerless4", "0,0.1,-0.2,0.98\n1,1,2,3\n2,-0.5,0.25,33108\n", ",", id="headerless-4"),
    ],
)
def test_apply_delimiters_bom_headerless(
    name: str, text: str, delimiter: str, cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / f"{name}.csv"
    src.write_bytes(text.encode())
    out = tmp_path / "out.csv"
    r = run(capsys, "apply", "--cal", cal, src, "-o", out)
    assert r.code == 0, r.err
    result = out.read_bytes().decode()
    src_lines = text.splitlines(keepends=True)
    out_lines = result.splitlines(keepends=True)
    assert len(out_lines) == len(src_lines)
    has_header = not name.startswith("headerless")
    if has_header:
        assert out_lines[0] == src_lines[0]  # BOM and all
        src_lines, out_lines = src_lines[1:], out_lines[1:]
    else:
        assert "note:" in r.err  # the calibration's columns (ax, ay, az) are not there: detected
    first = 1 if len(cells(src_lines[0].rstrip("\r\n"), delimiter)) == 4 else 0
    got = np.array([[float(c) for c in cells(ln.rstrip("\r\n"), delimiter)[first:]] for ln in out_lines])
    np.testing.assert_array_equal(got, corrected(RAW))
    for before, after in zip(src_lines, out_lines, strict=True):
        assert after.endswith("\r\n") == before.endswith("\r\n")
        if first:
            assert cells(after, delimiter)[0] == cells(before, delimiter)[0]


def test_apply_whitespace_aligned(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = write_cal(tmp_path / "cal.json", columns=("x", "y", "z"))
    lines = [
        "   2.9840000e-02   3.3108000e+04   3.3329000e+04   3.6429000e+04",
        "   3.9857000e-02   3.3096000e+04   3.3336000e+04   3.6437000e+04",
        "\t4.9840000e-02 \t 3.3104000e+04   3.3333000e+04\t3.6429000e+04  ",
    ]
    src = tmp_path / "xsens.txt"
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.txt"
    r = run(capsys, "apply", "--cal", cal, src, "-o", out)
    assert r.code == 0, r.err
    assert "note:" not in r.err  # 4 headerless columns are t,x,y,z: the calibration's own
    result = out.read_text().splitlines()
    assert len(result) == 3
    raw = np.array([[float(c) for c in ln.split()[1:]] for ln in lines])
    got = np.array([[float(c) for c in ln.split(" ")[1:]] for ln in result])  # single spaces
    np.testing.assert_array_equal(got, corrected(raw))
    assert [ln.split(" ")[0] for ln in result] == ["2.9840000e-02", "3.9857000e-02", "4.9840000e-02"]


def test_apply_uses_the_calibrations_columns_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # two accelerometer triplets: detection alone is ambiguous, the calibration names one
    src = tmp_path / "two.csv"
    src.write_text("t,acc_x,acc_y,acc_z,acc2_x,acc2_y,acc2_z\n0,1,2,3,4,5,6\n")
    raw = np.array([[4.0, 5.0, 6.0]])
    cal = write_cal(tmp_path / "cal.json", columns=("ACC2_X", "acc2_y", "acc2_z"))  # case-insensitive
    r = run(capsys, "apply", "--cal", cal, src)
    assert r.code == 0, r.err
    assert "note:" not in r.err
    row = r.out.splitlines()[1].split(",")
    assert row[:4] == ["0", "1", "2", "3"]
    np.testing.assert_array_equal([float(c) for c in row[4:]], corrected(raw)[0])


def test_apply_columns_option_overrides_the_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "two.csv"
    src.write_text("t,acc_x,acc_y,acc_z,acc2_x,acc2_y,acc2_z\n0,1,2,3,4,5,6\n")
    cal = write_cal(tmp_path / "cal.json", columns=("acc2_x", "acc2_y", "acc2_z"))
    for columns in ("acc_x,acc_y,acc_z", "1,2,3"):
        r = run(capsys, "apply", "--cal", cal, src, "--columns", columns)
        assert r.code == 0, r.err
        assert "note:" in r.err  # told that other columns than the calibration's are corrected
        row = r.out.splitlines()[1].split(",")
        assert row[0] == "0"
        assert row[4:] == ["4", "5", "6"]
        np.testing.assert_array_equal([float(c) for c in row[1:4]], corrected(np.array([[1.0, 2.0, 3.0]]))[0])


def test_apply_ambiguous_triplets_without_calibration_columns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "two.csv"
    src.write_text("t,acc_x,acc_y,acc_z,acc2_x,acc2_y,acc2_z\n0,1,2,3,4,5,6\n")
    cal = write_cal(tmp_path / "cal.json", columns=("ax", "ay", "az"))
    r = run(capsys, "apply", "--cal", cal, src)
    assert_one_error(
        r,
        f"{src}: several accelerometer triplets could be meant: acc_x,acc_y,acc_z; acc2_x,acc2_y,acc2_z",
        hint="--columns",
    )


def test_names_with_brackets_are_not_markup(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """File and column names reach stderr as they are (Rich would eat '[bold]' as markup)."""
    src = tmp_path / "cap[bold].csv"
    src.write_text("t,a[x],a[y],a[z]\n0,1,2,3\n")
    cal = write_cal(tmp_path / "cal.json")
    out = tmp_path / "out[red].csv"
    r = run(capsys, "apply", "--cal", cal, src, "-o", out, "--columns", "a[x],a[y],a[z]")
    assert r.code == 0, r.err
    assert f"note: {src}: correcting columns a[x], a[y], a[z] (the calibration was made from ax, ay, az)\n" in r.err
    assert f"corrected 1 rows of {src} (a[x], a[y], a[z]) -> {out}\n" in r.err


# -- help and version ------------------------------------------------------------------


@pytest.mark.parametrize("args", [["--help"], ["-h"], ["solve", "--help"]])
def test_help_mentions_exit_statuses(args: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, *args)
    assert r.code == 0
    assert r.out.startswith("Usage: tumblecal")
    text = " ".join(r.out.split())
    assert "Exit status, the first that applies: 2 usage or input error" in text
    assert "3 capture rejected by a quality check" in text
    assert "1 calibrated but outside its limits; 0 pass" in text


def test_apply_help_lists_only_its_own_exit_statuses(capsys: pytest.CaptureFixture[str]) -> None:
    text = " ".join(run(capsys, "apply", "--help").out.split())
    assert "Exit status: 0 corrected; 2 usage or input error (nothing written" in text
    assert "capture rejected" not in text  # apply never exits 3 or 1


def test_solve_help_explains_poses_and_sign(capsys: pytest.CaptureFixture[str]) -> None:
    text = " ".join(run(capsys, "solve", "--help").out.split())
    for words in ("--poses", "--up", "--reference", "9.80665", "16384", "reads -1 g", "--sensor"):
        assert words in text


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "--version")
    assert (r.code, r.out, r.err) == (0, f"tumblecal {__version__}\n", "")
    assert __version__ == "0.1.0"


@pytest.mark.slow
def test_python_dash_m_version() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "tumblecal_cli", "--version"], capture_output=True, timeout=60, check=False
    )
    assert (done.returncode, done.stdout, done.stderr) == (0, b"tumblecal 0.1.0\n", b"")


@pytest.mark.slow
def test_console_script_version() -> None:
    done = run_exe(["--version"])
    assert (done.returncode, done.stdout, done.stderr) == (0, b"tumblecal 0.1.0\n", b"")


def test_unknown_option_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", POSES_3[0], "--frobnicate")
    assert r.code == 2
    assert r.out == ""
    assert "--frobnicate" in r.err


# -- bad input: exit 2, one error line naming the file, nothing written --------------------

CAPTURE_ERRORS = [
    pytest.param("empty.csv", "empty file", id="empty"),
    pytest.param("header_only.csv", "a header but no data rows", id="header-only"),
    pytest.param("comments_only.csv", "no data: the file holds only blank or # comment lines", id="comments-only"),
    pytest.param("non_numeric_cell.csv", "not a number: 'oops' (line 3, column ay)", id="non-numeric"),
    pytest.param(
        "partly_empty_sensor_row.csv",
        "empty sensor cell in a row whose other sensor cells are filled (line 4, column ay)",
        id="partly-empty-row",
    ),
    pytest.param(
        "no_sensor_columns.csv", "no accelerometer x,y,z columns found (columns: a, b, c, d)", id="no-sensor-columns"
    ),
    pytest.param("ragged_row.csv", "row has 3 fields, the header has 4 (line 3)", id="ragged-row"),
    pytest.param("binary_garbage.bin", "binary data, not a CSV text file", id="binary-garbage"),
    pytest.param("not_utf8.csv", "not UTF-8 text (byte 36)", id="not-utf8"),
    pytest.param("does_not_exist.csv", "no such file", id="missing-file"),
]


@pytest.mark.parametrize(("name", "message"), CAPTURE_ERRORS)
def test_solve_bad_capture(name: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / name
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", pose, "-o", out)
    assert_one_error(r, f"{pose}: {message}")
    assert_untouched(out)


@pytest.mark.parametrize(("name", "message"), CAPTURE_ERRORS)
def test_apply_bad_capture_to_file(
    name: str, message: str, cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = BAD / name
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", cal, src, "-o", out)
    assert_one_error(r, f"{src}: {message}{apply_names_the_calibration(name, cal)}")
    assert_untouched(out)


@pytest.mark.parametrize(("name", "message"), CAPTURE_ERRORS)
def test_apply_bad_capture_to_stdout(name: str, message: str, cal: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = BAD / name
    r = run(capsys, "apply", "--cal", cal, src)
    assert_one_error(
        r, f"{src}: {message}{apply_names_the_calibration(name, cal)}"
    )  # not even the header reaches stdout


def apply_names_the_calibration(name: str, cal: Path) -> str:
    """What apply adds to a capture without the sensor's columns: the calibration's side."""
    return f", but {cal} calibrates accelerometer columns ax, ay, az" if name == "no_sensor_columns.csv" else ""


@pytest.mark.parametrize(
    ("name", "message"),
    [
        pytest.param("non_numeric_cell.csv", "not a number: 'oops' in column 'ay' (data row 2)", id="non-numeric"),
        pytest.param(
            "partly_empty_sensor_row.csv",
            "empty sensor cell in a row whose other sensor cells are filled in column 'ay' (data row 3)",
            id="partly-empty-row",
        ),
        pytest.param("ragged_row.csv", "row has 3 fields, the header has 4: '0.01,0.01,-0.02'", id="ragged-row"),
        pytest.param("header_only.csv", "a header but no data rows", id="header-only"),
        pytest.param("empty.csv", "empty file", id="empty"),
        pytest.param("binary_garbage.bin", "binary data, not a CSV text file", id="binary-garbage"),
    ],
)
def test_apply_bad_capture_on_stdin(
    name: str,
    message: str,
    cal: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    feed_stdin(monkeypatch, (BAD / name).read_bytes())
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", cal, "-o", out)
    assert_one_error(r, f"<stdin>: {message}")  # no line numbers without a second pass: the data row
    assert_untouched(out)


def test_solve_bad_capture_on_stdin(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    feed_stdin(monkeypatch, (BAD / "non_numeric_cell.csv").read_bytes())
    r = run(capsys, "solve", "--poses", "-")
    assert_one_error(r, "<stdin>: not a number: 'oops' in column 'ay' (data row 2)")


def test_solve_one_bad_pose_among_three(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pose = BAD / "partly_empty_sensor_row.csv"
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", POSES_3[0], pose, POSES_3[2], "-o", out)
    assert_one_error(r, f"{pose}: empty sensor cell in a row whose other sensor cells are filled (line 4, column ay)")
    assert_untouched(out)


def test_apply_capture_without_the_sensor_columns(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "gyro_only.csv"
    src.write_text("t,gyr_x,gyr_y,gyr_z\n0,1,2,3\n")
    out = precious(tmp_path / "out.csv")
    r = run(capsys, "apply", "--cal", cal, src, "-o", out)
    assert_one_error(
        r,
        f"{src}: no accelerometer x,y,z columns found (columns: t, gyr_x, gyr_y, gyr_z), "
        f"but {cal} calibrates accelerometer columns ax, ay, az",
    )
    assert_untouched(out)


def test_apply_columns_option_names_a_missing_column(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = SAMPLE / "capture.csv"
    r = run(capsys, "apply", "--cal", cal, src, "--columns", "ax,ay,nope")
    assert_one_error(r, f"{src}: column 'nope' not found (columns: t, ax, ay, az)", hint="0-based index")


CAL_ERRORS = [
    pytest.param("cal_empty.json", "empty calibration file", id="empty"),
    pytest.param(
        "cal_empty_object.json",
        "not a tumblecal calibration: missing field 'format' (expected 'tumblecal-calibration')",
        id="empty-object",
    ),
    pytest.param(
        "cal_not_an_object.json", "not a calibration file: expected a JSON/YAML object at the top", id="not-an-object"
    ),
    pytest.param("cal_truncated.json", "not valid JSON: Expecting value (line 17, column 5)", id="truncated"),
    pytest.param(
        "cal_unknown_format.json",
        "not a tumblecal calibration: unknown format 'imucal-calibration' (expected 'tumblecal-calibration')",
        id="unknown-format",
    ),
    pytest.param(
        "cal_unknown_version.json",
        "unsupported calibration version 2 (this tumblecal reads version 1)",
        id="unknown-version",
    ),
    pytest.param("cal_missing_matrix.json", "missing field 'matrix'", id="missing-field"),
    pytest.param("cal_offset_not_numbers.json", "field 'offset' must be a finite number", id="offset-not-numbers"),
    pytest.param("does_not_exist.json", "no such calibration file", id="missing-file"),
]


@pytest.mark.parametrize(("name", "message"), CAL_ERRORS)
def test_apply_bad_calibration(name: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = BAD / name
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", bad, SAMPLE / "capture.csv", "-o", out)
    assert_one_error(r, f"{bad}: {message}")
    assert_untouched(out)


def test_apply_yaml_python_tag_is_refused_not_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # where `echo PWNED > pwned.txt` would land if it ran
    bad = BAD / "cal_python_tag.yaml"
    r = run(capsys, "apply", "--cal", bad, SAMPLE / "capture.csv")
    assert_one_error(
        r,
        f"{bad}: field 'sensor' is of the tag !!python/object/apply:os.system: tumblecal reads JSON's values only "
        "(text, numbers, true/false, null, lists, objects) (line 3, column 9)",
    )
    assert not (tmp_path / "pwned.txt").exists()
    assert list(tmp_path.iterdir()) == []


# -- no command writes onto one of its inputs ---------------------------------------------


def _copy_poses(tmp_path: Path) -> list[Path]:
    copies = []
    for name in ("x.csv", "y.csv", "z.csv"):
        shutil.copy(SAMPLE / name, tmp_path / name)
        copies.append(tmp_path / name)
    return copies


@pytest.mark.parametrize("spelling", ["same", "dot-slash", "dot-dot", "absolute"])
def test_solve_output_onto_an_input(
    spelling: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "sub").mkdir()
    _copy_poses(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = (tmp_path / "y.csv").read_bytes()
    out = {"same": "y.csv", "dot-slash": "./y.csv", "dot-dot": "sub/../y.csv", "absolute": str(tmp_path / "y.csv")}
    r = run(capsys, "solve", "--poses", "x.csv", "y.csv", "z.csv", "-o", out[spelling])
    assert_one_error(r, f"{out[spelling]}: -o would overwrite the input y.csv", hint="write the output to a new file")
    assert (tmp_path / "y.csv").read_bytes() == before


@pytest.mark.parametrize("target", ["capture", "calibration"])
def test_apply_output_onto_an_input(
    target: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copy(SAMPLE / "capture.csv", tmp_path / "capture.csv")
    write_cal(tmp_path / "cal.json")
    monkeypatch.chdir(tmp_path)
    before = {p: (tmp_path / p).read_bytes() for p in ("capture.csv", "cal.json")}
    victim = "capture.csv" if target == "capture" else "cal.json"
    r = run(capsys, "apply", "--cal", "cal.json", "capture.csv", "-o", f"./{victim}")
    assert_one_error(r, f"./{victim}: -o would overwrite the input {victim}", hint="write the output to a new file")
    assert {p: (tmp_path / p).read_bytes() for p in before} == before


def test_apply_output_folder_missing(cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "no" / "such" / "out.csv"
    r = run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out)
    assert_one_error(r, f"{out}: the output folder does not exist", hint=f"make it first: mkdir -p {out.parent}")


# -- --debug -------------------------------------------------------------------------------


def test_debug_raises_the_error_in_process(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(InputError, match="no such file"):
        main(["--debug", "solve", "--poses", str(BAD / "does_not_exist.csv")])
    capsys.readouterr()
    r = run(capsys, "solve", "--poses", BAD / "does_not_exist.csv")  # --debug does not stick
    assert r.code == 2
    assert "Traceback" not in r.err


@pytest.mark.slow
def test_debug_shows_a_traceback_subprocess() -> None:
    done = run_exe(["--debug", "solve", "--poses", BAD / "empty.csv"])
    assert done.returncode == 2  # the documented status (a station reads 1 as a unit out of limits)
    assert b"Traceback" in done.stderr
    assert b"empty file" in done.stderr
    plain = run_exe(["solve", "--poses", BAD / "empty.csv"])
    assert plain.returncode == 2
    assert plain.stdout == b""
    assert plain.stderr == f"error: {BAD / 'empty.csv'}: empty file\nhint: the capture has no bytes at all\n".encode()


def test_solve_rejects_a_non_finite_reading(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """nan/inf would poison the pose mean; apply passes them through, solve names the cell."""
    pose = BAD / "nan_in_pose.csv"
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", pose, "-o", out)
    assert_one_error(r, f"{pose}: not a finite number: 'nan' (line 3, column ay)")
    assert_untouched(out)


def test_apply_passes_non_finite_readings_through_quietly(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A logger's inf or nan stays inf or nan on the axes M mixes it into, and only there (inf x 0
    is not a nan on the other axes), with no numpy warning (the suite turns warnings into errors)."""
    doc = json.loads(cal.read_text())
    diagonal = np.diag([1.01, 0.99, 1.0])
    doc |= {"matrix": diagonal.tolist(), "gain": np.diag(np.linalg.inv(diagonal)).tolist()}
    cal.write_text(json.dumps(doc))
    src = tmp_path / "c.csv"
    src.write_text("t,ax,ay,az\n1,0.1,0.2,1.0\n2,inf,0.2,1.0\n3,nan,nan,nan\n")
    r = run(capsys, "apply", "-q", "--cal", cal, src)
    assert (r.code, r.err) == (0, "")
    rows = [line.split(",") for line in r.out.splitlines()[1:]]
    assert [row[0] for row in rows] == ["1", "2", "3"]
    good = core.apply(np.array([[0.1, 0.2, 1.0]]), np.array(doc["offset"]), diagonal)[0]
    assert rows[1][1:] == ["inf", repr(float(good[1])), repr(float(good[2]))]
    assert rows[2][1:] == ["nan", "nan", "nan"]
    mixed = np.asarray(MATRIX)  # with cross-axis terms, inf reaches the axes that mix x in
    assert np.isinf(core.apply(np.array([[np.inf, 0.2, 1.0]]), OFFSET, mixed)[0]).tolist() == [
        bool(v) for v in mixed[:, 0] != 0
    ]


def test_gyro_bias_of_an_accelerometer_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Not "the unit moved" (exit 3) on the accelerometer's columns: the command line is wrong."""
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--method", "gyro-bias", "--poses", SAMPLE / "z.csv", "-o", out)
    assert_one_error(r, "gyro-bias is a gyroscope's zero-rate bias: give --sensor gyroscope (not accelerometer)")
    assert_untouched(out)


def test_up_with_several_pose_files_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--up names the face of one file; with three it would be silently ignored."""
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *POSES_3, "--up", "-x", "-o", out)
    assert_one_error(
        r,
        "--up names the face of a single pose file, not of 3",
        hint="label each file instead (+x=a.csv -x=b.csv ...), name them for their faces (xp.csv xn.csv ...), "
        "or give them in the order +x +y +z",
    )
    assert_untouched(out)


# -- the parser's usage errors and a closed pipe ----------------------------------------


@pytest.mark.parametrize(
    ("args", "expected", "hint"),
    [
        (
            ["solve", "--poses", "z.csv", "--reference", "abc"],
            "Invalid value for '--reference': 'abc' is not a valid float.",
            "see 'tumblecal solve --help'",
        ),
        (["frobnicate"], "No such command 'frobnicate'.", "see 'tumblecal --help'"),
        (["apply", "--cal"], "Option '--cal' requires an argument.", "see 'tumblecal --help'"),
    ],
)
def test_usage_errors_are_one_line(
    args: list[str], expected: str, hint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert_one_error(run(capsys, *args), expected, hint=hint)


@pytest.mark.slow
@pytest.mark.parametrize(
    "command",
    [
        ["show", SAMPLE / "lot" / "SN0001_20261121T090000Z.json"],
        ["export", SAMPLE / "lot" / "SN0001_20261121T090000Z.json", "-f", "c-header"],
    ],
)
def test_output_to_a_reader_already_gone_is_141(command: list[str | Path]) -> None:
    """`tumblecal show cal.json | head -0`: every write fails; quietly 141 (Rich's own handler exits 1)."""
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run(
            [tumblecal_exe(), *map(str, command)], stdout=write, stderr=subprocess.PIPE, timeout=60, check=False
        )
    finally:
        os.close(write)
    assert (proc.returncode, proc.stderr) == (141, b"")


@pytest.mark.slow
@pytest.mark.parametrize("command", ["apply", "solve"])
def test_output_onto_the_file_on_stdin_is_refused(command: str, cal: Path, tmp_path: Path) -> None:
    """`tumblecal apply --cal cal.json -o c.csv < c.csv`: the input arrives by stdin, not by name."""
    capture = tmp_path / "c.csv"
    shutil.copy(SAMPLE / "z.csv", capture)
    before = capture.read_bytes()
    args = ["apply", "--cal", str(cal)] if command == "apply" else ["solve", "--poses", "-"]
    with capture.open("rb") as stdin:
        proc = subprocess.run(
            [tumblecal_exe(), *args, "-o", str(capture)], stdin=stdin, capture_output=True, timeout=60, check=False
        )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.decode().splitlines()[0] == f"error: {capture}: -o would overwrite the input standard input"
    assert capture.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


@pytest.fixture(scope="module")
def big(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """170 MB: apply's worker processes take most of a second (2M rows ended too soon)."""
    path = tmp_path_factory.mktemp("big") / "big.csv"
    path.write_text("t,ax,ay,az\n" + "0.001,0.012345,0.023456,1.012345\n" * 5_000_000)
    return path


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "said"),
    [
        (signal.SIGTERM, "error: interrupted (SIGTERM)"),
        (signal.SIGINT, "error: interrupted"),  # Typer made Ctrl-C a silent 130
        (signal.SIGHUP, "error: interrupted (SIGHUP)"),  # it killed the run, its temporary file left behind
    ],
)
def test_a_stop_mid_apply_leaves_no_temporary_file(
    cal: Path, big: Path, tmp_path: Path, signum: signal.Signals, said: str
) -> None:
    """A station's kill (SIGTERM), Ctrl-C or a closed terminal: exit 130, said, the old output
    as it was, no hidden temporary file beside it."""
    out = tmp_path / "out"
    out.mkdir()
    target = precious(out / "corrected.csv")

    def as_at_a_terminal() -> None:  # a runner that started us in the background ignores both: not the case here
        for s in (signal.SIGINT, signal.SIGHUP):
            signal.signal(s, signal.SIG_DFL)

    with subprocess.Popen(
        [tumblecal_exe(), "apply", "-q", "--cal", str(cal), str(big), "-o", str(target)],
        stderr=subprocess.PIPE,
        preexec_fn=as_at_a_terminal,
    ) as proc:
        deadline = time.monotonic() + 30
        while not any(p.name.endswith(".tmp") for p in out.iterdir()) and time.monotonic() < deadline:
            time.sleep(0.01)  # until it has started writing
        proc.send_signal(signum)
        assert proc.wait(timeout=60) == 130
        assert proc.stderr is not None
        assert proc.stderr.read().decode().splitlines() == [said]
    assert_untouched(target)
    assert sorted(p.name for p in out.iterdir()) == ["corrected.csv"]


@pytest.mark.slow
def test_closed_standard_streams_are_as_if_dev_null(cal: Path, tmp_path: Path) -> None:
    """`>&-`, `2>&-`, `<&-`: a traceback and exit 1, the error printed on stdout, 'internal
    error: AttributeError' for stdin. Now the run goes on as if they were /dev/null."""
    exe, out = tumblecal_exe(), tmp_path / "out.csv"

    def sh(line: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(["sh", "-c", line], capture_output=True, text=True, timeout=60, check=False)

    shown = sh(f"'{exe}' show '{cal}' >&-")
    assert (shown.returncode, shown.stderr) == (0, "")  # a table for people: as print() drops it
    data = sh(f"'{exe}' solve -q -p {' '.join(map(str, POSES_3))} >&-")  # the calibration is data
    assert (data.returncode, data.stderr.splitlines()[0]) == (
        2,
        "error: <stdout>: is closed: the output has nowhere to go",
    )
    hung = sh(f"'{exe}' apply --cal '{cal}' '{tmp_path / 'none.csv'}' -o '{out}' 2>/dev/full")
    assert hung.returncode == 2  # a stderr that takes nothing: the status stands (it was 1)
    failed = sh(f"'{exe}' apply --cal '{cal}' '{tmp_path / 'none.csv'}' -o '{out}' 2>&-")
    assert (failed.returncode, failed.stdout) == (2, "")  # the error went where stderr went: nowhere
    solved = sh(f"'{exe}' solve -p {' '.join(map(str, POSES_3))} -o '{tmp_path / 'c.json'}' 2>&-")
    assert solved.returncode == 0
    empty = sh(f"'{exe}' apply --cal '{cal}' - -o '{out}' <&-")
    assert (empty.returncode, empty.stderr.splitlines()[0]) == (2, "error: <stdin>: empty file")
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_disk_is_an_error_not_a_bug() -> None:
    with open("/dev/full", "wb") as full:
        proc = subprocess.run(
            [tumblecal_exe(), "solve", "--poses", str(SAMPLE / "z.csv")],
            stdout=full,
            stderr=subprocess.PIPE,
            check=False,
        )
    assert proc.returncode == 2
    assert proc.stderr.decode().splitlines() == ["error: <stdout>: cannot write: No space left on device"]


@pytest.mark.slow
def test_output_to_a_named_pipe_writes_into_it_and_keeps_it(tmp_path: Path) -> None:
    """`-o /dev/null`, `-o /dev/stdout`, a FIFO: written into, never replaced by a file (an
    atomic replace there would put a regular file where the device was). Tested on a FIFO."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    proc = subprocess.run(
        [tumblecal_exe(), "solve", "-q", "--poses", str(SAMPLE / "z.csv"), "-o", str(fifo)],
        capture_output=True, timeout=60, check=False,
    )  # fmt: skip
    reader.join(timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert json.loads(received[0])["method"] == "one-pose"


@pytest.mark.slow
def test_output_to_dev_stdout_is_the_stream_not_the_file_behind_it(tmp_path: Path) -> None:
    """`{ echo head; tumblecal ... -o /dev/stdout; } >> log`: written to the stream, the lines
    before it kept (a rename onto /proc/self/fd/1's file would lose them)."""
    log = tmp_path / "log.txt"
    log.write_text("head\n")
    script = f"{tumblecal_exe()} solve -q --poses {SAMPLE / 'z.csv'} -o /dev/stdout >> {log}"
    proc = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    head, rest = log.read_text().split("\n", 1)
    assert head == "head"
    assert json.loads(rest)["method"] == "one-pose"


@pytest.mark.slow
def test_output_through_a_symbolic_link_replaces_its_target(tmp_path: Path) -> None:
    target = tmp_path / "cal_2026.json"
    target.write_text("old")
    link = tmp_path / "latest.json"
    link.symlink_to(target.name)
    proc = subprocess.run(
        [tumblecal_exe(), "solve", "-q", "--poses", str(SAMPLE / "z.csv"), "-o", str(link)],
        capture_output=True, timeout=60, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert link.is_symlink()
    assert json.loads(target.read_text())["method"] == "one-pose"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal_2026.json", "latest.json"]


@pytest.mark.slow
def test_a_narrow_terminal_never_crops_the_numbers(tmp_path: Path) -> None:
    """At 50 columns the summary's numbers are printed whole (the lines run long) rather than
    cut to digits that look valid and are not."""
    env = {**os.environ, "COLUMNS": "50", "NO_COLOR": "1"}
    proc = subprocess.run(
        [tumblecal_exe(), "solve", "--poses", *map(str, POSES_3), "-o", str(tmp_path / "cal.json")],
        capture_output=True, text=True, env=env, timeout=60, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "cal.json").read_text())
    lines = proc.stderr.splitlines()
    assert any(line.split()[:2] == ["axis", "column"] and line.rstrip().endswith("± tilt") for line in lines)
    x_row = next(line.split() for line in lines if line.startswith(" x "))
    assert x_row[2] == f"{doc['offset'][0]:.6g}"
    assert x_row[3] == f"{doc['uncertainty']['offset'][0]:.2g}"


@pytest.mark.slow
def test_a_file_too_large_names_the_output(cal: Path, tmp_path: Path) -> None:
    """A refused write to a file names that file (the OS error carries no name of its own)."""
    out = tmp_path / "corrected.csv"
    script = f"ulimit -f 2; exec {tumblecal_exe()} apply -q --cal {cal} {SAMPLE / 'capture.csv'} -o {out}"
    proc = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [f"error: {out}: cannot write: File too large"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]


@pytest.mark.slow
def test_closed_stdout_stops_quietly_with_141(tmp_path: Path) -> None:
    """`tumblecal apply ... | head -1`: the reader goes away; no traceback, status 141."""
    cal = tmp_path / "cal.json"
    assert (
        run_exe(["solve", "--poses", SAMPLE / "x.csv", SAMPLE / "y.csv", SAMPLE / "z.csv", "-o", cal]).returncode == 0
    )
    big = tmp_path / "big.csv"
    rows = "\n".join(f"{i},0.01,0.02,1.0" for i in range(300_000))
    big.write_text(f"t,ax,ay,az\n{rows}\n")
    with subprocess.Popen(
        [tumblecal_exe(), "apply", "-q", "--cal", str(cal), str(big)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    ) as proc:
        assert proc.stdout is not None
        assert proc.stderr is not None
        assert proc.stdout.readline() == b"t,ax,ay,az\n"
        proc.stdout.close()
        assert proc.wait(timeout=60) == 141
        assert proc.stderr.read() == b""


# -- --json: the status word, and an error as a JSON object ------------------------------------


def error_object(out: str) -> dict[str, Any]:
    """The one JSON document on stdout: an error object."""
    doc: dict[str, Any] = json.loads(out)
    assert list(doc) == ["status", "exit_status", "error"]
    assert list(doc["error"]) == ["file", "line", "column", "message", "hint", "more"]
    return doc


def test_json_input_error_prints_an_error_object(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "z.csv"
    bad.write_text("t,ax,ay,az\n0,0,0,1\n1,0,x,1\n")
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", bad, "-o", out, "--json")
    assert r.code == 2
    doc = error_object(r.out)
    assert (doc["status"], doc["exit_status"]) == ("error", 2)
    assert doc["error"] | {"hint": None} == {
        "file": str(bad),
        "line": 3,
        "column": "ay",
        "message": "not a number: 'x'",
        "hint": None,
        "more": [],
    }
    assert [ln for ln in r.err.splitlines() if ln.startswith("error:")] == [
        f"error: {bad}: not a number: 'x' (line 3, column ay)"
    ]  # stderr still has its one line
    assert_untouched(out)

    r = run(capsys, "solve", "--poses", bad, "-o", out)  # without --json: nothing on stdout
    assert (r.code, r.out) == (2, "")


@pytest.mark.parametrize(
    ("args", "message", "hint"),
    [
        (["solve", "--poses", "z.csv", "--json", "--max-tilt", "lots"], "Invalid value for '--max-tilt'", "--help"),
        (["check", "MISSING", "--max-offset", "1", "--json"], "no such calibration file", None),
        (["verify", "--cal", "MISSING", "z.csv", "--json"], "no such calibration file", None),
        (["batch", "MISSING", "--out-dir", "OUT", "--json"], "no such folder or manifest file", None),
        (["report", "MISSING", "--json"], "no such file or folder", None),
        (["show", "MISSING", "--json"], "no such calibration file", None),
    ],
    ids=["usage", "check", "verify", "batch", "report", "show"],
)
def test_every_json_command_prints_its_exit_2_as_an_error_object(
    args: list[str], message: str, hint: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    given = [a.replace("MISSING", str(tmp_path / "missing.json")).replace("OUT", str(tmp_path / "out")) for a in args]
    r = run(capsys, *given)
    assert r.code == 2
    doc = error_object(r.out)
    assert (doc["status"], doc["exit_status"]) == ("error", 2)
    assert message in doc["error"]["message"]
    if hint is not None:
        assert hint in doc["error"]["hint"]
    assert len([ln for ln in r.err.splitlines() if ln.startswith("error:")]) == 1


def test_json_after_double_dash_or_on_a_command_without_it_prints_nothing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    r = run(capsys, "apply", "--json")  # apply has no --json: its usage error stays on stderr
    assert (r.code, r.out) == (2, "")
    assert "No such option: --json" in r.err
    r = run(capsys, "solve", "--poses", "missing.csv", "-o", "cal.json", "--", "--json")
    assert (r.code, r.out) == (2, "")


@pytest.mark.parametrize(
    ("command", "status", "code"),
    [
        (["solve", "-p", *POSES_3, "--max-offset", "0.01"], "fail", 1),
        (["solve", "-p", *POSES_3], "pass", 0),
        (["solve", "-p", *POSES_3, "--max-noise", "0.0001"], "rejected", 3),
    ],
    ids=["fail", "pass", "rejected"],
)
def test_json_status_words(
    command: list[str], status: str, code: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, *command, "-o", out, "--json", "-q")
    assert r.code == code
    doc = json.loads(r.out)
    assert (doc["status"], doc["exit_status"]) == (status, code)
    if code in (0, 1):  # check judges it again; verify judges the captures it corrects
        judged = run(capsys, "check", out, "--json", "-q", "--max-offset", "0.01" if code == 1 else "1")
        assert (json.loads(judged.out)["status"], json.loads(judged.out)["exit_status"]) == (status, code)
        for limit, word in (("0.5", "pass"), ("1e-9", "fail")):
            verified = run(capsys, "verify", "--cal", out, *POSES_3, "--json", "-q", "--max-norm-error", limit)
            doc = json.loads(verified.out)
            assert (doc["status"], doc["exit_status"]) == (word, verified.code)


# -- a column named for two roles ---------------------------------------------------------------

TIME_TWICE = "--columns names 't', the time column"
THERMAL = ["thermal", f"+z={SAMPLE / 'thermal' / 'sweep_up_zp.csv'}", "--cal", "CAL", "--reference-temperature", "25"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        pytest.param(["solve", "-p", *POSES_3, "--columns", "t,ax,ay"], TIME_TWICE, id="solve"),
        pytest.param(["noise", POSES_3[0], "--columns", "t,ax,ay"], TIME_TWICE, id="noise"),
        pytest.param(["verify", "--cal", "CAL", "--columns", "t,ax,ay", POSES_3[0]], TIME_TWICE, id="verify"),
        pytest.param(
            ["apply", "--cal", "CAL", "--columns", "t,ax,ay", POSES_3[0], "-o", "OUT"], TIME_TWICE, id="apply"
        ),
        pytest.param(
            ["solve", "-p", *POSES_3, "--time-column", "ay"],
            "--time-column names 'ay', one of the accelerometer columns",
            id="time-column",
        ),
        pytest.param(
            [*THERMAL, "--temperature-column", "ax"],
            "--temperature-column names 'ax', one of the accelerometer columns",
            id="thermal-sensor",
        ),
        pytest.param(
            [*THERMAL, "--temperature-column", "t"],
            "--temperature-column names 't', the time column",
            id="thermal-time",
        ),
    ],
)
def test_a_column_named_for_two_roles_is_one_error_line_not_an_internal_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str | Path], message: str
) -> None:
    """A sensor column that is also the time (or temperature) column was read twice: 'internal
    error: KeyError: Field "0" exists 2 times in schema'."""
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "-q", "-p", *POSES_3, "-o", cal).code == 0
    out = precious(tmp_path / "out.csv")
    args = [cal if a == "CAL" else out if a == "OUT" else a for a in args]
    r = run(capsys, *args)
    assert r.code == 2, r.err
    assert r.out == ""
    error, hint = r.err.splitlines()
    assert error.startswith("error: ")
    assert error.endswith(message)
    assert hint.startswith("hint: name ")
    assert "(columns: t, " in hint
    assert_untouched(out)

"""The Python API (README "Using tumblecal from Python"): each solver through ``tumblecal.solve``
gives what ``tumblecal solve`` writes; ``Calibration.apply`` on arrays and DataFrames gives what
``tumblecal apply`` writes; data in memory solves as its files do; errors are the exception family."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tumblecal_cli as tumblecal
from tests.test_cli import run
from tests.test_solvers_cli import METHOD_CASES, six_faces, write_csv

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data"


def _api_call(given: Sequence[str | Path]) -> tuple[list[str], dict[str, object]]:
    """solve's command-line arguments as (pose items, keyword options) of tumblecal.solve."""
    items: list[str] = []
    options: dict[str, object] = {}
    k, args = 0, [str(a) for a in given]
    while k < len(args):
        flag = args[k]
        if flag == "--poses":
            k += 1
            while k < len(args) and not args[k].startswith("--"):
                items.append(args[k])
                k += 1
            continue
        name = flag.removeprefix("--").replace("-", "_")
        if name == "tilt_compensate":
            options[name] = True
            k += 1
            continue
        value = args[k + 1]
        options[name] = float(value) if name == "reference" else value
        k += 2
    return items, options


@pytest.mark.parametrize("method", list(METHOD_CASES))
def test_each_solver_through_the_api_is_the_command(
    method: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = METHOD_CASES[method](tmp_path)
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", *args, "-o", out)
    assert r.code == 0, r.err
    written = json.loads(out.read_text())
    items, options = _api_call(args)
    solved = tumblecal.solve(items, **options)
    assert solved.status == 0 and solved.error is None
    cal = solved.calibration
    assert cal is not None and cal.method == written["method"] == method
    assert cal.offset.tolist() == written["offset"]
    assert cal.matrix.tolist() == written["matrix"]
    assert cal.verdict is not None and cal.verdict.passed


def test_solve_with_limits_and_serial_then_save_and_load(tmp_path: Path) -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    solved = tumblecal.solve(poses, reference=1.0, limits=str(SAMPLE / "limits.yaml"), serial="A17")
    assert (solved.status, solved.failures, solved.rejections) == (0, [], [])
    assert solved.calibration is not None and solved.calibration.serial == "A17"
    for name in ("cal.json", "cal.yaml"):
        solved.calibration.save(str(tmp_path / name))
        back = tumblecal.load(str(tmp_path / name))
        assert back.to_dict() == solved.calibration.to_dict()
        assert back.verdict is not None and back.verdict.limits["offset"] == [0.05, 0.05, 0.05]


def test_outside_the_limits_is_status_1_with_the_failures() -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    solved = tumblecal.solve(poses, max_offset="0.001")
    assert solved.status == 1
    assert solved.calibration is not None and solved.calibration.failed
    assert {f.code for f in solved.failures} == {"limit.offset.x", "limit.offset.y", "limit.offset.z"}


def test_a_rejected_capture_is_status_3_not_an_exception(tmp_path: Path) -> None:
    z = SAMPLE / "z.csv"
    solved = tumblecal.solve([f"+x={z}", f"+y={z}", f"+z={z}"])  # one capture passed off as three faces
    assert solved.status == 3 and solved.calibration is None
    assert solved.error is not None and solved.error.exit_code == 3


def test_input_errors_raise_the_exception_family(tmp_path: Path) -> None:
    with pytest.raises(tumblecal.InputError, match="no such file"):
        tumblecal.solve([str(tmp_path / "missing.csv")])
    with pytest.raises(tumblecal.InputError, match="--reference must be a positive number"):
        tumblecal.solve([str(SAMPLE / "z.csv")], reference=-1.0)
    with pytest.raises(TypeError):
        tumblecal.solve([str(SAMPLE / "z.csv")], no_such_option=1)
    assert issubclass(tumblecal.InputError, tumblecal.TumblecalError)
    assert issubclass(tumblecal.CaptureRejected, tumblecal.TumblecalError)


def test_data_in_memory_solves_as_its_files_do(tmp_path: Path) -> None:
    files = six_faces(tmp_path)
    from_files = tumblecal.solve([f"{face}={path}" for face, path in files.items()])
    frames = {face: tumblecal.read_capture(str(path)) for face, path in files.items()}
    from_frames = tumblecal.solve(frames)
    arrays = {face: frame[["ax", "ay", "az"]].to_numpy() for face, frame in frames.items()}
    from_arrays = tumblecal.solve(arrays)
    assert from_files.calibration is not None
    for other in (from_frames, from_arrays):
        assert other.calibration is not None and other.calibration.method == "six-pose"
        np.testing.assert_allclose(other.calibration.offset, from_files.calibration.offset, rtol=0, atol=1e-12)
        np.testing.assert_allclose(other.calibration.matrix, from_files.calibration.matrix, rtol=0, atol=1e-12)
    assert from_frames.calibration is not None and from_frames.calibration.columns == ["ax", "ay", "az"]
    with pytest.raises(tumblecal.InputError, match="unknown face"):
        tumblecal.solve({"+w": arrays["+x"]})


def test_apply_on_arrays_and_dataframes_is_the_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal_path, out = tmp_path / "cal.json", tmp_path / "out.csv"
    six = six_faces(tmp_path)
    assert run(capsys, "solve", "--poses", *six.values(), "-o", cal_path).code == 0  # cross-axis terms
    rng = np.random.default_rng(3)
    capture = tmp_path / "capture.csv"
    values = np.column_stack([np.arange(500) * 0.01, rng.normal(0, 1, (500, 3)), np.arange(500)])
    write_csv(capture, values, header=("t", "ax", "ay", "az", "n"), fmt="%.6f")
    assert run(capsys, "apply", "--cal", cal_path, capture, "-o", out).code == 0
    by_command = pd.read_csv(out)

    cal = tumblecal.load(str(cal_path))
    frame = tumblecal.read_capture(str(capture)).set_index(pd.RangeIndex(100, 600))
    fixed = cal.apply(frame)
    np.testing.assert_allclose(fixed[cal.columns].to_numpy(), by_command[cal.columns].to_numpy(), rtol=0, atol=1e-12)
    assert list(fixed.columns) == list(frame.columns)
    assert fixed.index.equals(frame.index)
    assert fixed["t"].equals(frame["t"]) and fixed["n"].equals(frame["n"])
    assert fixed.dtypes.drop(cal.columns).equals(frame.dtypes.drop(cal.columns))
    assert frame["ax"].iloc[0] == pytest.approx(values[0, 1])  # the input is not touched
    raw = frame[cal.columns].to_numpy()
    np.testing.assert_allclose(cal.apply(raw), by_command[cal.columns].to_numpy(), rtol=0, atol=1e-12)
    with pytest.raises(tumblecal.InputError, match="has no columns ax, ay, az"):
        cal.apply(frame.rename(columns={"ax": "a", "ay": "b", "az": "c"}))
    with pytest.raises(tumblecal.InputError, match="shape"):
        cal.apply(np.zeros((4, 2)))


def test_read_capture_reads_a_station_file_as_the_commands_do(tmp_path: Path) -> None:
    path = tmp_path / "station.csv"
    path.write_text("# station 7\r\ntime;ax;ay;az;label\r\n0.5;1;2;3;a\r\n1.5;4;5;6;b\r\n", encoding="utf-8")
    frame = tumblecal.read_capture(str(path))
    assert list(frame.columns) == ["time", "ax", "ay", "az", "label"]
    assert frame["ax"].tolist() == [1, 4] and frame["label"].tolist() == ["a", "b"]
    bad = tmp_path / "bad.csv"
    bad.write_text("ax,ay,az\n1,2,3\n1,x,3\n", encoding="utf-8")
    with pytest.raises(tumblecal.InputError, match=r"bad\.csv: not a number: 'x' \(line 3, column ay\)"):
        tumblecal.read_capture(str(bad))


def test_the_other_pipelines_answer_in_python(tmp_path: Path) -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    solved = tumblecal.solve(poses, serial="B2")
    assert solved.calibration is not None
    cal = str(tmp_path / "cal.json")
    solved.calibration.save(cal)
    checked = tumblecal.check(cal, max_offset="0.001")
    assert checked.status == 1 and checked.calibration.failed
    verified = tumblecal.verify([str(SAMPLE / "x.csv")], cal)
    assert verified.status == 0 and len(verified.table()) == 1  # type: ignore[arg-type]
    assert "fitted on this capture" in verified.notes[0]
    assert tumblecal.verify([str(SAMPLE / "capture.csv")], cal).status == 3  # not static
    header = tumblecal.export(cal, "c-header")
    assert "tumblecal_accel_apply" in header
    reported = tumblecal.report([cal])
    assert reported.status == 0 and reported.result.units == 1
    applied = tumblecal.correct(str(SAMPLE / "capture.csv"), cal, output=str(tmp_path / "c.csv"))
    assert applied.rows == 3000 and applied.columns == ["ax", "ay", "az"]


def test_public_names_are_listed() -> None:
    for name in tumblecal.__all__:
        assert getattr(tumblecal, name) is not None
    with pytest.raises(AttributeError):
        _ = tumblecal.no_such_name

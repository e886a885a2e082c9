"""The Python API (docs/python.md): each solver through ``tumblecal.solve``
gives what ``tumblecal solve`` writes; ``Calibration.apply`` on arrays and DataFrames gives what
``tumblecal apply`` writes; data in memory solves as its files do; errors are the exception family."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import tumblecal_cli as tumblecal
from tests.conftest import run, unnamed
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


@pytest.mark.slow
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
    solved = tumblecal.solve(items, **options)  # type: ignore[arg-type]
    assert solved.status == 0
    assert solved.error is None
    cal = solved.calibration
    assert cal is not None
    assert cal.method == written["method"] == method
    assert cal.offset.tolist() == written["offset"]
    assert cal.matrix.tolist() == written["matrix"]
    assert cal.verdict is not None
    assert cal.verdict.passed


def test_solve_with_limits_and_serial_then_save_and_load(tmp_path: Path) -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    solved = tumblecal.solve(poses, reference=1.0, limits=str(SAMPLE / "limits.yaml"), serial="A17")
    assert (solved.status, solved.failures, solved.rejections) == (0, [], [])
    assert solved.calibration is not None
    assert solved.calibration.serial == "A17"
    for name in ("cal.json", "cal.yaml"):
        solved.calibration.save(str(tmp_path / name))
        back = tumblecal.load(str(tmp_path / name))
        assert back.to_dict() == solved.calibration.to_dict()
        assert back.verdict is not None
        assert back.verdict.limits["offset"] == [0.05, 0.05, 0.05]


def test_outside_the_limits_is_status_1_with_the_failures() -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    solved = tumblecal.solve(poses, max_offset="0.001")
    assert solved.status == 1
    assert solved.calibration is not None
    assert solved.calibration.failed
    assert {f.code for f in solved.failures} == {"limit.offset.x", "limit.offset.y", "limit.offset.z"}


def test_a_rejected_capture_is_status_3_not_an_exception(tmp_path: Path) -> None:
    z = SAMPLE / "z.csv"
    solved = tumblecal.solve([f"+x={z}", f"+y={z}", f"+z={z}"])  # one capture passed off as three faces
    assert solved.status == 3
    assert solved.calibration is None
    assert solved.error is not None
    assert solved.error.exit_code == 3


def test_input_errors_raise_the_exception_family(tmp_path: Path) -> None:
    with pytest.raises(tumblecal.InputError, match="no such file"):
        tumblecal.solve([str(tmp_path / "missing.csv")])
    with pytest.raises(tumblecal.InputError, match="--reference must be a positive number"):
        tumblecal.solve([str(SAMPLE / "z.csv")], reference=-1.0)
    with pytest.raises(TypeError):
        tumblecal.solve([str(SAMPLE / "z.csv")], no_such_option=1)  # type: ignore[call-arg]
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
        assert other.calibration is not None
        assert other.calibration.method == "six-pose"
        np.testing.assert_allclose(other.calibration.offset, from_files.calibration.offset, rtol=0, atol=1e-12)
        np.testing.assert_allclose(other.calibration.matrix, from_files.calibration.matrix, rtol=0, atol=1e-12)
    assert from_frames.calibration is not None
    assert from_frames.calibration.columns == ["ax", "ay", "az"]
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
    assert fixed["t"].equals(frame["t"])
    assert fixed["n"].equals(frame["n"])
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
    assert frame["ax"].tolist() == [1, 4]
    assert frame["label"].tolist() == ["a", "b"]
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
    assert checked.status == 1
    assert checked.calibration.failed
    verified = tumblecal.verify([str(SAMPLE / "x.csv")], cal)
    assert verified.status == 0
    assert len(verified.table()) == 1
    assert "fitted on this capture" in verified.notes[0]
    assert tumblecal.verify([str(SAMPLE / "capture.csv")], cal).status == 3  # not static
    header = tumblecal.export(cal, "c-header")
    assert "tumblecal_accel_apply" in header
    reported = tumblecal.report([cal])
    assert reported.status == 0
    assert reported.result.units == 1
    applied = tumblecal.correct(str(SAMPLE / "capture.csv"), cal, output=str(tmp_path / "c.csv"))
    assert applied.rows == 3000
    assert applied.columns == ["ax", "ay", "az"]


def test_public_names_are_listed() -> None:
    for name in tumblecal.__all__:
        assert getattr(tumblecal, name) is not None
    with pytest.raises(AttributeError):
        _ = tumblecal.no_such_name


def test_a_rejected_draft_is_never_trusted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The draft of a rejected solve fails its verdict: saved, apply refuses it without --force."""
    # +x and +y swapped: files not named for their faces, so their order gives the faces
    solved = tumblecal.solve([str(f) for f in unnamed([SAMPLE / f"{a}.csv" for a in "yxz"], tmp_path / "in")])
    assert solved.status == 3
    assert solved.calibration is None
    assert solved.draft is not None
    assert solved.draft.failed
    draft = tmp_path / "draft.json"
    solved.draft.save(draft)
    r = run(capsys, "apply", "--cal", draft, SAMPLE / "capture.csv", "-o", tmp_path / "out.csv")
    assert r.code == 2
    assert "refusing to correct with it" in r.err
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"method": "bogus"}, "--method: 'bogus' is not one of auto"),
        ({"time_unit": "fortnight"}, "--time-unit: 'fortnight'"),
        ({"reference": "1"}, "--reference takes a number"),
        ({"min_samples": "5"}, "--min-samples takes a whole number"),
        ({"fixture_tolerance": 40}, "--fixture-tolerance is 0 to 30 degrees"),
        ({"gain_tolerance": -0.01}, "--gain-tolerance is a fraction from 0 to below 1"),
        ({"gain_tolerance": "2%"}, "--gain-tolerance takes a number"),
        ({"no_check": ["bogus"]}, "--no-check: 'bogus' is not one of"),
    ],
)
def test_options_given_in_python_are_checked_as_the_parser_checks_them(options: dict[str, object], words: str) -> None:
    with pytest.raises(tumblecal.InputError, match=words):
        tumblecal.solve([str(SAMPLE / f"{a}.csv") for a in "xyz"], **options)  # type: ignore[arg-type]


def test_one_check_name_as_a_string_is_that_check() -> None:
    poses = [str(SAMPLE / f"{a}.csv") for a in "xyz"]
    assert tumblecal.solve(poses, max_noise=1e-4).status == 3  # moved
    assert tumblecal.solve(poses, max_noise=1e-4, no_check="moved").status == 0


def test_paths_single_paths_and_calibrations_are_taken_where_a_file_is(tmp_path: Path) -> None:
    z = SAMPLE / "z.csv"
    one = tumblecal.solve(z)  # a single path: one pose
    assert one.calibration is not None
    assert one.calibration.method == "one-pose"
    solved = tumblecal.solve([SAMPLE / f"{a}.csv" for a in "xyz"])
    assert solved.calibration is not None
    solved.calibration.save(tmp_path / "cal.yaml")
    cal = tumblecal.load(tmp_path / "cal.yaml")
    assert tumblecal.check(cal, max_offset=1.0).status == 0
    assert "tumblecal_accel_apply" in tumblecal.export(cal, "c-header")
    assert tumblecal.verify(SAMPLE / "x.csv", cal).status == 0
    assert tumblecal.correct(SAMPLE / "capture.csv", cal, output=tmp_path / "c.csv").rows == 3000
    assert tumblecal.report(tmp_path / "cal.yaml").result.files == 1
    assert list(tumblecal.read_capture(SAMPLE / "x.csv").columns) == ["t", "ax", "ay", "az"]


def test_data_that_cannot_be_read_is_an_input_error(tmp_path: Path) -> None:
    frame = tumblecal.read_capture(SAMPLE / "z.csv")
    cal = tumblecal.solve([SAMPLE / f"{a}.csv" for a in "xyz"]).calibration
    assert cal is not None
    for call in (
        lambda: tumblecal.solve_log(frame.drop(columns="az")),
        lambda: tumblecal.verify([frame.assign(ay="a")], cal),
        lambda: tumblecal.correct(frame.rename(columns={"ax": "a"}), cal),
        lambda: tumblecal.verify([], cal),
        lambda: tumblecal.solve({"+z": frame.assign(ax="a")}),
        lambda: cal.apply({"ax": [1.0]}),
        lambda: cal.apply(frame.assign(AX=frame["ax"]).rename(columns={"ax": "Ax"})),  # two in other cases
    ):
        with pytest.raises(tumblecal.InputError):
            call()
    three = [tumblecal.read_capture(SAMPLE / f"{a}.csv") for a in "xyz"]
    assert tumblecal.solve(three).status == 0  # a list of data: labelled as three files are, +x +y +z


# -- data in memory where a capture goes: every function that reads one ------------------------

SESSION = SAMPLE / "imucal" / "session_every4th.csv"  # real, m/s^2, 25.6 Hz as kept here
STILL = ROOT / "tests" / "data" / "xsens_acc_still.txt"  # real, still, headerless: t, x, y, z
ACC = ["acc_x", "acc_y", "acc_z"]


def _same_calibration(a: tumblecal.Solved, b: tumblecal.Solved) -> None:
    assert a.calibration is not None
    assert b.calibration is not None
    assert a.calibration.method == b.calibration.method
    np.testing.assert_allclose(a.calibration.offset, b.calibration.offset, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.calibration.matrix, b.calibration.matrix, rtol=0, atol=1e-12)


def test_solve_log_takes_a_dataframe_or_an_array() -> None:
    by_file = tumblecal.solve_log(SESSION, rate=25.6, reference=9.81)
    frame = tumblecal.read_capture(SESSION)
    by_frame = tumblecal.solve_log(frame, rate=25.6, reference=9.81)
    _same_calibration(by_frame, by_file)
    assert by_frame.calibration is not None
    assert by_frame.calibration.columns == ACC
    assert by_frame.calibration.poses[0].file == "<DataFrame>"
    _same_calibration(tumblecal.solve_log(frame[ACC].to_numpy(), rate=25.6, reference=9.81), by_file)
    timed = frame.assign(t=frame["n_samples"] / 102.4)  # (every 4th sample of 102.4 Hz) a clock, as in a file
    _same_calibration(tumblecal.solve_log(timed, reference=9.81), by_file)


def test_segment_takes_a_dataframe_or_an_array_with_a_rate(tmp_path: Path) -> None:
    by_file = tumblecal.segment(SESSION, rate=25.6, out_dir=tmp_path / "file")
    frame = tumblecal.read_capture(SESSION)
    pd.testing.assert_frame_equal(tumblecal.segment(frame, rate=25.6).table(), by_file.table())
    pd.testing.assert_frame_equal(tumblecal.segment(frame[ACC].to_numpy(), rate=25.6).table(), by_file.table())
    written = tumblecal.segment(frame, rate=25.6, out_dir=tmp_path / "frame")
    assert sorted(p.name for p in (tmp_path / "frame").iterdir()) == sorted(
        p.name for p in (tmp_path / "file").iterdir()
    )
    for name in written.files.values():  # each block: the same readings (written as CSVs of the readings)
        mine, theirs = (
            tumblecal.read_capture(tmp_path / "frame" / name),
            tumblecal.read_capture(tmp_path / "file" / name),
        )
        np.testing.assert_array_equal(mine[ACC].to_numpy(), theirs[ACC].to_numpy())
    again = tumblecal.segment(frame, rate=25.6, out_dir=tmp_path / "frame")  # a second run replaces the first
    assert again.removed == 0


def test_noise_takes_a_dataframe_or_an_array() -> None:
    by_file = tumblecal.noise(STILL, no_header=True)
    frame = tumblecal.read_capture(STILL, no_header=True)
    assert list(frame.columns) == ["t", "x", "y", "z"]
    for data, options in ((frame, {}), (frame.to_numpy(), {}), (frame[["x", "y", "z"]].to_numpy(), {"rate": 100.0})):
        got = tumblecal.noise(data, **options)  # type: ignore[arg-type]
        assert (got.rate, got.samples, got.status) == (by_file.rate, by_file.samples, by_file.status)
        np.testing.assert_allclose(got.curve.adev, by_file.curve.adev, rtol=1e-12, atol=0)
    with pytest.raises(tumblecal.InputError, match=r"<array>: the sample rate is unknown"):
        tumblecal.noise(frame[["x", "y", "z"]].to_numpy())


def test_verify_takes_dataframes_and_arrays() -> None:
    poses = [SAMPLE / f"{a}.csv" for a in "xyz"]
    cal = tumblecal.solve(poses).calibration
    assert cal is not None
    by_file = tumblecal.verify(poses, cal).table()
    frames = [tumblecal.read_capture(p) for p in poses]
    mixed = tumblecal.verify([frames[0], frames[1][["ax", "ay", "az"]].to_numpy(), poses[2]], cal).table()
    assert mixed["file"].tolist() == ["<DataFrame>", "<array>", str(poses[2])]
    pd.testing.assert_frame_equal(mixed.drop(columns="file"), by_file.drop(columns="file"))
    one = tumblecal.verify(frames[0], cal)
    assert one.rows[0]["norm_after"] == by_file["norm_after"][0]


def test_correct_takes_a_dataframe_or_an_array(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal_path = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *(SAMPLE / f"{a}.csv" for a in "xyz"), "-o", cal_path).code == 0
    assert run(capsys, "apply", "--cal", cal_path, SAMPLE / "capture.csv", "-o", tmp_path / "cmd.csv").code == 0
    by_command = tumblecal.read_capture(tmp_path / "cmd.csv")
    frame = tumblecal.read_capture(SAMPLE / "capture.csv")
    done = tumblecal.correct(frame, cal_path)
    assert (done.capture, done.rows, done.columns, done.output) == ("<DataFrame>", 3000, ["ax", "ay", "az"], "")
    pd.testing.assert_frame_equal(done.data, by_command)
    arr = tumblecal.correct(frame[["ax", "ay", "az"]].to_numpy(), cal_path)
    np.testing.assert_array_equal(arr.data, by_command[["ax", "ay", "az"]].to_numpy())
    written = tumblecal.correct(frame, cal_path, output=tmp_path / "out.csv.gz")
    assert written.output == str(tmp_path / "out.csv.gz")
    pd.testing.assert_frame_equal(tumblecal.read_capture(tmp_path / "out.csv.gz"), by_command)
    with pytest.raises(tumblecal.InputError, match="has no columns ax, ay, az"):
        tumblecal.correct(frame.rename(columns={"ax": "a", "ay": "b", "az": "c"}), cal_path)


@pytest.mark.parametrize(
    ("data", "said"),
    [
        pytest.param(
            lambda f: f.assign(acc_y=["abc", *f["acc_y"][1:]]),
            "<DataFrame>: not a number: 'abc' (row 0, column acc_y)",
            id="text",
        ),
        pytest.param(
            lambda f: f.drop(columns="acc_z"),
            "<DataFrame>: no accelerometer x,y,z columns found (columns: n_samples, gyr_x, gyr_y, gyr_z, acc_x, acc_y)",
            id="missing",
        ),
        pytest.param(
            lambda f: f.assign(acc_x=[None, *f["acc_x"][1:]]),
            "<DataFrame>: empty sensor cell in a row whose other sensor cells are filled (row 0, column acc_x)",
            id="partly-empty",
        ),
        pytest.param(
            lambda f: f[["acc_x", "acc_y"]].to_numpy(),
            "<array>: an array of readings is (n, 3): x, y, z, or (n, 4): t, x, y, z; got shape (2594, 2)",
            id="array-shape",
        ),
    ],
)
def test_bad_data_in_memory_is_named_as_a_bad_file_is(data: Any, said: str) -> None:
    frame = tumblecal.read_capture(SESSION)
    for call in (tumblecal.solve_log, tumblecal.segment, tumblecal.noise):
        with pytest.raises(tumblecal.InputError) as err:
            call(data(frame), rate=25.6)
        assert str(err.value) == said


def test_rows_without_readings_are_left_out_as_a_file_s_are() -> None:
    """All three sensor cells NaN: an interleaved log's row of another sensor, skipped."""
    frame = tumblecal.read_capture(SESSION)
    gaps = frame.copy()
    gaps.loc[::7, ACC] = np.nan
    by_frame = tumblecal.segment(gaps, rate=25.6)
    assert len(by_frame.blocks.log.values) == len(frame) - len(frame[::7])


def test_a_calibration_built_by_hand_applies() -> None:
    offset, matrix, gain = [1, 0, 0], np.eye(3).tolist(), [1, 1, 1]  # lists, as a hand-written script has them
    cal = tumblecal.Calibration("accelerometer", "three-pose", 1.0, ["x", "y", "z"], offset, matrix, gain)  # type: ignore[arg-type]
    np.testing.assert_array_equal(cal.apply(np.array([[2.0, 1.0, 0.0]])), [[1.0, 1.0, 0.0]])


def test_saving_onto_a_folder_is_an_input_error(tmp_path: Path) -> None:
    """It was IsADirectoryError from inside the writer."""
    cal = tumblecal.load(str(SAMPLE / "lot" / "SN0001_20261121T090000Z.json"))
    with pytest.raises(tumblecal.InputError, match="is a folder: an output is a file name"):
        cal.save(str(tmp_path))


#: Arguments of a kind the signatures do not take (typed Any: a notebook's code is not type-checked).
NOTHING: Any = None
A_LIST: Any = [SAMPLE / "x.csv"]
A_NUMBER: Any = 5
CAL = str(SAMPLE / "lot" / "SN0001_20261121T090000Z.json")
POSES = [str(SAMPLE / f"{a}.csv") for a in "xyz"]


@pytest.mark.parametrize(
    ("call", "said"),
    [
        pytest.param(
            lambda: tumblecal.read_capture(NOTHING), "read_capture reads a capture file, not a NoneType", id="read-none"
        ),
        pytest.param(lambda: tumblecal.read_capture(A_LIST), "not a list", id="read-list"),
        pytest.param(
            lambda: tumblecal.segment(NOTHING),
            "segment reads a log: a file ('-': stdin), a DataFrame or an (n, 3) array, not a NoneType",
            id="segment",
        ),
        pytest.param(lambda: tumblecal.noise(A_NUMBER), "noise reads a still capture: a file, a DataFrame", id="noise"),
        pytest.param(lambda: tumblecal.solve_log(A_NUMBER), "solve_log takes a log: a file, a DataFrame", id="log"),
        pytest.param(lambda: tumblecal.import_peer(NOTHING), "import_peer reads a file of another tool", id="import"),
        pytest.param(lambda: tumblecal.run_batch(str(SAMPLE / "lot.csv"), NOTHING), "writes into a folder", id="batch"),
        pytest.param(
            lambda: tumblecal.correct(str(SAMPLE / "capture.csv"), NOTHING, output="-"),
            "needs a calibration",
            id="correct",
        ),
        pytest.param(lambda: tumblecal.report(NOTHING), "report takes calibration files", id="report"),
        pytest.param(lambda: tumblecal.verify(NOTHING, CAL), "verify takes capture files", id="verify"),
        pytest.param(
            lambda: tumblecal.thermal(["+z=a.csv"], NOTHING), "a calibration is a Calibration or its file", id="thermal"
        ),
        pytest.param(lambda: tumblecal.solve(POSES, serial=A_NUMBER), "--serial is text, not a int", id="serial"),
    ],
)
def test_arguments_of_the_wrong_kind_raise_the_family(call: Any, said: str) -> None:
    """They raised TypeError, AttributeError or ValueError from inside (a DataFrame's truth value)."""
    with pytest.raises(tumblecal.InputError, match=re.escape(said)):
        call()

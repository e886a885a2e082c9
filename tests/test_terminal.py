"""What people read on a terminal: output laid out for its width (COLUMNS) and whole in a file or
a pipe, names shortened in the middle, the rejection first and alone, what the user acts on by
default (the detail under -v), times as times, the tilt note only where it changes a decision,
and a --help that starts with examples and fits a screen or two."""

from __future__ import annotations

import gzip
import json
import shutil
from pathlib import Path

import pytest

from tests.conftest import IMUCAL, SAMPLE, SIX_FACES, run
from tumblecal_cli.cli import render

LOGS = Path(__file__).resolve().parent / "data" / "logs"
POSES_3 = [str(SAMPLE / f"{f}.csv") for f in "xyz"]
IMUCAL_6 = [str(IMUCAL / f"{f}.csv") for f in SIX_FACES]


@pytest.fixture(scope="module")
def xsens(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """imu_tk's Xsens log (headerless: t and three columns of raw counts), decompressed."""
    target = tmp_path_factory.mktemp("xsens") / "xsens_acc.mat.txt"
    with gzip.open(LOGS / "xsens_acc.txt.gz", "rb") as f, target.open("wb") as out:
        shutil.copyfileobj(f, out)
    return target


def lines(text: str) -> list[str]:
    return [line.rstrip() for line in text.splitlines()]


# -- width ---------------------------------------------------------------------------------------


@pytest.mark.slow
def test_columns_60_and_160_lay_the_same_solve_out_differently(
    xsens: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = {}
    for width in (60, 160):
        monkeypatch.setenv("COLUMNS", str(width))
        r = run(capsys, "solve", "--log", xsens, "-o", tmp_path / "cal.json")
        assert r.code == 0, r.err
        out[width] = lines(r.err)
        assert max(len(line) for line in out[width] if not line.startswith("wrote ")) <= width, r.err
    assert len(out[60]) > len(out[160])  # the notes wrap at 60, not at 160
    assert any(len(line) > 80 for line in out[160])  # a wide terminal is used, not 80 columns whatever it is
    note = next(line for line in out[60] if line.startswith("note: auto fits the sphere"))
    following = out[60][out[60].index(note) + 1]
    assert following.startswith("  ")
    assert not following.startswith("   ")


def test_a_pipe_gets_each_note_whole_on_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """No COLUMNS and not a terminal (the test's captured stderr): the width the content needs."""
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    note = next(line for line in lines(r.err) if line.startswith("note: fixture tilt"))
    assert note.endswith("(six-pose takes offsets and gains from vertical readings only)")
    assert "…" not in r.err


def test_a_note_wraps_at_the_terminal_width(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    got = lines(r.err)
    start = next(i for i, line in enumerate(got) if line.startswith("note: fixture tilt"))
    assert all(len(line) <= 80 for line in got[start:])
    assert got[start + 1].startswith("  level") or got[start + 1].startswith("  ")
    joined = " ".join(line.strip() for line in got[start : start + 6])
    assert "--fixture-tolerance, or capture the six faces" in joined  # words kept whole, in order


# -- names shortened in the middle ---------------------------------------------------------------


def test_middle_keeps_the_start_and_the_end() -> None:
    assert render.middle("xsens_acc.mat.txt #1", 8) == "xsen… #1"
    assert render.middle("xsens_acc.mat.txt #12", 10) == "xsens… #12"
    assert render.middle("x.csv", 8) == "x.csv"
    assert len(render.middle("a" * 50, 12)) == 12


def test_a_long_file_name_is_shortened_in_the_middle_not_wrapped(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    long = [tmp_path / f"station-7_unit-{n}_2026-11-27_pose_{f}_capture.csv" for n, f in zip("abc", "xyz", strict=True)]
    for path, face in zip(long, "xyz", strict=True):
        path.write_bytes((SAMPLE / f"{face}.csv").read_bytes())
    monkeypatch.setenv("COLUMNS", "80")
    r = run(capsys, "solve", "--poses", *map(str, long), "-o", tmp_path / "cal.json", "-v")
    assert r.code == 0, r.err
    rows = [line for line in lines(r.err) if "mean" in line]
    assert len(rows) == 3
    for row, face in zip(rows, "xyz", strict=True):
        name = row.split()[1]
        assert "…" in name, row
        assert name.startswith("stat"), row
        assert name.endswith(".csv"), row
        assert f"+{face}" == row.split()[0]
    assert not any(line.strip().startswith(("capture.csv", "_capture")) for line in lines(r.err))  # never wrapped
    assert all(len(line) <= 80 for line in lines(r.err) if "mean" in line or "std" in line)


# -- what the user acts on by default, the detail under -v ---------------------------------------


@pytest.mark.slow
def test_solve_log_of_the_xsens_session_fits_one_screen(
    xsens: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """It printed 216 lines: every block, every pose. Now the calibration, the verdict and the
    notes; -v adds the blocks and the poses."""
    monkeypatch.setenv("COLUMNS", "80")
    r = run(capsys, "solve", "--log", xsens, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    got = lines(r.err)
    assert len(got) <= 40, r.err
    assert got[0] == "xsens_acc.mat.txt: 38 of 41 still blocks kept (3 too short); -v lists them"
    assert any(line.startswith("sphere calibration") for line in got)
    assert any(line.startswith("verdict: PASS") for line in got)
    verbose = run(capsys, "solve", "--log", xsens, "-o", tmp_path / "cal.json", "-v")
    assert verbose.code == 0, verbose.err
    assert len(lines(verbose.err)) > 100
    assert any(line.startswith("still blocks of xsens_acc.mat.txt") for line in lines(verbose.err))
    assert any(line.startswith("poses") for line in lines(verbose.err))


def test_a_rejected_solve_prints_the_rejection_first_and_only(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Swapped files opened with a 'three-pose calibration' table with gains of -0.506."""
    a, b, c = (tmp_path / f"{n}.csv" for n in "abc")
    for path, face in zip((a, b, c), "yxz", strict=True):
        path.write_bytes((SAMPLE / f"{face}.csv").read_bytes())
    r = run(capsys, "solve", "--poses", a, b, c, "-o", tmp_path / "cal.json")
    assert r.code == 3, r.err
    got = lines(r.err)
    assert got[0].startswith(f"error: {a}: declared +x but reads like +y"), r.err
    assert all(line.startswith(("error: ", "hint: ")) for line in got), r.err
    assert "calibration" not in r.err.split("\n")[0]
    assert not (tmp_path / "cal.json").exists()
    detail = run(capsys, "solve", "--poses", a, b, c, "-o", tmp_path / "cal.json", "-v")  # the draft on request
    assert detail.code == 3
    assert "three-pose calibration" in detail.err


def test_a_rejected_solve_json_keeps_its_draft(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Only what people read changed: --json still holds the draft's parameters."""
    a, b, c = (tmp_path / f"{n}.csv" for n in "abc")
    for path, face in zip((a, b, c), "yxz", strict=True):
        path.write_bytes((SAMPLE / f"{face}.csv").read_bytes())
    r = run(capsys, "solve", "--poses", a, b, c, "-o", tmp_path / "cal.json", "--json")
    assert r.code == 3
    doc = json.loads(r.out)
    assert doc["status"] == "rejected"
    assert doc["gain"] is not None


def test_noise_on_a_moving_log_prints_the_rejection_alone(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """It printed a full figure table before 'not a still capture'."""
    path = tmp_path / "hassan.csv"
    path.write_bytes((LOGS / "hassan_mobile_30orient.csv").read_bytes())
    r = run(capsys, "noise", path, "--rate", "100")
    assert r.code == 3, r.err
    got = lines(r.err)
    assert all(line.startswith(("error: ", "hint: ")) for line in got), r.err
    assert "not a still capture" in got[0]


# -- times ---------------------------------------------------------------------------------------


def test_an_epoch_ns_clock_reads_as_utc_times(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A start shown as 1.73015e+18: now the date once (UTC) and each block's time of day."""
    rows = gzip.decompress((LOGS / "xsens_acc.txt.gz").read_bytes()).decode().split("\n")[:12000]
    epoch = 1_730_150_000_000_000_000
    text = ["t,x,y,z"] + [
        f"{epoch + round(float(t) * 1e9)},{x},{y},{z}" for t, x, y, z in (r.split() for r in rows if r.strip())
    ]
    log = tmp_path / "epoch.csv"
    log.write_text("\n".join(text) + "\n")
    r = run(capsys, "segment", log, "-d", tmp_path / "poses")
    assert r.code == 0, r.err
    assert "still blocks of epoch.csv, 2024-10-28 UTC" in r.err
    first = next(line for line in lines(r.err) if line.split()[:1] == ["1"])
    assert first.split()[2] == "21:13:20.029", first
    assert "e+18" not in r.err


def test_iso_time_only_for_an_epoch_clock() -> None:
    assert render.iso_time(1_730_150_000.0295) == "2024-10-28T21:13:20.029Z"
    assert render.iso_time(238.5) is None


# -- the tilt note where it changes a decision ---------------------------------------------------


def test_tilt_note_when_tilt_is_over_ten_times_the_noise(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Three-pose: 1° moves the offsets by 0.018 against a noise of 4.5e-05 (400 times)."""
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "cal.json")
    assert "note: fixture tilt, not noise, limits this calibration" in r.err


def test_no_tilt_note_when_tilt_is_a_few_times_the_noise_and_no_limit_is_near(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """imucal's six faces: 1° moves the offsets by 1.2 counts, noise 0.18 (6.7 times), no limit:
    the note came with every run of such a station and changed nothing."""
    r = run(capsys, "solve", "--poses", *IMUCAL_6, "--reference", "9.81", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert "note: fixture tilt" not in r.err
    far = run(capsys, "solve", "--poses", *IMUCAL_6, "--reference", "9.81", "--max-offset", "100", "-o", tmp_path / "c")
    assert far.code == 0, far.err
    assert "note: fixture tilt" not in far.err


def test_tilt_note_when_tilt_could_move_an_offset_past_its_limit(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """The y offset is -48.29 counts, its tilt shift 1.2: a limit of 48.5 is within reach, so the
    verdict rests on the fixture's level, and the note says so (exit 0: inside the limit)."""
    r = run(capsys, "solve", "--poses", *IMUCAL_6, "--reference", "9.81", "--max-offset", "48.5", "-o", tmp_path / "c")
    assert r.code == 0, r.err
    assert "note: fixture tilt, not noise, limits this calibration" in r.err
    assert "enough to cross the limits of the y offset" in r.err
    outside = run(
        capsys, "solve", "--poses", *IMUCAL_6, "--reference", "9.81", "--max-offset", "47.5", "-o", tmp_path / "d"
    )
    assert outside.code == 1  # outside by less than the tilt: the note as well
    assert "enough to cross the limits of the y offset" in outside.err


# -- help ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["solve", "batch"])
def test_help_fits_under_100_lines_and_starts_with_examples(
    command: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    r = run(capsys, command, "--help")
    assert r.code == 0
    got = lines(r.out)
    assert len(got) < 100, len(got)
    assert max(len(line) for line in got) <= 80, max(got, key=len)
    examples = [i for i, line in enumerate(got) if line.strip().startswith(f"tumblecal {command} ")]
    options = next(i for i, line in enumerate(got) if line.startswith("Options"))
    assert 2 <= len([i for i in examples if i < options]) <= 4  # examples before any option
    full = run(capsys, command, "--help-all")
    assert len(lines(full.out)) > len(got)
    assert "--fixture-tolerance" in r.out
    assert "--fixture-tolerance" in full.out


@pytest.mark.slow
@pytest.mark.parametrize("command", ["segment", "noise", "verify", "apply", "thermal", "report", "show", "check"])
def test_every_help_starts_with_examples(
    command: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    got = lines(run(capsys, command, "--help").out)
    options = next(i for i, line in enumerate(got) if line.startswith(("Options", "Arguments")))
    assert any(line.strip().startswith(f"tumblecal {command}") for line in got[:options])
    assert len(got) < 100


def test_verify_on_a_moving_capture_prints_the_rejection_alone(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    r = run(capsys, "verify", "--cal", cal, SAMPLE / "capture.csv", SAMPLE / "x.csv")
    assert r.code == 3, r.err
    assert all(line.startswith(("error: ", "hint: ")) for line in lines(r.err)), r.err


def test_noise_says_where_figures_were_read_only_under_verbose(capsys: pytest.CaptureFixture[str]) -> None:
    still = Path(__file__).resolve().parent / "data" / "xsens_acc_still.txt"
    plain = run(capsys, "noise", still, "--no-header")
    assert plain.code == 0, plain.err
    assert "τ =" not in plain.err
    assert "bias instability: xyz not determined" in plain.err  # why a figure is missing: always
    verbose = run(capsys, "noise", still, "--no-header", "-v")
    assert "noise density: x τ = 0.01–20.5 s" in verbose.err


def test_verify_shortens_a_long_capture_name_in_the_middle(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    long = tmp_path / "a_very_long_capture_name_from_the_station_x.csv"
    long.write_bytes((SAMPLE / "x.csv").read_bytes())
    monkeypatch.setenv("COLUMNS", "60")
    r = run(capsys, "verify", "--cal", cal, long, SAMPLE / "y.csv")
    assert r.code == 0, r.err
    row = next(line for line in lines(r.err) if line.lstrip().startswith("a_very"))
    assert row.split()[0] == "a_very…x.csv"
    assert "FAIL" not in r.err.split("\n")[2]  # no empty verdict column without a limit


def test_check_prints_the_poses_only_under_verbose(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    plain = run(capsys, "check", cal, "--max-offset", "0.05")
    assert plain.code == 0, plain.err
    assert "poses" not in plain.err.split()
    assert "verdict: PASS (limits: offset)" in plain.err
    verbose = run(capsys, "check", cal, "--max-offset", "0.05", "-v")
    assert "poses" in verbose.err.split()


def test_every_command_takes_help_all(capsys: pytest.CaptureFixture[str]) -> None:
    """--help-all on each command (current, added later, had none: exit 2 'No such option')."""
    names = ["solve", "segment", "batch", "apply", "verify", "noise", "thermal", "current", "align"]
    for name in [*names, "show", "check", "export", "import", "report", "logs"]:
        r = run(capsys, name, "--help-all")
        assert r.code == 0, (name, r.err)
        assert "Usage: tumblecal" in r.out

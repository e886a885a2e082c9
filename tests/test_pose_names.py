"""solve --poses on files named for their faces (README "Pose labels"): the names give the faces
whatever the order the shell lists them in (xn.csv before xp.csv); a name that says another face
than its place, where the names cannot give every face, is exit 2; explicit labels and --up win;
the order checks blame the names, not the order, when the names gave the faces; the Python API
does the same."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import tumblecal_cli as tumblecal
from tests.conftest import SAMPLE, Result, assert_one_error, assert_untouched, precious, run
from tumblecal_cli.core.gate import NAMED_HINT
from tumblecal_cli.errors import InputError
from tumblecal_cli.pipeline.solve.solving import named_faces

#: The sample unit's six faces: face -> its file in sample_data.
SAMPLE_FACES = {
    "+x": "x.csv",
    "-x": "xn.csv",
    "+y": "y.csv",
    "-y": "yn.csv",
    "+z": "z.csv",
    "-z": "zn.csv",
}
#: Ways of naming the six faces, each as face -> file name stem.
SPELLINGS = {
    "xp": {"+x": "xp", "-x": "xn", "+y": "yp", "-y": "yn", "+z": "zp", "-z": "zn"},
    "x_p": {"+x": "x_p", "-x": "x_n", "+y": "y_p", "-y": "y_n", "+z": "z_p", "-z": "z_n"},
    "xplus": {"+x": "xplus", "-x": "xminus", "+y": "yplus", "-y": "yminus", "+z": "zplus", "-z": "zminus"},
    "X_POS": {"+x": "X_POS", "-x": "X_NEG", "+y": "Y_POS", "-y": "Y_NEG", "+z": "Z_POS", "-z": "Z_NEG"},
    "+x": {f: f for f in SAMPLE_FACES},
}


def copies(folder: Path, names: dict[str, str], faces: dict[str, str] = SAMPLE_FACES) -> dict[str, Path]:
    """The sample poses copied into ``folder`` under ``names`` (face -> stem); face -> path.
    ``faces`` says which sample file each face's copy holds."""
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for face, stem in names.items():
        out[face] = folder / f"{stem}.csv"
        shutil.copy(SAMPLE / faces[face], out[face])
    return out


def shell_order(paths: dict[str, Path]) -> list[Path]:
    """The files as `*.csv` lists them: by name (C locale)."""
    return sorted(paths.values(), key=lambda p: p.name)


def poses_of(cal: Path) -> dict[str, str]:
    """file name -> the face the calibration file records for it."""
    doc = json.loads(cal.read_text())
    return {Path(p["file"]).name: p["pose"] for p in doc["poses"]}


def notes(r: Result) -> list[str]:
    return [line for line in r.err.splitlines() if line.startswith("note: faces taken")]


@pytest.mark.parametrize("spelling", list(SPELLINGS))
def test_six_faces_in_the_shells_order_take_their_faces_from_their_names(
    spelling: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = copies(tmp_path / "unit", SPELLINGS[spelling])
    given = shell_order(files)
    assert given[0] == files["-x"] or spelling == "+x", "the shell lists xn before xp"
    labelled = tmp_path / "labelled.json"
    r = run(capsys, "solve", "-p", *[f"{face}={p}" for face, p in files.items()], "-o", labelled)
    assert r.code == 0, r.err
    assert notes(r) == [], "labelled files: the names are not asked"
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *given, "-o", out)
    assert r.code == 0, r.err
    assert poses_of(out) == {p.name: face for face, p in files.items()}
    said = ", ".join(f"{p.name} {face}" for face, p in ((poses_of(out)[p.name], p) for p in given))
    if given == list(files.values()):  # "+x" sorts as +x -x +y ...: the order already agrees
        assert notes(r) == []
    else:
        assert notes(r) == [f"note: faces taken from the file names: {said}"]
    a, b = json.loads(labelled.read_text()), json.loads(out.read_text())
    assert b["method"] == "six-pose"
    assert (a["method"], a["offset"], a["matrix"]) == (b["method"], b["offset"], b["matrix"])


def test_three_faces_out_of_order_take_their_faces_from_their_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    standard = tmp_path / "standard.json"
    assert run(capsys, "solve", "-p", *[SAMPLE / f"{a}.csv" for a in "xyz"], "-o", standard, "-q").code == 0
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *[SAMPLE / f"{a}.csv" for a in "zyx"], "-o", out)
    assert r.code == 0, r.err
    assert notes(r) == ["note: faces taken from the file names: z.csv +z, y.csv +y, x.csv +x"]
    assert poses_of(out) == {"x.csv": "+x", "y.csv": "+y", "z.csv": "+z"}
    a, b = json.loads(standard.read_text()), json.loads(out.read_text())
    assert (a["method"], a["offset"], a["matrix"]) == (b["method"], b["offset"], b["matrix"])


def test_named_files_in_the_standard_order_change_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """xp.csv yp.csv zp.csv, as the shell lists them, is also +x +y +z: no note."""
    files = copies(tmp_path, {"+x": "xp", "+y": "yp", "+z": "zp"})
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *shell_order(files), "-o", out)
    assert r.code == 0, r.err
    assert notes(r) == []
    assert poses_of(out) == {"xp.csv": "+x", "yp.csv": "+y", "zp.csv": "+z"}


def test_one_file_named_for_a_face_takes_it_unless_up_is_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", SAMPLE / "xn.csv", "-o", out)
    assert r.code == 0, r.err
    assert notes(r) == ["note: faces taken from the file names: xn.csv -x"]
    assert poses_of(out) == {"xn.csv": "-x"}
    r = run(capsys, "solve", "-p", SAMPLE / "xn.csv", "--up", "+z", "-o", out)  # --up is the label: it wins
    assert r.code == 3
    assert "declared +z but reads like -x" in r.err


def test_a_name_that_contradicts_its_place_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """y.csv first among files not all named for a face: its place says +x, its name +y."""
    shutil.copy(SAMPLE / "x.csv", tmp_path / "pose.csv")
    y, z = SAMPLE / "y.csv", SAMPLE / "z.csv"
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "-p", y, tmp_path / "pose.csv", z, "-o", out)
    assert_one_error(
        r,
        f"{y}: its name says +y but its place in --poses gives it +x; "
        "the names cannot give the faces: not every file is named for one",
        hint=f"label every item with its face (+y={y} ...), or name each file for a different face",
    )
    assert_untouched(out)
    with pytest.raises(InputError, match="its name says \\+y but its place in --poses gives it \\+x"):
        tumblecal.solve([str(y), str(tmp_path / "pose.csv"), str(z)])


def test_names_of_the_same_face_that_contradict_their_places_are_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = copies(tmp_path, {"+x": "x", "+y": "x_p", "+z": "z"})  # x_p.csv holds the +y pose
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "-p", files["+x"], files["+y"], files["+z"], "-o", out)
    assert_one_error(
        r,
        f"{files['+y']}: its name says +x but its place in --poses gives it +y; "
        "the names cannot give the faces: x.csv and x_p.csv both say +x",
        hint="label every item with its face",
    )
    assert_untouched(out)


def test_names_that_agree_with_their_places_need_not_name_every_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    shutil.copy(SAMPLE / "y.csv", tmp_path / "pose.csv")
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", SAMPLE / "x.csv", tmp_path / "pose.csv", SAMPLE / "z.csv", "-o", out)
    assert r.code == 0, r.err
    assert notes(r) == []
    assert poses_of(out) == {"x.csv": "+x", "pose.csv": "+y", "z.csv": "+z"}


def test_explicit_labels_win_over_the_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    x, y, z = (SAMPLE / f"{a}.csv" for a in "xyz")
    r = run(capsys, "solve", "-p", f"+x={y}", f"+y={x}", f"+z={z}", "-o", tmp_path / "cal.json")
    assert r.code == 3
    assert f"error: {y}: declared +x but reads like +y" in r.err
    assert notes(r) == []


def test_poses_misnamed_are_blamed_on_their_names_not_their_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """xp.csv holds the +y pose and yp.csv the +x one; the shell lists xn xp yn yp zn zp. The names
    gave the faces, so the order is not what to fix: the check says so and its hint too."""
    faces = SAMPLE_FACES | {"+x": "y.csv", "+y": "x.csv"}
    files = copies(tmp_path / "unit", SPELLINGS["xp"], faces)
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "-p", *shell_order(files), "-o", out, "--method", "six-pose")
    assert r.code == 3, r.err
    errors = [line for line in r.err.splitlines() if line.startswith("error:")]
    assert errors[0].startswith(f"error: {files['+x']}: declared +x but reads like +y")
    assert errors[0].endswith("; its file's name gives +x: was it captured on another face, or misnamed?")
    assert "order" not in r.err
    assert r.err.rstrip("\n").endswith(f"hint: {NAMED_HINT}")
    assert_untouched(out)


def test_three_misnamed_poses_rejected_through_their_gains_blame_the_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The upside-down check (a gain <= 0) on faces from the names: misnamed, not out of order."""
    files = copies(tmp_path, {"+x": "xp", "+y": "yp", "+z": "zp"}, SAMPLE_FACES | {"+x": "y.csv", "+y": "x.csv"})
    given = [files["+z"], files["+y"], files["+x"]]  # typed out of order: the names give the faces
    r = run(capsys, "solve", "-p", *given, "-o", tmp_path / "cal.json", "--no-check", "orientation")
    assert r.code == 3, r.err
    assert "(upside down, or its file misnamed)" in r.err
    assert "order" not in r.err
    assert r.err.rstrip("\n").endswith(f"hint: {NAMED_HINT}")


def test_the_api_takes_faces_from_names_as_the_command_does(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = copies(tmp_path / "unit", SPELLINGS["x_p"])
    given = shell_order(files)
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *given, "-o", out, "-q")
    assert r.code == 0, r.err
    got = tumblecal.solve([str(p) for p in given])
    assert got.status == 0
    assert got.calibration is not None
    written = json.loads(out.read_text())
    assert got.calibration.offset.tolist() == written["offset"]
    assert got.calibration.matrix.tolist() == written["matrix"]
    assert got.notes[0] == "faces taken from the file names: " + ", ".join(
        f"{p.name} {face}" for p in given for face, q in files.items() if q == p
    )


@pytest.mark.parametrize(
    ("files", "placed", "faces", "note", "clash"),
    [
        (["a/x.csv", "a/y.csv", "a/z.csv"], ["+x", "+y", "+z"], ["+x", "+y", "+z"], False, None),
        (["y.csv", "x.csv", "z.csv"], ["+x", "+y", "+z"], ["+y", "+x", "+z"], True, None),
        (["xp.csv", "xn.csv"], [None, None], ["+x", "-x"], True, None),  # no place gives a face: the names do
        (["x.csv", "b.csv"], [None, None], [None, None], False, None),
        (["b.csv", "x.csv", "c.csv"], ["+x", "+y", "+z"], ["+x", "+y", "+z"], False, "x.csv: its name says +x"),
        (["x.csv", "xp.csv", "z.csv"], ["+x", "+y", "+z"], ["+x", "+y", "+z"], False, "xp.csv: its name says +x"),
        (["x.tar.csv", "y.v2.csv", "z"], ["+x", "+y", "+z"], ["+x", "+y", "+z"], False, None),  # name to first dot
        (["-"], ["+z"], ["+z"], False, None),  # stdin has no name
    ],
)
def test_named_faces(
    files: list[str], placed: list[str | None], faces: list[str | None], note: bool, clash: str | None
) -> None:
    got = named_faces(files, placed)
    assert [f for f, _ in got.items] == faces
    assert [p for _, p in got.items] == files
    assert got.by_name is note
    assert (got.clash is None) == (clash is None)
    if clash is not None:
        assert got.clash is not None
        assert str(got.clash).startswith(clash)


def test_a_solver_that_takes_no_faces_asks_no_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A gyroscope's zero-rate bias ignores the faces: neither the note nor the clash."""
    shutil.copy(SAMPLE / "x.csv", tmp_path / "pose.csv")
    gyro: list[str | Path] = ["--sensor", "gyroscope", "--columns", "ax,ay,az", "-o", tmp_path / "gyro.json"]
    for given in ([SAMPLE / "y.csv", tmp_path / "pose.csv", SAMPLE / "z.csv"], [SAMPLE / f"{a}.csv" for a in "yxz"]):
        r = run(capsys, "solve", "-p", *given, *gyro)
        assert r.code == 0, r.err
        assert notes(r) == []
        assert json.loads((tmp_path / "gyro.json").read_text())["method"] == "gyro-bias"

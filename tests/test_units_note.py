"""Data in m/s^2 solved with the default --reference 1 (gains of about 9.81, corrected output in
g) gets one note naming --reference 9.80665 --units m/s^2; data in g solved with --reference
9.81 the note the other way. Data in the reference's units, counts, or a station that said
its units gets none (docs/reference/model.md)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import tumblecal_cli as tumblecal
from tests.conftest import IMUCAL, POSES_3, SIX_FACES, assert_one_error, run

#: imucal's Ferraris session: a real accelerometer's log in m/s^2 (not calibrated), 25.6 Hz as kept here.
SESSION = IMUCAL / "session_every4th.csv"
MS2_NOTE = (
    "the data looks like m/s^2, corrected into g as --reference 1 asks; "
    "for corrected data in m/s^2, run with --reference 9.80665 --units m/s^2"
)
G_NOTE = (
    "the data looks like g, corrected into m/s^2 as --reference 9.81 asks; "
    "for corrected data in g, run with --reference 1"
)


def notes(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("note: the gains")]


@pytest.fixture(scope="module")
def ms2_faces(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The session's best block of each face as a pose file of its own (segment's xp.csv ...)."""
    folder = tmp_path_factory.mktemp("faces")
    done = tumblecal.segment(str(SESSION), rate=25.6, out_dir=str(folder))
    assert done.out_dir is not None
    return {name: folder / f"{name}.csv" for name in SIX_FACES}


def test_a_log_in_m_s2_solved_into_g_gets_one_note(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--log", SESSION, "--rate", "25.6", "-o", tmp_path / "cal.json", "--json")
    assert r.code == 0, r.err
    said = notes(r.err)
    assert len(said) == 1, r.err
    assert said[0].startswith("note: the gains (9.")
    assert said[0].endswith(MS2_NOTE)
    assert [n for n in json.loads(r.out)["notes"] if n.startswith("the gains")] == [said[0].removeprefix("note: ")]
    solved = tumblecal.solve_log(SESSION, rate=25.6)
    assert [n for n in solved.notes if MS2_NOTE in n] == [said[0].removeprefix("note: ")]


@pytest.mark.parametrize("faces", [("xp", "yp", "zp"), SIX_FACES], ids=["three-pose", "six-pose"])
def test_pose_files_in_m_s2_get_the_note(
    faces: tuple[str, ...], ms2_faces: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "solve", "--poses", *(ms2_faces[f] for f in faces), "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert len(notes(r.err)) == 1, r.err
    assert notes(r.err)[0].endswith(MS2_NOTE)
    assert tumblecal.load(tmp_path / "cal.json").method == ("three-pose" if len(faces) == 3 else "six-pose")


@pytest.mark.parametrize(
    "args",
    [
        pytest.param(["--reference", "9.81"], id="m/s^2 with --reference 9.81"),
        pytest.param(["--units", "g"], id="m/s^2 into g, said with --units"),
        pytest.param(["--input-units", "m/s^2"], id="m/s^2 into g, said with --input-units"),
    ],
)
def test_no_note_when_the_units_are_meant(args: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--log", SESSION, "--rate", "25.6", *args, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert notes(r.err) == []


@pytest.mark.parametrize(
    "poses",
    [
        pytest.param(POSES_3, id="g"),
        pytest.param([str(IMUCAL / f"{f}.csv") for f in SIX_FACES], id="counts"),
    ],
)
def test_no_note_on_data_in_g_or_counts(poses: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = run(capsys, "solve", "--poses", *poses, "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert notes(r.err) == []


def test_g_data_solved_into_m_s2_gets_the_note_the_other_way(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "solve", "--poses", *POSES_3, "--reference", "9.81", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert len(notes(r.err)) == 1
    assert notes(r.err)[0].startswith("note: the gains (0.10")
    assert notes(r.err)[0].endswith(G_NOTE)
    r = run(capsys, "solve", "--poses", *POSES_3, "--reference", "9.81", "--units", "m/s^2", "-o", tmp_path / "c.json")
    assert notes(r.err) == []


def test_judged_gains_in_other_units_are_still_an_error(
    ms2_faces: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """With a gain limit the gains are judged: m/s^2 against a nominal 1 is exit 2 (gate.check_gains)."""
    r = run(capsys, "solve", "--poses", *ms2_faces.values(), "--max-gain-error", "0.05")
    assert_one_error(
        r, r.err.splitlines()[0].removeprefix("error: "), hint="the data looks like m/s^2: run with --reference 9.80665"
    )
    assert "a units mistake?" in r.err


# -- units that do not fit the sensor, a reference that is not a unit at rest (issue 42, item 7) --

MAG = Path(__file__).resolve().parent / "data" / "ckexplorer_mag" / "mag_every10.csv"


@pytest.mark.parametrize(
    ("sensor", "flag", "units", "error"),
    [
        ("accelerometer", "--units", "uT", "--units uT is a unit of magnetic field, and an accelerometer measures "),
        ("accelerometer", "--input-units", "deg/s", "--input-units deg/s is a unit of angular rate, and an "),
        ("magnetometer", "--units", "g", "--units g is a unit of acceleration, and a magnetometer measures magnetic"),
    ],
)
def test_units_of_another_quantity_are_refused(
    sensor: str, flag: str, units: str, error: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--units uT` on an accelerometer was written into its calibration, and export then
    converted "microtesla" into m/s^2."""
    poses = [str(MAG)] if sensor == "magnetometer" else POSES_3
    r = run(capsys, "solve", "--sensor", sensor, "--poses", *poses, flag, units, "-o", tmp_path / "c.json")
    assert r.code == 2
    assert r.err.splitlines()[0].startswith(f"error: {error}")
    assert not (tmp_path / "c.json").exists()


@pytest.mark.parametrize(
    ("units", "reference", "note"),
    [
        ("uT", "1", "--reference 1 uT is not a field the Earth has (22–67 uT): is --reference in --units?"),
        ("uT", "46", None),
        ("gauss", "0.46", None),
        ("nT", "46", "--reference 46 nT is not a field the Earth has (2.2e+04–6.7e+04 nT): is --reference in --units?"),
    ],
)
def test_magnetometer_reference_that_no_earth_field_is_gets_a_note(
    units: str, reference: str, note: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--units uT --reference 1`: a field of 1 µT, taken without a word (the Earth's is 22–67 µT)."""
    args: list[str | Path] = [
        "solve",
        "--sensor",
        "magnetometer",
        "--poses",
        MAG,
        "--units",
        units,
        "--reference",
        reference,
    ]
    r = run(capsys, *args, "-o", tmp_path / "m.json")
    assert r.code == 0, r.err
    said = [ln for ln in r.err.splitlines() if "is not a field the Earth has" in ln]
    assert said == (
        [] if note is None else [f"note: {note} (a lab's coils may make it; --location gives the local field)"]
    )


def test_accelerometer_reference_that_is_not_gravity_in_its_units_gets_a_note(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    r = run(capsys, "solve", "--poses", *POSES_3, "--units", "m/s^2", "-o", tmp_path / "c.json")
    assert r.code == 0, r.err
    assert "note: --reference 1 m/s^2 is not gravity (9.807 m/s^2): is --reference in --units?" in r.err.splitlines()
    r = run(capsys, "solve", "--poses", *POSES_3, "--units", "mg", "--reference", "1000", "-o", tmp_path / "c.json")
    assert "is not gravity" not in r.err


def test_export_of_a_calibration_solved_with_reference_9_80665_knows_its_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`solve --reference 9.80665` without --units, then `export --format px4`: "the calibration's
    corrected units are None" (a Python word; an accelerometer at 9.80665 is in m/s^2). A
    conventional reference records its units (1: g, 9.80665: m/s^2, 1000: mg)."""
    poses = []
    for name in POSES_3:
        lines = Path(name).read_text().splitlines()
        rows = [
            ",".join([c[0], *(f"{9.80665 * float(v):.6f}" for v in c[1:])]) for c in (ln.split(",") for ln in lines[1:])
        ]
        poses.append(tmp_path / Path(name).name)
        poses[-1].write_text("\n".join([lines[0], *rows]) + "\n")
    r = run(capsys, "solve", "--poses", *poses, "--reference", "9.80665", "-o", tmp_path / "c.json", "-q")
    assert r.code == 0, r.err
    assert json.loads((tmp_path / "c.json").read_text())["units"] == "m/s^2"
    r = run(capsys, "export", tmp_path / "c.json", "--format", "px4")
    assert r.code == 0, r.err
    assert "# corrected = (raw - CAL_ACC0_xOFF) * CAL_ACC0_xSCALE per axis, in m/s^2" in r.out


def test_solve_json_carries_the_residual_and_the_coverage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`solve --json` had neither the residual nor the coverage of a fit over samples (only the
    calibration file did)."""
    r = run(capsys, "solve", "--sensor", "magnetometer", "--poses", MAG, "-o", tmp_path / "m.json", "--json", "-q")
    assert r.code == 0, r.err
    doc, cal = json.loads(r.out), json.loads((tmp_path / "m.json").read_text())
    assert doc["residuals"] == cal["residuals"]
    assert set(doc["residuals"]) >= {"rms", "max", "count"}
    assert doc["coverage"] == cal["coverage"] == 1.0
    r = run(capsys, "solve", "--poses", *POSES_3, "-o", tmp_path / "c.json", "--json", "-q")
    assert json.loads(r.out)["coverage"] is None  # three poses: no directions to cover


def test_an_accelerometer_turned_while_it_logs_gets_a_note_of_its_motion(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A capture turned continuously, forced through --method ellipsoid: residual 0.3 m/s^2 and no
    word that its readings hold the motion's own acceleration."""
    import numpy as np

    rng = np.random.default_rng(1)
    n = 3000
    theta, phi = np.linspace(0, np.pi, n), np.linspace(0, 12 * np.pi, n)
    g = 9.81 * np.c_[np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
    capture = tmp_path / "turned.csv"
    np.savetxt(capture, np.c_[np.arange(n) / 100, g + rng.normal(0, 0.3, (n, 3))], delimiter=",",
               header="t,ax,ay,az", comments="", fmt="%.5f")  # fmt: skip
    r = run(capsys, "solve", "--poses", capture, "--reference", "9.81", "--method", "ellipsoid", "-o", tmp_path / "c")
    assert r.code == 0, r.err
    assert "reads the motion's own acceleration beside gravity, which no calibration removes" in r.err
    r = run(capsys, "solve", "--sensor", "magnetometer", "--poses", MAG, "-o", tmp_path / "m.json")
    assert "motion's own acceleration" not in r.err

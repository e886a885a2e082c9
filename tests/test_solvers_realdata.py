"""The new solvers on real captures nobody here made, judged the honest way: by the norm of static
orientations the fit did *not* use (``tumblecal verify``). Any method fitted on six poses reads
1 g on those six by construction; only held-out orientations tell a calibration from a fit.

Data, each folder with its SOURCE.md and LICENSE (all MIT):

- ``tests/data/hassan_gnls``: 49 averaged orientations in g (Hassan & Bao), and the 24- and
  31-orientation subsets of them that their repository ships. ``sphere`` on a subset, verified
  on the rest.
- ``sample_data/imucal``: six faces of a 16-bit accelerometer in raw counts (imucal).
  ``least-squares`` on five faces, verified on the sixth, for each face; ``six-pose`` and
  ``six-pose-diagonal`` on all six.
- ``tests/data/ncsu_microstrain`` (+ ``tests/data/ncsu_xplus_head.csv``): the still heads of six
  single-face logs of a factory-calibrated MicroStrain 3DM-CX5, in g. ``six-pose`` and the same
  leave-one-face-out ``least-squares``.
- ``tests/data/imucal_session``: imucal's continuous Ferraris session (nominal m/s^2), every 4th
  row. ``six-pose`` on the six labelled sections, verified on seven unlabelled still blocks.

Every bound below was measured (the figure in the comment next to it) and given a margin. The
case functions return :class:`Heldout` figures; ``python tests/realdata_figures.py`` prints them
as the README's table.
"""

from __future__ import annotations

import csv
import gzip
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import tumblecal

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
IMUCAL = ROOT / "sample_data" / "imucal"
HASSAN = DATA / "hassan_gnls"
NCSU = DATA / "ncsu_microstrain"
SESSION = DATA / "imucal_session"

SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
#: imucal's section labels (x_p: x reads +g, x_a: x reads -g) as faces.
SESSION_FACES = {"x_p": "+x", "x_a": "-x", "y_p": "+y", "y_a": "-y", "z_p": "+z", "z_a": "-z"}
#: Still blocks of the session that its section list does not label, as [first, end) of
#: ``n_samples`` at the full 102.4 Hz. Found offline on the full upstream file: a centred rolling
#: standard deviation over 51 samples (0.5 s), its largest axis below 0.03 m/s^2, runs of 250
#: samples or more that overlap no labelled section. Each block sits before or after one of the
#: 360-degree rotations, which turn the unit about the vertical axis: so every one rests on the
#: +x, +y or +z face again, re-placed by hand, not on a new orientation. (One more still run,
#: 223-293 on +x before the first section, is 70 samples long and left out.)
SESSION_STILL = {
    "still_06291_xp.csv": (6291, 6749),  # +x, before x_rot
    "still_07116_xp.csv": (7116, 7595),  # +x, after x_rot
    "still_07740_yp.csv": (7740, 8060),  # +y, before y_rot
    "still_08496_yp.csv": (8496, 8776),  # +y, after y_rot
    "still_08906_zp.csv": (8906, 9183),  # +z, before z_rot
    "still_09535_zp.csv": (9535, 9882),  # +z, after z_rot
    "still_09949_zp.csv": (9949, 10199),  # +z, to the end of the session
}


def solve(cal: Path, poses: Sequence[str | Path], *options: str) -> dict[str, Any]:
    """``tumblecal solve``: exit 0, and the calibration file it wrote."""
    r = tumblecal("solve", "-p", *poses, "-o", cal, "--quiet", *options)
    assert r.code == 0, r.err
    doc: dict[str, Any] = json.loads(cal.read_text())
    return doc


def verify(cal: Path, captures: Sequence[str | Path], *options: str) -> dict[str, Any]:
    """``tumblecal verify --json``: exit 0 (no --max-norm-error given), and its summary."""
    r = tumblecal("verify", "--cal", cal, *captures, "--json", "--quiet", *options)
    assert r.code == 0, r.err
    doc: dict[str, Any] = json.loads(r.out)
    return doc


# -- held-out figures ------------------------------------------------------------------------------


def _rms(values: Sequence[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


@dataclass(frozen=True)
class Heldout:
    """Norm errors of static captures against the reference, in the corrected units."""

    dataset: str
    method: str
    fitted_on: str
    verified_on: str
    units: str
    captures: tuple[str, ...]
    after: tuple[float, ...]  # |corrected mean| - reference, per capture
    before: tuple[float, ...] | None  # |raw mean| - reference, where the raw units are the output's
    held_out: bool = True  # False: verified on the poses it was fitted on (a self-check)

    @property
    def rms_after(self) -> float:
        return _rms(self.after)

    @property
    def max_after(self) -> float:
        return max(abs(v) for v in self.after)

    @property
    def rms_before(self) -> float | None:
        return None if self.before is None else _rms(self.before)

    @property
    def max_before(self) -> float | None:
        return None if self.before is None else max(abs(v) for v in self.before)


def figures(
    verified: dict[str, Any], reference: float, *, raw_in_output_units: bool
) -> tuple[tuple[str, ...], tuple[float, ...], tuple[float, ...] | None]:
    """Names, errors after and (when the raw data is in the output units) before, from verify."""
    rows = verified["captures"]
    names = tuple(str(Path(r["file"]).name) for r in rows)
    after = tuple(float(r["error_after"]) for r in rows)
    before = tuple(float(r["norm_before"]) - reference for r in rows) if raw_in_output_units else None
    return names, after, before


@dataclass(frozen=True)
class FaceSet:
    """Six face captures of one unit, and how to solve them."""

    dataset: str
    files: dict[str, Path]  # face -> capture
    reference: float
    units: str
    raw_in_output_units: bool  # raw data already in the output units: "before" means something
    options: tuple[str, ...] = ()  # for solve and verify


def leave_one_face_out(workdir: Path, faces: FaceSet) -> Heldout:
    """``least-squares`` on five faces, verified on the sixth, for each face in turn."""
    names: list[str] = []
    after: list[float] = []
    before: list[float] = []
    for out in SIX:
        cal = workdir / f"{faces.files[out].stem}_left_out.json"
        poses = [f"{face}={faces.files[face]}" for face in SIX if face != out]
        doc = solve(cal, poses, "-m", "least-squares", "--reference", f"{faces.reference}", *faces.options)
        assert doc["method"] == "least-squares"
        verified = verify(cal, [faces.files[out]], *faces.options)
        n, a, b = figures(verified, faces.reference, raw_in_output_units=faces.raw_in_output_units)
        names.extend(n)
        after.extend(a)
        before.extend(b or ())
    return Heldout(
        faces.dataset,
        "least-squares",
        "5 faces (each left out in turn)",
        "the left-out face",
        faces.units,
        tuple(names),
        tuple(after),
        tuple(before) if faces.raw_in_output_units else None,
    )


def all_six_faces(workdir: Path, faces: FaceSet, method: str) -> Heldout:
    """``method`` on all six faces, verified on the same six: a self-check, nothing is held out."""
    cal = workdir / f"{faces.files['+x'].stem}_{method}.json"
    poses = [f"{face}={faces.files[face]}" for face in SIX]
    doc = solve(cal, poses, "-m", method, "--reference", f"{faces.reference}", *faces.options)
    assert doc["method"] == method
    verified = verify(cal, [faces.files[face] for face in SIX], *faces.options)
    names, after, before = figures(verified, faces.reference, raw_in_output_units=faces.raw_in_output_units)
    return Heldout(faces.dataset, method, "6 faces", "the same 6", faces.units, names, after, before, held_out=False)


# -- 1. Hassan & Bao: 49 averaged orientations, sphere on a subset -------------------------------------


def hassan_lines(name: str) -> list[str]:
    """The data lines of one of the Hassan & Bao files (one averaged orientation each, in g)."""
    lines = (HASSAN / name).read_text().splitlines()
    assert lines[0] == "x,y,z"
    return lines[1:]


def hassan_split(subset: str) -> tuple[list[int], list[int]]:
    """Rows of the 49-orientation set in ``subset`` (matched by their exact text) and the rest."""
    all49 = hassan_lines("orient49.csv")
    fitted = [all49.index(line) for line in hassan_lines(subset)]
    return fitted, [i for i in range(len(all49)) if i not in fitted]


def hassan_sphere(workdir: Path, subset: str) -> Heldout:
    """``sphere`` on the orientations of ``subset``, one single-row file each, verified on the rest."""
    all49 = hassan_lines("orient49.csv")
    files = []
    for i, line in enumerate(all49):
        path = workdir / f"hassan_{i:02d}.csv"
        path.write_text(f"x,y,z\n{line}\n")
        files.append(path)
    fitted, rest = hassan_split(subset)
    cal = workdir / f"hassan_{len(fitted)}.json"
    doc = solve(cal, [files[i] for i in fitted], "--min-samples", "1")  # 12+ unlabelled files: sphere
    assert doc["method"] == "sphere"
    names, after, before = figures(verify(cal, [files[i] for i in rest]), 1.0, raw_in_output_units=True)
    return Heldout(
        "Hassan & Bao, 49 orientations (g)",
        doc["method"],
        f"{len(fitted)} orientations ({subset})",
        f"the other {len(rest)}",
        "g",
        names,
        after,
        before,
    )


def test_hassan_subsets_are_exact_rows_of_the_49() -> None:
    """The repository's 24- and 31-orientation files are rows of the 49 (SOURCE.md). The 49 are
    three turns: rows 0-15 about x, 16-32 about z, 33-48 about y. The 24 take about every other
    row of all three; the 31 are rows 14-44, so their fit is verified mostly on the turn about x,
    which it saw only near +z."""
    fitted24, rest24 = hassan_split("orient24.csv")
    fitted31, rest31 = hassan_split("orient31.csv")
    assert (len(fitted24), len(rest24), len(fitted31), len(rest31)) == (24, 25, 31, 18)
    assert fitted31 == list(range(14, 45))
    assert len(set(hassan_lines("orient49.csv"))) == 49  # no repeated orientation


@pytest.mark.parametrize(
    ("subset", "rms_after", "max_after", "rms_before"),
    [
        # measured: after RMS 0.0012, max 0.0034; before RMS 0.0159, max 0.0341 (g)
        ("orient24.csv", 0.002, 0.005, 0.012),
        # measured: after RMS 0.0011, max 0.0030; before RMS 0.0181, max 0.0371 (g)
        ("orient31.csv", 0.002, 0.005, 0.012),
    ],
    ids=["24-of-49", "31-of-49"],
)
def test_hassan_sphere_on_a_subset_holds_on_the_other_orientations(
    tmp_path: Path, subset: str, rms_after: float, max_after: float, rms_before: float
) -> None:
    """The orientation-free fit brings the held-out orientations from 1.6-1.8% to 0.1% of 1 g."""
    h = hassan_sphere(tmp_path, subset)
    assert h.method == "sphere"
    assert h.rms_after < rms_after
    assert h.max_after < max_after
    assert h.rms_before is not None
    assert h.rms_before > rms_before
    assert h.rms_after < h.rms_before / 6  # measured 13x (24) and 16x (31)


def test_hassan_sphere_json_summary(tmp_path: Path) -> None:
    for i, line in enumerate(hassan_lines("orient24.csv")):
        (tmp_path / f"o{i:02d}.csv").write_text(f"x,y,z\n{line}\n")
    cal = tmp_path / "cal.json"
    poses = sorted(tmp_path.glob("o*.csv"))
    r = tumblecal("solve", "-p", *poses, "--min-samples", "1", "-o", cal, "--json", "--quiet")
    assert r.code == 0, r.err
    assert json.loads(r.out)["method"] == "sphere"


# -- 2. imucal: six faces in raw counts --------------------------------------------------------


IMUCAL_FACES = FaceSet(
    "imucal, 6 faces (counts)",
    {
        face: IMUCAL / name
        for face, name in zip(SIX, ("xp.csv", "xn.csv", "yp.csv", "yn.csv", "zp.csv", "zn.csv"), strict=True)
    },
    9.81,  # imucal's own reference (its examples use 9.81 m/s^2)
    "m/s²",
    raw_in_output_units=False,
)


def test_imucal_least_squares_on_five_faces_predicts_the_sixth(tmp_path: Path) -> None:
    """Each face left out is read within 0.12 m/s^2 (11 mg) of 9.81. The y faces are the worst:
    without one of them, the y offset comes only from the four poses where y is horizontal, whose
    y readings a tilt of the fixture moves to first order (docs/reference/model.md): without -y it is
    -59.8 counts, against -48.3 from the two vertical readings (six-pose), 0.055 m/s^2 apart."""
    h = leave_one_face_out(tmp_path, IMUCAL_FACES)
    errors = dict(zip(h.captures, h.after, strict=True))
    # measured (m/s^2): xp +0.0267, xn -0.0247, yp +0.1121, yn -0.1106, zp +0.0307, zn -0.0241
    for name in ("xp.csv", "xn.csv", "zp.csv", "zn.csv"):
        assert abs(errors[name]) < 0.045, (name, errors[name])
    for name in ("yp.csv", "yn.csv"):
        assert 0.08 < abs(errors[name]) < 0.15, (name, errors[name])
    assert h.rms_after < 0.09  # measured 0.0679
    assert h.max_after < 0.15  # measured 0.1121


def test_imucal_six_pose_with_cross_axis_terms_fits_the_faces_better_than_diagonal(tmp_path: Path) -> None:
    """A self-check (the same six faces): six-pose leaves 0.7 mm/s^2 RMS, the diagonal form 3.2 mm/s^2,
    the cross-axis terms it leaves out. Both far below the 5-face predictions above."""
    full = all_six_faces(tmp_path, IMUCAL_FACES, "six-pose")
    diagonal = all_six_faces(tmp_path, IMUCAL_FACES, "six-pose-diagonal")
    assert full.rms_after < 0.0015  # measured 0.00066
    assert full.max_after < 0.003  # measured 0.00146 (zn)
    assert 0.002 < diagonal.rms_after < 0.005  # measured 0.00319
    assert diagonal.max_after < 0.01  # measured 0.00661 (zn)
    assert diagonal.rms_after > 2 * full.rms_after


# -- 3. NCSU: a factory-calibrated MicroStrain, still heads of six single-face logs ------------------


NCSU_FACES = FaceSet(
    "NCSU MicroStrain 3DM-CX5 (g, factory-calibrated)",
    {
        "+x": DATA / "ncsu_xplus_head.csv",  # the first 200 lines, like the five below (tests/data/README.md)
        "-x": NCSU / "xminus_head.csv",
        "+y": NCSU / "yplus_head.csv",
        "-y": NCSU / "yminus_head.csv",
        "+z": NCSU / "zplus_head.csv",
        "-z": NCSU / "zminus_head.csv",
    },
    1.0,
    "g",
    raw_in_output_units=True,
    # The unit was at rest in a hand or on a table that shook: in its first 0.13 s the means of
    # 50-sample blocks wander by up to 0.025 g (xminus, z), above the default --max-noise of 0.02.
    options=("--max-noise", "0.05"),
)


def test_ncsu_factory_calibrated_unit_gains_nothing_from_five_faces(tmp_path: Path) -> None:
    """The factory calibration reads each face within 0.75% of 1 g; a 5-face fit predicts the
    sixth worse, worst on the x faces: without one of them, the x offset comes from the x readings
    of the y and z poses, where x is horizontal and the hand-placed poses are tilted (the +y head
    reads x = -0.065 g, 3.7 degrees off its face): without +x it is -0.020 g, against +0.0003 g
    from the two vertical readings (six-pose). The six faces a fit used do not show this (below)."""
    h = leave_one_face_out(tmp_path, NCSU_FACES)
    assert h.rms_before is not None
    assert h.max_before is not None
    errors = dict(zip(h.captures, h.after, strict=True))
    # measured (g): ncsu_xplus +0.0425, xminus -0.0349, yplus +0.0109, yminus -0.0083, zplus -0.0061, zminus +0.0110
    assert 0.025 < abs(errors["ncsu_xplus_head.csv"]) < 0.06
    assert 0.02 < abs(errors["xminus_head.csv"]) < 0.05
    assert h.rms_after < 0.035  # measured 0.0237
    assert h.max_after < 0.06  # measured 0.0425
    assert h.rms_before < 0.005  # measured 0.0031
    assert h.max_before < 0.01  # measured 0.0074 (+y)
    assert h.rms_after > 3 * h.rms_before  # measured 7.6x: the factory calibration is the better one here


@pytest.mark.parametrize(
    ("method", "rms_after", "max_after"),
    [
        ("six-pose", 0.0015, 0.003),  # measured RMS 0.00084, max 0.0014 (-x)
        ("six-pose-diagonal", 0.002, 0.004),  # measured RMS 0.0012, max 0.0022 (+y)
    ],
    ids=["six-pose", "six-pose-diagonal"],
)
def test_ncsu_six_pose_self_check(tmp_path: Path, method: str, rms_after: float, max_after: float) -> None:
    """On the six faces it was fitted on, six-pose reads 1 g within 2.5 mg: a self-check that looks
    better than the factory calibration (RMS 0.0031 g, 0.0074 on +y) while the 5-face predictions
    above say otherwise."""
    h = all_six_faces(tmp_path, NCSU_FACES, method)
    assert h.rms_before is not None
    assert h.rms_after < rms_after
    assert h.max_after < max_after
    assert 0.002 < h.rms_before < 0.005  # measured 0.0031


# -- 4. imucal's continuous session (nominal m/s^2) --------------------------------------------------


def session_lines() -> tuple[str, dict[int, str]]:
    """The header and the data lines of the session by ``n_samples`` (every 4th sample kept)."""
    lines = (SESSION / "session_every4th.csv").read_text().splitlines()
    header = lines[0]
    assert header.split(",")[0] == "n_samples"
    return header, {int(line.split(",", 1)[0]): line for line in lines[1:]}


def session_cut(workdir: Path, name: str, first: int, end: int) -> Path:
    """The session's rows with ``first <= n_samples < end`` (imucal's iloc[start:end]), verbatim."""
    header, rows = session_lines()
    path = workdir / name
    kept = [line for n, line in rows.items() if first <= n < end]
    path.write_text("\n".join([header, *kept]) + "\n")
    return path


def session_sections(workdir: Path) -> dict[str, Path]:
    """The six labelled sections of the section list, one file per face."""
    sections = json.loads((SESSION / "example_ferraris_session_list.json").read_text())
    return {
        face: session_cut(workdir, f"{label}.csv", sections[label]["start"], sections[label]["end"])
        for label, face in SESSION_FACES.items()
    }


def session_six_pose(workdir: Path, method: str) -> Heldout:
    sections = session_sections(workdir)
    still = [session_cut(workdir, name, first, end) for name, (first, end) in SESSION_STILL.items()]
    cal = workdir / f"session_{method}.json"
    doc = solve(cal, [f"{face}={path}" for face, path in sections.items()], "-m", method, "--reference", "9.81")
    assert doc["method"] == method
    names, after, before = figures(verify(cal, still), 9.81, raw_in_output_units=True)
    return Heldout(
        "imucal session (nominal m/s²)",
        method,
        "6 labelled sections",
        f"{len(still)} unlabelled still blocks (+x +y +z faces)",
        "m/s²",
        names,
        after,
        before,
    )


def test_session_sections_are_the_faces_they_are_labelled() -> None:
    """x_p reads about +g on x, x_a about -g, and so on (imucal's convention)."""
    header, rows = session_lines()
    sections = json.loads((SESSION / "example_ferraris_session_list.json").read_text())
    acc = [header.split(",").index(c) for c in ("acc_x", "acc_y", "acc_z")]
    for label, face in SESSION_FACES.items():
        span = range(sections[label]["start"], sections[label]["end"])
        values = [[float(line.split(",")[i]) for i in acc] for n, line in rows.items() if n in span]
        mean = [sum(v[k] for v in values) / len(values) for k in range(3)]
        axis = "xyz".index(face[1])
        assert mean[axis] * (1 if face[0] == "+" else -1) > 9.0, (label, mean)
        assert all(abs(mean[k]) < 1.0 for k in range(3) if k != axis), (label, mean)


@pytest.mark.parametrize(
    ("method", "rms_after", "max_after"),
    [
        ("six-pose", 0.01, 0.018),  # measured RMS 0.0066, max 0.0118 (+x after x_rot)
        ("six-pose-diagonal", 0.009, 0.016),  # measured RMS 0.0058, max 0.0106 (the same block)
    ],
    ids=["six-pose", "six-pose-diagonal"],
)
def test_session_six_pose_holds_on_the_unlabelled_still_blocks(
    tmp_path: Path, method: str, rms_after: float, max_after: float
) -> None:
    """The raw data, in nominal m/s^2, reads 0.52-0.65 m/s^2 off 9.81 on the still blocks; the
    six-pose calibration of the labelled sections brings them within 0.012 m/s^2 (1.2 mg). The
    blocks rest on faces it was fitted on, so this checks re-placement, not new orientations."""
    h = session_six_pose(tmp_path, method)
    assert h.rms_before is not None
    assert h.rms_after < rms_after
    assert h.max_after < max_after
    assert h.rms_before > 0.5  # measured 0.595, max 0.653 (+z)
    assert h.rms_after < h.rms_before / 50  # measured 90x (six-pose), 100x (diagonal)


# -- 5. continuous logs: segmented, the sphere fitted on every other still block -----------------------


LOGS = DATA / "logs"


@dataclass(frozen=True)
class Log:
    """A continuous public log and how to calibrate it."""

    dataset: str
    file: str  # in tests/data/logs (.gz: compressed)
    reference: float
    units: str
    raw_in_output_units: bool


XSENS_LOG = Log("imu_tk Xsens log (raw counts)", "xsens_acc.txt.gz", 1.0, "g", False)
CKEXPLORER_LOG = Log("CK-Explorer log (g)", "ckexplorer_acc_log.csv", 1.0, "g", True)
HASSAN_LOG = Log("Hassan & Bao phone log (m/s²)", "hassan_mobile_30orient.csv", 9.81, "m/s²", True)


def log_sphere(workdir: Path, log: Log) -> Heldout:
    """``tumblecal segment`` the log, fit ``sphere`` on the odd-numbered kept blocks (1st, 3rd
    ...) and verify on the even ones: orientations it did not see, from the same session."""
    source = LOGS / log.file
    path = workdir / log.file.removesuffix(".gz")
    if log.file.endswith(".gz"):
        path.write_bytes(gzip.decompress(source.read_bytes()))
    else:
        path = source
    blocks = workdir / f"{path.stem}_blocks"
    r = tumblecal("segment", path, "-d", blocks, "-q")
    assert r.code == 0, r.err
    with (blocks / "segments.csv").open(newline="") as f:
        kept = [row for row in csv.DictReader(f) if row["status"] == "kept"]
    files = [blocks / row["file"] for row in sorted(kept, key=lambda row: int(row["block"]))]
    fit, held = files[0::2], files[1::2]
    cal = workdir / f"{path.stem}_sphere.json"
    doc = solve(cal, fit, "--method", "sphere", "--reference", f"{log.reference}")
    assert doc["method"] == "sphere"
    names, after, before = figures(verify(cal, held), log.reference, raw_in_output_units=log.raw_in_output_units)
    return Heldout(
        log.dataset, "sphere", f"{len(fit)} still blocks (every other)", f"the other {len(held)}", log.units,
        names, after, before,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("log", "rms_after", "max_after"),
    [(XSENS_LOG, 3e-4, 1e-3), (CKEXPLORER_LOG, 2e-3, 5e-3), (HASSAN_LOG, 0.12, 0.4)],  # measured x2-3
    ids=["xsens", "ckexplorer", "hassan"],
)
def test_continuous_log_sphere_holds_on_its_other_still_blocks(
    tmp_path: Path, log: Log, rms_after: float, max_after: float
) -> None:
    """Segmented with defaults, fitted on half the still blocks, read on the other half."""
    h = log_sphere(tmp_path, log)
    assert len(h.captures) >= 12
    assert h.rms_after < rms_after
    assert h.max_after < max_after
    if h.rms_before is not None:
        assert h.rms_after < h.rms_before / 5


def all_figures(workdir: Path) -> list[Heldout]:
    """Every case, in the README's order (``tests/realdata_figures.py``)."""
    return [
        hassan_sphere(workdir, "orient24.csv"),
        hassan_sphere(workdir, "orient31.csv"),
        leave_one_face_out(workdir, IMUCAL_FACES),
        all_six_faces(workdir, IMUCAL_FACES, "six-pose"),
        all_six_faces(workdir, IMUCAL_FACES, "six-pose-diagonal"),
        leave_one_face_out(workdir, NCSU_FACES),
        all_six_faces(workdir, NCSU_FACES, "six-pose"),
        all_six_faces(workdir, NCSU_FACES, "six-pose-diagonal"),
        session_six_pose(workdir, "six-pose"),
        session_six_pose(workdir, "six-pose-diagonal"),
        log_sphere(workdir, XSENS_LOG),
        log_sphere(workdir, CKEXPLORER_LOG),
        log_sphere(workdir, HASSAN_LOG),
    ]


# -- 6. six faces from a real log: what auto picks, judged on the log's other still blocks ------------------


SESSION_LOG = Log("imucal example session (m/s²)", "imucal_ferraris_session.csv.gz", 9.81, "m/s²", True)


@dataclass(frozen=True)
class FaceChoice:
    """Held-out RMS norm error (output units) of each face solver on one log's six face blocks."""

    auto_method: str
    auto: float
    six: float
    diagonal: float
    before: float | None
    notes: str


def face_solvers_on_a_log(workdir: Path, log: Log, *segment_options: str) -> FaceChoice:
    """``tumblecal segment`` the log; solve its six face blocks (the files it names xp.csv ...)
    with auto, six-pose and six-pose-diagonal; verify each on every other kept block."""
    source = LOGS / log.file
    path = workdir / log.file.removesuffix(".gz")
    path.write_bytes(gzip.decompress(source.read_bytes()) if log.file.endswith(".gz") else source.read_bytes())
    blocks = workdir / "blocks"
    r = tumblecal("segment", path, "-d", blocks, "-q", *segment_options)
    assert r.code == 0, r.err
    with (blocks / "segments.csv").open(newline="") as f:
        kept = [row for row in csv.DictReader(f) if row["status"] == "kept"]
    names = {"+x": "xp.csv", "-x": "xn.csv", "+y": "yp.csv", "-y": "yn.csv", "+z": "zp.csv", "-z": "zn.csv"}
    poses = [f"{face}={blocks / name}" for face, name in names.items()]
    held = [blocks / row["file"] for row in kept if row["file"] not in names.values()]
    assert len(held) >= 6
    errors: dict[str, float] = {}
    method, notes, before = "", "", None
    for m in ("auto", "six-pose", "six-pose-diagonal"):
        cal = workdir / f"{m}.json"
        r = tumblecal("solve", "-p", *poses, "-m", m, "--reference", f"{log.reference}", "-o", cal)
        assert r.code == 0, r.err
        _, after, raw = figures(verify(cal, held), log.reference, raw_in_output_units=log.raw_in_output_units)
        errors[m] = _rms(after)
        if m == "auto":
            method, notes, before = json.loads(cal.read_text())["method"], r.err, None if raw is None else _rms(raw)
    return FaceChoice(method, errors["auto"], errors["six-pose"], errors["six-pose-diagonal"], before, notes)


@pytest.mark.parametrize(
    ("log", "options", "method"),
    [
        (XSENS_LOG, (), "six-pose-magnitude"),  # its +x block 15.9° off, -z 10°: hand-placed
        (HASSAN_LOG, (), "six-pose-magnitude"),  # faces 2-8° off
        (CKEXPLORER_LOG, (), "six-pose-magnitude"),  # +z 15° off
        (SESSION_LOG, ("--rate", "102.4"), "six-pose"),  # a fixture: every face within 1.1°
    ],
    ids=["xsens", "hassan", "ckexplorer", "imucal-session"],
)
def test_auto_on_six_real_faces_is_never_worse_than_the_better_face_solver(
    tmp_path: Path, log: Log, options: tuple[str, ...], method: str
) -> None:
    """The issue's bar: auto's held-out error within 25 % (or 0.3 mg) of the better of six-pose and
    six-pose-diagonal, and below the uncalibrated error. Measured, auto vs six-pose / diagonal (mg,
    or 0.1 % of reference): xsens 3.8 vs 28.6 / 8.2; hassan 5.1 vs 13.8 / 6.5 (raw 29.3);
    ckexplorer 1.8 vs 20.8 / 4.6 (raw 15.5); imucal session 0.48 vs 0.48 / 0.41 (raw 59)."""
    c = face_solvers_on_a_log(tmp_path, log, *options)
    assert c.auto_method == method
    assert f"note: auto chose {method}" in c.notes
    slack = 0.0003 * log.reference
    assert c.auto <= 1.25 * min(c.six, c.diagonal) + slack
    if c.before is not None:
        assert c.auto < c.before / 5
    if method == "six-pose-magnitude":  # the hand-placed logs: six-pose is the trap
        assert c.auto < c.six / 2

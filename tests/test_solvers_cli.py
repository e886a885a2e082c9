"""End-to-end CLI tests of issue 4: pose labels, the solvers behind --method, the calibration
file's new fields, magnetometer and gyroscope calibration, ``apply`` with several --cal and
``verify`` (docs/reference/model.md, "Calibration file (format version 1)" and
"Exit status").

Every capture is synthetic with a known truth (tests/synth.py), written to tmp_path, except the
imucal sample set, whose published calibration is the known answer of the six-pose solver.
Every run is in-process through ``run(capsys, ...)``.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import IMUCAL, SAMPLE, Result, assert_untouched, assert_usage_error, precious, run, unnamed, write
from tests.synth import FloatArray, pose_samples
from tumblecal_cli.core.model import FACES

#: the truth of the synthetic accelerometer: raw = A v + OFFSET, A = diag(GAIN) + CROSS, |v| = 1
OFFSET = np.array([0.021, -0.034, 0.047])
GAIN = np.array([1.012, 0.987, 1.005])
CROSS = np.array([[0.0, 0.004, -0.003], [0.002, 0.0, 0.005], [-0.004, 0.003, 0.0]])
A_TRUE = np.diag(GAIN) + CROSS
SIX = ("+x", "-x", "+y", "-y", "+z", "-z")
ALIAS = {"+x": "xp", "-x": "xn", "+y": "yp", "-y": "yn", "+z": "zp", "-z": "zn"}

#: imucal's published calibration of sample_data/imucal (Ferraris 6-position, gravity 9.81)
IMUCAL_FILES = [IMUCAL / f"{name}.csv" for name in ("xp", "xn", "yp", "yn", "zp", "zn")]
IMUCAL_OFFSET = [-6.018868019671572, -48.287874016760156, -28.96636637224333]
IMUCAL_MATRIX = [
    [4.7941075750e-3, -3.3657395500e-5, 5.2667296510e-5],
    [4.0523316827e-5, 4.8076518588e-3, -1.0969773274e-4],
    [-1.0191238382e-4, 5.2568900273e-5, 4.6548524031e-3],
]

#: the synthetic magnetometer: raw = SOFT_IRON (FIELD u) + HARD_IRON + noise, SOFT_IRON symmetric
FIELD = 50.0
HARD_IRON = np.array([12.0, -25.0, 30.0])
SOFT_IRON = np.array([[1.05, 0.03, -0.02], [0.03, 0.97, 0.04], [-0.02, 0.04, 1.01]])


# -- helpers -------------------------------------------------------------------------------


def unit(v: Sequence[float]) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    out: FloatArray = a / np.linalg.norm(a)
    return out


def acc_values(
    direction: Sequence[float] | str,
    *,
    seed: int,
    n: int = 200,
    noise: float = 0.002,
    tilt_deg: float = 0.0,
    offset: FloatArray = OFFSET,
    gain: FloatArray = GAIN,
    cross: FloatArray | None = CROSS,
) -> FloatArray:
    """(n, 3) raw readings of a static pose whose up direction is a face name or a vector."""
    vec = FACES[direction] if isinstance(direction, str) else tuple(unit(direction))
    rng = np.random.default_rng(seed)
    return pose_samples(
        rng, vec, offset=offset, gain=gain, reference=1.0, noise=noise, n=n, cross=cross, tilt_deg=tilt_deg
    )


def write_csv(path: Path, values: FloatArray, header: Sequence[str] = ("ax", "ay", "az"), fmt: str = "%.7f") -> Path:
    return write(path, values, header=",".join(header), fmt=fmt)


def six_faces(tmp_path: Path, **kwargs: Any) -> dict[str, Path]:
    """The six faces of the synthetic unit, as xp.csv ... zn.csv; face -> path."""
    return {
        face: write_csv(tmp_path / f"{ALIAS[face]}.csv", acc_values(face, seed=k, **kwargs))
        for k, face in enumerate(SIX)
    }


def directional(tmp_path: Path, directions: Sequence[Sequence[float]], prefix: str = "d") -> list[Path]:
    return [write_csv(tmp_path / f"{prefix}{k:02d}.csv", acc_values(d, seed=100 + k)) for k, d in enumerate(directions)]


def label(vector: Sequence[float]) -> str:
    return ",".join(f"{v:g}" for v in vector)


def solved(r: Result, path: Path, code: int = 0) -> dict[str, Any]:
    """The calibration a successful solve wrote to ``path``."""
    assert r.code == code, r.err
    assert "Traceback" not in r.err
    doc: dict[str, Any] = json.loads(path.read_text())
    return doc


def assert_rejected(r: Result, *words: str) -> None:
    """Exit 3, nothing on stdout, one error line that holds every word."""
    assert r.code == 3, r.err
    assert r.out == ""
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1, r.err
    for word in words:
        assert word in errors[0]


#: directions of 14 static poses spread over the whole sphere: the six faces and eight corners
SPHERE_14 = [tuple(FACES[f]) for f in SIX] + [(i, j, k) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]
#: 14 directions on the upper half only (z >= 0.3): no pose anywhere near -z
HALF_14 = [
    (math.cos(t) * math.sqrt(1 - z * z), math.sin(t) * math.sqrt(1 - z * z), z)
    for z, count in ((0.3, 6), (0.7, 5), (0.95, 3))
    for t in np.linspace(0.0, 2 * math.pi, count, endpoint=False)
]


def magnetometer(
    rng: np.random.Generator,
    directions: FloatArray,
    *,
    soft_iron: FloatArray = SOFT_IRON,
    noise: float = 0.3,
) -> FloatArray:
    """Raw magnetometer samples: soft iron times the field along ``directions``, plus hard iron."""
    raw: FloatArray = (FIELD * directions) @ soft_iron.T + HARD_IRON + rng.normal(0.0, noise, (len(directions), 3))
    return raw


def sphere_directions(rng: np.random.Generator, n: int, z_min: float = -1.0) -> FloatArray:
    """``n`` directions uniform on the sphere, or on the cap z >= z_min."""
    u = rng.standard_normal((8 * n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    cap: FloatArray = u[u[:, 2] >= z_min][:n]
    assert len(cap) == n
    return cap


def write_mag(path: Path, values: FloatArray) -> Path:
    return write_csv(path, values, header=("mx", "my", "mz"), fmt="%.4f")


# -- 1. pose labels ----------------------------------------------------------------------


def test_face_labels_name_the_poses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "--poses", f"+x={files['+x']}", f"+y={files['+y']}", f"+z={files['+z']}", "-o", out)
    doc = solved(r, out)
    assert doc["method"] == "three-pose"
    assert [p["pose"] for p in doc["poses"]] == ["+x", "+y", "+z"]
    assert [p["file"] for p in doc["poses"]] == [str(files[f]) for f in ("+x", "+y", "+z")]


def test_alias_labels_are_the_faces(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    out = tmp_path / "cal.json"
    items = [f"{ALIAS[f]}={files[f]}" for f in ("+z", "-x", "+y", "-z", "+x", "-y")]
    doc = solved(run(capsys, "solve", "--poses", *items, "-o", out), out)
    assert doc["method"] == "six-pose"
    assert [p["pose"] for p in doc["poses"]] == list(SIX)  # in the solver's order, whatever the command line's
    assert [p["file"] for p in doc["poses"]] == [str(files[f]) for f in SIX]


@pytest.mark.slow
@pytest.mark.parametrize(
    "layout",
    [
        pytest.param("minus-first", id="minus-label-first-after-poses"),
        pytest.param("short-flag", id="minus-label-first-after-p"),
        pytest.param("equals", id="poses=minus-label"),
        pytest.param("options-after", id="options-follow-the-items"),
    ],
)
def test_labels_starting_with_minus_are_pose_items(
    layout: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = six_faces(tmp_path)
    out = tmp_path / "cal.json"
    minus = [f"{f}={files[f]}" for f in ("-x", "-y", "-z")]
    plus = [f"{f}={files[f]}" for f in ("+x", "+y", "+z")]
    args: list[str | Path]
    if layout == "minus-first":
        args = ["solve", "--poses", *minus, *plus, "-o", out]
    elif layout == "short-flag":
        args = ["solve", "-o", out, "-p", *minus, *plus]
    elif layout == "equals":
        args = ["solve", f"--poses={minus[0]}", *minus[1:], *plus, "-o", out]
    else:
        args = ["solve", "--poses", *plus, *minus, "--reference", "1", "-q", "--max-tilt", "20", "-o", out]
    r = run(capsys, *args)
    doc = solved(r, out)
    assert doc["method"] == "six-pose"
    assert [p["pose"] for p in doc["poses"]] == list(SIX)
    assert [p["file"] for p in doc["poses"]] == [str(files[f]) for f in SIX]
    if layout == "options-after":
        assert r.err == "", "-q after the items was taken as an option"


def test_one_labelled_file_takes_its_label_not_up(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    zn = write_csv(tmp_path / "zn.csv", acc_values("-z", seed=1, cross=None))
    out = tmp_path / "cal.json"
    doc = solved(run(capsys, "solve", "--poses", f"-z={zn}", "--up", "+x", "-o", out), out)
    assert doc["method"] == "one-pose"
    assert doc["poses"][0]["pose"] == "-z"
    mean = np.loadtxt(zn, delimiter=",", skiprows=1).mean(axis=0)
    np.testing.assert_allclose(doc["offset"], mean - np.array([0.0, 0.0, -1.0]), atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("faces", "up", "expected"),
    [
        (["+z"], None, ["+z"]),
        (["-y"], "-y", ["-y"]),
        (["-x"], "xn", ["-x"]),
        (["+x", "+y", "+z"], None, ["+x", "+y", "+z"]),
        (list(SIX), None, list(SIX)),
    ],
    ids=["1-default-up", "1-up", "1-up-alias", "3", "6"],
)
def test_unlabelled_files_get_the_labels_of_their_count(
    faces: list[str], up: str | None, expected: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    paths = [write_csv(tmp_path / f"p{k}.csv", acc_values(f, seed=k, cross=None)) for k, f in enumerate(faces)]
    out = tmp_path / "cal.json"
    args: list[str | Path] = ["solve", "--poses", *paths, "-o", out]
    if up is not None:
        args.append(f"--up={up}")
    doc = solved(run(capsys, *args), out)
    assert [p["pose"] for p in doc["poses"]] == expected
    assert [p["file"] for p in doc["poses"]] == [str(p) for p in paths]
    assert doc["method"] == {1: "one-pose", 3: "three-pose", 6: "six-pose"}[len(faces)]


def test_shuffled_face_labels_give_the_ordered_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    ordered, shuffled = tmp_path / "ordered.json", tmp_path / "shuffled.json"
    a = solved(run(capsys, "solve", "--poses", *(files[f] for f in SIX), "-o", ordered), ordered)
    order = ("-z", "+y", "+x", "-y", "+z", "-x")
    b = solved(run(capsys, "solve", "--poses", *(f"{f}={files[f]}" for f in order), "-o", shuffled), shuffled)
    assert a["method"] == b["method"] == "six-pose"
    np.testing.assert_allclose(b["offset"], a["offset"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b["matrix"], a["matrix"], rtol=1e-12, atol=1e-15)
    # and that calibration is the truth, within the noise
    np.testing.assert_allclose(a["offset"], OFFSET, atol=1e-3)
    np.testing.assert_allclose(np.linalg.inv(a["matrix"]), A_TRUE, atol=1e-3)


def test_swapped_face_labels_change_the_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The labels are used, not just counted: +x and -x swapped is a different (upside-down) solution."""
    files = six_faces(tmp_path)
    out = tmp_path / "cal.json"
    swapped = {"+x": files["-x"], "-x": files["+x"]}
    items = [f"{f}={swapped.get(f, files[f])}" for f in SIX]
    r = run(capsys, "solve", "--poses", *items, "--no-checks", "-o", out)
    doc = solved(r, out)
    assert doc["matrix"][0][0] < 0


def test_direction_labels_for_least_squares(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    extra = [(0.707, 0.0, 0.707), (-0.6, 0.0, 0.8), (0.0, -0.6, -0.8)]
    angled = directional(tmp_path, extra, prefix="angled")
    out = tmp_path / "cal.json"
    # the first item is a direction starting with '-', right after --poses
    items = [f"{label(extra[1])}={angled[1]}", f"{label(extra[0])}={angled[0]}", f"{label(extra[2])}={angled[2]}"]
    items += [f"{f}={files[f]}" for f in SIX]
    doc = solved(run(capsys, "solve", "--poses", *items, "-o", out), out)
    assert doc["method"] == "least-squares"
    assert len(doc["poses"]) == 9
    recorded = {p["file"]: p["pose"] for p in doc["poses"]}
    for vec, path in zip(extra, angled, strict=True):
        np.testing.assert_allclose([float(v) for v in recorded[str(path)].split(",")], unit(vec), atol=1e-6)
    assert recorded[str(files["-y"])] == "-y"
    np.testing.assert_allclose(doc["offset"], OFFSET, atol=1e-3)
    np.testing.assert_allclose(np.linalg.inv(doc["matrix"]), A_TRUE, atol=1e-3)
    assert doc["residuals"]["count"] == 9


@pytest.mark.parametrize("bad", ["1,2", "1,2,x", "0,0,0", "1,,2"])
def test_bad_direction_label_is_a_usage_error(bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    out = precious(tmp_path / "cal.json")
    items = [f"{f}={files[f]}" for f in SIX[:5]] + [f"{bad}={files['-z']}"]
    r = run(capsys, "solve", "--poses", *items, "-o", out)
    assert_usage_error(r, f"'{bad}'")
    assert_untouched(out)


def test_mixing_labelled_and_unlabelled_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = six_faces(tmp_path)
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", f"+x={files['+x']}", files["+y"], f"+z={files['+z']}", "-o", out)
    assert_usage_error(r, "label every pose file or none")
    assert_untouched(out)


# -- 2. --method and auto ------------------------------------------------------------------


def _args_one(tmp_path: Path) -> list[str | Path]:
    return ["--poses", write_csv(tmp_path / "z.csv", acc_values("+z", seed=1, cross=None))]


def _args_three(tmp_path: Path) -> list[str | Path]:
    files = six_faces(tmp_path, cross=None)
    return ["--poses", files["+x"], files["+y"], files["+z"]]


def _args_six(tmp_path: Path) -> list[str | Path]:
    return ["--poses", *six_faces(tmp_path).values()]


def _args_diagonal(tmp_path: Path) -> list[str | Path]:
    return [*_args_six(tmp_path), "--method", "six-pose-diagonal"]


def _args_least_squares(tmp_path: Path) -> list[str | Path]:
    files = six_faces(tmp_path)
    extra = [(1.0, 1.0, 0.0), (0.0, 1.0, -1.0)]
    angled = directional(tmp_path, extra)
    return [
        "--poses",
        *(f"{f}={p}" for f, p in files.items()),
        *(f"{label(d)}={p}" for d, p in zip(extra, angled, strict=True)),
    ]


def _args_sphere(tmp_path: Path) -> list[str | Path]:
    return ["--poses", *directional(tmp_path, SPHERE_14)]


def _args_tilt(tmp_path: Path) -> list[str | Path]:
    return [*_args_one(tmp_path), "--tilt-compensate"]


#: solve with min/max on a magnetometer capture in a 50-unit field; the capture follows
MINMAX = ("solve", "--sensor", "magnetometer", "--method", "minmax", "--reference", "50", "--poses")


def _args_mag(tmp_path: Path) -> list[str | Path]:
    rng = np.random.default_rng(7)
    path = write_mag(tmp_path / "turn.csv", magnetometer(rng, sphere_directions(rng, 3000)))
    return ["--sensor", "magnetometer", "--reference", str(FIELD), "--poses", path]


def _args_minmax(tmp_path: Path) -> list[str | Path]:
    return [*_args_mag(tmp_path), "--method", "minmax"]


def _args_gyro(tmp_path: Path) -> list[str | Path]:
    return ["--sensor", "gyroscope", "--poses", IMUCAL / "xp.csv"]


METHOD_CASES: dict[str, Callable[[Path], list[str | Path]]] = {
    "one-pose": _args_one,
    "three-pose": _args_three,
    "six-pose": _args_six,
    "six-pose-diagonal": _args_diagonal,
    "least-squares": _args_least_squares,
    "sphere": _args_sphere,
    "one-pose-tilt": _args_tilt,
    "minmax": _args_minmax,
    "ellipsoid": _args_mag,
    "gyro-bias": _args_gyro,
}


@pytest.mark.slow
@pytest.mark.parametrize("method", list(METHOD_CASES))
def test_method_field(method: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", *METHOD_CASES[method](tmp_path), "-o", out)
    doc = solved(r, out)
    assert doc["method"] == method
    assert f"{method} calibration" in r.err  # people's summary names it too
    if method == "six-pose-diagonal":
        m = np.array(doc["matrix"])
        assert (m == np.diag(np.diag(m))).all()
        np.testing.assert_allclose(doc["gain"], GAIN, atol=1e-3)  # the cross terms leave the gains alone
    if method == "sphere":
        np.testing.assert_allclose(doc["offset"], OFFSET, atol=2e-3)
        assert 0.0 <= doc["coverage"] <= 1.0


@pytest.mark.slow
@pytest.mark.parametrize("method", ["six-pose", "sphere"])
def test_explicit_method_gives_the_auto_result(method: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = METHOD_CASES[method](tmp_path)
    auto, explicit = tmp_path / "auto.json", tmp_path / "explicit.json"
    a = solved(run(capsys, "solve", *args, "-o", auto), auto)
    b = solved(run(capsys, "solve", *args, "--method", method, "-o", explicit), explicit)
    assert a["method"] == b["method"] == method
    assert a["offset"] == b["offset"]
    assert a["matrix"] == b["matrix"]


def _few_six(tmp_path: Path) -> list[str | Path]:
    files = six_faces(tmp_path)
    return ["--method", "six-pose", "--poses", files["+x"], files["+y"], files["+z"]]


def _few_three(tmp_path: Path) -> list[str | Path]:
    return ["--method", "three-pose", *_args_one(tmp_path)]


def _few_least_squares(tmp_path: Path) -> list[str | Path]:
    files = six_faces(tmp_path)
    return ["--method", "least-squares", "--poses", *(f"{f}={files[f]}" for f in SIX[:3])]


def _few_sphere(tmp_path: Path) -> list[str | Path]:
    return ["--method", "sphere", "--poses", *directional(tmp_path, SPHERE_14[:11])]


def _few_one(tmp_path: Path) -> list[str | Path]:
    return ["--method", "one-pose", *_args_three(tmp_path)[:3]]


def _few_auto(tmp_path: Path) -> list[str | Path]:
    files = six_faces(tmp_path)
    return ["--poses", files["+x"], files["+y"]]


@pytest.mark.parametrize(
    ("case", "words"),
    [
        (_few_six, ["six-pose", "6"]),
        (_few_three, ["three-pose", "3"]),
        (_few_least_squares, ["least-squares", "4", "got 3"]),
        (_few_sphere, ["sphere", "12", "11"]),
        (_few_one, ["one-pose", "2"]),
        (_few_auto, ["no face on the z axis", "add +z or -z"]),
    ],
    ids=["six-pose", "three-pose", "least-squares", "sphere", "one-pose", "auto"],
)
def test_too_few_files_for_a_method_is_a_usage_error(
    case: Callable[[Path], list[str | Path]], words: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", *case(tmp_path), "-o", out)
    assert_usage_error(r, *words)
    assert_untouched(out)


@pytest.mark.parametrize(
    "directions",
    [
        pytest.param([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (1, 1, 0)], id="one-plane-through-origin"),
        pytest.param([(1, 0, 1), (-1, 0, 1), (0, 1, 1), (0, -1, 1), (1, 1, 1.4142135623730951)], id="one-cone"),
    ],
)
def test_least_squares_on_undetermined_directions_is_rejected_even_without_checks(
    directions: list[tuple[float, float, float]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """[u 1] of rank 3: in one plane (u_z = 0), or on one cone (u_z the same for all): the
    directions span 3-D, but not with the offset."""
    paths = directional(tmp_path, directions)
    u = np.array([unit(d) for d in directions])
    assert np.linalg.matrix_rank(np.column_stack([u, np.ones(len(u))]), tol=1e-9) == 3
    out = precious(tmp_path / "cal.json")
    items = [f"{label(d)}={p}" for d, p in zip(directions, paths, strict=True)]
    r = run(capsys, "solve", "--poses", *items, "--method", "least-squares", "--no-checks", "-o", out)
    assert_rejected(r, "do not determine", "rank 3")
    assert_untouched(out)


def test_sphere_on_half_sphere_is_rejected_naming_the_missing_face(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *directional(tmp_path, HALF_14), "--no-checks", "-o", out)
    assert_rejected(r, "-z")
    assert_untouched(out)


def test_ellipsoid_on_half_sphere_is_rejected_naming_the_missing_face(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(3)
    path = write_mag(tmp_path / "half.csv", magnetometer(rng, sphere_directions(rng, 3000, z_min=0.0)))
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--sensor", "magnetometer", "--reference", "50", "--poses", path, "--no-checks", "-o", out)
    assert_rejected(r, "-z")
    assert_untouched(out)


def test_six_pose_with_one_capture_for_both_x_faces_is_rejected_even_without_checks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """+x and -x the same capture: the x column of A is 0, so M does not exist."""
    files = six_faces(tmp_path)
    items = [f"{f}={files['+x'] if f == '-x' else files[f]}" for f in SIX]
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", "--poses", *items, "--no-checks", "-o", out)
    assert_rejected(r, "do not determine")
    assert_untouched(out)


def _undetermined_least_squares(tmp_path: Path) -> list[str | Path]:
    directions = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (1, 1, 0)]
    return ["--poses", *(f"{label(d)}={p}" for d, p in zip(directions, directional(tmp_path, directions), strict=True))]


def _half_sphere_ellipsoid(tmp_path: Path) -> list[str | Path]:
    rng = np.random.default_rng(4)
    path = write_mag(tmp_path / "half.csv", magnetometer(rng, sphere_directions(rng, 3000, z_min=0.0)))
    return ["--sensor", "magnetometer", "--reference", "50", "--poses", path]


@pytest.mark.parametrize(
    ("case", "code", "word"),
    [(_undetermined_least_squares, "poses.undetermined", "rank 3"), (_half_sphere_ellipsoid, "poses.coverage", "-z")],
    ids=["least-squares", "ellipsoid"],
)
def test_solver_rejection_prints_the_json_head(
    case: Callable[[Path], list[str | Path]], code: str, word: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", *case(tmp_path), "--no-checks", "--json", "-q", "-o", out)
    assert r.code == 3, r.err
    head = json.loads(r.out)
    assert head["status"] == "rejected"
    assert head["exit_status"] == 3
    assert head["file"] is None
    assert head["verdict"] is None
    assert [x["code"] for x in head["rejections"]] == [code]
    assert word in head["rejections"][0]["message"]
    assert [ln for ln in r.err.splitlines() if ln.startswith("error:")] == [
        f"error: {head['rejections'][0]['message']}"
    ]
    assert_untouched(out)


def test_gains_with_a_zero_reference_are_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = precious(tmp_path / "gyr.json")
    r = run(capsys, "solve", "--sensor", "gyroscope", "--method", "six-pose", "--poses", *IMUCAL_FILES, "-o", out)
    assert_usage_error(r, "--reference")
    assert "Warning" not in r.err
    assert_untouched(out)


# -- 3. six-pose on imucal's sample set: the known answer ------------------------------------


def test_six_pose_on_imucal_equals_its_published_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    doc = solved(run(capsys, "solve", "--poses", *IMUCAL_FILES, "--reference", "9.81", "-o", out), out)
    assert doc["method"] == "six-pose"
    assert doc["columns"] == ["acc_x", "acc_y", "acc_z"]
    np.testing.assert_allclose(doc["offset"], IMUCAL_OFFSET, rtol=1e-6)
    np.testing.assert_allclose(doc["matrix"], IMUCAL_MATRIX, rtol=1e-6)
    # the new fields
    cross = np.array(doc["uncertainty"]["cross_axis"])
    assert cross.shape == (3, 3)
    assert (np.diag(cross) == 0).all()
    assert (cross[~np.eye(3, dtype=bool)] > 0).all()
    tilt_cross = np.array(doc["tilt_sensitivity"]["cross_axis"])
    assert tilt_cross.shape == (3, 3)
    assert (tilt_cross[~np.eye(3, dtype=bool)] > 0).all()
    cov = doc["covariance"]
    assert len(cov["parameters"]) == 12
    assert len(set(cov["parameters"])) == 12
    matrix = np.array(cov["matrix"])
    assert matrix.shape == (12, 12)
    np.testing.assert_allclose(matrix, matrix.T, rtol=1e-9, atol=0)
    assert np.linalg.eigvalsh(matrix).min() >= -1e-9 * np.abs(matrix).max()
    # the diagonal agrees with the 1-sigma offsets it is reported with
    np.testing.assert_allclose(np.sqrt(np.diag(matrix)[:3]), doc["uncertainty"]["offset"], rtol=1e-6)
    res = doc["residuals"]
    assert res["count"] == 6
    assert 0 < res["rms"] <= res["max"] < 0.01 * 9.81


@pytest.mark.slow
def test_show_and_check_accept_the_six_pose_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.json"
    solved(run(capsys, "solve", "--poses", *IMUCAL_FILES, "--reference", "9.81", "-q", "-o", out), out)
    shown = run(capsys, "show", out)
    assert shown.code == 0, shown.err
    assert "six-pose" in shown.out
    assert run(capsys, "show", out, "--json").code == 0
    passing = run(capsys, "check", out, "--max-offset", "100", "--json")
    assert passing.code == 0, passing.err
    assert json.loads(passing.out)["status"] == "pass"
    failing = run(capsys, "check", out, "--max-offset", "10", "--json")  # |offset y| is 48
    assert failing.code == 1, failing.err
    assert json.loads(failing.out)["status"] == "fail"


# -- 4. magnetometer -------------------------------------------------------------------------


def test_ellipsoid_recovers_the_hard_iron(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(11)
    raw = magnetometer(rng, sphere_directions(rng, 3000))
    path = write_mag(tmp_path / "turn.csv", raw)
    out = tmp_path / "mag.json"
    r = run(capsys, "solve", "--sensor", "magnetometer", "--reference", "50", "--poses", path, "-o", out)
    doc = solved(r, out)  # exit 0: a rotation capture is not a pose that "moved"
    assert doc["method"] == "ellipsoid"
    assert doc["sensor"] == "magnetometer"
    assert doc["columns"] == ["mx", "my", "mz"]
    np.testing.assert_allclose(doc["offset"], HARD_IRON, atol=0.1)
    np.testing.assert_allclose(doc["matrix"], np.linalg.inv(SOFT_IRON), atol=2e-3)
    assert 0.9 <= doc["coverage"] <= 1.0
    corrected = (raw - np.array(doc["offset"])) @ np.array(doc["matrix"]).T
    assert abs(np.linalg.norm(corrected, axis=1).mean() - FIELD) < 0.05


def test_magnetometer_limits_judge_the_fit_not_the_turning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A turning capture's spread is the turning and its mean is no pose: the noise limit does
    not apply (a note says so) and the residual limit judges the fit's largest residual over the
    samples (about 4 noise sigmas here), not the norm of the capture's mean."""
    rng = np.random.default_rng(13)
    path = write_mag(tmp_path / "turn.csv", magnetometer(rng, sphere_directions(rng, 3000)))
    limits = tmp_path / "limits.yaml"
    out = tmp_path / "mag.json"
    base: list[str | Path] = ["solve", "--sensor", "magnetometer", "--reference", "50", "-p", path, "-o", out]
    limits.write_text("noise: 1\nresidual: 2\n")
    r = run(capsys, *base, "--limits", limits)
    assert r.code == 0, r.err
    doc = json.loads(out.read_text())
    assert doc["verdict"] == {"pass": True, "failures": [], "limits": {"residual": 2.0}}
    assert 0.8 < doc["residuals"]["max"] < 2.0
    assert (
        "note: the ellipsoid solver fits a capture turned through many orientations (its spread is the turning), "
        "so the noise limit does not apply"
    ) in r.err.splitlines()
    limits.write_text("residual: 0.5\n")
    r = run(capsys, *base, "--limits", limits)
    assert r.code == 1, r.err
    [failure] = json.loads(out.read_text())["verdict"]["failures"]
    assert (failure["code"], failure["bound"]) == ("limit.residual", 0.5)
    assert failure["value"] == doc["residuals"]["max"]
    r = run(capsys, "check", out, "--limits", limits)  # check judges it the same way
    assert r.code == 1, r.err
    assert "limit.residual: the fit's largest residual over the samples is" in r.err
    stripped = json.loads(out.read_text())
    del stripped["residuals"]
    out.write_text(json.dumps(stripped))
    r = run(capsys, "check", out, "--limits", limits)  # nothing to judge the residual limit by
    assert r.code == 2
    assert r.err.splitlines()[0] == f"error: {out}: has no fit residuals to judge the residual limit by"


def test_minmax_recovers_the_hard_iron_roughly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(12)
    path = write_mag(tmp_path / "turn.csv", magnetometer(rng, sphere_directions(rng, 3000)))
    out = tmp_path / "mag.json"
    args: list[str | Path] = [*MINMAX, path]
    doc = solved(run(capsys, *args, "-o", out), out)
    assert doc["method"] == "minmax"
    np.testing.assert_allclose(doc["offset"], HARD_IRON, atol=1.0)
    assert doc["matrix"] == np.eye(3).tolist()
    assert 0.0 <= doc["coverage"] <= 1.0


def test_minmax_in_one_plane(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Turned about z: the field's horizontal part goes round the xy plane, its vertical part stays."""
    rng = np.random.default_rng(13)
    heading = np.linspace(0.0, 4 * math.pi, 2000)
    dip = math.radians(60.0)
    directions = np.column_stack(
        [math.cos(dip) * np.cos(heading), math.cos(dip) * np.sin(heading), np.full(len(heading), math.sin(dip))]
    )
    raw = magnetometer(rng, directions, soft_iron=np.diag([1.04, 0.96, 1.0]), noise=0.1)
    path = write_mag(tmp_path / "flat.csv", raw)
    out = tmp_path / "mag.json"
    args: list[str | Path] = [
        "solve",
        "--sensor",
        "magnetometer",
        "--method",
        "minmax",
        "--plane",
        "xy",
        "--poses",
        path,
    ]
    doc = solved(run(capsys, *args, "--reference", "50", "-o", out), out)
    assert doc["method"] == "minmax"
    np.testing.assert_allclose(doc["offset"][:2], HARD_IRON[:2], atol=0.3)
    assert doc["offset"][2] == 0.0  # not determined in 2-D
    assert 0.0 <= doc["coverage"] <= 1.0
    # the same capture as a 3-D min/max is refused: the z axis was never turned
    rejected = precious(tmp_path / "again.json")
    r = run(capsys, "solve", "--sensor", "magnetometer", "--method", "minmax", "--poses", path, "-o", rejected)
    assert r.code == 3, r.err
    assert_untouched(rejected)
    # ... and so is the wrong plane: z's noise alone would go round the xz "circle"
    for plane in ("xz", "yz"):
        r = run(capsys, *args[:6], plane, "--poses", path, "--reference", "50", "-o", rejected, "--json")
        assert r.code == 3, r.err
        [rejection] = json.loads(r.out)["rejections"]
        assert rejection["code"] == "poses.coverage"
        assert rejection["message"].startswith(f"the samples did not turn in the {plane} plane: z spans ")
        assert rejection["message"].endswith("it looks like the xy plane")
        assert_untouched(rejected)


@pytest.mark.parametrize("spread", ["-1", "nan", "inf"])
def test_bias_spread_must_be_a_finite_non_negative_number(
    spread: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", *_args_one(tmp_path), "--tilt-compensate", "--bias-spread", spread, "-o", out)
    assert r.code == 2
    assert f"--bias-spread must be a number of 0 or more (the bias's 1-sigma spread), got {float(spread)}" in r.err
    assert_untouched(out)


def test_minmax_half_sphere_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """magcal's failure: min/max of the upper half puts the z offset half a field (25) off."""
    rng = np.random.default_rng(14)
    path = write_mag(tmp_path / "half.csv", magnetometer(rng, sphere_directions(rng, 3000, z_min=0.0)))
    out = precious(tmp_path / "mag.json")
    args: list[str | Path] = [*MINMAX, path]
    r = run(capsys, *args, "-o", out)
    assert_rejected(r, "-z")
    assert_untouched(out)


def test_minmax_on_a_little_more_than_half_sphere_is_rejected(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(15)
    path = write_mag(tmp_path / "cap.csv", magnetometer(rng, sphere_directions(rng, 3000, z_min=-0.1)))
    out = tmp_path / "mag.json"
    args: list[str | Path] = [*MINMAX, path]
    r = run(capsys, *args, "-o", out)
    if r.code == 0:  # accepted: then the offset must be right
        doc = json.loads(out.read_text())
        np.testing.assert_allclose(doc["offset"], HARD_IRON, atol=2.0)
    else:
        assert_rejected(r, "-z")
        assert not out.exists()


# -- 5. gyroscope ------------------------------------------------------------------------------


def test_gyro_bias_is_the_column_means(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "gyr.json"
    doc = solved(run(capsys, "solve", "--sensor", "gyroscope", "--poses", IMUCAL / "xp.csv", "-o", out), out)
    assert doc["method"] == "gyro-bias"
    assert doc["sensor"] == "gyroscope"
    assert doc["reference"] == 0
    assert doc["columns"] == ["gyr_x", "gyr_y", "gyr_z"]
    gyr = np.genfromtxt(IMUCAL / "xp.csv", delimiter=",", skip_header=1, usecols=(5, 6, 7))
    np.testing.assert_allclose(doc["offset"], gyr.mean(axis=0), rtol=1e-12, atol=1e-12)
    assert doc["matrix"] == np.eye(3).tolist()
    np.testing.assert_allclose(doc["uncertainty"]["offset"], gyr.std(axis=0, ddof=1) / math.sqrt(len(gyr)), rtol=1e-6)


def test_gyro_bias_of_several_captures_weighs_by_samples(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "gyr.json"
    files = [IMUCAL / "xp.csv", IMUCAL / "zn.csv"]
    doc = solved(run(capsys, "solve", "--sensor", "gyroscope", "--poses", *files, "-o", out), out)
    assert doc["method"] == "gyro-bias"
    gyr = np.concatenate([np.genfromtxt(f, delimiter=",", skip_header=1, usecols=(5, 6, 7)) for f in files])
    np.testing.assert_allclose(doc["offset"], gyr.mean(axis=0), rtol=1e-12, atol=1e-12)


# -- 6. apply with several calibrations ---------------------------------------------------------


@pytest.fixture
def two_cals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, Path]:
    """An accelerometer six-pose calibration (full M) and a gyroscope bias, from synthetic captures."""
    acc, gyr = tmp_path / "acc.json", tmp_path / "gyr.json"
    solved(run(capsys, "solve", "--poses", *six_faces(tmp_path).values(), "-q", "-o", acc), acc)
    rng = np.random.default_rng(21)
    still = np.array([0.8, -1.3, 0.45]) + 0.05 * rng.standard_normal((300, 3))
    gyr_capture = write_csv(tmp_path / "still.csv", still, header=("gyr_x", "gyr_y", "gyr_z"), fmt="%.5f")
    solved(run(capsys, "solve", "--sensor", "gyroscope", "--poses", gyr_capture, "-q", "-o", gyr), gyr)
    return acc, gyr


def write_mixed_capture(path: Path, *, gyro: bool = True) -> Path:
    """t, the accelerometer, the gyroscope (optional) and a temperature, each with its own text."""
    rng = np.random.default_rng(22)
    n = 50
    lines = ["t,ax,ay,az" + (",gyr_x,gyr_y,gyr_z" if gyro else "") + ",temp"]
    for k in range(n):
        acc = acc_values((1, 2, 3), seed=k, n=1)[0]
        cells = [f"{k / 100:.2f}", *(f"{v:.6f}" for v in acc)]
        if gyro:
            cells += [f"{v:.4f}" for v in np.array([0.8, -1.3, 0.45]) + 5 * rng.standard_normal(3)]
        cells.append(f"{25 + 0.01 * k:.3f}")
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_apply_two_calibrations_in_one_pass(
    two_cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, gyr = two_cals
    capture = write_mixed_capture(tmp_path / "capture.csv")
    out = tmp_path / "corrected.csv"
    r = run(capsys, "apply", "--cal", acc, "--cal", gyr, capture, "-o", out)
    assert r.code == 0, r.err
    assert r.out == ""
    before = capture.read_text().splitlines()
    after = out.read_text().splitlines()
    assert after[0] == before[0]
    assert len(after) == len(before)
    raw = np.loadtxt(capture, delimiter=",", skiprows=1)
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    for path, cols in ((acc, slice(1, 4)), (gyr, slice(4, 7))):
        doc = json.loads(path.read_text())
        expected = (raw[:, cols] - np.array(doc["offset"])) @ np.array(doc["matrix"]).T
        np.testing.assert_allclose(got[:, cols], expected, rtol=1e-12, atol=1e-12)
        assert not np.allclose(got[:, cols], raw[:, cols], atol=1e-3)  # each triplet was really corrected
    for b, a in zip(before[1:], after[1:], strict=True):  # t and temp: the same text, byte for byte
        assert a.split(",")[0] == b.split(",")[0]
        assert a.split(",")[-1] == b.split(",")[-1]


def test_apply_two_calibrations_in_either_order(
    two_cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, gyr = two_cals
    capture = write_mixed_capture(tmp_path / "capture.csv")
    a = run(capsys, "apply", "--cal", acc, "--cal", gyr, capture)
    b = run(capsys, "apply", "-c", gyr, "-c", acc, capture)
    assert a.code == b.code == 0, a.err + b.err
    assert a.out == b.out
    assert a.out.count("\n") == 51


def test_apply_one_column_claimed_twice(
    two_cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, gyr = two_cals
    twin = shutil.copy(acc, tmp_path / "acc-again.json")
    capture = write_mixed_capture(tmp_path / "capture.csv")
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", acc, "--cal", gyr, "--cal", twin, capture, "-o", out)
    assert_usage_error(r, str(acc), str(twin), "ax")
    assert_untouched(out)


def test_apply_columns_with_two_calibrations(
    two_cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, gyr = two_cals
    capture = write_mixed_capture(tmp_path / "capture.csv")
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", acc, "--cal", gyr, "--columns", "ax,ay,az", capture, "-o", out)
    assert_usage_error(r, "--columns")
    assert_untouched(out)


def test_apply_second_calibration_without_its_columns(
    two_cals: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    acc, gyr = two_cals
    capture = write_mixed_capture(tmp_path / "capture.csv", gyro=False)
    out = precious(tmp_path / "corrected.csv")
    r = run(capsys, "apply", "--cal", acc, "--cal", gyr, capture, "-o", out)
    assert_usage_error(r, str(gyr), "gyr_x")
    assert_untouched(out)


# -- 7. verify --------------------------------------------------------------------------------------


@pytest.fixture
def acc_cal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    cal = tmp_path / "acc.json"
    solved(run(capsys, "solve", "--poses", *six_faces(tmp_path).values(), "-q", "-o", cal), cal)
    return cal


CHECK_DIRECTIONS = [(0.6, 0.8, 0.0), (0.0, 0.6, -0.8), (1.0, -1.0, 1.0)]


def checks(tmp_path: Path, **kwargs: Any) -> list[Path]:
    return [
        write_csv(tmp_path / f"check{k}.csv", acc_values(d, seed=200 + k, **kwargs))
        for k, d in enumerate(CHECK_DIRECTIONS)
    ]


def test_verify_json_per_capture_figures(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    captures = checks(tmp_path)
    r = run(capsys, "verify", "--cal", acc_cal, *captures, "--json", "-q")
    assert r.code == 0, r.err
    assert r.err == ""
    doc = json.loads(r.out)
    assert doc["status"] == "pass"
    assert doc["reference"] == 1.0
    assert [row["file"] for row in doc["captures"]] == [str(c) for c in captures]
    for row, path in zip(doc["captures"], captures, strict=True):
        mean = np.loadtxt(path, delimiter=",", skiprows=1).mean(axis=0)
        assert row["norm_before"] == pytest.approx(np.linalg.norm(mean), rel=1e-9)
        assert abs(row["norm_before"] - 1.0) > 0.005  # the raw data is off ...
        assert abs(row["error_after"]) < 1.5e-3  # ... and the calibration fixes it
        assert row["error_after"] == pytest.approx(row["norm_after"] - 1.0, abs=1e-12)
    errors = np.array([row["error_after"] for row in doc["captures"]])
    assert doc["max_error"] == pytest.approx(np.abs(errors).max(), rel=1e-12)
    assert doc["rms_error"] == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-12)
    # the raw data is in g already (gains near 1): the error before is given too, and overall
    raw = np.array([row["error_before"] for row in doc["captures"]])
    np.testing.assert_allclose(raw, [row["norm_before"] - 1.0 for row in doc["captures"]], rtol=0, atol=1e-12)
    assert doc["rms_error_before"] == pytest.approx(np.sqrt(np.mean(raw**2)), rel=1e-12)
    assert doc["max_error_before"] > 10 * doc["max_error"]
    assert doc["notes"] == []


def test_verify_on_a_fitted_capture_says_it_is_a_self_check(
    acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fitted = json.loads(acc_cal.read_text())["poses"][0]["file"]
    r = run(capsys, "verify", "--cal", acc_cal, fitted, *checks(tmp_path), "--json")
    assert r.code == 0, r.err
    [note] = json.loads(r.out)["notes"]
    assert note.startswith(f"{fitted}: the calibration was fitted on this capture ({fitted}): ")
    assert f"note: {note}" in r.err.splitlines()


def test_verify_max_norm_error(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    good = checks(tmp_path)
    within = run(capsys, "verify", "--cal", acc_cal, *good, "--max-norm-error", "0.005", "--json")
    assert within.code == 0, within.err
    assert json.loads(within.out)["failed"] == []
    other_unit = write_csv(tmp_path / "other.csv", acc_values((0, 0, 1), seed=300, gain=GAIN * 1.05))
    r = run(capsys, "verify", "--cal", acc_cal, *good, other_unit, "--max-norm-error", "0.005", "--json")
    assert r.code == 1, r.err
    doc = json.loads(r.out)
    assert doc["status"] == "fail"
    assert doc["failed"] == [str(other_unit)]
    assert doc["captures"][-1]["error_after"] == pytest.approx(0.05, abs=0.01)
    assert "error:" not in r.err


def test_verify_moving_capture_is_rejected(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    moving = write_csv(tmp_path / "moving.csv", acc_values((0, 0, 1), seed=301, noise=0.2))
    r = run(capsys, "verify", "--cal", acc_cal, checks(tmp_path)[0], moving, "-q")
    assert_rejected(r, "moving.csv", "not a static capture")
    assert run(capsys, "verify", "--cal", acc_cal, moving, "--max-noise", "0", "-q").code == 0  # the check is off


def test_verify_reference_override(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    captures = checks(tmp_path)
    r = run(capsys, "verify", "--cal", acc_cal, *captures, "--reference", "1.02", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["reference"] == 1.02
    for row in doc["captures"]:
        assert row["error_after"] == pytest.approx(-0.02, abs=2e-3)
    judged = run(capsys, "verify", "--cal", acc_cal, *captures, "--reference", "1.02", "--max-norm-error", "0.01")
    assert judged.code == 1, judged.err


def test_verify_in_other_units_than_the_calibration_is_a_units_mistake(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """imucal's calibration (counts in, m/s^2 out) on a capture in g read 0.000485 against 9.81
    (-100 %), 'not judged', exit 0; a --reference off by 25 % or more is the same mistake."""
    cal = tmp_path / "counts.json"
    assert run(capsys, "solve", "-q", "-p", *IMUCAL_FILES, "--reference", "9.81", "-o", cal).code == 0
    capture = checks(tmp_path)[0]  # readings in g
    r = run(capsys, "verify", "--cal", cal, capture)
    assert r.code == 2, r.err
    assert r.out == ""
    error, hint = r.err.splitlines()
    assert error.startswith(f"error: {capture}: corrected magnitude ")
    assert error.endswith("from the reference 9.81: a units mistake, or another sensor's calibration?")
    assert hint.startswith("hint: the calibration's poses read about 20")
    assert run(capsys, "verify", "--cal", cal, IMUCAL_FILES[0]).code == 0  # its own units: fine
    g_cal = tmp_path / "g.json"
    assert run(capsys, "solve", "-q", "-p", *six_faces(tmp_path).values(), "-o", g_cal).code == 0
    assert run(capsys, "verify", "--cal", g_cal, capture, "--reference", "1.4").code == 2
    zero = run(capsys, "verify", "--cal", g_cal, capture, "--reference", "0")  # it judged errors of +1, exit 0
    assert (zero.code, zero.err.splitlines()[0]) == (2, "error: --reference must be a positive number, got 0")


def test_verify_missing_capture(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nowhere.csv"
    r = run(capsys, "verify", "--cal", acc_cal, checks(tmp_path)[0], missing)
    assert_usage_error(r, str(missing))


def test_verify_missing_calibration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nocal.json"
    r = run(capsys, "verify", "--cal", missing, checks(tmp_path)[0])
    assert_usage_error(r, str(missing))


def test_verify_table_goes_to_stderr(acc_cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    captures = checks(tmp_path)
    r = run(capsys, "verify", "--cal", acc_cal, *captures)
    assert r.code == 0, r.err
    assert r.out == ""
    for c in captures:
        assert c.name in r.err
    assert "norm error after calibration" in r.err
    assert "six-pose" in r.err
    assert "error:" not in r.err


# -- 8. tilt compensation -------------------------------------------------------------------------


def test_tilt_compensate_removes_the_fixture_tilt_from_the_up_offset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = np.array([0.003, -0.002, 0.047])  # small horizontal offsets: the attitude assumes them zero
    values = acc_values("+z", seed=31, n=1000, tilt_deg=5.0, offset=truth, gain=np.ones(3), cross=None)
    pose = write_csv(tmp_path / "tilted.csv", values)
    plain_out, tilt_out = tmp_path / "plain.json", tmp_path / "tilt.json"
    plain = solved(run(capsys, "solve", "--poses", pose, "-o", plain_out), plain_out)
    tilted = solved(run(capsys, "solve", "--poses", pose, "--tilt-compensate", "-o", tilt_out), tilt_out)
    assert plain["method"] == "one-pose"
    assert tilted["method"] == "one-pose-tilt"
    cosine_error = 1.0 - math.cos(math.radians(5.0))  # 3.8e-3
    plain_error = plain["offset"][2] - truth[2]
    tilt_error = tilted["offset"][2] - truth[2]
    assert plain_error == pytest.approx(-cosine_error, abs=3e-4)
    assert abs(tilt_error) < 0.15 * cosine_error
    assert tilted["matrix"] == np.eye(3).tolist()
    np.testing.assert_allclose(tilted["offset"][:2], plain["offset"][:2], atol=1e-12)  # the horizontal ones: 1-pose


def test_tilt_compensate_with_several_poses_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = precious(tmp_path / "cal.json")
    r = run(capsys, "solve", *_args_three(tmp_path), "--tilt-compensate", "-o", out)
    assert_usage_error(r, "one-pose-tilt")
    assert_untouched(out)


# -- units mistakes: gains judged against a nominal gain far off it, every axis alike --------------------


def assert_units_mistake(r: Result, *words: str) -> None:
    """Exit 2 (a misconfigured station, not a bad unit), one error line and a hint naming the fix."""
    assert r.code == 2, r.err
    assert r.out == ""
    assert "a units mistake?" in r.err
    for word in words:
        assert word in r.err


def test_gains_judged_in_the_wrong_units_are_exit_2_not_a_failing_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Data in g, --reference 9.81 and a gain limit: every gain reads 0.102, which exit 1 would
    report as a unit outside its limits; it is the station's setting, so exit 2 says which."""
    files = six_faces(tmp_path)
    out = precious(tmp_path / "cal.json")
    for solver in ("six-pose", "six-pose-diagonal", "six-pose-magnitude", "auto"):
        r = run(capsys, "solve", "-p", *files.values(), "-m", solver, "--reference", "9.81", "--max-gain-error", "0.02",
                "-o", out)  # fmt: skip
        assert_units_mistake(r, "from the nominal gain 1", "hint: the data looks like g: run with --reference 1")
        assert_untouched(out)
    r = run(capsys, "solve", "-p", *[files[f] for f in ("+x", "+y", "+z")], "--nominal-gain", "9.81", "-o", out)
    assert_units_mistake(r, "from the nominal gain 9.81", "check --nominal-gain")


def test_counts_judged_against_a_nominal_of_1_name_the_nominal_gain(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """imucal's counts at --reference 9.81 with a limits file made for g: the hint gives both ways out."""
    out = tmp_path / "cal.json"
    r = run(capsys, "solve", "-p", *IMUCAL_FILES, "--reference", "9.81", "--limits", SAMPLE / "limits.yaml", "-o", out)
    assert_units_mistake(r, "--nominal-gain 210", "--reference 2048")
    assert not out.exists()
    # unjudged gains are the counts-to-m/s^2 scale a gain solver is for; judged against the right nominal, a unit
    for args in ([], ["--nominal-gain", "210", "--max-gain-error", "0.05"]):
        r = run(capsys, "solve", "-p", *IMUCAL_FILES, "--reference", "9.81", *args, "-o", out)
        assert r.code == 0, r.err


def test_a_nominal_gain_of_1_given_is_judged_and_check_says_what_solve_says(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--nominal-gain 1 said out loud is a nominal to judge by (it was taken for the default and
    g data at --reference 9.81 passed); check of a counts calibration against a limits file in g
    is the same units mistake (exit 2) that solve reports, not a unit outside its limits."""
    files = six_faces(tmp_path)
    out = precious(tmp_path / "cal.json")
    three = [files[f] for f in ("+x", "+y", "+z")]
    r = run(capsys, "solve", "-p", *three, "--reference", "9.81", "--nominal-gain", "1", "-o", out)
    assert_units_mistake(r, "from the nominal gain 1", "hint: the data looks like g: run with --reference 1")
    assert_untouched(out)
    counts = tmp_path / "counts.json"
    assert run(capsys, "solve", "-p", *IMUCAL_FILES, "--reference", "9.81", "-o", counts).code == 0
    r = run(capsys, "check", counts, "--limits", SAMPLE / "limits.yaml")
    assert_units_mistake(r, f"{counts}: gains", "--nominal-gain 210")
    assert run(capsys, "check", counts, "--nominal-gain", "210", "--max-gain-error", "0.05").code == 0
    in_g = tmp_path / "g.json"  # data in g solved at --reference 9.81: check has no --reference to give
    assert run(capsys, "solve", "-q", "-p", *three, "--reference", "9.81", "-o", in_g).code == 0
    r = run(capsys, "check", in_g, "--max-gain-error", "0.05")
    assert_units_mistake(r, "hint: the data looks like g: solve it again with --reference 1")


def test_auto_names_a_pose_captured_on_another_face_not_a_tilt(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The real +z capture given again in the +x place: auto's magnitude fit cannot use it and
    said 'the six poses' magnitudes do not determine offsets and gains: +x 64°', hint 'rest the
    unit flat'; the orientation check says which file reads like which face, as six-pose does."""
    files = [tmp_path / f"p_{n}.csv" for n in ("xp", "xn", "yp", "yn", "zp", "zn")]
    for source, copy in zip([IMUCAL_FILES[4], *IMUCAL_FILES[1:]], files, strict=True):
        shutil.copy(source, copy)
    out = tmp_path / "cal.json"
    for method in ("auto", "six-pose-magnitude", "six-pose"):
        r = run(capsys, "solve", "-q", "-p", *files, "--reference", "9.81", "-m", method, "-o", out)
        assert r.code == 3, r.err
        assert f"error: {files[0]}: declared +x but reads like +z" in r.err
        assert "hint: give the pose files in the order +x -x +y -y +z -z" in r.err
        assert not out.exists()


def test_labelled_files_on_the_wrong_faces_blame_the_labels_not_their_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """+x=xn.csv -x=xp.csv: the labels gave the faces, so 'were the files given in the order
    x -x y -y z -z?' and 'give the pose files in the order ...' pointed at the wrong fix."""
    d = {n: f for n, f in zip(("xp", "xn", "yp", "yn", "zp", "zn"), IMUCAL_FILES, strict=True)}
    items = [f"+x={d['xn']}", f"-x={d['xp']}", f"+y={d['yp']}", f"-y={d['yn']}", f"+z={d['zp']}", f"-z={d['zn']}"]
    for method in ("auto", "six-pose"):
        r = run(capsys, "solve", "-q", "-p", *items, "--reference", "9.81", "-m", method, "-o", tmp_path / "c.json")
        assert r.code == 3, r.err
        assert f"error: {d['xn']}: declared +x but reads like -x" in r.err
        assert "it is labelled +x: was it captured on another face, or labelled wrong?" in r.err
        assert "order" not in r.err
        assert r.err.endswith(
            "hint: label each file with the face that pointed up while it was captured (+x=FILE: its x axis up)\n"
        )


def test_a_negative_gain_is_a_warning_even_with_the_checks_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--no-checks with the x faces' files swapped wrote gain -208.5 and said PASS, nothing else."""
    files = [tmp_path / "a.csv", tmp_path / "b.csv", *IMUCAL_FILES[2:]]
    shutil.copy(IMUCAL_FILES[1], files[0])
    shutil.copy(IMUCAL_FILES[0], files[1])
    r = run(capsys, "solve", "-p", *files, "--reference", "9.81", "--no-checks", "-o", tmp_path / "cal.json")
    assert r.code == 0, r.err
    assert "warning: gain -208.5 on x is negative: this calibration mirrors x" in r.err
    assert [line for line in r.err.splitlines() if line.startswith("warning: gain")] == [
        "warning: gain -208.5 on x is negative: this calibration mirrors x (a pose upside down or on the wrong face; "
        "the check that rejects it is off) (pose.upside_down)"
    ]  # y and z are not


def test_one_axis_off_is_the_checks_and_limits_business_not_a_units_mistake(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """+x and +y files swapped: gains near 0 on two axes is a pose problem (exit 3), never exit 2."""
    files = six_faces(tmp_path)
    swapped = unnamed([files["+y"], files["+x"], files["+z"]], tmp_path / "unnamed")  # their order gives the faces
    r = run(capsys, "solve", "-p", *swapped, "--max-gain-error", "0.02", "-o", tmp_path / "cal.json")
    assert r.code == 3, r.err


def test_sphere_on_too_few_distinct_directions_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Thirteen poses on six faces: the sphere cannot fit 9 parameters, and the message says why."""
    faces = [FACES[f] for f in SIX] * 2 + [FACES["+z"]]
    files = directional(tmp_path, faces)
    r = run(capsys, "solve", "-p", *files, "-m", "sphere", "-o", tmp_path / "cal.json")
    assert_rejected(r, "13 poses, 6 distinct directions", "the sphere needs 9+")

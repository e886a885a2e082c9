"""Calibration files (tumblecal_cli/io/calfiles/calfile.py, docs/reference/calibration-file.md): round trip,
contract, rejects, atomicity."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tumblecal_cli import __version__
from tumblecal_cli.core.model import Solution
from tumblecal_cli.errors import InputError
from tumblecal_cli.io import outputs as files
from tumblecal_cli.io.calfiles import calfile

POSES = [
    {"pose": "+x", "file": "x.csv", "sha256": "0" * 64, "rows": [2, 2001], "samples": 2000, "mean": [1.01, 0.0, 0.02]},
]


def solution(offset: Any = (0.02, -0.015, 0.03), gain: Any = (1.01, 0.98, 1.02)) -> Solution:
    return Solution(
        method="three-pose",
        offset=np.array(offset, dtype=float),
        matrix=np.diag(1.0 / np.array(gain, dtype=float)),
        offset_se=np.array([3e-5, 3e-5, 4e-5]),
        gain_se=np.array([5e-5, 5e-5, 6e-5]),
    )


def document(sol: Solution | None = None, *, sensor: str = "accelerometer", reference: float = 1.0) -> dict[str, Any]:
    return calfile.build(sol or solution(), calfile.Basis(sensor, reference, ["ax", "ay", "az"]), POSES).to_dict()


# --- round trip -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def outdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A module-scoped folder: Hypothesis runs many examples per test call, so no tmp_path.
    Each example makes a folder of its own in it (``one_example``)."""
    return tmp_path_factory.mktemp("roundtrip")


@contextlib.contextmanager
def one_example(outdir: Path) -> Iterator[Path]:
    """A fresh folder in ``outdir`` for one Hypothesis example (no file of an earlier example,
    or of a replay, is ever read in its place), and ``created`` fixed for the example (the
    clock and the caller's SOURCE_DATE_EPOCH, whatever it holds, play no part)."""
    epoch = calfile.CALLER_EPOCH.set("1700000000")
    try:
        yield Path(tempfile.mkdtemp(dir=outdir))
    finally:
        calfile.CALLER_EPOCH.reset(epoch)


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@pytest.mark.slow
@settings(max_examples=50, deadline=None)
@given(
    offset=st.tuples(finite, finite, finite),
    matrix=st.lists(st.floats(-1e3, 1e3), min_size=9, max_size=9),
    suffix=st.sampled_from([".json", ".yaml", ".yml", ".YAML"]),
)
def test_round_trip_keeps_offset_and_matrix_exactly(
    outdir: Path, offset: tuple[float, float, float], matrix: list[float], suffix: str
) -> None:
    m = np.array(matrix).reshape(3, 3)
    assume(abs(np.linalg.det(m)) > 1e-9 and np.linalg.cond(m) < 1e9)  # build() inverts M for the gains
    sol = Solution(
        method="least-squares", offset=np.array(offset), matrix=m, offset_se=np.zeros(3), gain_se=np.zeros(3)
    )
    with one_example(outdir) as folder:
        doc = document(sol)
        path = str(folder / f"cal{suffix}")
        calfile.write(doc, path)
        loaded = calfile.load(path)

    assert loaded.offset.tolist() == list(offset)  # exact, not approximately
    assert loaded.matrix.tolist() == m.tolist()
    assert loaded.to_dict() == doc  # every field, including the gains, the poses and the created time
    assert loaded.columns == ["ax", "ay", "az"]
    assert loaded.sensor == "accelerometer"
    assert loaded.path == path
    with open(path, encoding="utf-8") as f:
        text = f.read()
    assert text.lstrip().startswith("{") == (suffix == ".json")


def test_load_reads_stdin_for_dash(monkeypatch: pytest.MonkeyPatch) -> None:
    text = calfile.dumps(document(), "cal.json")
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(text.encode())))
    assert calfile.load("-").offset.tolist() == [0.02, -0.015, 0.03]
    yaml_text = calfile.dumps(document(), "cal.yaml")
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(yaml_text.encode())))
    assert calfile.load("-").offset.tolist() == [0.02, -0.015, 0.03]


# --- the contract of docs/reference/calibration-file.md -------------------------------------

FIELDS = [
    "format",
    "version",
    "sensor",
    "method",
    "reference",
    "units",
    "input_units",
    "columns",
    "offset",
    "matrix",
    "gain",
    "uncertainty",
    "poses",
    "unit",
    "verdict",
    "created",
    "tool",
]


def test_written_json_has_every_version_1_field(tmp_path: Path) -> None:
    path = tmp_path / "unit-0042.json"
    calfile.write(document(), str(path))
    doc = json.loads(path.read_text(encoding="utf-8"))

    assert list(doc) == FIELDS  # in the order of docs/reference/calibration-file.md
    assert doc["format"] == "tumblecal-calibration"
    assert doc["version"] == 1
    assert doc["sensor"] == "accelerometer"
    assert doc["method"] == "three-pose"
    assert doc["reference"] == 1.0
    assert doc["units"] == "g"
    assert doc["input_units"] is None
    assert doc["columns"] == ["ax", "ay", "az"]
    assert doc["offset"] == [0.02, -0.015, 0.03]
    assert doc["matrix"] == np.diag(1.0 / np.array([1.01, 0.98, 1.02])).tolist()
    np.testing.assert_allclose(doc["gain"], [1.01, 0.98, 1.02], rtol=1e-15)
    assert doc["uncertainty"] == {"offset": [3e-5, 3e-5, 4e-5], "gain": [5e-5, 5e-5, 6e-5]}
    assert doc["poses"] == POSES
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", doc["created"])
    assert doc["tool"] == f"tumblecal {__version__}"


def test_written_json_keeps_vectors_on_one_line(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    calfile.write(document(), str(path))
    lines = path.read_text(encoding="utf-8").splitlines()
    assert '  "offset": [0.02, -0.015, 0.03],' in lines
    assert path.read_text(encoding="utf-8").endswith("}\n")


@pytest.mark.parametrize(
    ("sensor", "reference", "units"),
    [
        ("accelerometer", 1.0, "g"),
        ("accelerometer", 9.80665, "m/s^2"),
        ("accelerometer", 1000.0, "mg"),
        ("accelerometer", 16384.0, None),
        ("magnetometer", 1.0, None),
        ("gyroscope", 0.0, None),
    ],
)
def test_units_default_only_for_an_accelerometer_with_a_conventional_reference(
    sensor: str, reference: float, units: str | None
) -> None:
    assert document(sensor=sensor, reference=reference)["units"] == units


def test_units_given_are_kept() -> None:
    basis = calfile.Basis("accelerometer", 9.80665, ["x", "y", "z"], "m/s^2", "counts")
    doc = calfile.build(solution(), basis, []).to_dict()
    assert (doc["units"], doc["input_units"]) == ("m/s^2", "counts")


# --- load rejects bad files, naming the file and the field ---------------------------------------------


def valid_text(path: Path) -> str:
    return calfile.dumps(document(), str(path))


def mutated(path: Path, **changes: Any) -> Path:
    """A valid calibration with some fields replaced (value ``...``: the field removed), written as JSON."""
    doc = document()
    for name, value in changes.items():
        if value is ...:
            del doc[name]
        else:
            doc[name] = value
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def rejects(path: Path, message: str) -> None:
    """load() raises InputError whose whole message is '<path>: <message>'."""
    with pytest.raises(InputError, match=f"^{re.escape(str(path))}: {message}$") as caught:
        calfile.load(str(path))
    assert caught.value.file == str(path)
    assert caught.value.exit_code == 2


def test_load_rejects_a_missing_file(tmp_path: Path) -> None:
    rejects(tmp_path / "nope.json", "no such calibration file")


@pytest.mark.parametrize("text", ["", "\n  \n", "\ufeff"])
def test_load_rejects_an_empty_file(tmp_path: Path, text: str) -> None:
    path = tmp_path / "empty.json"
    path.write_text(text, encoding="utf-8")
    rejects(path, "empty calibration file")


def test_load_rejects_a_file_that_is_not_text(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    rejects(path, "not a calibration file: not UTF-8 text")


def test_load_rejects_an_empty_object(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text("{}", encoding="utf-8")
    rejects(path, re.escape("not a tumblecal calibration: missing field 'format' (expected 'tumblecal-calibration')"))


@pytest.mark.parametrize("text", ["[1, 2, 3]", '"tumblecal-calibration"', "42", "null"])
def test_load_rejects_a_document_that_is_not_an_object(tmp_path: Path, text: str) -> None:
    path = tmp_path / "cal.json"
    path.write_text(text, encoding="utf-8")
    rejects(path, re.escape("not a calibration file: expected a JSON/YAML object at the top"))


def test_load_rejects_truncated_json_with_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    text = valid_text(path)
    path.write_text(text[: text.index('  "sensor"')], encoding="utf-8")  # cut after '"version": 1,\n'
    rejects(path, re.escape("not valid JSON: Expecting property name enclosed in double quotes (line 4, column 1)"))


def test_load_rejects_broken_yaml_with_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "cal.yaml"
    path.write_text("format: tumblecal-calibration\nversion: 1\noffset: [0.1, 0.2\n", encoding="utf-8")
    rejects(path, r"not valid YAML: expected ',' or '\]', but got '<stream end>' \(line 4, column 1\)")


def test_load_rejects_an_unknown_format(tmp_path: Path) -> None:
    path = mutated(tmp_path / "cal.json", format="imucal")
    rejects(path, re.escape("not a tumblecal calibration: unknown format 'imucal' (expected 'tumblecal-calibration')"))


@pytest.mark.parametrize("version", [2, 0, "1", True, None])
def test_load_rejects_an_unknown_version(tmp_path: Path, version: Any) -> None:
    path = mutated(tmp_path / "cal.json", version=version)
    with pytest.raises(InputError) as caught:
        calfile.load(str(path))
    assert str(caught.value) == f"{path}: unsupported calibration version {version!r} (this tumblecal reads version 1)"
    assert caught.value.hint == "upgrade tumblecal to read newer calibration files"


@pytest.mark.parametrize("name", calfile.REQUIRED)
def test_load_rejects_each_missing_required_field(tmp_path: Path, name: str) -> None:
    path = mutated(tmp_path / "cal.json", **{name: ...})
    rejects(path, rf"(not a tumblecal calibration: )?missing field '{name}'( \(expected 'tumblecal-calibration'\))?")


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("offset", [0.1, 0.2], "field 'offset' must be a list of 3 numbers"),
        ("offset", "0.1, 0.2, 0.3", "field 'offset' must be a list of 3 numbers"),
        ("offset", {"x": 0.1, "y": 0.2, "z": 0.3}, "field 'offset' must be a list of 3 numbers"),
        ("offset", ["0.1", 0.2, 0.3], "field 'offset' must be a finite number"),
        ("offset", [True, 0.2, 0.3], "field 'offset' must be a finite number"),
        ("offset", [None, 0.2, 0.3], "field 'offset' must be a finite number"),
        ("matrix", [[1, 0], [0, 1]], "field 'matrix' must be a 3x3 list of numbers"),
        ("matrix", [[1, 0, 0], [0, 1, 0]], "field 'matrix' must be a 3x3 list of numbers"),
        ("matrix", [1, 0, 0, 0, 1, 0, 0, 0, 1], "field 'matrix' must be a 3x3 list of numbers"),
        ("matrix", [[1, 0, 0], [0, 1, 0], [0, 0, "1"]], "field 'matrix' must be a finite number"),
        ("gain", [1.0, 1.0], "field 'gain' must be a list of 3 numbers"),
        ("reference", "1", "field 'reference' must be a finite number"),
        ("columns", ["x", "y"], "field 'columns' must be a list of three column names"),
        ("columns", ["x", "y", "z", "t"], "field 'columns' must be a list of three column names"),
        ("columns", [0, 1, 2], "field 'columns' must be a list of three column names"),
        ("columns", "x,y,z", "field 'columns' must be a list of three column names"),
        ("sensor", "barometer", "field 'sensor' must be one of accelerometer, magnetometer, gyroscope"),
    ],
)
def test_load_rejects_a_malformed_field(tmp_path: Path, field: str, value: Any, message: str) -> None:
    rejects(mutated(tmp_path / "cal.json", **{field: value}), re.escape(message))


@pytest.mark.parametrize(
    ("line", "replacement", "field"),
    [
        ("offset:", "offset: [.nan, -0.015, 0.03]", "offset"),
        ("offset:", "offset: [0.02, -.inf, 0.03]", "offset"),
        ("reference:", "reference: .nan", "reference"),
        ("- [", "- [.inf, 0.0, 0.0]", "matrix"),  # the first matrix row
    ],
)
def test_load_rejects_non_finite_numbers(tmp_path: Path, line: str, replacement: str, field: str) -> None:
    path = tmp_path / "cal.yaml"
    lines = valid_text(path).splitlines()
    i = next(i for i, text in enumerate(lines) if text.lstrip().startswith(line))
    lines[i] = lines[i][: len(lines[i]) - len(lines[i].lstrip())] + replacement
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    # refused where it is read, with its place: the element, the line and the column
    rejects(path, re.escape(f"field '{field}") + r"(\[\d\])*' must be a finite number \(.*\) \(line \d+, column \d+\)")


@pytest.mark.parametrize("where", ["top", "field"])
def test_load_never_runs_yaml_python_tags(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str) -> None:
    monkeypatch.chdir(tmp_path)
    payload = '!!python/object/apply:os.system ["echo pwned > PWNED"]'
    path = tmp_path / "evil.yaml"
    if where == "top":
        path.write_text(payload + "\n", encoding="utf-8")
    else:
        path.write_text(valid_text(path).replace("sensor: accelerometer", f"sensor: {payload}"), encoding="utf-8")
    rejects(
        path,
        ("the document" if where == "top" else "field 'sensor'")
        + r" is of the tag !!python/object/apply:os.system: tumblecal reads JSON's values only "
        r"\(text, numbers, true/false, null, lists, objects\) \(line \d+, column \d+\)",
    )
    assert not (tmp_path / "PWNED").exists()


# --- atomic writes ------------------------------------------------------------------------------------


def test_write_replaces_an_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text("old contents\n", encoding="utf-8")
    path.chmod(0o640)
    calfile.write(document(solution(offset=(1.0, 2.0, 3.0))), str(path))
    assert calfile.load(str(path)).offset.tolist() == [1.0, 2.0, 3.0]
    assert os.listdir(tmp_path) == ["cal.json"]  # no temp file left
    assert path.stat().st_mode & 0o777 == 0o640  # the replaced file keeps its permissions


def test_write_refuses_a_missing_folder(tmp_path: Path) -> None:
    path = tmp_path / "no" / "cal.json"
    with pytest.raises(InputError, match=f"^{re.escape(str(path))}: the output folder does not exist$"):
        calfile.write(document(), str(path))


def test_a_failed_serialisation_leaves_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "cal.json"
    calfile.write(document(), str(path))
    before = path.read_bytes()

    def broken(doc: dict[str, Any], path: str) -> str:
        raise TypeError("Object of type ndarray is not JSON serializable")

    monkeypatch.setattr(calfile, "dumps", broken)
    with pytest.raises(TypeError):
        calfile.write(document(solution(offset=(1.0, 2.0, 3.0))), str(path))
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["cal.json"]


@pytest.mark.parametrize("error", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_a_failure_while_writing_leaves_the_old_file_and_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: BaseException
) -> None:
    """The whole new text is in the temp file when the write fails (disk full, Ctrl-C)."""
    path = tmp_path / "cal.json"
    calfile.write(document(), str(path))
    before = path.read_bytes()
    real = files.atomic_output
    seen: list[str] = []

    @contextlib.contextmanager
    def interrupted(target: str) -> Iterator[IO[bytes]]:
        with real(target) as out:
            yield out  # calfile.write writes the whole document here
            out.flush()
            seen.extend(n for n in os.listdir(tmp_path) if n.endswith(".tmp"))
            raise error

    monkeypatch.setattr(calfile, "atomic_output", interrupted)
    # a full disk becomes the one-line error naming the output (the OS error names no file)
    expected = InputError if isinstance(error, OSError) else type(error)
    with pytest.raises(expected) as caught:
        calfile.write(document(solution(offset=(1.0, 2.0, 3.0))), str(path))
    if isinstance(error, OSError):
        assert str(caught.value) == f"{path}: cannot write: No space left on device"
    assert len(seen) == 1  # the temp file was there, in the target folder...
    assert path.read_bytes() == before  # ...but the old file is untouched
    assert os.listdir(tmp_path) == ["cal.json"]  # and the temp file is gone


def test_atomic_output_block_error_leaves_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "cal.yaml"
    path.write_bytes(b"old")

    def partial_then_fail() -> None:
        with files.atomic_output(str(path)) as out:
            out.write(b"partial")
            raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match=r"^boom$"):
        partial_then_fail()
    assert path.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["cal.yaml"]


def test_show_of_a_file_whose_tilt_block_states_no_tolerance(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """tilt_sensitivity without tolerance_deg (another tool's file, or hand-edited) is valid: show
    says what tilt limits without a number of degrees (was an internal error, found by fuzzing)."""
    import json

    from tests.conftest import POSES_3, run

    cal = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", cal).code == 0
    doc = json.loads(cal.read_text())
    del doc["tilt_sensitivity"]["tolerance_deg"]
    cal.write_text(json.dumps(doc))
    code, out, err = run(capsys, "show", cal)  # show's summary is its output: stdout
    assert code == 0, err
    assert "fixture tilt, not noise, limits this calibration: the fixture's tilt moves the offsets" in out


@pytest.mark.parametrize(
    ("text", "name"), [('"note": NaN', "x.json"), ('"note": -Infinity', "x.json"), ("note: .nan", "x.yaml")]
)
def test_a_number_json_has_no_form_for_is_refused(tmp_path: Path, text: str, name: str) -> None:
    """NaN or Infinity in any field (here one tumblecal does not know, which it keeps) was read and
    then written by `show --json` as a NaN no JSON reader takes: one clear line, exit 2."""
    path = tmp_path / name
    path.write_text(f"{{{text}}}\n" if name.endswith(".json") else f"{text}\n")
    with pytest.raises(InputError, match=r"(NaN|Infinity|\.nan)"):
        calfile.load(str(path))

"""Hostile input, round two: outputs that race, and exports that our own ``import`` or a C
compiler would reject. Each test is named for the defect it pins, and failed before its fix."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

import tumblecal_cli as tumblecal
from tests.conftest import POSES_3, SAMPLE, assert_usage_error, run, tumblecal_exe
from tumblecal_cli.io.calfiles import calfile
from tumblecal_cli.pipeline import apply as correct_module

OTHER_RUN = b"t,ax,ay,az\n0,1,2,3\n"


@pytest.fixture
def cal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    path = tmp_path / "cal.json"
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", path).code == 0
    return path


# -- apply --out-dir: the check that a name is free and the publish are one step ------------------


def test_apply_out_dir_never_replaces_a_file_another_run_writes_meanwhile(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two runs correcting captures of one name into one folder: the other run's file appears
    after this run's "never replaces a file" check, while it streams. Before: both exited 0 and
    the other run's output was silently replaced. Now: this run is exit 2 naming the file, the
    other run's output stays as it was, and no temporary file is left behind."""
    out = tmp_path / "out"
    capture = tmp_path / "a" / "capture.csv"
    capture.parent.mkdir()
    capture.write_bytes((SAMPLE / "capture.csv").read_bytes())
    stream = correct_module._stream

    def other_run_first(*args: object) -> int:  # the other run publishes while this one streams
        (out / "capture.csv").write_bytes(OTHER_RUN)
        return stream(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(correct_module, "_stream", other_run_first)
    r = run(capsys, "apply", "--cal", cal, capture, "--out-dir", out)
    assert r.code == 2, r.err
    assert r.out == ""
    assert "Traceback" not in r.err
    errors = [ln for ln in r.err.splitlines() if ln.startswith("error:")]
    assert any(f"{out / 'capture.csv'}: already exists" in ln for ln in errors), r.err
    assert (out / "capture.csv").read_bytes() == OTHER_RUN
    assert sorted(os.listdir(out)) == ["capture.csv"], "no temporary file is left behind"


@pytest.mark.slow
def test_apply_out_dir_two_runs_racing_for_one_name_never_both_succeed(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The race as it happens: two processes correct different captures named alike into one
    folder, three times. Each time exactly one exits 0 and its output is the file there; the
    other exits 2 naming the file (before: both exited 0, one output lost, 4 tries in 6)."""
    lines = (SAMPLE / "capture.csv").read_bytes().splitlines(keepends=True)
    captures = []
    for name, rows in (("a", lines), ("b", lines[: len(lines) // 2])):
        (tmp_path / name).mkdir()
        captures.append(tmp_path / name / "capture.csv")
        captures[-1].write_bytes(b"".join(rows))
    wanted = []
    for k, capture in enumerate(captures):
        alone = tmp_path / f"alone{k}"
        assert run(capsys, "apply", "--cal", cal, capture, "--out-dir", alone).code == 0
        wanted.append((alone / "capture.csv").read_bytes())
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        runs = [
            subprocess.Popen(
                [tumblecal_exe(), "apply", "--cal", str(cal), str(c), "--out-dir", str(out)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                env={**os.environ, "NO_COLOR": "1"},
            )
            for c in captures
        ]
        done = [(p.wait(timeout=120), p.stderr.read().decode() if p.stderr else "") for p in runs]
        for p in runs:
            for stream in (p.stdout, p.stderr):
                if stream:
                    stream.close()
        codes = [code for code, _ in done]
        assert sorted(codes) == [0, 2], done
        winner, loser = codes.index(0), codes.index(2)
        assert (out / "capture.csv").read_bytes() == wanted[winner]
        assert f"{out / 'capture.csv'}: already exists" in done[loser][1]
        assert "Traceback" not in done[loser][1]
        assert sorted(os.listdir(out)) == ["capture.csv"], "no temporary file is left behind"


# -- what load accepts, every export writes and import reads back -----------------------------------

#: Serials (stations, operators) an export has to carry: comment terminators and openers, C99
#: trigraphs (``??/`` is a backslash, ``??=`` a ``#``), backslashes (one last), quotes, text
#: beyond ASCII and beyond the BMP, YAML's line breaks (NEL, U+2028, U+2029) and the characters a
#: YAML reader refuses a file for, and text shaped like the export's own record.
HOSTILE = [
    '*/ #include "x" /*',
    "/*/",
    "/**/ // x",
    "a??/",
    "??=define X 1",
    "??" * 4 + "/",
    "?\\?/",
    "back\\slash \\n \\u0041 \\x41",
    "ends with a backslash\\",
    "Müller 温度 😀",
    "\U0010ffff\ufeff",
    "\"q\" 's' `b`",
    "%{",
    "#include <stdio.h>",
    "x\x85SM: [1, 0, 0, 0, 1, 0, 0, 0, 1]",
    "y\u2028[: 1",
    "z\u2029]",
    "\ufffe\uffff",
    "",
    "  lead and trail  ",
    '{"sensor": "gyroscope", "reference": 9.81}',
    "A1; reference 9.81; columns t, ay, az",
]


def hostile_cal(folder: Path, cal: Path, text: str, name: str = "hostile.json") -> Path:
    """``cal`` with ``text`` as its serial, station and operator (and a meta value)."""
    doc = json.loads(cal.read_text(encoding="utf-8"))
    doc["unit"] = {"serial": text, "station": text, "operator": text, "meta": {"note": text}}
    path = folder / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize("fmt", ["imucal-json", "ros-yaml"])
@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_an_exported_serial_that_import_cannot_read_back(
    text: str, fmt: str, cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """export → import gives back the serial, station and operator that load read, for any text
    load accepts (before: a character beyond the BMP came back from ros-yaml as two halves of a
    surrogate pair, an internal error; a NEL or U+2028 in a YAML comment made the rest of its
    line data)."""
    path = hostile_cal(tmp_path, cal, text)
    assert run(capsys, "show", path).code == 0
    peer, back = tmp_path / f"peer.{fmt}", tmp_path / "back.json"
    r = run(capsys, "export", path, "--format", fmt, "-o", peer)
    assert r.code == 0, r.err
    r = run(capsys, "import", peer, "--from", fmt, "-o", back)
    assert r.code == 0, r.err
    unit = json.loads(back.read_text(encoding="utf-8"))["unit"]
    assert (unit["serial"], unit["station"], unit["operator"]) == (text, text, text)


@pytest.mark.parametrize(
    ("unit", "field", "what"),
    [
        ({"station": ["a", {"b": 1}]}, "field 'unit.station'", "must be text, not a list"),
        ({"operator": {"name": "Kim"}}, "field 'unit.operator'", "must be text, not an object"),
        ({"serial": True}, "field 'unit.serial'", "must be text, not true/false"),
        ({"serial": 1.50}, "field 'unit.serial'", "must be text, not a decimal number"),
        ({"meta": {"lot": [1, 2]}}, "field 'unit.meta.lot'", "must be text, not a list"),
        ({"meta": {"lot": None}}, "field 'unit.meta.lot'", "must be text, not null"),
        ({"meta": {"lot": "4\n2"}}, "field 'unit.meta.lot'", "holds a control character"),
        ({"serial": "\ud800"}, "field 'unit.serial'", "holds \\ud800, half of a UTF-16 surrogate pair"),
    ],
    ids=["list", "object", "bool", "decimal", "meta-list", "meta-null", "meta-newline", "lone-surrogate"],
)
def test_a_unit_field_that_is_not_text_passes_load_but_no_export_can_carry(
    unit: dict[str, object], field: str, what: str, cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A unit field that is not text has no form every export can write and import read back
    (before: show and every export took a list, writing its Python repr; a lone surrogate was an
    internal error): load refuses it, exit 2 naming the file and the field."""
    doc = json.loads(cal.read_text(encoding="utf-8"))
    doc["unit"] = {"serial": None, "station": None, "operator": None, "meta": {}} | unit
    path = tmp_path / "odd.json"
    path.write_text(json.dumps(doc), encoding="utf-8")  # "\ud800" as JSON writes it: an escape
    commands: list[list[str | Path]] = [
        ["show", path],
        ["export", path, "-f", "imucal-json"],
        ["export", path, "-f", "c-header"],
    ]
    for args in commands:
        r = run(capsys, *args)
        assert_usage_error(r, f"error: {path}: {field} {what}")


def test_a_whole_number_serial_is_read_as_its_text_by_every_export(
    cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hand-written YAML ``serial: 1234`` is still read, as "1234", and comes back so."""
    doc = json.loads(cal.read_text(encoding="utf-8"))
    doc["unit"] = {"serial": 1234, "station": None, "operator": None, "meta": {"lot": 7}}
    path = tmp_path / "number.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    peer, back = tmp_path / "peer.json", tmp_path / "back.json"
    assert run(capsys, "export", path, "--format", "imucal-json", "-o", peer).code == 0
    assert run(capsys, "import", peer, "-o", back).code == 0
    assert json.loads(back.read_text(encoding="utf-8"))["unit"]["serial"] == "1234"


GCC = shutil.which("gcc")
GCC_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]


@pytest.mark.slow
@pytest.mark.skipif(GCC is None, reason="gcc is not installed: the C header is compiled to be checked")
@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_a_serial_that_breaks_the_c_header(
    text: str, cal: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The C header of a calibration whose serial, station and operator are ``text`` (and whose
    path holds ``/*`` too) compiles with gcc -std=c99 -Wall -Wextra -Werror -pedantic, in a
    program that uses it (before: ``*/ #include "x" /*`` gave '"/*" within comment', ``a??/`` a
    trigraph that ends a line)."""
    path = hostile_cal(tmp_path, cal, text, name="*cal ??( é\\.json")
    r = run(capsys, "export", path, "--format", "c-header", "-o", tmp_path / "unit.h")
    assert r.code == 0, r.err
    assert (tmp_path / "unit.h").read_bytes().isascii()
    (tmp_path / "main.c").write_text(
        '#include "unit.h"\nint main(void) {\n    float v[3] = {1.0f, 2.0f, 3.0f};\n'
        "    tumblecal_accel_apply(v, v);\n    return v[0] > 1e30f;\n}\n"
    )
    built = subprocess.run(
        [str(GCC), *GCC_FLAGS, "main.c", "-o", "main"], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert built.returncode == 0, built.stderr


@pytest.mark.slow
@pytest.mark.skipif(GCC is None, reason="gcc is not installed: the C header is compiled to be checked")
def test_a_c_header_of_any_text_compiles(cal: Path, tmp_path: Path) -> None:
    """What load refuses can still reach the C header through the library (a Calibration made
    in Python): control characters, NUL, DEL, C1 controls and lone surrogates in every text that
    reaches its comment (the unit, the columns, the method, the time and the file name)."""
    worst = "a\nb\r\x00\x1b[31m */ /* ??/\\\ud800\x7f\x85\u2028 é"
    made = replace(
        calfile.load(str(cal)),
        unit=calfile.Unit(worst, worst, worst, {worst: worst}),
        columns=[f"{worst}{axis}" for axis in "xyz"],
        method=worst,
        created=worst,
        path=worst,
    )
    header = tumblecal.export(made, "c-header")
    assert header.isascii()
    (tmp_path / "unit.h").write_text(header, encoding="ascii")
    (tmp_path / "main.c").write_text('#include "unit.h"\nint main(void) { return 0; }\n')
    built = subprocess.run(
        [str(GCC), *GCC_FLAGS, "main.c", "-o", "main"], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert built.returncode == 0, built.stderr

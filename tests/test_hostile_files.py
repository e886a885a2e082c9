"""Files that broke a command (issue "Hostile input, round two", item 8): each is now one error
line naming the file, exit 2, no internal error; or, where the file means something plain, read
as it looks. Each test is named for the defect it pins, and failed before its fix."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import POSES_3, SAMPLE, Result, assert_one_error, precious, run
from tumblecal_cli.errors import InputError

KEEP = " (text, numbers, true/false, null, lists, objects)"


def solved(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> Path:
    """The sample calibration, solved into ``tmp_path / name`` (JSON or YAML by its suffix)."""
    path = tmp_path / name
    assert run(capsys, "solve", "--poses", *POSES_3, "-o", path).code == 0
    return path


def edited(path: Path, old: str, new: str) -> Path:
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


#: Every command that reads a calibration, with ``{f}`` for it and ``{out}`` for an output.
READERS = {
    "show": ["show", "{f}"],
    "show-json": ["show", "--json", "{f}"],
    "check": ["check", "{f}", "--max-offset", "1"],
    "apply": ["apply", "--cal", "{f}", str(SAMPLE / "capture.csv"), "-o", "{out}"],
    "verify": ["verify", "--cal", "{f}", POSES_3[0]],
    "export": ["export", "{f}", "--format", "imucal-json", "-o", "{out}"],
}


def read_by(command: str, cal: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Result, Path]:
    """Run ``command`` on ``cal``; its result and its output (an existing file it must leave)."""
    out = precious(cal.parent / "out.json")
    args = [a.replace("{f}", str(cal)).replace("{out}", str(out)) for a in READERS[command]]
    return run(capsys, *args), out


@pytest.mark.parametrize("command", READERS)
def test_a_yaml_integer_of_5000_digits_breaks_no_command(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: 'internal error: ValueError: Exceeds the limit (4300 digits)' from every command
    (JSON's reader already said so in one line)."""
    cal = edited(solved(tmp_path, capsys, "cal.yaml"), "version: 1", "version: " + "1" * 5000)
    r, out = read_by(command, cal, capsys)
    expected = (
        f"{cal}: field 'version' is an integer of 5000 digits: more than tumblecal reads (4300) (line 2, column 10)"
    )
    assert_one_error(r, expected, json_out=command == "show-json")
    assert out.read_bytes() == precious(tmp_path / "again.json").read_bytes()


@pytest.mark.parametrize(
    ("value", "kind"),
    [
        ("!!binary U04tMDA0Mg==", "binary data (!!binary)"),
        ("!!set {SN-1, SN-2}", "a set (!!set)"),
        ("!!timestamp 2024-05-01T10:00:00Z", "a timestamp (!!timestamp)"),
        ("!!omap [{a: 1}]", "an ordered map (!!omap)"),
        ("!!pairs [{a: 1}]", "a list of pairs (!!pairs)"),
    ],
    ids=["binary", "set", "timestamp", "omap", "pairs"],
)
@pytest.mark.parametrize("command", ["show", "show-json", "export"])
def test_yaml_values_json_has_no_form_for_are_refused_at_read(
    value: str, kind: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `show` printed the serial (b'SN-0042', {'SN-1', 'SN-2'} ...) and `show --json`
    failed with 'internal error: TypeError: Object of type bytes is not JSON serializable'."""
    cal = edited(solved(tmp_path, capsys, "cal.yaml"), "serial: null", f"serial: {value}")
    r, _ = read_by(command, cal, capsys)
    message = f"field 'unit.serial' is {kind}: tumblecal reads JSON's values only{KEEP}"
    assert_one_error(r, f"{cal}: {message} (line 64, column 11)", json_out=command == "show-json")


@pytest.mark.parametrize("command", [*READERS, "report"])
def test_a_lone_surrogate_in_json_is_refused_at_read(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: show and export failed with 'internal error: UnicodeEncodeError', while check,
    apply, verify and report took the file, and export --format imucal-json wrote a file that
    import then refused."""
    cal = edited(solved(tmp_path, capsys, "cal.json"), '"serial": null', '"serial": "\\udc00\\ud800"')
    message = (
        f"{cal}: field 'unit.serial' holds \\udc00, half of a UTF-16 surrogate pair: not a character"
        " (write the character itself, in UTF-8)"
    )
    if command == "report":
        r = run(capsys, "report", cal)
        assert r.code == 2
        assert [ln for ln in r.err.splitlines() if ln.startswith("error:")] == [f"error: {message}"]
        return
    r, out = read_by(command, cal, capsys)
    assert_one_error(r, message, json_out=command == "show-json")
    assert out.read_bytes() == precious(tmp_path / "again.json").read_bytes()


def test_a_pair_of_surrogate_escapes_in_json_is_its_character(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = edited(solved(tmp_path, capsys, "cal.json"), '"serial": null', '"serial": "SN-\\ud83d\\ude00"')
    r = run(capsys, "show", "--json", cal)
    assert r.code == 0, r.err
    assert json.loads(r.out)["unit"]["serial"] == "SN-\U0001f600"


@pytest.mark.parametrize("name", ["cal.json", "cal.yaml"])
def test_a_key_given_twice_is_refused_not_read_last_wins(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: the second "offset" ([1e9, 1e9, 1e9]) was the calibration's offset."""
    cal = solved(tmp_path, capsys, name)
    if name.endswith(".json"):
        edited(cal, '  "gain":', '  "offset": [1e9, 1e9, 1e9],\n  "gain":')
        expected = f"{cal}: key 'offset' is given twice in one object: which one is meant?"
    else:
        edited(cal, "gain:", "offset: [1.0e+9, 1.0e+9, 1.0e+9]\ngain:")
        expected = f"{cal}: key 'offset' is given twice: which one is meant? (line 14, column 1)"
    out = precious(tmp_path / "out.csv")
    assert_one_error(run(capsys, "apply", "--cal", cal, SAMPLE / "capture.csv", "-o", out), expected)
    assert out.read_bytes() == precious(tmp_path / "again.csv").read_bytes()


def test_a_key_given_twice_deeper_in_yaml_names_its_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = edited(solved(tmp_path, capsys, "cal.yaml"), "meta: {}", "meta: {lot: A, lot: B}")
    r = run(capsys, "show", cal)
    assert_one_error(
        r, f"{cal}: key 'lot' of field 'unit.meta' is given twice: which one is meant? (line 67, column 18)"
    )


def test_a_yaml_sexagesimal_reference_is_text_not_60(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """YAML 1.1 reads 1:00 as 60 (base 60): before, show said 'reference 60 g' and apply
    corrected by it."""
    cal = edited(solved(tmp_path, capsys, "cal.yaml"), "reference: 1.0", "reference: 1:00")
    r = run(capsys, "show", cal)
    assert_one_error(r, f"{cal}: field 'reference' must be a finite number")
    edited(cal, "reference: 1:00", "reference: !!float 1:00")
    r = run(capsys, "show", cal)
    assert_one_error(r, f"{cal}: field 'reference' is a base-60 number (1:00): write it in decimal (line 5, column 12)")


@pytest.mark.parametrize(
    ("written", "read"),
    [("0042", "0042"), ("NO", "NO"), ("off", "off"), ("2024-05-01", "2024-05-01"), ("12:30", "12:30")],
)
def test_a_yaml_serial_reads_as_it_looks(
    written: str, read: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """YAML 1.1 read 0042 as octal 34, NO and off as false, a date as a date (which show --json
    could not write) and 12:30 as 750: each is the text it looks like."""
    cal = edited(solved(tmp_path, capsys, "cal.yaml"), "serial: null", f"serial: {written}")
    r = run(capsys, "show", "--json", cal)
    assert r.code == 0, r.err
    assert json.loads(r.out)["unit"]["serial"] == read


def test_yaml_numbers_still_read_as_numbers() -> None:
    """What YAML 1.1 reads as a number and looks like one still is one: 1, -0.5, 1.0e-3, 0x10; .inf
    and .nan are refused, as NaN and Infinity are in JSON: no export could write them."""
    from tumblecal_cli.io.calfiles import documents

    doc = documents.parse_object(b"a: 1\nb: -0.5\nc: 1.0e-3\nd: 0x10\nf: true\ng: ~\nh: 1_000\n", "x.yaml", "file")
    assert doc == {"a": 1, "b": -0.5, "c": 1e-3, "d": 16, "f": True, "g": None, "h": 1000}
    with pytest.raises(InputError, match=r"field 'e' must be a finite number \(\.inf"):
        documents.parse_object(b"a: 1\ne: .inf\n", "x.yaml", "file")


@pytest.mark.parametrize("command", ["segment", "solve"])
def test_a_time_column_of_steps_of_1e_300_is_one_error(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: 'internal error: OverflowError: Python int too large to convert to C long' (a
    window of 0.5 s was 5e299 samples)."""
    log = tmp_path / "log.csv"
    rows = [f"{k * 1e-300!r},0.01,0.02,{1 + 0.001 * (k % 7 - 3) / 3:.4f}" for k in range(120)]
    log.write_text("t,ax,ay,az\n" + "\n".join(rows) + "\n", encoding="utf-8")
    args: list[str | Path] = (
        ["segment", log] if command == "segment" else ["solve", "--log", log, "-o", tmp_path / "cal.json"]
    )
    assert_one_error(
        run(capsys, *args),
        f"{log}: time column 't' advances 1e-300 per sample: a sample every 1e-300 s, faster than any sensor's "
        "clock (up to 1e+09 Hz)",
        hint="give --time-unit s, ms, us or ns",
    )
    assert not (tmp_path / "cal.json").exists()


def test_a_segmentation_window_of_more_samples_than_any_log_is_an_input_error() -> None:
    """The same clock reached past the time unit's judgement (which reads the first 100,000
    steps): the window sizing refuses it rather than overflowing."""
    from tumblecal_cli.core.blocks import detect
    from tumblecal_cli.errors import InputError

    values = np.tile([0.01, 0.02, 1.0], (50, 1))
    with pytest.raises(InputError, match=r"^a sample every 1e-300 s: 0\.5 s would be 5e\+299 samples"):
        detect(values, times=np.arange(50, dtype=np.float64) * 1e-300)


@pytest.mark.parametrize("command", ["show", "check"])
def test_column_names_with_control_characters_reach_no_terminal_raw(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: a column named 'a<ESC>[31mx' coloured the rest of the terminal red; now it is
    escaped as a serial or file name is ('a\\x1b[31mx'); C1's CSI too."""
    cal = edited(solved(tmp_path, capsys, "cal.json"), '"ax"', '"a\\u001b[31mx"')
    edited(cal, '"ay"', '"a\\u009b31my"')
    args: list[str | Path] = ["show", cal] if command == "show" else ["check", cal, "--max-offset", "1e-9"]
    r = run(capsys, *args)
    assert r.code == (0 if command == "show" else 1), r.err
    shown = r.out + r.err
    assert "\x1b" not in shown
    assert "\x9b" not in shown
    assert "a\\x1b[31mx" in shown
    assert "a\\x9b31my" in shown


def _manifest(path: Path, serials: list[str]) -> Path:
    rows = ["serial,x,y,z", *(f"{s},{','.join(POSES_3)}" for s in serials)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_a_look_alike_serial_is_a_duplicate_in_batch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """SN + KELVIN SIGN (U+212A) beside SNK: before, two units (two files a reader, or a disk
    that normalises names, takes for one)."""
    manifest = _manifest(tmp_path / "lot.csv", ["SNK", "SN\u212a"])
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert_one_error(
        r, f"{manifest}: serial 'SN\\u212a' is 'SNK' in look-alike characters: it is also on line 2 (line 3, column 1)"
    )
    assert not (tmp_path / "out").exists()


def test_a_serial_in_look_alike_characters_is_noted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _manifest(tmp_path / "lot.csv", ["SN\u212a"])
    r = run(capsys, "batch", manifest, "--out-dir", tmp_path / "out")
    assert r.code == 0, r.err
    assert f"note: {manifest}: serial 'SN\\u212a' on line 2 is written in look-alike characters of SNK" in r.err

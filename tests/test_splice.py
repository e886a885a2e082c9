"""apply's fast path (io/csv/splice.py) writes what the general path writes, byte for byte.

Every case corrects one file twice, spliced (``correct_stream``'s default) and with
``splice=False`` (pyarrow's reader and writer only), and wants the same bytes out and the
same error, if any. The files are made to hit what the fast path must take (CRLF, a
preamble, interleaved rows, several sensors, decimal commas, floats either formatter
spells) and what it must hand back (comments, blank lines, ragged rows, bad cells).
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import POSES_3, spliced_blocks, write
from tumblecal_cli.core import arrays, model
from tumblecal_cli.errors import TumblecalError
from tumblecal_cli.io.csv import capture, sniff, splice
from tumblecal_cli.io.csv.capture import open_capture
from tumblecal_cli.io.readspec import Dialect, ReadSpec
from tumblecal_cli.io.rewrite import writer as rewrite

RNG = np.random.default_rng(7)
MATRIX = np.eye(3) + RNG.normal(0, 0.02, (3, 3))
OFFSET = RNG.normal(0, 0.05, 3)


def corrected(path: str, *, splice_on: bool, more: int = 0, **options: object) -> tuple[bytes, str | None]:
    """The bytes ``correct_stream`` writes for ``path``, and the error it stopped on."""
    out = io.BytesIO()
    try:
        with open_capture(path, ReadSpec(**options)) as cap:  # type: ignore[arg-type]
            extra = [(sniff.sensor_columns(cap.layout, "gyroscope", ["gx", "gy", "gz"]), _gyro)] if more else []
            rewrite.correct_stream(cap, out, _accel, more=extra, splice=splice_on)
    except TumblecalError as err:
        return out.getvalue(), str(err)
    return out.getvalue(), None


def _accel(raw: arrays.FloatArray) -> arrays.FloatArray:
    return model.apply(raw, OFFSET, MATRIX)


def _gyro(raw: arrays.FloatArray) -> arrays.FloatArray:
    return model.apply(raw, -OFFSET, MATRIX.T)


def same(path: Path, more: int = 0, **options: object) -> tuple[bytes, str | None]:
    fast = corrected(str(path), splice_on=True, more=more, **options)
    general = corrected(str(path), splice_on=False, more=more, **options)
    assert fast[1] == general[1]
    assert fast[0] == general[0]
    return fast


def cells(values: np.ndarray, fmt: str = "{!r}") -> list[str]:
    return [fmt.format(v) for v in values.tolist()]


def table(rows: int, *, seed: int = 1, scale: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal([0.01, -0.02, 1.01], 0.01, size=(rows, 3)) * scale


def lines(values: np.ndarray, time: bool = True, sep: str = ",", fmt: str = "{:.6f}") -> list[str]:
    out = []
    for i, row in enumerate(values.tolist()):
        parts = [fmt.format(v) for v in row]
        out.append(sep.join([f"{i / 1000:.3f}", *parts] if time else parts))
    return out


CASES: dict[str, Callable[[], str | bytes]] = {
    "plain": lambda: "t,ax,ay,az\n" + "\n".join(lines(table(3000))) + "\n",
    "crlf": lambda: "t,ax,ay,az\r\n" + "\r\n".join(lines(table(3000))) + "\r\n",
    "no final line end": lambda: "t,ax,ay,az\n" + "\n".join(lines(table(50))),
    "crlf, no final line end": lambda: "t,ax,ay,az\r\n" + "\r\n".join(lines(table(50))),
    "preamble": lambda: "Fs,100\nDevice,MPU6050\nt,ax,ay,az\n" + "\n".join(lines(table(500))) + "\n",
    "comment preamble and BOM": lambda: (
        "\ufeff# logger 3\n# 2026-11-21\nt,ax,ay,az\n" + "\n".join(lines(table(500))) + "\n"
    ),
    "headerless": lambda: "\n".join(lines(table(500))) + "\n",
    "headerless xyz": lambda: "\n".join(lines(table(500), time=False)) + "\n",
    "sensor first": lambda: "ax,ay,az,t\n" + "\n".join(f"{a},{b},{c},{i}" for i, (a, b, c) in enumerate(table(400))),
    "sensor apart": lambda: (
        "ax,t,ay,label,az\n"
        + "\n".join(f"{a:.5f},{i},{b:.5f},ok é,{c:.5f}" for i, (a, b, c) in enumerate(table(400).tolist()))
        + "\n"
    ),
    "semicolons": lambda: "t;ax;ay;az\n" + "\n".join(lines(table(500), sep=";")) + "\n",
    "tabs": lambda: "t\tax\tay\taz\n" + "\n".join(lines(table(500), sep="\t")) + "\n",
    "decimal commas": lambda: (
        "t;ax;ay;az\n" + "\n".join(ln.replace(".", ",") for ln in lines(table(500), sep=";")) + "\n"
    ),
    "kept text": lambda: (
        "t,ax,ay,az,note\n"
        + "\n".join(f"00{i:06d},{a:.6f},{b:.6f},{c:.6f}, x  y " for i, (a, b, c) in enumerate(table(300).tolist()))
        + "\n"
    ),
    "quotes in a cell": lambda: 't,ax,ay,az,note\n1,0.5,0.25,1.5,"a"\n2,0.5,0.25,1.5,b\n',
    "whole numbers and tiny ones": lambda: (
        "t,ax,ay,az\n" + "\n".join(f"{i},{i % 5},{(i % 7) * 1e-7!r},{(i % 3) * 1e12!r}" for i in range(2000)) + "\n"
    ),
    "every scale": lambda: (
        "t,ax,ay,az\n"
        + "\n".join(
            f"{i},{a!r},{b!r},{c!r}"
            for i, (a, b, c) in enumerate(
                (RNG.normal(size=(3000, 3)) * 10.0 ** RNG.integers(-9, 14, size=(3000, 3))).tolist()
            )
        )
        + "\n"
    ),
    "nan and inf": lambda: "t,ax,ay,az\n1,nan,0.5,0.25\n2,inf,-inf,1.5\n3,0.1,0.2,0.3\n4,1e308,-1e308,0\n",
    "interleaved rows": lambda: (
        "t,ax,ay,az\n"
        + "\n".join(
            f"{i},,," if i % 3 == 0 else f"{i},{a:.6f},{b:.6f},{c:.6f}" for i, (a, b, c) in enumerate(table(900))
        )
        + "\n"
    ),
    "only empty sensor cells": lambda: "t,ax,ay,az\n1,,,\n2,,,\n",
    "comments between rows": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n# pause\n2,0.25,0.25,0.25\n",
    "a comment row as wide as the header": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n# a,b,c,d\n2,0.25,0.25,0.25\n",
    "blank lines": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n\n2,0.25,0.25,0.25\n\n",
    "spaces around cells": lambda: "t,ax,ay,az\n1, 0.5 ,0.5,0.5\n2,0.25,0.25 ,0.25\n",
    "mixed line ends": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\r\n2,0.25,0.25,0.25\n",
    "whitespace separated": lambda: "t ax ay az\n" + "\n".join(lines(table(200), sep="   ")) + "\n",
    "cr line ends": lambda: "t,ax,ay,az\r" + "\r".join(lines(table(200))) + "\r",
    "not a number": lambda: "t,ax,ay,az\n" + "\n".join(lines(table(300))) + "\n301,0.5,oops,0.5\n",
    "partly empty": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n2,0.25,,0.25\n",
    "ragged row": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n2,0.25,0.25\n3,0.25,0.25,0.25\n",
    "too many cells": lambda: "t,ax,ay,az\n1,0.5,0.5,0.5\n2,0.25,0.25,0.25,9\n3,0.25,0.25,0.25\n",
    "not utf-8": lambda: b"t,ax,ay,az,note\n1,0.5,0.5,0.5,ok\n2,0.25,0.25,0.25,\xff\xfe\n",
    "header only": lambda: "t,ax,ay,az\n",
}


@pytest.mark.parametrize("case", list(CASES))
def test_spliced_bytes_are_the_general_paths(case: str, tmp_path: Path) -> None:
    path = write(tmp_path / "c.csv", CASES[case]())
    with contextlib.suppress(TumblecalError):  # refused when opened: neither path runs
        same(path)


def test_the_fast_path_takes_plain_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The cases it is for are spliced, not handed back (else the test above proves little)."""
    taken = spliced_blocks(monkeypatch)
    for case in ["plain", "crlf", "preamble", "semicolons", "decimal commas", "interleaved rows", "every scale"]:
        taken.clear()
        same(write(tmp_path / "c.csv", CASES[case]()))
        assert taken, case
        assert all(taken), case


@pytest.mark.slow
def test_a_plain_block_after_a_bad_one_is_spliced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Files bigger than a block: a comment in one block hands that block back, not the file;
    an error far into the file names its line, as the general path does."""
    body = lines(table(120_000))
    body[60_000] = "# paused"
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(body) + "\n")
    taken = spliced_blocks(monkeypatch)
    out, error = same(path)
    assert error is None
    assert out.count(b"\n") == 120_000
    assert len(taken) > 3
    assert taken.count(False) == 1
    body[60_000] = "60,0.5,oops,0.5"
    body[100_000] = "# again"
    path = write(tmp_path / "c.csv", "t,ax,ay,az\n" + "\n".join(body) + "\n")
    _, error = same(path)
    assert error == f"{path}: not a number: 'oops' (line 60002, column ay)"


def test_several_sensors_in_one_pass(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two triplets, one after the other, or apart: each corrected by its own calibration."""
    values = table(2000)
    rows = "\n".join(f"{i},{a:.6f},{b:.6f},{c:.6f},{c:.4f},{b:.4f},{a:.4f}" for i, (a, b, c) in enumerate(values))
    taken = spliced_blocks(monkeypatch)
    same(write(tmp_path / "c.csv", "t,ax,ay,az,gx,gy,gz\n" + rows + "\n"), more=1)
    rows = "\n".join(f"{a:.6f},{c:.4f},{b:.6f},{b:.4f},{c:.6f},{a:.4f},{i}" for i, (a, b, c) in enumerate(values))
    same(write(tmp_path / "c.csv", "ax,gx,ay,gy,az,gz,t\n" + rows + "\n"), more=1)
    assert taken == [True, True]


def test_a_line_longer_than_a_block(tmp_path: Path) -> None:
    text = "t,ax,ay,az,note\n1,0.5,0.5,0.5,ok\n2,0.5,0.5,0.5," + "n" * (capture.BLOCK_BYTES + 10) + "\n"
    out, _ = same(write(tmp_path / "c.csv", text))
    assert len(out) > capture.BLOCK_BYTES


def test_dropped_last_line(tmp_path: Path) -> None:
    text = "t,ax,ay,az\n" + "\n".join(lines(table(100))) + "\n101,0.5"
    same(write(tmp_path / "c.csv", text), dialect=Dialect(drop_incomplete=True))


def test_orjson_spells_as_pyarrow_where_it_is_used() -> None:
    """The range where orjson writes floats is where both spell them alike."""
    assert splice._orjson_agrees()


@pytest.mark.slow
def test_memory_is_bounded_by_the_block_whatever_the_columns(tmp_path: Path) -> None:
    """A 3 MB capture of 100,000 columns corrects in the memory of any small file (the general
    reader once took 1.25 GB for it)."""
    cal = tmp_path / "cal.json"
    subprocess.run(
        [sys.executable, "-m", "tumblecal_cli", "solve", "-q", "--poses", *POSES_3, "-o", str(cal)], check=True
    )
    width = 100_000
    header = ",".join(["ax", "ay", "az", *(f"c{i}" for i in range(width - 3))])
    row = ",".join(["0.5", "0.25", "1.0", *("1" for _ in range(width - 3))])
    wide = write(tmp_path / "wide.csv", header + "\n" + (row + "\n") * 10)  # 3 MB
    small = write(tmp_path / "small.csv", "ax,ay,az\n0.5,0.25,1.0\n")
    peaks = {}
    for path in (wide, small):
        argv = ["apply", "-q", "--cal", str(cal), str(path), "-o", f"{path}.out"]
        with subprocess.Popen([sys.executable, "-m", "tumblecal_cli", *argv]) as proc:
            _, status, usage = os.wait4(proc.pid, 0)  # the child's own peak, not the test's
            proc.returncode = os.waitstatus_to_exitcode(status)
        assert proc.returncode == 0
        peaks[path.name] = usage.ru_maxrss / 1024  # MiB
    assert peaks["wide.csv"] < peaks["small.csv"] + 150, peaks
    assert (tmp_path / "wide.csv.out").read_bytes().count(b"\n") == 11


@pytest.mark.slow
def test_apply_with_several_calibrations_writes_the_general_paths_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``tumblecal apply --cal acc.json --cal gyro.json`` (the pipeline the command calls): the
    spliced output is the general path's, on an IMU log with a comment line in its preamble."""
    import functools
    import json

    from tumblecal_cli.pipeline.apply import correct

    cal = tmp_path / "acc.json"
    subprocess.run(
        [sys.executable, "-m", "tumblecal_cli", "solve", "-q", "--poses", *POSES_3, "-o", str(cal)], check=True
    )
    gyro = json.loads(cal.read_text())
    gyro["columns"], gyro["sensor"] = ["gx", "gy", "gz"], "gyroscope"
    (tmp_path / "gyro.json").write_text(json.dumps(gyro))
    values = table(3000)
    rows = "\r\n".join(f"{i},{a:.6f},{b:.6f},{c:.6f},{c:.3f},{a:.3f},{b:.3f}" for i, (a, b, c) in enumerate(values))
    log = write(tmp_path / "imu.csv", "# imu 7\r\nt,ax,ay,az,gx,gy,gz\r\n" + rows + "\r\n")
    cals = [str(cal), str(tmp_path / "gyro.json")]
    taken = spliced_blocks(monkeypatch)
    fast = correct(str(log), cals, output=str(tmp_path / "fast.csv"))
    assert taken == [True]
    monkeypatch.setattr(rewrite, "correct_stream", functools.partial(rewrite.correct_stream, splice=False))
    general = correct(str(log), cals, output=str(tmp_path / "general.csv"))
    assert fast.rows == general.rows == 3000
    assert fast.columns == general.columns == ["ax", "ay", "az", "gx", "gy", "gz"]
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "general.csv").read_bytes()


def _warm(raw: arrays.FloatArray, temperature: arrays.FloatArray) -> arrays.FloatArray:
    """A correction that depends on each row's temperature, as a thermal block's does."""
    return model.apply(raw, OFFSET, MATRIX) + 1e-4 * (temperature[:, None] - 25.0)


def thermal_corrected(path: str, *, splice_on: bool) -> tuple[bytes, str | None]:
    out = io.BytesIO()
    try:
        with open_capture(path) as cap:
            assert cap.layout.per_row_column is not None
            rewrite.correct_stream(cap, out, _warm, temperature=cap.layout.per_row_column, splice=splice_on)
    except TumblecalError as err:
        return out.getvalue(), str(err)
    return out.getvalue(), None


@pytest.mark.parametrize(
    ("case", "text"),
    [
        (
            "temperature after",
            "t,ax,ay,az,temp\n" + "".join(f"{i},0.5,0.25,1.0{i % 7},{20 + i / 100:.2f}\n" for i in range(3000)),
        ),
        (
            "temperature before",
            "temp,ax,ay,az\n" + "".join(f"{20 + i / 100:.2f},0.5,0.2{i % 9},1.0\n" for i in range(3000)),
        ),
        (
            "interleaved rows",
            "t,temp,ax,ay,az\n" + "".join(f"{i},,,,\n{i},{20 + i / 50:.2f},0.5,0.25,1.0\n" for i in range(1500)),
        ),
        ("a row without its temperature", "t,temp,ax,ay,az\n1,21.5,0.5,0.25,1\n2,,0.5,0.25,1\n"),
        ("a temperature that is text", "t,temp,ax,ay,az\n1,21.5,0.5,0.25,1\n2,warm,0.5,0.25,1\n"),
    ],
)
def test_a_thermal_correction_spliced_writes_the_general_paths_bytes(case: str, text: str, tmp_path: Path) -> None:
    """Each row's temperature reaches the correction on the fast path as on the general one;
    a row the fast path cannot take (no temperature, text) is the general path's error."""
    path = str(write(tmp_path / "c.csv", text))
    fast, general = thermal_corrected(path, splice_on=True), thermal_corrected(path, splice_on=False)
    assert fast == general, case
    assert (fast[1] is not None) == case.startswith("a "), fast[1]

"""Helpers shared by the test modules: running ``tumblecal`` (in-process or as the installed
script) and probing what a fresh interpreter imports, the sample data's paths, reading in small
blocks, the checks of a run's output (one error line, a PNG's size, the "a failed run leaves
the output alone" check), writing a test's input files, and the unit folders that ``batch``
reads. Test modules import them with ``from tests.conftest import ...`` (``small_blocks`` is a
fixture); a helper that two modules need lives here, once.

Slow tests carry ``@pytest.mark.slow`` (a whole module: ``pytestmark``): the Dask cluster, the
real-data logs, the Monte Carlo benchmark and scatter checks, subprocesses (the installed script,
pools, signals, gcc, the docs' shell sessions), PNG rendering, and the slowest tests (over about
0.25 s on a 2-core machine). ``pytest -m "not slow"`` (``make check``) is the fast
tier, under 30 s; ``pytest`` (``make test``) runs everything.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import struct
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, NamedTuple, overload

import numpy as np
import pytest
from hypothesis import settings
from numpy.typing import NDArray

from tumblecal_cli.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data"
IMUCAL = SAMPLE / "imucal"
BAD = Path(__file__).resolve().parent / "data" / "bad"
POSES_3 = [str(SAMPLE / "x.csv"), str(SAMPLE / "y.csv"), str(SAMPLE / "z.csv")]
SIX_FACES = ("xp", "xn", "yp", "yn", "zp", "zn")
PRECIOUS = b"an existing output that a failed run must leave alone\n"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


# -- Hypothesis: the same examples on every CI run, a failing one printed whole -------------------

#: ``ci``: each test's examples follow from the test itself (derandomize), with no example
#: database, so a CI run is repeated exactly by the next. ``dev`` (the default): random
#: examples, as Hypothesis finds more with them. Both print a failing example's
#: ``@reproduce_failure`` blob, which replays it exactly. HYPOTHESIS_PROFILE picks one (CI set:
#: ``ci``). Set before the test modules import, so their ``@settings`` inherit it.
settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") else "dev"))


# -- running tumblecal ----------------------------------------------------------------------


class Result(NamedTuple):
    """One run's exit status, stdout and stderr (unpacks as ``code, out, err``)."""

    code: int
    out: str
    err: str


def run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> Result:
    """``tumblecal ARGS`` in-process."""
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return Result(code, captured.out, captured.err)


def tumblecal(*args: str | Path) -> Result:
    """``tumblecal ARGS`` in-process, stdout and stderr captured (also outside pytest)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return Result(code, out.getvalue(), err.getvalue())


def tumblecal_exe() -> str:
    """The console script of the interpreter running the tests."""
    beside = Path(sys.executable).parent / "tumblecal"
    found = str(beside) if beside.exists() else shutil.which("tumblecal")
    assert found, "the tumblecal console script is not installed"
    return found


@overload
def run_exe(
    args: Sequence[str | Path],
    stdin: bytes = b"",
    cwd: Path | None = None,
    *,
    text: Literal[False] = False,
    env: Mapping[str, str] | None = None,
    timeout: float = 60,
) -> subprocess.CompletedProcess[bytes]: ...


@overload
def run_exe(
    args: Sequence[str | Path],
    stdin: str = "",
    cwd: Path | None = None,
    *,
    text: Literal[True],
    env: Mapping[str, str] | None = None,
    timeout: float = 60,
) -> subprocess.CompletedProcess[str]: ...


def run_exe(
    args: Sequence[str | Path],
    stdin: bytes | str | None = None,
    cwd: Path | None = None,
    *,
    text: bool = False,
    env: Mapping[str, str] | None = None,
    timeout: float = 60,
) -> subprocess.CompletedProcess[bytes] | subprocess.CompletedProcess[str]:
    """``tumblecal ARGS`` as the installed script, in a subprocess: ``stdin`` its whole input
    (never this process's), its output captured as bytes (``text``: as str), and its environment
    this process's with NO_COLOR and ``env`` added."""
    return subprocess.run(
        [tumblecal_exe(), *map(str, args)],
        input=stdin if stdin is not None else ("" if text else b""),
        capture_output=True,
        text=text,
        cwd=cwd,
        env={**os.environ, "NO_COLOR": "1", **(env or {})},
        timeout=timeout,
        check=False,
    )


PROBE = """
import json, sys
{body}
print(json.dumps(sorted(m for m in {watch!r} if m in sys.modules)))
"""


def imported(body: str, watch: tuple[str, ...]) -> list[str]:
    """Which of ``watch`` are in ``sys.modules`` after running ``body`` in a fresh Python (what
    the test process has already imported hides nothing)."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(body=body, watch=watch)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr
    found: list[str] = json.loads(done.stdout.splitlines()[-1])
    return found


def feed_stdin(monkeypatch: pytest.MonkeyPatch, data: bytes) -> None:
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))


# -- reading in small blocks ---------------------------------------------------------------


@pytest.fixture
def small_blocks(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """Files read in blocks of the test module's ``BLOCK`` bytes (``capture.BLOCK_BYTES``): a
    small file is many blocks, so the readers cross every kind of seam between two."""
    from tumblecal_cli.io.csv import capture

    monkeypatch.setattr(capture, "BLOCK_BYTES", request.module.BLOCK)


def spliced_blocks(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Records, per block, whether apply's fast path (``io.csv.splice``) took it (the general path
    never asks)."""
    from tumblecal_cli.io.csv import splice

    taken: list[bool] = []
    block = splice.Splicer.block

    def spy(self: splice.Splicer, buf: bytes) -> object:
        done = block(self, buf)
        taken.append(done is not None)
        return done

    monkeypatch.setattr(splice.Splicer, "block", spy)
    return taken


# -- a run's memory: its peak, or a bound on its address space --------------------------------

#: Runs the command given after it and prints its peak resident memory (KiB on Linux): a fresh
#: process each time, so the children's peak is that command's alone.
PEAK = (
    "import resource, subprocess, sys; "
    "done = subprocess.run(sys.argv[1:], capture_output=True, check=False); "
    "print(done.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)
#: The address space a command run by :func:`limited` may take (make fuzz's too): a reader that
#: allocates by a declared count is stopped well before the machine is.
LIMIT = 3 << 30


def peak_rss(*args: str | Path) -> int:
    """Peak resident bytes of ``tumblecal ARGS`` in a fresh process (which must exit 0)."""
    command = [sys.executable, "-c", PEAK, sys.executable, "-m", "tumblecal_cli", *map(str, args)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=900, check=True)
    code, peak = done.stdout.split()
    assert code == "0", done.stdout
    return int(peak) * 1024


def limited(*args: str | Path, timeout: float = 60) -> Result:
    """``tumblecal ARGS`` in a subprocess whose address space is ``LIMIT`` (from the project's
    root), stopped after ``timeout`` seconds."""
    import resource

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))

    done = subprocess.run(
        [sys.executable, "-m", "tumblecal_cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=cap,
        cwd=ROOT,
        env={**os.environ, "NO_COLOR": "1"},
        check=False,
    )
    return Result(done.returncode, done.stdout, done.stderr)


def still_pose(path: Path, rows: int) -> Path:
    """A still +z pose at 1 kHz: t,ax,ay,az, noise 2 mg, written by pyarrow (millions of rows
    in seconds)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(5)
    path.write_text("t,ax,ay,az\n")
    with path.open("ab") as f:
        for start in range(0, rows, 1_000_000):
            k = min(1_000_000, rows - start)
            v = 0.02 + 0.002 * rng.standard_normal((k, 3))
            v[:, 2] += 1.0
            cols = [pa.array(np.arange(start, start + k) / 1000.0)]
            cols += [pa.array(np.round(v[:, j], 6)).cast(pa.decimal128(9, 6), safe=False) for j in range(3)]
            table = pa.table(cols, names=["t", "ax", "ay", "az"])
            pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    return path


# -- checking a run -------------------------------------------------------------------------


def assert_one_error(
    result: Result, expected: str, *, code: int = 2, hint: str | None = None, json_out: bool = False
) -> None:
    """Exit ``code``, nothing on stdout, and on stderr exactly ``error: <expected>`` (plus a hint).
    ``json_out`` (the command had --json): stdout is the error object saying the same instead."""
    assert result.code == code, result.err
    if json_out:
        doc = json.loads(result.out)
        assert (doc["status"], doc["exit_status"]) == ({2: "error", 3: "rejected"}[code], code)
        error = doc["error"]
        assert expected.startswith((f"{error['file']}: " if error["file"] else "") + error["message"])
        assert error["hint"] == next((ln[6:] for ln in result.err.splitlines() if ln.startswith("hint: ")), None)
    else:
        assert result.out == ""
    assert "Traceback" not in result.err
    lines = result.err.splitlines()
    assert [ln for ln in lines if ln.startswith("error:")] == [f"error: {expected}"]
    other = [ln for ln in lines if not ln.startswith(("error:", "hint:"))]
    assert other == [], "only the error line and its hint go to stderr"
    hints = [ln for ln in lines if ln.startswith("hint:")]
    if hint is not None:
        assert len(hints) == 1
        assert hint in hints[0]


def assert_usage_error(result: Result, *words: str, reported_first: bool = False) -> None:
    """Exit 2, nothing on stdout, no traceback, exactly one ``error:`` line holding every word,
    and on stderr nothing else but a hint (``reported_first``: the command's report too, which
    it wrote before it stopped, as segment's table of blocks)."""
    assert result.code == 2, result.err
    assert result.out == ""
    assert "Traceback" not in result.err
    lines = result.err.splitlines()
    errors = [ln for ln in lines if ln.startswith("error:")]
    assert len(errors) == 1, result.err
    assert reported_first or all(ln.startswith(("error:", "hint:")) for ln in lines), result.err
    for word in words:
        assert word in errors[0], errors[0]


def png_size(data: bytes) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk, after checking the signature."""
    assert data[:8] == PNG_SIGNATURE
    length, kind = struct.unpack(">I4s", data[8:16])
    assert (length, kind) == (13, b"IHDR")
    width, height = struct.unpack(">II", data[16:24])
    return int(width), int(height)


def precious(path: Path) -> Path:
    path.write_bytes(PRECIOUS)
    return path


def assert_untouched(path: Path) -> None:
    assert path.read_bytes() == PRECIOUS
    leftovers = [p.name for p in path.parent.iterdir() if p.name.startswith(f".{path.name}.")]
    assert leftovers == [], "no temporary file is left behind"


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# -- building inputs ------------------------------------------------------------------------


def write(
    path: Path,
    content: str | bytes | Mapping[str, Any] | NDArray[Any],
    *,
    header: str = "t,x,y,z",
    fmt: str | Sequence[str] = "%.6f",
) -> Path:
    """``content`` into ``path`` (its folder made if need be), and ``path``: text (as UTF-8) and
    bytes byte for byte, a mapping as JSON, and a table of numbers as CSV: ``header``, then each
    row in ``fmt`` (one format for every column, or one per column) joined by commas. A table's
    bytes are those ``numpy.savetxt`` writes, formatted in one go rather than row by row."""
    if isinstance(content, np.ndarray):
        formats = [fmt] * content.shape[1] if isinstance(fmt, str) else list(fmt)
        row = ",".join(formats) + "\n"
        content = header + "\n" + (row * len(content)) % tuple(content.ravel().tolist())
    elif isinstance(content, Mapping):
        content = json.dumps(content)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


def unit(root: Path, serial: str, kind: str) -> Path:
    """A unit folder ``root/serial`` of one kind:

    good (x y z of the sample set: passes), six (imucal's six faces in counts: passes without
    limits, fails any limit in g), rejected (x.csv given as y: pose.orientation, exit 3),
    error (z is a header without data: exit 2).
    """
    folder = root / serial
    folder.mkdir(parents=True)
    if kind == "six":
        for face in SIX_FACES:
            shutil.copy(IMUCAL / f"{face}.csv", folder / f"{face}.csv")
        return folder
    for name in "xyz":
        shutil.copy(SAMPLE / f"{name}.csv", folder / f"{name}.csv")
    if kind == "rejected":
        shutil.copy(SAMPLE / "x.csv", folder / "y.csv")
    elif kind == "error":
        (folder / "z.csv").write_text("t,ax,ay,az\n")
    else:
        assert kind == "good", kind
    return folder


def unnamed(files: Sequence[str | Path], folder: Path) -> list[Path]:
    """Copies of pose files, in the same order, under names that give no face (pose1.csv ...):
    their place in --poses gives their faces, as for any unlabelled files not named for one."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k, f in enumerate(files, start=1):
        out.append(folder / f"pose{k}.csv")
        shutil.copy(f, out[-1])
    return out


def with_registered(setup: str, *args: str | Path, columns: str | None = "100") -> subprocess.CompletedProcess[str]:
    """``tumblecal ARGS`` in a fresh Python that runs ``setup`` first (a stand-in's registration:
    tests/standin_*.py), then the console script's own entry point: a registration made in the
    test process is not seen by a new one. ``columns``: the terminal's width (None: not set)."""
    code = f"import sys; sys.argv[0] = 'tumblecal'; {setup}; from tumblecal_cli.cli.app import main_exit; main_exit()"
    return subprocess.run(
        [sys.executable, "-c", code, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={**os.environ, "NO_COLOR": "1", **({"COLUMNS": columns} if columns else {})},
        timeout=120,
        check=False,
    )

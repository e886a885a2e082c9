"""Mutation fuzzing of every reader (``make fuzz``; not part of ``make test``).

Each case takes one of the project's own good files (a pose capture, a calibration in JSON and
in YAML, a limits file, a peer's calibration), mutates it with a seeded random generator (bytes
flipped, inserted or cut, lines duplicated or dropped, cells replaced by huge, empty, non-finite
or non-UTF-8 text, control characters, the file truncated), and runs the commands that read that
kind of file in-process. The binary logs (ULog, DataFlash binary and text, ROS 1 bags with lz4 and
bz2 chunks, MCAP with zstd chunks) and compressed CSV are mutated by their framing as well
(tests/fuzz_binary.py: declared counts, lengths and offsets, definitions given twice, compression
claims, chunks that inflate to gigabytes). Every case runs in a worker process under an
address-space limit (``LIMIT``, 3 GiB) and a time limit (``TIMEOUT``): a reader that allocates
what a file declares, or inflates without a bound, is a failure, not a machine that swaps. It
passes when every run ends in a documented exit status (0, 1, 2, 3)
with no internal error, no traceback, every error on one line, and an existing output either left
byte for byte (exit 2 or 3) or replaced whole. A failing case is written to ``fuzz-failures/``
with the command that broke, for a test of its own.

    python tests/fuzz.py [--cases 3000] [--seed 1] [--only log.ulg]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import resource
import select
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data"
sys.path.insert(0, str(ROOT))  # (run as a script: the tests' writers are imported as tests.*)
#: Each case's worker: its address space (bytes) and the seconds a case may take.
LIMIT = 3 << 30
TIMEOUT = 60.0
#: A case whose worker's peak resident memory passes this read more than a small log holds (the
#: worker is then started afresh, as the peak only grows).
CEILING = 1 << 30

#: Cells worth trying in a CSV or a JSON/YAML number's place.
NASTY = [
    "",
    "nan",
    "inf",
    "-inf",
    "1e400",
    "1e200",
    "-0",
    "9" * 400,
    "0x10",
    "1,5",
    '"',
    "#",
    "\x00",
    "\u2028",
    "\x0b",
    "é",
    "*a",
    "&a [1]",
    "!!python/object:os.system",
    "[[[[",
    "{",
    '=HYPERLINK("http://x")',
    "+x",
    "@SUM(1)",
    "\uff1d1+1",
    "99",
    "banana",
    "../../../../etc/passwd",
    "/etc/passwd",
    "!!binary aGk=",
    "!!set {a}",
    "!!timestamp 2024-05-01",
    "1:00",
    "0042",
    "\\udc00",
    '"offset": [1e9, 1e9, 1e9], ',
]


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One to three random edits of ``data``."""
    for _ in range(rng.randint(1, 3)):
        kind = rng.randrange(7)
        if not data:
            return rng.choice(NASTY).encode()
        at = rng.randrange(len(data))
        if kind == 0:  # flip a byte
            data = data[:at] + bytes([rng.randrange(256)]) + data[at + 1 :]
        elif kind == 1:  # insert a nasty token
            data = data[:at] + rng.choice(NASTY).encode("utf-8", "surrogatepass") + data[at:]
        elif kind == 2:  # cut a span
            data = data[:at] + data[at + rng.randint(1, 64) :]
        elif kind == 3:  # truncate
            data = data[:at]
        elif kind == 4:  # duplicate or drop a line
            lines = data.split(b"\n")
            k = rng.randrange(len(lines))
            lines[k : k + 1] = [] if rng.random() < 0.5 else [lines[k], lines[k]]
            data = b"\n".join(lines)
        elif kind == 5:  # a cell of a CSV row becomes nasty
            lines = data.split(b"\n")
            k = rng.randrange(len(lines))
            cells = lines[k].split(b",")
            cells[rng.randrange(len(cells))] = rng.choice(NASTY).encode()
            lines[k] = b",".join(cells)
            data = b"\n".join(lines)
        else:  # line ends
            data = data.replace(b"\n", rng.choice([b"\r\n", b"\r", b"\n\n"]))
    return data


def seeds(folder: Path) -> dict[str, tuple[bytes, list[list[str]]]]:
    """The good files by kind, and the commands that read each (``{f}``: the mutated file,
    ``{cal}``: a good calibration, ``{out}``: an existing output)."""
    from tumblecal_cli.cli import main

    cal = folder / "good.json"
    with contextlib.redirect_stderr(io.StringIO()):
        assert main(["solve", "--poses", *(str(SAMPLE / f"{a}.csv") for a in "xyz"), "-o", str(cal)]) == 0
        assert main(["export", str(cal), "--format", "ros-yaml", "-o", str(folder / "ros.yaml")]) == 0
    yaml_text = cal.read_text()  # JSON is YAML too; a .yaml name makes the YAML reader take it
    capture = ["apply", "--cal", "{cal}", "{f}", "-o", "{out}"]
    return {
        "pose.csv": ((SAMPLE / "x.csv").read_bytes(), [["solve", "--poses", "{f}", "-o", "{out}"], capture]),
        # a long pose file, summed as it is read (io.csv.posefile): here past SUMMED_ROWS at 64 rows
        LONG_POSE: (
            (SAMPLE / "x.csv").read_bytes(),
            [
                ["solve", "--poses", "{f}", "-o", "{out}"],
                ["solve", "--poses", "{f}", str(SAMPLE / "y.csv"), str(SAMPLE / "z.csv"), "-o", "{out}"],
                ["verify", "--cal", "{cal}", "{f}"],
            ],
        ),
        "capture.csv": ((SAMPLE / "capture.csv").read_bytes()[:4000], [capture, ["verify", "--cal", "{cal}", "{f}"]]),
        "cal.json": (
            cal.read_bytes(),
            [
                ["show", "{f}"],
                ["show", "--json", "{f}"],
                ["check", "{f}", "--max-offset", "1"],
                ["export", "{f}", "--format", "c-header"],
                ["export", "{f}", "--format", "imucal-json"],
            ],
        ),
        "cal.yaml": (
            yaml_text.encode(),
            [["show", "{f}"], ["show", "--json", "{f}"], ["apply", "--cal", "{f}", str(SAMPLE / "x.csv")]],
        ),
        "limits.yaml": ((SAMPLE / "limits.yaml").read_bytes(), [["check", "{cal}", "--limits", "{f}"]]),
        "ros.yaml": ((folder / "ros.yaml").read_bytes(), [["import", "{f}", "-o", "{out}"]]),
        "log.csv": (_tumble_log(), [["segment", "{f}"], ["solve", "--log", "{f}", "-o", "{out}"]]),
        **{name: (data, LOG_COMMANDS) for name, data in _binary_seeds(folder).items()},
        "cals/summary.csv": (
            _summary(folder),
            [["batch", str(folder / "units"), "-d", str(folder / "cals"), "--resume"]],
        ),
    }


def _summary(folder: Path) -> bytes:
    """A batch's summary.csv (units A, B and C of the sample poses, C's +x and +y swapped: a
    rejected unit), in ``folder/cals`` beside the calibrations it names: --resume reads it back."""
    import shutil

    from tumblecal_cli.cli import main

    for serial, (x, y) in {"A": ("x", "y"), "B": ("x", "y"), "C": ("y", "x")}.items():
        unit = folder / "units" / serial
        unit.mkdir(parents=True)
        for face, name in (("x", x), ("y", y), ("z", "z")):
            shutil.copy(SAMPLE / f"{name}.csv", unit / f"{face}.csv")
    with contextlib.redirect_stderr(io.StringIO()):
        assert main(["batch", str(folder / "units"), "-d", str(folder / "cals"), "-q"]) == 3
    return (folder / "cals" / "summary.csv").read_bytes()


def _tumble_log() -> bytes:
    """A session at 100 Hz rested on each of six faces for 2 s, turned between (45 kB)."""
    import numpy as np

    rng = np.random.default_rng(11)
    faces = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    rows = []
    for k, face in enumerate(faces):
        turn = np.linspace(faces[k - 1], face, 50) + rng.normal(0, 0.2, (50, 3)) if k else np.zeros((0, 3))
        rows += [turn, face + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.002, (200, 3))]
    xyz = np.vstack(rows)
    t = np.arange(len(xyz)) / 100.0
    lines = [f"{a:.2f},{x:.5f},{y:.5f},{z:.5f}" for a, (x, y, z) in zip(t, xyz.tolist(), strict=True)]
    return ("t,x,y,z\n" + "\n".join(lines) + "\n").encode()


#: What reads a log of any format.
LOG_COMMANDS = [
    ["logs", "{f}"],
    ["segment", "{f}"],
    ["solve", "--log", "{f}", "-o", "{out}"],
    ["noise", "{f}"],
]


def _binary_seeds(folder: Path) -> dict[str, bytes]:
    """A good log of each binary format (and the tumble log compressed), by its file name."""
    from tests import fuzz_binary

    ulog = fuzz_binary.ulog_seed()
    binary, text = fuzz_binary.dataflash_seed(folder)
    return {
        "log.ulg": ulog,
        "log.bin": binary,
        "log.log": text,
        **fuzz_binary.ros_seeds(folder),
        **fuzz_binary.compressed_seeds(_tumble_log()),
    }


def mutated(name: str, data: bytes, rng: random.Random) -> bytes:
    """``data`` of kind ``name`` mutated: a binary kind by its framing four times in five, else (and
    every text kind) by the byte and line edits of :func:`mutate`."""
    from tests import fuzz_binary

    framed = {
        ".ulg": fuzz_binary.ulog_mutate,
        ".bin": fuzz_binary.dataflash_mutate,
        ".log": fuzz_binary.dataflash_text_mutate,
        ".bag": fuzz_binary.bag_mutate,
        ".mcap": fuzz_binary.mcap_mutate,
        ".gz": fuzz_binary.compressed_mutate,
        ".bz2": fuzz_binary.compressed_mutate,
        ".xz": fuzz_binary.compressed_mutate,
        ".zst": fuzz_binary.compressed_mutate,
    }.get(Path(name).suffix)
    if framed is not None and rng.random() < 0.8:
        return framed(data, rng)
    return mutate(data, rng)


#: The kind whose pose files are read as long ones: summed in blocks of a few rows.
LONG_POSE = "long_pose.csv"


def one(folder: Path, name: str, data: bytes, command: list[str]) -> str | None:
    """Run one case; what is wrong with it, or None."""
    from unittest import mock

    from tumblecal_cli.cli import main
    from tumblecal_cli.io.csv import capture as reader
    from tumblecal_cli.io.csv import posefile

    if name == LONG_POSE:
        with mock.patch.object(posefile, "SUMMED_ROWS", 64), mock.patch.object(reader, "BLOCK_BYTES", 2048):
            return _one(folder, name, data, command, main)
    return _one(folder, name, data, command, main)


def _one(folder: Path, name: str, data: bytes, command: list[str], main: Callable[[list[str]], int]) -> str | None:

    target = folder / name  # (cals/summary.csv: in the batch's folder)
    target.write_bytes(data)
    out = folder / "out.txt"
    out.write_bytes(b"precious\n")
    args = [
        a.replace("{f}", str(target)).replace("{cal}", str(folder / "good.json")).replace("{out}", str(out))
        for a in command
    ]
    err, stdout = io.StringIO(), io.TextIOWrapper(io.BytesIO())  # stdout has a .buffer, as a real one
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(stdout):
        try:
            code = main(args)
        except BaseException as crash:
            return f"escaped the error boundary: {type(crash).__name__}: {crash}"
    text = err.getvalue()
    if code not in (0, 1, 2, 3):
        return f"exit {code}"
    if "internal error" in text or "Traceback" in text or "MemoryError" in text:
        return text.strip().splitlines()[0]
    errors = [line for line in text.splitlines() if line.startswith("error:")]
    # a batch's status is its units' (a rejected unit kept from the summary is 3): its own error
    # line is needed only for a 2 no unit's "A: error: ..." line explains
    units = command[0] == "batch" and (code != 2 or any(": error:" in line for line in text.splitlines()))
    if code in (2, 3) and not errors and not units:
        return f"exit {code} with no error line"
    if code in (2, 3) and out.read_bytes() != b"precious\n":
        return f"exit {code} but the output was changed"
    leftovers = [p.name for p in folder.iterdir() if p.name.startswith(".") and p.name.endswith(".tmp")]
    if leftovers:
        return f"temporary files left: {leftovers}"
    return None


class Worker:
    """A process that runs cases (``fuzz.py --worker FOLDER``) under the address-space limit, one
    at a time: a case is a line on its stdin, its verdict a line on file descriptor 3. One that
    dies or takes over TIMEOUT is the case's failure, and is started again."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.proc: subprocess.Popen[bytes] | None = None

    def _start(self) -> None:
        read, write = os.pipe()
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--worker", str(self.folder)],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(write,),
            preexec_fn=_limited,
            env={**os.environ, "TUMBLECAL_FUZZ_FD": str(write), "PYTHONPATH": str(ROOT)},
        )
        os.close(write)
        self.replies = os.fdopen(read, "rb")

    def run(self, name: str, data: bytes, command: list[str]) -> str | None:
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        assert self.proc is not None
        assert self.proc.stdin is not None
        case = self.folder / "case.bin"
        case.write_bytes(data)
        self.proc.stdin.write(json.dumps({"name": name, "command": command}).encode() + b"\n")
        self.proc.stdin.flush()
        began = time.monotonic()
        ready, _, _ = select.select([self.replies], [], [], TIMEOUT)
        line = self.replies.readline() if ready else b""
        if line:
            reply = json.loads(line)
            wrong: str | None = reply["wrong"]
            if wrong is None and reply["rss"] > CEILING:
                self.stop()
                wrong = f"peak memory {reply['rss'] >> 20} MiB, over {CEILING >> 20} MiB"
            return wrong
        took = time.monotonic() - began
        self.stop()
        if not ready:
            return f"took over {TIMEOUT:g} s (killed)"
        return (
            f"the worker died after {took:.1f} s (exit {self.proc.returncode}: out of memory under {LIMIT >> 30} GiB?)"
        )

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.replies.close()
            self.proc = None


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def worker(folder: Path) -> int:
    """The worker's loop: each case line run in-process, its verdict written back."""
    out = os.fdopen(int(os.environ["TUMBLECAL_FUZZ_FD"]), "w")
    for line in sys.stdin:
        case = json.loads(line)
        data = (folder / "case.bin").read_bytes()
        wrong = one(folder, case["name"], data, case["command"])
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # (KiB on Linux)
        out.write(json.dumps({"wrong": wrong, "rss": rss}) + "\n")
        out.flush()
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--only", action="append", help="only the kinds named (log.ulg, pose.csv, ...)")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    given = parser.parse_args()
    if given.worker is not None:
        return worker(given.worker)
    rng = random.Random(given.seed)
    failures = 0
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="tumblecal-fuzz-") as tmp:
        folder = Path(tmp)
        kinds = seeds(folder)
        names = sorted(n for n in kinds if not given.only or n in given.only)
        runner = Worker(folder)
        try:
            for case in range(given.cases):
                name = names[case % len(names)]
                good, commands = kinds[name]
                data = mutated(name, good, rng)
                command = rng.choice(commands)
                wrong = runner.run(name, data, command)
                if wrong is not None:
                    failures += 1
                    keep = ROOT / "fuzz-failures"
                    keep.mkdir(exist_ok=True)
                    (keep / f"case{case:05d}-{name.replace('/', '-')}").write_bytes(data)
                    print(f"case {case} ({name}, {' '.join(command)}): {wrong}", flush=True)
        finally:
            runner.stop()
    took = time.monotonic() - started
    print(f"{given.cases} cases, seed {given.seed}: {failures} failed, {took:.0f} s")
    shutil.rmtree(ROOT / "fuzz-failures", ignore_errors=True) if not failures else None
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

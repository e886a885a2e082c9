"""apply's blocks corrected by forked worker processes, one per core, each writing its own.

A big regular file's blocks are corrected by ``io.csv.splice``, and threads do not share that
work out: orjson, which spells the corrected floats, holds the GIL for a third of it, and a
thread waiting for the GIL holds back the others (measured on 2 cores: two threads 1.25x
faster than one, not 2x). Processes share nothing. So:

- this process cuts the file into blocks of whole lines (reading a few KiB at each cut, not
  the file) and forks ``workers`` processes; worker i takes blocks i, i + workers, ...
- a worker reads its block from the file, corrects it, waits for its turn (a byte from the
  worker before it, around a ring of pipes), writes the bytes to the output itself, passes the
  turn on, and tells this process the block's rows;
- this process reads those reports in block order. A worker's error (an ``InputError`` naming
  the line, a broken pipe) comes back pickled in its block's turn, when every block before it
  is written and none after it can be: the workers are then killed, and the error goes on.

A worker is a ``fork`` of this process: it has the calibration, the splicer and every module
already. It never returns into the caller's code: it ends with ``os._exit``. Linux only
(``fork`` is unsafe on macOS); elsewhere, for files under ``MIN_BYTES``, for an output without
a file descriptor, for a line too long to find the cuts, and in a process that runs threads of
its own (a Dask worker: a fork copies their locks as they are), the caller's threads do the work.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import signal
import struct
import sys
import threading
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING

from tumblecal_cli.errors import STOPS

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

#: Below this much data a file is corrected in this process (forking costs ~10 ms a worker).
MIN_BYTES = 16 << 20
#: Most worker processes, whatever the number of cores.
MAX_WORKERS = 8

_REPORT = struct.Struct("<qqq")  # failed (0/1), rows, bytes of the pickled error that follow

#: A block's bytes and offset -> its corrected bytes, in pieces, and its rows.
Render = Callable[[bytes, int], tuple[Sequence[bytes | memoryview], int]]


def workers_for(path: str | None, size: int) -> int:
    """How many worker processes to correct ``size`` bytes of the file ``path`` with: 0 for
    this process alone (a small file, a stream, one core, not Linux)."""
    if path is None or size < MIN_BYTES or not sys.platform.startswith("linux") or not hasattr(os, "fork"):
        return 0
    if threading.active_count() > 1:  # a process with threads of its own (a Dask worker): no fork
        return 0
    cores = len(os.sched_getaffinity(0))
    return min(cores, MAX_WORKERS) if cores > 1 else 0


class Parts(io.RawIOBase):
    """A sink that keeps what is written to it (a worker's corrected block, in pieces). A file
    object, so that pyarrow's CSV writer takes it too."""

    def __init__(self) -> None:
        super().__init__()
        self.parts: list[bytes | memoryview] = []

    def writable(self) -> bool:
        return True

    def write(self, data: ReadableBuffer) -> int:
        self.parts.append(data if isinstance(data, bytes | memoryview) else bytes(data))
        return len(self.parts[-1])


def pipeline(
    path: str,
    blocks: list[tuple[int, int]],
    render: Render,
    out: IO[bytes],
    head: bytes,
    workers: int,
    written: Callable[[], object],
) -> int:
    """Correct ``blocks`` of ``path`` (``cuts``) with ``render(block, at)`` -> (the bytes in
    pieces, rows) on ``workers`` processes, written to ``out`` in order after ``head`` (with
    the first block: an error in it leaves ``out`` untouched). ``written()`` is called once the
    first block is out. Returns the rows written; raises a worker's error in its turn."""
    out.flush()  # what is buffered here goes before the workers' bytes, and is not copied into them
    sys.stdout.flush()
    sys.stderr.flush()
    pool = _Pool(workers)
    try:
        for i in range(workers):
            pool.start(i, _serve(i, workers, path, blocks, render, out.fileno(), head))
        rows = 0
        for k in range(len(blocks)):
            rows += pool.report(k % workers)
            if k == 0:
                written()
    except BaseException:
        pool.close(kill=True)
        raise
    pool.close(kill=False)
    return rows


class _Pool:
    """The workers, their reports' pipes, and the ring of pipes that passes the turn to write."""

    def __init__(self, workers: int) -> None:
        self.pids: list[int] = []
        self.reports: list[int] = []
        self.header = bytearray(_REPORT.size)
        self.ring = [os.pipe() for _ in range(workers)]  # ring[i]: worker i -> worker i + 1

    def start(self, i: int, serve: Callable[[int, int, int], None]) -> None:
        # a stop that lands in fork() is raised in its at-fork hooks, where Python drops it (the
        # run went on to exit 0): held until the worker is on the books, then acted on. The mask
        # is read first (a stop can be raised by the call that blocks): whatever stops this, the
        # caller's mask is put back and the pipes closed
        held = signal.pthread_sigmask(signal.SIG_BLOCK, ())
        report_r = report_w = -1
        try:
            report_r, report_w = os.pipe()
            signal.pthread_sigmask(signal.SIG_BLOCK, STOPS)
            pid = os.fork()
        except BaseException:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
            for fd in (report_r, report_w):
                if fd >= 0:
                    os.close(fd)
            raise
        if pid == 0:  # the worker: it never returns from here
            status = 1
            try:
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C and a hang-up are the parent's
                signal.signal(signal.SIGHUP, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
                turn_r, turn_w = self.ring[i - 1][0], self.ring[i][1]
                for fd in (*self.reports, report_r, *(end for pair in self.ring for end in pair)):
                    if fd not in (turn_r, turn_w):
                        os.close(fd)
                serve(turn_r, turn_w, report_w)
                status = 0
            finally:
                os._exit(status)
        os.close(report_w)
        self.pids.append(pid)
        self.reports.append(report_r)
        signal.pthread_sigmask(signal.SIG_SETMASK, held)  # a stop meanwhile: raised here, the worker known

    def report(self, worker: int) -> int:
        """The rows of ``worker``'s next block, written; its error raised."""
        fd = self.reports[worker]
        try:
            failed, rows, size = _REPORT.unpack(_read_exact(fd, _REPORT.size, self.header))
            data = _read_exact(fd, size, bytearray(size)) if failed else None
        except EOFError:
            raise RuntimeError("a worker process of apply ended without its block (killed?)") from None
        if data is not None:
            raise pickle.loads(data)
        return int(rows)

    def close(self, *, kill: bool) -> None:
        """Stop the workers and reap them: at the end of the file they have left; after an
        error (``kill``) some wait for a turn that never comes, and are killed."""
        for fd in (*self.reports, *(end for pair in self.ring for end in pair)):
            os.close(fd)
        for pid in self.pids:
            if kill:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)
        self.pids, self.reports, self.ring = [], [], []


def _serve(
    i: int,
    workers: int,
    path: str,
    blocks: list[tuple[int, int]],
    render: Render,
    out: int,
    head: bytes,
) -> Callable[[int, int, int], None]:
    def serve(turn_r: int, turn_w: int, report: int) -> None:
        fd = os.open(path, os.O_RDONLY)
        token = bytearray(1)
        for k in range(i, len(blocks), workers):
            at, size = blocks[k]
            try:
                parts, rows = render(_pread_exact(fd, size, at), at)
                if k:
                    _read_exact(turn_r, 1, token)
                _write_all(out, [head, *parts] if k == 0 else parts)
            except Exception as err:  # the parent raises it in its turn (an InputError names the line)
                error = _pickled(err)
                _write_all(report, [_REPORT.pack(1, 0, len(error)), error])
                return
            _write_all(turn_w, [b"."])
            _write_all(report, [_REPORT.pack(0, rows, 0)])

    return serve


def _pickled(err: Exception) -> bytes:
    try:
        return pickle.dumps(err)
    except Exception:  # an error that does not pickle: its type and message
        return pickle.dumps(RuntimeError(f"{type(err).__name__}: {err}"))


def _read_exact(fd: int, size: int, buffer: bytearray) -> memoryview:
    view = memoryview(buffer)[:size]
    got = 0
    while got < size:
        n = os.readv(fd, [view[got:]])
        if n == 0:
            raise EOFError
        got += n
    return view


def _pread_exact(fd: int, size: int, at: int) -> bytes:
    data = os.pread(fd, size, at)
    while len(data) < size:  # a regular file gives it all at once, but not by contract
        more = os.pread(fd, size - len(data), at + len(data))
        if not more:
            raise OSError(f"the file ended at byte {at + len(data)} (was it changed while read?)")
        data += more
    return data


def _write_all(fd: int, parts: Sequence[bytes | memoryview]) -> None:
    for part in parts:
        view = memoryview(part).cast("B")
        while view.nbytes:
            view = view[os.write(fd, view) :]

"""Where many independent pieces of work run: here, in worker processes, or on a Dask cluster.

``batch`` runs its units through an :data:`Engine`, and ``apply --out-dir`` its captures. Nothing
heavy is imported until an engine runs: ``distributed`` only when a scheduler is given.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import multiprocessing.util
import os
import re
import shutil
import stat
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import forkserver
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Protocol, TypeVar, TypeVarTuple

from tumblecal_cli.errors import InputError
from tumblecal_cli.io.outputs import alive

if TYPE_CHECKING:
    from concurrent.futures import Future

#: Pieces submitted to a Dask cluster at a time (a million-unit lot is not a million futures).
IN_FLIGHT = 1000
#: Seconds to wait for a Dask worker, at the start and whenever no piece finishes.
WORKERS_TIMEOUT = 10.0

Result = TypeVar("Result")
Args = TypeVarTuple("Args")  # the arguments of one call


class Engine(Protocol):
    """Runs ``fn(*args)`` for each args of ``work``; yields (args, result) as they finish. On a
    cluster the result may be the exception that lost the piece (a worker gone)."""

    def __call__(
        self, fn: Callable[[*Args], Result], work: Sequence[tuple[*Args]], /
    ) -> Iterator[tuple[tuple[*Args], Result | Exception]]: ...


def engine(jobs: int, scheduler: str | None) -> Engine:
    """Where the work runs: here (jobs 1), in ``jobs`` processes, or on the Dask cluster at
    ``scheduler`` (connected to at once)."""
    if scheduler is not None:
        return _dask(scheduler)
    if jobs > 1:
        return _processes(jobs)
    return _here


def _here(
    fn: Callable[[*Args], Result], work: Sequence[tuple[*Args]], /
) -> Iterator[tuple[tuple[*Args], Result | Exception]]:
    return ((args, fn(*args)) for args in work)


def _processes(jobs: int) -> Engine:
    def run(
        fn: Callable[[*Args], Result], work: Sequence[tuple[*Args]], /
    ) -> Iterator[tuple[tuple[*Args], Result | Exception]]:

        context = multiprocessing.get_context("forkserver")  # safe beside the progress bar's thread
        context.set_forkserver_preload(
            [
                __name__,
                "tumblecal_cli.pipeline.solve.solving",
                "tumblecal_cli.io.csv.readings",
                "tumblecal_cli.core.solvers",
            ]
        )
        _pool_folder()
        # this process's end, as the workers see it: the pipe's writing end closes with it, however
        # it ends (a kill -9 too), and whether or not its caller has reaped it yet
        gone, here = context.Pipe(duplex=False)
        sent: dict[Future[Result], tuple[*Args]] = {}
        try:
            with ProcessPoolExecutor(
                max_workers=jobs, mp_context=context, initializer=_watch_parent, initargs=(gone,)
            ) as pool:
                try:
                    for args in work:  # keep a few pieces in flight per worker, not the whole lot
                        sent[pool.submit(fn, *args)] = args
                        if len(sent) >= 4 * jobs:
                            done, _ = wait(sent, return_when=FIRST_COMPLETED)
                            yield from ((sent.pop(f), f.result()) for f in done)
                    while sent:
                        done, _ = wait(sent, return_when=FIRST_COMPLETED)
                        yield from ((sent.pop(f), f.result()) for f in done)
                except BaseException:  # the pieces running finish (milliseconds), the others are dropped
                    pool.shutdown(wait=True, cancel_futures=True)
                    raise
        finally:  # the workers have exited: none is told to go
            here.close()
            gone.close()

    return run


def _watch_parent(gone: Connection[object, object]) -> None:
    """In a worker process: hold none of the caller's pipes, and exit when the process that
    started the pool is gone (killed with -9, it cannot shut its pool down), instead of living
    on with the units in flight.

    A check of its pid would not do: a process killed while its caller reads its output to the
    end before reaping it (``subprocess.run(capture_output=True)``) is a zombie, which a signal 0
    still finds, and the caller would wait for the pipes this worker holds, for ever. The end of
    the pipe ``gone`` reads is the process's own: it closes when the process ends."""
    _hold_no_pipes()

    def watch() -> None:
        with contextlib.suppress(EOFError, OSError):
            while True:  # nothing is ever sent: this returns at the end of the pipe
                gone.recv_bytes()
        os._exit(1)

    threading.Thread(target=watch, name="tumblecal-parent-watch", daemon=True).start()


def _hold_no_pipes() -> None:
    """This process's stdin, stdout and stderr onto /dev/null: a helper process of the pool holds
    none of the caller's pipes, which a caller reads until every holder has closed them."""
    null = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        if fd != null:
            os.dup2(null, fd)
    if null > 2:
        os.close(null)


def _in_fork_server() -> bool:
    """Whether this module is being imported by multiprocessing's fork server, as its preload:
    the server's own code is on the stack."""
    frame = sys._getframe()
    while frame is not None:
        if frame.f_code is forkserver.main.__code__:
            return True
        frame = frame.f_back  # type: ignore[assignment]
    return False


if _in_fork_server():  # the fork server outlives a killed pool as long as its workers do: it holds no pipe either
    _hold_no_pipes()


#: The file that marks a multiprocessing folder (``pymp-*`` in $TMPDIR, where the fork server's
#: socket is) as a tumblecal pool's: the pid of the process whose pool it is.
POOL_MARK = re.compile(r"tumblecal-(\d+)")


def _pool_folder() -> None:
    """Mark this process's multiprocessing folder as a tumblecal pool's, and remove the ones of
    pools whose process is gone (:func:`remove_stale_pools`)."""
    mine = multiprocessing.util.get_temp_dir()
    with contextlib.suppress(OSError), open(os.path.join(mine, f"tumblecal-{os.getpid()}"), "a"):
        pass
    remove_stale_pools(os.path.dirname(mine))


def remove_stale_pools(folder: str) -> list[str]:
    """Remove the multiprocessing folders (``pymp-*``) in ``folder`` that pools of processes now
    gone left (killed with -9, a process cannot remove its own): only this user's, marked as a
    tumblecal pool's, none of a process still running, none of another program's. The names removed."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.listdir(folder):
            path = os.path.join(folder, entry)
            if not entry.startswith("pymp-"):
                continue
            with contextlib.suppress(OSError):
                found = os.lstat(path)
                if not stat.S_ISDIR(found.st_mode) or found.st_uid != os.getuid():
                    continue
                pids = [int(m.group(1)) for m in map(POOL_MARK.fullmatch, os.listdir(path)) if m is not None]
                if pids and not any(pid == os.getpid() or alive(pid) for pid in pids):
                    shutil.rmtree(path)
                    removed.append(entry)
    return removed


def _dask(address: str) -> Engine:
    try:
        import distributed
    except ImportError:
        raise InputError(
            "--dask-scheduler needs Dask's distributed scheduler, which is not installed",
            hint="pip install 'tumblecal[dask]'",
        ) from None

    try:  # at once: an unreachable cluster is an error before anything is written
        client = distributed.Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as err:
        raise InputError(
            f"cannot reach the Dask scheduler at {address}: {err}",
            hint="start one with 'dask scheduler', or check the address (tcp://host:8786)",
        ) from None

    try:  # a scheduler without workers would take the units and never run them
        client.wait_for_workers(1, timeout=WORKERS_TIMEOUT)
    except (OSError, TimeoutError) as err:
        client.close()
        raise InputError(
            f"the Dask scheduler at {address} has no workers ({err})",
            hint="start some: dask worker ADDRESS --nworkers N --nthreads 1 (with tumblecal installed there)",
        ) from None

    def run(
        fn: Callable[[*Args], Result], work: Sequence[tuple[*Args]], /
    ) -> Iterator[tuple[tuple[*Args], Result | Exception]]:
        with client:
            todo = iter(work)  # a bounded number in flight: the scheduler spreads them over the workers
            sent = {}  # distributed.Future (untyped: the optional extra is read as Any) -> its args
            for args in itertools.islice(todo, IN_FLIGHT):
                sent[client.submit(fn, *args, pure=False)] = args
            while sent:
                try:
                    done, _ = distributed.wait(list(sent), timeout=WORKERS_TIMEOUT, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    if not client.nthreads():  # every worker gone (one that cannot import tumblecal exits)
                        raise InputError(
                            f"every Dask worker at {address} is gone, with {len(sent)} units unfinished",
                            hint="check the workers' logs (tumblecal installed there?); "
                            "--resume continues the lot once workers are back",
                        ) from None
                    continue  # long units: still running
                for future in done:
                    args = sent.pop(future)
                    result: Result | Exception
                    try:  # a lost worker (KilledWorker), tumblecal missing there: that piece's error
                        result = future.result()
                    except Exception as err:
                        result = err
                    yield args, result
                    future.release()
                    for more in itertools.islice(todo, 1):
                        sent[client.submit(fn, *more, pure=False)] = more

    return run

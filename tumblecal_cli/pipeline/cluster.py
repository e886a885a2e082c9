"""Where many independent pieces of work run: here, in worker processes, or on a Dask cluster.

``batch`` runs its units through an :data:`Engine`, and ``apply --out-dir`` its captures. Nothing
heavy is imported until an engine runs: ``distributed`` only when a scheduler is given.
"""

from __future__ import annotations

import itertools
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
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
            ["tumblecal_cli.pipeline.solve", "tumblecal_cli.io.readings", "tumblecal_cli.core.solvers"]
        )
        sent: dict[Future[Result], tuple[*Args]] = {}
        with ProcessPoolExecutor(
            max_workers=jobs, mp_context=context, initializer=_watch_parent, initargs=(os.getpid(),)
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

    return run


def _watch_parent(parent: int) -> None:
    """In a worker process: exit when the batch that started it is gone (killed with -9, it
    cannot shut its pool down), instead of living on with the units in flight."""

    def watch() -> None:
        while alive(parent):
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="tumblecal-parent-watch", daemon=True).start()


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

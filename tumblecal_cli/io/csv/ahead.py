"""Work on a stream's next blocks while its last one is used: ``ahead`` runs an iterator on a
thread of its own, a few items ahead of its consumer.

pyarrow's CSV reader and casts, numpy's loops over large arrays and file reads let go of
Python's lock, so a capture's next block is parsed on one core while the last one is summed on
the other (``noise``: 10M rows parsed and summed at once, not one after the other)."""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Generator, Iterator
from typing import TypeVar, cast

T = TypeVar("T")

#: How long the consumer's clean-up waits between checks that the producer has stopped (s).
POLL = 0.05


def ahead(items: Iterator[T], depth: int = 2) -> Generator[T, None, None]:
    """The items of ``items``, in order, made on a thread of their own up to ``depth`` ahead. An
    exception it raises is raised here, in its place in the order; when the consumer stops early
    (an error of its own, a break) the producer stops too, before this generator is closed, so
    that whatever ``items`` reads from may be closed after it."""
    found: queue.Queue[tuple[bool, T | BaseException | None]] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                while not stop.is_set():
                    try:
                        found.put((True, item), timeout=POLL)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            found.put((False, None))
        except BaseException as err:  # raised in the consumer's thread, in order
            found.put((False, err))
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()

    thread = threading.Thread(target=produce, name="tumblecal-ahead", daemon=True)
    thread.start()
    try:
        while True:
            more, item = found.get()
            if not more:
                if isinstance(item, BaseException):
                    raise item
                return
            yield cast(T, item)
    finally:
        stop.set()
        while thread.is_alive():  # let a producer waiting on a full queue see the stop
            with contextlib.suppress(queue.Empty):
                found.get(timeout=POLL)
        thread.join()

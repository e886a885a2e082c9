"""io.csv.ahead: an iterator run on a thread of its own, a few items ahead of its consumer."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from tumblecal_cli.errors import InputError
from tumblecal_cli.io.csv.ahead import ahead


def test_items_come_in_order_and_an_error_in_its_place() -> None:
    def blocks() -> Iterator[int]:
        yield from range(5)
        raise InputError("not a number: 'x'", file="capture.csv", line=7)

    seen: list[int] = []
    with pytest.raises(InputError, match="not a number") as err:
        seen.extend(ahead(blocks(), depth=2))
    assert seen == [0, 1, 2, 3, 4]  # every block before the bad one was used first
    assert err.value.line == 7


def test_a_consumer_that_stops_stops_the_producer_before_it_returns() -> None:
    closed = threading.Event()
    made = []

    def blocks() -> Iterator[int]:
        try:
            for k in range(1_000_000):
                made.append(k)
                yield k
        finally:
            closed.set()

    items = ahead(blocks(), depth=2)
    for item in items:
        if item == 3:
            break
    items.close()  # (a for loop's break leaves it to the garbage collector)
    assert closed.is_set()  # the source may be closed now: nothing reads it any more
    assert len(made) <= 3 + 1 + 2 + 1  # no more than depth ahead of the consumer
    assert not any(t.name == "tumblecal-ahead" for t in threading.enumerate())

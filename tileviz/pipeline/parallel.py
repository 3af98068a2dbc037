"""A generic helper for work done ahead in an executor, delivered in order."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from typing import TypeVar

__all__ = ["results_in_order"]

T = TypeVar("T")
R = TypeVar("R")


def results_in_order(items: Iterator[T], submit: Callable[[T], Future[R]],
                     window: int) -> Iterator[tuple[T, R]]:
    """``(item, result)`` for every item of ``items`` in order, the work of up to ``window``
    items submitted ahead (``submit`` hands one to an executor). An error raised by ``items``
    (a bad row) is raised after every earlier item was delivered; an item's own error when its
    turn comes. Work not yet taken is cancelled when the caller stops early."""
    pending: deque[tuple[T, Future[R]]] = deque()
    error: Exception | None = None
    try:
        while True:
            while error is None and len(pending) < window:
                try:
                    item = next(items)
                except StopIteration:
                    break
                except Exception as e:  # noqa: BLE001 - raised at its turn, below
                    error = e
                    break
                pending.append((item, submit(item)))
            if not pending:
                break
            item, fut = pending.popleft()
            yield item, fut.result()
    finally:
        for _, fut in pending:
            fut.cancel()
    if error is not None:
        raise error

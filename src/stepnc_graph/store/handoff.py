"""A bounded hand-off from one producer thread to worker threads that cannot deadlock.

The store's loaders feed text to threads that write it (Oxigraph's bulk loaders, the kept
texts' compressor). A queue with one end-of-input marker per worker deadlocked when a worker
failed: on a full disk (ENOSPC in its last bulk-load call, after it had taken its own marker),
the failing worker waited for a second marker that never came, and the producer waited for it in
``join`` forever, holding the store's writer lock. Here nothing is shared but the items: the
producer *closes* the hand-off when it has put everything, anyone may *abort* it (a worker's
error, the producer's), and every wait -- a full hand-off for the producer, an empty one for a
worker -- ends at once when it is closed or aborted. So a failure anywhere stops every thread,
and the caller joins them and raises the first error.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")


class Handoff(Generic[T]):
    """At most ``size`` items in flight between a producer and its workers (see the module docstring)."""

    def __init__(self, size: int) -> None:
        self._items: deque[T] = deque()
        self._size = max(1, size)
        self._changed = threading.Condition()
        self._closed = False
        self._aborted = False

    def put(self, item: T) -> bool:
        """Hand ``item`` over, waiting while the hand-off is full; False (and ``item`` dropped) once
        it is aborted: the producer then stops."""
        with self._changed:
            while len(self._items) >= self._size and not self._aborted:
                self._changed.wait()
            if self._aborted:
                return False
            self._items.append(item)
            self._changed.notify_all()
            return True

    def get(self) -> T | None:
        """The next item, waiting while there is none; None once the hand-off is closed and empty,
        or aborted: the worker then stops."""
        with self._changed:
            while not self._items and not self._closed and not self._aborted:
                self._changed.wait()
            if self._aborted or not self._items:
                return None
            item = self._items.popleft()
            self._changed.notify_all()
            return item

    def close(self) -> None:
        """No more items: workers take what is left, then stop."""
        with self._changed:
            self._closed = True
            self._changed.notify_all()

    def abort(self) -> None:
        """Stop everyone now: items not taken are dropped, waits end."""
        with self._changed:
            self._aborted = True
            self._items.clear()
            self._changed.notify_all()

    @property
    def aborted(self) -> bool:
        return self._aborted

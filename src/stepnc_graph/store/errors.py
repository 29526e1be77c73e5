"""The store's errors: a directory that cannot be used, a write its files refused, a busy writer."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING


from stepnc_graph.core.errors import StepncGraphError

if TYPE_CHECKING:
    from stepnc_graph.store.locks import Writer


class StoreError(StepncGraphError):
    """A store directory that cannot be used (not a store, newer format, missing, not writable)."""


class StoreWriteError(StoreError, OSError):
    """A write that the store's own files refused (a full disk, a read-only one), rolled back: a
    :class:`StoreError` that names the store, and still the ``OSError`` it was (``errno``)."""


class StoreBusy(StoreError):
    """Another process is writing to the store."""

    def __init__(self, path: Path, writer: Writer) -> None:
        super().__init__(f"{path} is being written by {writer}; try again when it is done, or wait for it "
                         f"(--wait)")
        self.writer = writer

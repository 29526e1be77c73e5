"""The store's process locks: one writer (``write.lock``), readers on the generation they read
(``gNNNNNN.lock``); ``flock``, so the kernel releases them when a process dies."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from stepnc_graph.store.errors import StoreBusy



LOCK_POLL = 0.2


@dataclass(frozen=True)
class Writer:
    """Who holds a store's writer lock, as it wrote it in ``write.lock``."""

    pid: int | None
    command: str
    since: str

    def __str__(self) -> str:
        who = f"pid {self.pid}" if self.pid else "another process"
        return f"{who}{': ' + self.command if self.command else ''}{', since ' + self.since if self.since else ''}"


class Locks:
    """The store's file locks (``flock``: released by the kernel when a process dies)."""

    @staticmethod
    def try_lock(path: Path, shared: bool) -> int | None:
        """An open descriptor holding the lock on ``path``, or None if it is held elsewhere.

        A reader of a store it cannot write (a read-only file system: an archived store; or no
        write permission) opens the lock file read-only, which ``flock`` allows. On a read-only
        file system no writer can delete a generation, so when even the lock file is missing
        a shared lock on the store directory stands for it."""
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            if not shared or e.errno not in (errno.EROFS, errno.EACCES, errno.EPERM):
                raise
            try:
                fd = os.open(path, os.O_RDONLY)
            except FileNotFoundError:
                if e.errno != errno.EROFS:
                    raise
                fd = os.open(path.parent, os.O_RDONLY)
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        return fd

    @staticmethod
    def release(fd: int | None) -> None:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)


def command_line() -> str:

    name = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
    return " ".join([name, *sys.argv[1:]])[:200]


def writer_of(store: Path) -> Writer:
    """Who holds the writer's lock of the store in ``store``, as it wrote it (empty when unreadable)."""
    try:
        info = json.loads((store / "write.lock").read_text() or "{}")
    except (OSError, ValueError):
        info = {}
    return Writer(info.get("pid"), info.get("command", ""), info.get("since", ""))


def lock_writer(store: Path, wait: bool | float, on_wait: Callable[[Writer], None] | None) -> int:
    """The writer's lock of the store in ``store`` (its descriptor, with this process named in
    ``write.lock``), or :class:`StoreBusy` when another process holds it (after ``wait``: True,
    or seconds; ``on_wait(writer)`` is called once before waiting)."""
    lock = store / "write.lock"
    fd = Locks.try_lock(lock, shared=False)
    if fd is None:
        if not wait:
            raise StoreBusy(store, writer_of(store))
        if on_wait is not None:
            on_wait(writer_of(store))
        deadline = None if wait is True else time.monotonic() + float(wait)
        while fd is None:
            if deadline is not None and time.monotonic() > deadline:
                raise StoreBusy(store, writer_of(store))
            time.sleep(LOCK_POLL)
            fd = Locks.try_lock(lock, shared=False)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({"pid": os.getpid(), "command": command_line(),
                                  "since": time.strftime("%Y-%m-%d %H:%M:%S")}).encode(), 0)
    except BaseException:
        Locks.release(fd)
        raise
    return fd

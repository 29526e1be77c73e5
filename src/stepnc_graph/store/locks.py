"""The store's process locks: one writer (``write.lock``), readers on the generation they read
(``gNNNNNN.lock``); ``flock``, so the kernel releases them when a process dies."""

from __future__ import annotations

import errno
import fcntl
import os
import sys
from dataclasses import dataclass
from pathlib import Path



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

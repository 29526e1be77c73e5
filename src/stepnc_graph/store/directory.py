"""The store directory and its generations: the marker and its format, the ``CURRENT`` pointer,
publishing ``work/`` as the next generation, recovering ``work/`` from the published one, deleting
generations no reader holds, and migrating a format-1 store (the layout is in :mod:`stepnc_graph.store`).

These are functions of the directory, not of an open store: the writer calls them with its lock
held (:class:`~stepnc_graph.store.embedded.GraphStore`), so no two processes run them at once.
"""

from __future__ import annotations

import errno
import gc
import json
import os
import shutil
from pathlib import Path

import pyoxigraph as ox

from stepnc_graph.store.errors import StoreError
from stepnc_graph.store.files import FORMAT_VERSION, MARKER, clone_checkpoint, fsync_dir
from stepnc_graph.store.locks import Locks


def check_directory(path: Path, create: bool) -> None:
    """Refuse ``path`` unless it is a store of a format this version reads (a newer one, a
    directory holding something else), or create it as an empty store when ``create``."""
    marker = path / MARKER
    if not path.exists():
        if not create:
            raise StoreError(f"no store at {path} (`stepnc-graph load` creates one)")
        try:
            path.mkdir(parents=True)
        except OSError as e:
            raise StoreError(f"cannot create the store directory {path}: {e.strerror or e}") from None
    elif not path.is_dir():
        raise StoreError(f"{path} is not a directory")
    if marker.exists():
        try:
            version = json.loads(marker.read_text()).get("format", 0)
        except (OSError, ValueError) as e:
            raise StoreError(f"{marker}: unreadable store marker ({e})") from None
        if version > FORMAT_VERSION:
            raise StoreError(f"{path}: store format {version} is newer than this stepnc-graph supports")
    elif any(path.iterdir()):
        raise StoreError(f"{path} is not empty and is not a stepnc-graph store")
    elif not create:
        raise StoreError(f"no store at {path} (`stepnc-graph load` creates one)")
    else:
        try:
            marker.write_text(json.dumps({"format": FORMAT_VERSION}) + "\n")
        except OSError as e:
            raise StoreError(f"cannot write to the store directory {path}: {e.strerror or e}") from None


def open_error(path: Path, e: OSError) -> StoreError:
    """An error opening the store in ``path``, said as the user can act on it."""
    if e.errno == errno.EROFS:
        return StoreError(f"cannot write to the store in {path}: it is on a read-only file system (info, "
                          "export, query and validate can still read it)")
    return StoreError(f"cannot open the store in {path}: {e.strerror or e}")


def current(path: Path) -> str | None:
    """The published generation named in ``CURRENT`` (None: the store is new)."""
    try:
        return (path / "CURRENT").read_text().strip() or None
    except FileNotFoundError:
        return None


def publish(path: Path, db: ox.Store) -> str:
    """Checkpoint ``db`` (the writer's ``work/``) as the next generation, name it in ``CURRENT``
    (an atomic rename) and return its name."""
    now = current(path)
    number = int(now[1:]) + 1 if now else 1
    name = f"g{number:06d}"
    tmp = path / (name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    db.flush()
    db.backup(str(tmp))
    tmp.rename(path / name)
    (path / (name + ".lock")).touch()
    pointer = path / "CURRENT.tmp"
    pointer.write_text(name + "\n")
    with open(pointer, "rb+") as fh:
        os.fsync(fh.fileno())
    os.replace(pointer, path / "CURRENT")
    fsync_dir(path)
    (path / "work.generation").write_text(name)
    (path / "work.dirty").unlink(missing_ok=True)
    return name


def recover(path: Path) -> None:
    """Make ``work/`` the published generation again unless it is known to be it."""
    now = current(path)
    assert now is not None
    work, dirty, stamp = path / "work", path / "work.dirty", path / "work.generation"
    clean = work.is_dir() and not dirty.exists() and stamp.exists() and stamp.read_text().strip() == now
    if clean:
        return
    shutil.rmtree(work, ignore_errors=True)
    shutil.rmtree(path / "rebuild", ignore_errors=True)
    shutil.rmtree(path / "difference", ignore_errors=True)
    clone_checkpoint(path / now, work)
    stamp.write_text(now)
    dirty.unlink(missing_ok=True)


def collect(path: Path) -> None:
    """Delete generations no reader holds, except the current one."""
    now = current(path)
    for entry in path.iterdir():
        name = entry.name
        if name.endswith(".tmp") and entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
            continue
        if not (name.startswith("g") and name[1:].isdigit() and entry.is_dir()) or name == now:
            continue
        fd = Locks.try_lock(path / (name + ".lock"), shared=False)
        if fd is None:
            continue  # a reader still reads it; a later writer deletes it
        try:
            shutil.rmtree(entry, ignore_errors=True)
            (path / (name + ".lock")).unlink(missing_ok=True)
        finally:
            Locks.release(fd)


def migrate_format1(path: Path) -> str | None:
    """A format-1 store (``oxigraph/``, ``journal/``): roll back an interrupted load, then adopt
    the database as ``work/`` and publish it. Returns the generation published (None: not a
    format-1 store)."""
    old = path / "oxigraph"
    if not old.exists():
        return None
    journal = path / "journal"
    if (journal / "loading").exists() and (journal / "checkpoint").exists():
        shutil.rmtree(old)
        (journal / "checkpoint").rename(old)
    shutil.rmtree(journal, ignore_errors=True)
    shutil.rmtree(path / "work", ignore_errors=True)
    old.rename(path / "work")
    db = ox.Store(str(path / "work"))
    name = publish(path, db)
    (path / MARKER).write_text(json.dumps({"format": FORMAT_VERSION}) + "\n")
    db.flush()
    del db
    gc.collect()  # pyoxigraph releases the database (and its RocksDB lock) when collected
    return name

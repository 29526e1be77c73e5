"""The store directory's format: its names, where it is by default, checkpoints cloned by hard
links, and its size on disk (see the layout in :mod:`stepnc_graph.store`)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path



STORE_ENV = "STEPNC_GRAPH_STORE"


DEFAULT_STORE = ".stepnc-graph"


FORMAT_VERSION = 2


MARKER = "stepnc-graph-store.json"


#: the file in a store directory that counts the quads deleted since ``work/`` was last compacted
DELETED_QUADS = "deleted-quads"


def default_store_path() -> Path:
    return Path(os.environ.get(STORE_ENV) or DEFAULT_STORE)


def fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def clone_checkpoint(source: Path, target: Path) -> None:
    """A writable copy of an Oxigraph checkpoint: SST files hard-linked (RocksDB never
    changes one in place), the small bookkeeping files copied."""
    target.mkdir()
    for f in source.iterdir():
        if f.suffix == ".sst":
            os.link(f, target / f.name)
        else:
            shutil.copy2(f, target / f.name)


def directory_bytes(path: Path) -> int:
    """Bytes the files under ``path`` take on disk, a file hard-linked into several places (the
    store's generations share their SST files) counted once."""
    seen: dict[tuple[int, int], int] = {}
    for root, _dirs, files in os.walk(path):
        for name in files:
            try:
                st = os.stat(os.path.join(root, name))
            except FileNotFoundError:  # a generation collected meanwhile
                continue
            seen[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return sum(seen.values())

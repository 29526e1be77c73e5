"""Where the project's data directories are, installed or in a source tree.

The wheel carries ``ontology/``, ``shapes/`` and ``queries/`` under
``stepnc_graph/data/``; an editable install or a checkout finds them at the
repository root. ``STEPNC_GRAPH_DATA`` overrides both (a directory holding the
three folders).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent.parent  # this file is stepnc_graph/core/resources.py
_CANDIDATES = (_PACKAGE / "data", _PACKAGE.parent.parent)


def data_root() -> Path:
    override = os.environ.get("STEPNC_GRAPH_DATA")
    if override:
        return Path(override)
    for candidate in _CANDIDATES:
        if (candidate / "ontology" / "express" / "schemas.toml").is_file():
            return candidate
    raise FileNotFoundError(
        "stepnc-graph data (ontology/express/schemas.toml) not found; reinstall the package "
        "or set STEPNC_GRAPH_DATA to a directory containing ontology/, shapes/ and queries/"
    )


def ontology_dir() -> Path:
    return data_root() / "ontology"


def express_dir() -> Path:
    return ontology_dir() / "express"


def shapes_dir() -> Path:
    return data_root() / "shapes"


def queries_dir() -> Path:
    return data_root() / "queries"


def reference_html() -> Path:
    """The generated HTML reference of the vocabulary (``docs/ontology.html``; in the wheel under
    ``stepnc_graph/data/docs/``)."""
    return data_root() / "docs" / "ontology.html"


def sources_digest(files: Iterable[tuple[str, bytes]]) -> str:
    """SHA-256 over source files (relative name and content, in the order given) that a generated
    file was built from: the digest a compiled file records to tell when it is stale.

    Line ends are normalised to LF first, so a checkout that converts them does not make a
    shipped file stale.
    """
    h = hashlib.sha256()
    for name, data in files:
        content = data.replace(b"\r\n", b"\n")
        h.update(f"{name}\0{len(content)}\0".encode())
        h.update(content)
    return h.hexdigest()

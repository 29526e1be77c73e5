"""Shared fixtures. Tests that need ../shared skip cleanly when it is absent."""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = Path(__file__).resolve().parent / "fixtures"
SHARED = ROOT.parent / "shared"
sys.path.insert(0, str(ROOT / "bench"))  # the program generator and the Oxigraph server helper


@pytest.fixture(scope="session")
def shared() -> Path:
    if not (SHARED / "reference").is_dir():
        pytest.skip("../shared reference material is not present")
    return SHARED


@pytest.fixture(scope="session")
def iso_model():  # type: ignore[no-untyped-def]
    from stepnc_graph.schema.catalog import iso14649

    return iso14649()


def bounded(seconds: int) -> Iterator[None]:
    """Fail (instead of hanging CI) when the test runs longer than ``seconds``."""

    def expired(*_: object) -> None:
        raise TimeoutError(f"took longer than {seconds} s: a hang")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


_GENERATED: dict[str, dict[str, str]] = {}


def _inputs_digest(express_directory: Path) -> str:
    """Every input :func:`stepnc_graph.artefacts.build.generate` reads under a root, by content: the
    EXPRESS and its catalogue, the other editions beside them, the query library, the process shapes."""
    import hashlib

    root = express_directory.parent.parent
    digest = hashlib.sha256()
    for directory, pattern in ((express_directory, "*"), (express_directory.parent / "editions", "**/*"),
                               (root / "queries", "*.rq"), (root / "shapes" / "process", "*.ttl")):
        for path in sorted(directory.glob(pattern)):
            if path.is_file():
                digest.update(f"{path.relative_to(root)}\0".encode() + path.read_bytes() + b"\0")
    return digest.hexdigest()


@pytest.fixture
def generate_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """``generate`` (every artefact, ~6 CPU-s) run once per set of inputs in a test session: the
    build and staleness tests build the same inputs over and over, and only what they change
    (an edited EXPRESS file, a process shape added) needs a fresh generation. The files are
    compared and written by the real ``build``; only the generation is shared."""
    from stepnc_graph.artefacts import build

    real = build.generate

    def once(express_directory: Path | None = None) -> dict[str, str]:
        if express_directory is None:
            return real(express_directory)
        key = _inputs_digest(express_directory)
        if key not in _GENERATED:
            _GENERATED[key] = real(express_directory)
        return dict(_GENERATED[key])

    monkeypatch.setattr(build, "generate", once)


@pytest.fixture
def time_bound() -> Iterator[None]:
    yield from bounded(20)


@pytest.fixture
def process_time_bound() -> Iterator[None]:
    """For tests that drive other processes: a generous bound, still far below CI's."""
    yield from bounded(240)

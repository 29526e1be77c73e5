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


@pytest.fixture
def time_bound() -> Iterator[None]:
    yield from bounded(20)


@pytest.fixture
def process_time_bound() -> Iterator[None]:
    """For tests that drive other processes: a generous bound, still far below CI's."""
    yield from bounded(240)

"""Damaged Part 21 and JSON-LD inputs and the checks every load of one must pass.

Used by ``bench/fuzz_load.py`` (hundreds of thousands of inputs, in worker
processes with a memory limit) and by the test suite (a few hundred).

A damaged Part 21 input (:func:`mutate`) and its check (:func:`check`) are in
:mod:`.fuzz_part21`; a damaged JSON-LD input (:func:`mutate_jsonld`), its check
(:func:`check_jsonld`) and the :class:`LoopbackListener` that must receive nothing are in
:mod:`.fuzz_jsonld`. This module names them all, and describes and shrinks a failure.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from stepnc_graph.testing.fuzz_jsonld import (JSONLD_KINDS, LoopbackListener, check_jsonld, mutate_jsonld,
                                              watch_network)
from stepnc_graph.testing.fuzz_part21 import BASIC, KINDS, LAYOUT, NASTY, Outcome, _unkept_text, check, mutate

__all__ = ["BASIC", "JSONLD_KINDS", "KINDS", "LAYOUT", "NASTY", "LoopbackListener", "Outcome", "_unkept_text", "check",
           "check_jsonld", "describe_exception", "failure_class", "mutate", "mutate_jsonld", "shrink", "watch_network"]


def describe_exception(error: BaseException) -> str:
    """One line naming an unexpected exception by its type and the last function of stepnc-graph
    it went through (``ValueError from jsonld_load.parse_json``): what :func:`failure_class` counts."""
    import traceback

    frames = traceback.extract_tb(error.__traceback__)
    own = [f for f in frames if "/stepnc_graph/" in f.filename.replace("\\", "/")]
    where = own[-1] if own else frames[-1] if frames else None
    place = f" from {Path(where.filename).stem}.{where.name}" if where is not None else ""
    message = " ".join(str(error).split())[:160]
    return f"exception {type(error).__name__}{place}: {message}"


def failure_class(detail: str) -> str:
    """A short name for a failure, to count failures by kind: the broken promise (the text before
    its first ':'), or for an exception its type and place (see :func:`describe_exception`)."""
    first = detail.strip().split("\n", 1)[0]
    return re.sub(r"[0-9]+", "N", first.split(":", 1)[0])[:120] or "failed"


def shrink(data: bytes, fails: Callable[[bytes], bool], budget: int = 400) -> bytes:
    """A smaller input that still ``fails`` (delta debugging over byte chunks, at most ``budget``
    tries): for reproducers a person can read."""
    chunks = 2
    tries = 0
    while len(data) > 1 and tries < budget:
        size = max(len(data) // chunks, 1)
        for start in range(0, len(data), size):
            candidate = data[:start] + data[start + size:]
            tries += 1
            if fails(candidate):
                data = candidate
                chunks = max(chunks - 1, 2)
                break
            if tries >= budget:
                return data
        else:
            if size == 1:
                return data
            chunks = min(chunks * 2, len(data))
    return data

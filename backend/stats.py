"""Per-thread counters (a statistic, never silent): walk-cap hits, NaN samples dropped, rays.

Each work item's counters are taken by the thread that rendered it and returned with its result;
the master sums them into the render report. Thread-local, so render threads sharing one process
never take each other's counts.
"""
from __future__ import annotations

import threading
from collections import Counter

_LOCAL = threading.local()


def _counts() -> Counter:
    c = getattr(_LOCAL, "counts", None)
    if c is None:
        c = _LOCAL.counts = Counter()
    return c


def add(name: str, value: int | float = 1) -> None:
    if value:
        _counts()[name] += value


def take() -> dict:
    """Return and reset the counters of this thread."""
    c = _counts()
    out = dict(c)
    c.clear()
    return out


def merge(into: dict, other: dict) -> dict:
    for k, v in other.items():
        into[k] = into.get(k, 0) + v
    return into

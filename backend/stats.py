"""Process-wide counters (a statistic, never silent): walk-cap hits, NaN samples dropped, rays.

Workers return a snapshot with each work item; the master sums them into the render report.
"""
from __future__ import annotations

from collections import Counter

_COUNTS: Counter = Counter()


def add(name: str, value: int | float = 1) -> None:
    if value:
        _COUNTS[name] += value


def take() -> dict:
    """Return and reset the counters of this process."""
    out = dict(_COUNTS)
    _COUNTS.clear()
    return out


def merge(into: dict, other: dict) -> dict:
    for k, v in other.items():
        into[k] = into.get(k, 0) + v
    return into

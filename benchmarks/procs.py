"""Processes of a running render, read from /proc (Linux): for the worker scripts
(worker_kill, worker_memory)."""
from __future__ import annotations

import os


def children(pid: int) -> list[int]:
    """The direct child processes of ``pid`` (empty when it is gone)."""
    out = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out += [int(c) for c in f.read().split()]
    except OSError:
        pass
    return out


def tree(pid: int) -> list[int]:
    """``pid`` and all its descendants."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo += children(p)
    return out


def render_workers(pids: list[int]) -> list[int]:
    """Those of ``pids`` that are render workers (not the resource tracker multiprocessing starts)."""
    out = []
    for p in pids:
        try:
            with open(f"/proc/{p}/cmdline", "rb") as f:
                if b"resource_tracker" not in f.read():
                    out.append(p)
        except OSError:
            pass
    return out

"""What the report was measured on: CPU, cores, load, software versions, git commit."""
from __future__ import annotations

import os
import platform
import subprocess
import sys

from .scenes import REPO


def _cpuinfo() -> dict:
    info = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if ":" in line:
                    k, v = (s.strip() for s in line.split(":", 1))
                    info.setdefault(k, v)
    except OSError:
        pass
    return info


def _version(module: str) -> str:
    try:
        mod = __import__(module)
    except Exception as exc:  # noqa: BLE001 - report, never fail
        return f"not importable ({type(exc).__name__})"
    for attr in ("__version__", "VERSION"):
        v = getattr(mod, attr, None)
        if v:
            return str(v)
    try:
        from importlib.metadata import version
        return version(module)
    except Exception:  # noqa: BLE001
        return "?"


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        return "?"


def describe() -> dict:
    cpu = _cpuinfo()
    try:
        load = os.getloadavg()
    except OSError:
        load = (float("nan"),) * 3
    # The report's own outputs (rewritten by this very run) do not make the code dirty.
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", "backend", "benchmarks",
                 ":(exclude)benchmarks/report", ":(exclude)benchmarks/REPORT.md")
    return {
        "cpu": cpu.get("model name", platform.processor() or platform.machine()),
        "cpu_mhz": cpu.get("cpu MHz", "?"),
        "cores": os.cpu_count(),
        "load_at_start": [round(x, 2) for x in load],
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "embreex": _version("embreex"),
        "OpenImageIO": _version("OpenImageIO"),
        "matplotlib": _version("matplotlib"),
        "commit": _git("rev-parse", "--short", "HEAD") + (" (with uncommitted changes)" if dirty else ""),
        "branch": _git("rev-parse", "--abbrev-ref", "HEAD"),
        "executable": sys.executable,
    }


def load_now() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")

"""Which files a scene load reads, and where a cluster worker reads its copies of them.

A render on a Dask cluster (backend/cluster.py) must give the workers every file the scene
refers to — meshes, textures, IES profiles, environment maps, preset documents — without a
shared file system. Rather than teach every reader about transfers, each reader asks for its
file through :func:`local_file`, and preset names go through :func:`preset_file`:

* while a :class:`Recorder` is active (the master's load), both record what was asked for and
  change nothing;
* while a :class:`Redirect` is active (a worker's load), both return the worker's local copy of
  the file the master read under the same path (or preset name). Paths are still resolved
  against the master's folders, so the keys match and error messages name the user's files.

Without either (every ordinary render) both return their argument.
"""
from __future__ import annotations

import contextvars
import os
from pathlib import Path

_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("lamina_scene_inputs", default=None)


def local_file(path: Path) -> Path:
    """The file to read for ``path`` (resolved against the scene's folder)."""
    hook = _ACTIVE.get()
    return path if hook is None else hook.file(Path(path))


def preset_file(name: str, found: Path | None) -> Path | None:
    """The preset document for ``name``: ``found`` (this machine's library) unless a worker's
    redirect knows the master's file. Returns the path to resolve textures against; read it
    through :func:`local_file`."""
    hook = _ACTIVE.get()
    return found if hook is None else hook.preset(name, found)


class _Hook:
    def __enter__(self):
        self._token = _ACTIVE.set(self)
        return self

    def __exit__(self, *exc):
        _ACTIVE.reset(self._token)
        return False


class Recorder(_Hook):
    """Records the files (absolute path strings, in first-use order) and preset names a load
    reads. Nested loads (a preset's textures) record into the same recorder."""

    def __init__(self):
        self.files: dict[str, None] = {}
        self.presets: dict[str, str] = {}

    def file(self, path: Path) -> Path:
        self.files.setdefault(str(path), None)
        return path

    def preset(self, name: str, found: Path | None) -> Path | None:
        if found is not None:
            self.presets[name] = str(found)
        return found


class Redirect(_Hook):
    """Maps the master's paths to local copies: ``files`` {absolute master path: local path},
    ``presets`` {name: master path of its document}. Paths not in the map are read as they are
    (a shared file system, or a file the master did not read)."""

    def __init__(self, files: dict[str, str], presets: dict[str, str]):
        self.files = files
        self.presets = presets

    def file(self, path: Path) -> Path:
        local = self.files.get(os.path.abspath(path))      # as the master's keys (cluster_files)
        return Path(local) if local is not None else path

    def preset(self, name: str, found: Path | None) -> Path | None:
        master = self.presets.get(name)
        return Path(master) if master is not None else found


def record_inputs():
    """A Recorder, unless one is active already (then None: the outer load records)."""
    return Recorder() if _ACTIVE.get() is None else None

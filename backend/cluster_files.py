"""A scene's files for cluster workers: content-hashed, sent once, cached on each worker machine.

The master describes a scene by a :class:`ScenePackage`: the scene document and every file its
load read (scene/inputs.py), each named by the SHA-256 of its bytes. A worker keeps the files it
was sent in a cache folder, one file per hash, so the next frame or a re-render of the same
scene finds them there and nothing unchanged is sent again; only a changed file has a new hash.
Workers that share a cache folder (the worker processes of one machine) are sent a file once.

Cache folder (first match): ``$LAMINA_CLUSTER_CACHE``; the platform's user cache folder +
``lamina/cluster-files`` (beside the kernel cache, backend/kernels/cache.py). Files in it are
never changed once written (written to a temporary name, then renamed), so it may be deleted
whenever no render runs; it is not trimmed automatically.

With ``shared=True`` nothing is copied: the workers read the master's paths (a file system
mounted at the same paths everywhere); only the scene document travels, also by hash.
"""
from __future__ import annotations

import hashlib
import json
import os
import socket
from dataclasses import dataclass, field
from pathlib import Path

from .errors import LaminaError

CHUNK = 1 << 20          # bytes read at a time while hashing (files may be hundreds of MB)


@dataclass(frozen=True)
class ScenePackage:
    """What a worker needs to load the master's scene; small (hashes and paths, no data)."""
    key: str                      # hash of everything below: identifies the scene on a worker
    document: str                 # hash of the scene document (JSON, UTF-8)
    where: str                    # the scene's name in messages
    base_dir: str                 # the master's folder that relative paths are resolved against
    files: dict = field(default_factory=dict)     # master path -> (hash, suffix)
    presets: dict = field(default_factory=dict)   # preset name -> master path of its document

    def hashes(self) -> dict:
        """{hash: suffix} of every file a worker must hold (the document included)."""
        out = {self.document: ".json"}
        for digest, suffix in self.files.values():
            out[digest] = suffix
        return out


def file_hash(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(CHUNK), b""):
            digest.update(chunk)
    return digest.hexdigest()


def make_package(scene, source, shared: bool = False) -> tuple[ScenePackage, dict]:
    """The package of a loaded scene and, for the master, {hash: path or bytes} of the data."""
    # Paths are made absolute the same way on both sides (os.path.abspath: the master's current
    # folder for relative ones, ".." folded, symbolic links kept), so that the master's recorded
    # paths and the worker's resolved ones are the same strings (scene/inputs.py, Redirect).
    if isinstance(source, (str, Path)):
        path = Path(source)
        from .limits import short
        document = path.read_bytes()
        where, base = short(source, 300), os.path.abspath(path.parent)
    else:
        data, where, base = source
        document = json.dumps(data).encode("utf-8")
        # load_scene_data resolves against the current folder without a base: the master's.
        base = os.path.abspath(base) if base else os.getcwd()
    blobs: dict = {}
    doc_hash = hashlib.sha256(document).hexdigest()
    blobs[doc_hash] = document
    inputs = getattr(scene, "inputs", None) or {}
    files: dict = {}
    if not shared:
        for name in inputs.get("files", []):
            p = Path(name)
            if not p.is_file():
                continue                   # resolved but never read (the load would have failed)
            digest = file_hash(p)
            files[os.path.abspath(name)] = (digest, p.suffix.lower())
            blobs.setdefault(digest, p)
    presets = {k: os.path.abspath(v) for k, v in inputs.get("presets", {}).items()} if not shared else {}
    key = hashlib.sha256(json.dumps([doc_hash, where, base, sorted(files.items()),
                                     sorted(presets.items())]).encode()).hexdigest()
    return ScenePackage(key, doc_hash, str(where), base, files, presets), blobs


def blob_bytes(blob) -> bytes:
    return blob if isinstance(blob, bytes) else Path(blob).read_bytes()


# --------------------------------------------------------------------------- worker side

def cache_dir() -> Path:
    env = os.environ.get("LAMINA_CLUSTER_CACHE")
    if env:
        return Path(env)
    from .kernels.cache import user_cache_root
    kernels = user_cache_root()
    # The kernel cache root is ``.../lamina/kernels`` unless LAMINA_KERNEL_CACHE moved it.
    base = kernels.parent if kernels.name == "kernels" else kernels
    return base / "cluster-files"


def cached_path(digest: str, suffix: str) -> Path:
    # The suffix is kept: readers pick the format by it (OpenImageIO, .npz, .ies).
    return cache_dir() / digest[:2] / f"{digest}{suffix}"


def worker_inventory(hashes: dict) -> dict:
    """On a worker: which of ``hashes`` ({hash: suffix}) its cache lacks, the cache's identity
    (workers with the same one share the files) and the backend's version key (the master
    refuses workers whose renderer differs: they would not give the same image)."""
    from .kernels.cache import source_key
    from . import __version__
    folder = cache_dir()
    missing = [h for h, suffix in hashes.items() if not cached_path(h, suffix).is_file()]
    return {"missing": missing, "cache": f"{socket.gethostname()}:{folder.resolve()}",
            "version": f"{__version__}/{source_key()}"}


def store(digest: str, suffix: str, data: bytes) -> int:
    """On a worker: keep one file in the cache (checked against its hash). Returns its size."""
    if hashlib.sha256(data).hexdigest() != digest:
        raise LaminaError(f"a scene file arrived damaged (hash mismatch for {digest[:12]})")
    target = cached_path(digest, suffix)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, target)           # atomic: a reader sees the whole file or none
    return len(data)


def missing_files(package: ScenePackage) -> list[str]:
    """On a worker: the hashes of the package it does not hold (a worker that joined late)."""
    return [h for h, suffix in package.hashes().items() if not cached_path(h, suffix).is_file()]


def load_package(package: ScenePackage):
    """On a worker: the scene, loaded from the cached copies under the master's paths."""
    from .scene.inputs import Redirect
    from .scene.loader import load_scene_data
    from .scene.reader import read_json
    text = cached_path(package.document, ".json").read_text(encoding="utf-8")
    data = read_json(text, package.where)
    local = {path: str(cached_path(digest, suffix)) for path, (digest, suffix) in package.files.items()}
    with Redirect(local, package.presets):
        return load_scene_data(data, package.where, Path(package.base_dir))

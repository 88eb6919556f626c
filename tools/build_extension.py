#!/usr/bin/env python3
"""Build the Lamina Blender extension zip and validate it with Blender's own extension tool.

    python tools/build_extension.py [--platform linux-x64 ...] [--python 3.11 ...]
                                    [--universal] [--no-wheels] [--output-dir build/dist]

One zip per platform and Blender generation (the default): ``lamina-VERSION-PLATFORM-cpXY.zip``
with only that platform's wheels for that Python, and a manifest whose Blender version range
picks it — cp311 for Blender 4.2–5.0 (``blender_version_max = "5.1.0"``, exclusive), cp313 for
5.1 and later — so an artist downloads one file of 60–80 MB instead of one 370 MB zip that
carries every platform and both Pythons. ``--universal``: that one zip (development, offline
use). The build lists what it made, with sizes, and what it removed from the output folder.

Steps: download the wheels of the compiled dependencies — embreex (ray casting), numba and
llvmlite (the compiled render kernels), at the versions pinned in requirements.txt; never numpy:
Blender's own numpy is used — into build/wheels/ with ``pip download --no-deps
--only-binary=:all:``; stage the repository into
build/stage/ filtered by the manifest's ``paths_exclude_pattern``, with the wheels and a manifest
that lists them; build with ``blender_ext.py build`` and check with ``blender_ext.py validate``
(the script ships inside the bpy module and Blender, and runs without a Blender binary).
Nothing downloaded or built is committed (build/ is git-ignored).
"""
from __future__ import annotations

import argparse
import glob
import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUILD = ROOT / "build"
BUNDLED = ("embreex", "numba", "llvmlite")     # wheels the extension ships (pins: requirements.txt)

# Blender platform → pip platform tag of the embreex wheels (checked 2026-11: no macOS x64
# wheel exists for embreex 4.x, and the arm64 one needs macOS ≥ 13).
PIP_PLATFORMS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_13_0_arm64",
}
WHEEL_PATTERNS = {
    "linux-x64": "*linux*_x86_64.whl",
    "windows-x64": "*win_amd64.whl",
    "macos-arm64": "*macosx_*_arm64.whl",
}
PYTHONS = ("3.11", "3.13")     # Blender 4.2–5.0 bundle 3.11, Blender 5.1 bundles 3.13
#: The Blender versions whose bundled Python each zip is for: (min, max exclusive or None).
BLENDER_RANGE = {"3.11": ("4.2.0", "5.1.0"), "3.13": ("5.1.0", None)}


def find_blender_ext() -> Path:
    """blender_ext.py from the installed bpy module (or $BLENDER_EXT)."""
    import os
    if os.environ.get("BLENDER_EXT"):
        return Path(os.environ["BLENDER_EXT"])
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("error: the bpy module is not installed here (pip install bpy), "
                         "or set BLENDER_EXT to .../scripts/addons_core/bl_pkg/cli/blender_ext.py")
    base = Path(list(spec.submodule_search_locations)[0])
    hits = sorted(glob.glob(str(base / "*" / "scripts" / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py")))
    if not hits:
        raise SystemExit(f"error: blender_ext.py not found under {base}")
    return Path(hits[-1])


def load_blender_ext(path: Path):
    spec = importlib.util.spec_from_file_location("blender_ext", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["blender_ext"] = module
    spec.loader.exec_module(module)
    return module


def pinned(package: str) -> str:
    """``package==version`` as pinned in requirements.txt (one source of truth)."""
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        if line.split("==")[0].strip().lower() == package.lower():
            return line.strip()
    raise SystemExit(f"error: {package} is not pinned in requirements.txt")


def wheel_for(folder: Path, package: str, platform: str, python: str) -> Path | None:
    tag = "cp" + python.replace(".", "")
    version = pinned(package).split("==")[1]
    hits = sorted(folder.glob(f"{package}-{version}-{tag}-{tag}-{WHEEL_PATTERNS[platform]}"))
    return hits[-1] if hits else None


def download_wheels(platforms, pythons, folder: Path, allow_missing: bool) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    wheels = []
    for platform in platforms:
        for python in pythons:
            for package in BUNDLED:
                found = wheel_for(folder, package, platform, python)
                if found is None:
                    print(f"[build] downloading {package} for {platform}, Python {python}", flush=True)
                    cmd = [sys.executable, "-m", "pip", "download", pinned(package), "--no-deps",
                           "--only-binary=:all:", "--platform", PIP_PLATFORMS[platform],
                           "--python-version", python, "-d", str(folder), "-q",
                           "--disable-pip-version-check"]
                    code = subprocess.call(cmd)
                    found = wheel_for(folder, package, platform, python)
                    if code != 0 or found is None:
                        message = f"no {package} wheel for {platform} / Python {python}"
                        if not allow_missing:
                            raise SystemExit(f"error: {message} (use --allow-missing-wheels to build without)")
                        print(f"[build] warning: {message}; the zip will not include it", flush=True)
                        continue
                wheels.append(found)
    return wheels


def stage(blender_ext, stage_dir: Path, wheels: list[Path], platforms, pythons=None) -> None:
    import tomllib
    manifest_text = (ROOT / "blender_manifest.toml").read_text(encoding="utf-8")
    manifest = tomllib.loads(manifest_text)
    patterns = manifest.get("build", {}).get("paths_exclude_pattern", [])
    matcher = blender_ext.PathPatternMatch(patterns)
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    stage_dir.mkdir(parents=True)
    for path in sorted(ROOT.rglob("*")):
        rel = path.relative_to(ROOT).as_posix()
        if any(part in (".git", ".venv", "build") for part in Path(rel).parts[:1]):
            continue
        test = rel + "/" if path.is_dir() else rel
        if matcher.test_path(test) or any(matcher.test_path(p + "/") for p in _parents(rel)):
            continue
        if path.is_file():
            target = stage_dir / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, target)
    wheel_dir = stage_dir / "wheels"
    wheel_dir.mkdir()
    for wheel in wheels:
        shutil.copy2(wheel, wheel_dir / wheel.name)
    lines = ", ".join(f'"./wheels/{w.name}"' for w in wheels)
    text = re.sub(r"^platforms\s*=.*$", "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
                  manifest_text, flags=re.M)
    if wheels:
        text = text.replace("\n[permissions]", f"\nwheels = [{lines}]\n\n[permissions]", 1)
    if pythons is not None and len(pythons) == 1:
        low, high = BLENDER_RANGE[pythons[0]]
        text = re.sub(r'^blender_version_min\s*=.*$', f'blender_version_min = "{low}"', text, flags=re.M)
        if high is not None:
            text = text.replace(f'blender_version_min = "{low}"',
                                f'blender_version_min = "{low}"\nblender_version_max = "{high}"', 1)
    (stage_dir / "blender_manifest.toml").write_text(text, encoding="utf-8")


def _wheel_platform(wheel: Path) -> str | None:
    for platform, pattern in WHEEL_PATTERNS.items():
        if Path(wheel.name).match(pattern):
            return platform
    return None


def _parents(rel: str) -> list[str]:
    parts = rel.split("/")[:-1]
    return ["/".join(parts[:i + 1]) for i in range(len(parts))]


def run_ext(blender_ext_path: Path, *args: str) -> None:
    cmd = [sys.executable, str(blender_ext_path), *args]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    output = (proc.stdout + proc.stderr).strip()
    if output:
        print("\n".join("  " + line for line in output.splitlines()))
    if proc.returncode != 0:
        raise SystemExit(f"error: {' '.join(args[:1])} failed (status {proc.returncode})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--platform", action="append", choices=sorted(PIP_PLATFORMS),
                        help="target platform (repeatable; default: all three)")
    parser.add_argument("--python", action="append", choices=PYTHONS,
                        help="Python version of the target Blender (repeatable; default: 3.11 and 3.13)")
    parser.add_argument("--universal", action="store_true",
                        help="one zip for every platform and Python asked for (default: one zip per "
                             "platform and Python, each for the Blender versions that bundle that Python)")
    parser.add_argument("--split-platforms", action="store_true", help=argparse.SUPPRESS)  # the default now
    parser.add_argument("--no-wheels", action="store_true",
                        help="do not bundle the embreex, numba and llvmlite wheels")
    parser.add_argument("--allow-missing-wheels", action="store_true",
                        help="build even if a wheel cannot be downloaded (offline)")
    parser.add_argument("--output-dir", default=str(BUILD / "dist"))
    parser.add_argument("--build-dir", default=str(BUILD), help="staging folder (default build/)")
    parser.add_argument("--wheel-dir", default=str(BUILD / "wheels"), help="wheel download cache")
    args = parser.parse_args(argv)

    platforms = args.platform or list(PIP_PLATFORMS)
    pythons = args.python or list(PYTHONS)
    ext_path = find_blender_ext()
    blender_ext = load_blender_ext(ext_path)
    wheels = [] if args.no_wheels else download_wheels(platforms, pythons, Path(args.wheel_dir),
                                                       args.allow_missing_wheels)
    out = Path(args.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    for old in sorted(out.glob("lamina-*.zip")):
        print(f"[build] removed the previous {old.name}", flush=True)
        old.unlink()
    version = re.search(r'^version\s*=\s*"([^"]+)"', (ROOT / "blender_manifest.toml").read_text(), re.M).group(1)
    if args.universal:
        targets = [(platforms, pythons, out / f"lamina-{version}.zip")]
    else:
        targets = [([p], [py], out / f"lamina-{version}-{p.replace('-', '_')}-cp{py.replace('.', '')}.zip")
                   for p in platforms for py in pythons]
    print(f"[build] building with {ext_path}", flush=True)
    made = []
    for target_platforms, target_pythons, zip_path in targets:
        chosen = [w for w in wheels if any(f"-cp{py.replace('.', '')}-" in w.name for py in target_pythons)
                  and any(_wheel_platform(w) == p for p in target_platforms)]
        stage_dir = Path(args.build_dir) / "stage" / "lamina"
        stage(blender_ext, stage_dir, chosen, target_platforms, target_pythons)
        run_ext(ext_path, "build", "--source-dir", str(stage_dir), "--output-filepath", str(zip_path))
        run_ext(ext_path, "validate", str(zip_path))
        made.append(zip_path)
    print("[build] made (each validated by Blender's extension tool):", flush=True)
    for z in made:
        print(f"[build]   {z} ({z.stat().st_size / 1e6:.1f} MB)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

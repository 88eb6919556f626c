"""Seeded fuzzing of scene loading and rendering (issue 18): every input either renders finite
pixels or fails with exit status 2 and one error line — never a traceback, a hang or Inf/NaN.

    python -m benchmarks.fuzz [--seed 0] [--mutations 500] [--ies] [--meshes] [--keep DIR]

Cases:
* **mutations** of base documents — the demo (layered stacks, a texture) and small scenes
  covering every light type, an IES file, an environment map, inline and .npz meshes — one to
  three edits each: a value replaced by an interesting one (0, −1, 1e30, 1e308, NaN, Inf, 10^30,
  a 5000-digit integer, 2^63, "", a 10⁵-character string, deep lists, wrong types, …), a field
  deleted or an unknown one added, a number scaled, a value wrapped in lists, a list emptied or
  grown; one case in eight mutates the JSON *text* instead (truncated, a byte changed);
* **IES truncations**: every bundled IES file cut at several points, with one byte flipped;
* **mesh truncations**: every bundled .npz mesh cut at several points.

Each case runs ``python -m backend render`` in this process (``backend.cli.main``) at a tiny
resolution, one sample per pixel, one worker: exit 0 must give an EXR whose every value is finite;
exit 2 must print exactly one ``error:`` line (warnings allowed) and no traceback; anything else —
another status, an exception escaping ``main``, a Python warning, a case slower than
``SLOW_CASE`` seconds — is a failure. Same seed ⇒ same cases.
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import random
import shutil
import signal
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SLOW_CASE = 30.0          # seconds: a case slower than this counts as a hang
RESOLUTION = "12x8"

HUGE_INT = "__FUZZ_HUGE_INT__"     # replaced in the JSON text (json.dumps refuses such ints)
DEEP_LIST = "__FUZZ_DEEP_LIST__"   # replaced in the JSON text (json.dumps would recurse)

INTERESTING = [0, -1, 1, 2, 3, 0.5, -0.5, 1e-320, 1e-30, 1e12, 1.5e12, 1e30, 1e31, 1e308, -1e308,
               float("nan"), float("inf"), -float("inf"), 10 ** 30, 2 ** 63, -2 ** 63 - 1, 2 ** 64,
               65536, 65537, 1 << 24, (1 << 24) + 1, 1 << 31, HUGE_INT, DEEP_LIST, True, False, None,
               "", "x", "a" * 100_000, "../../../../etc/passwd", "nul\x00byte", "ünïcødé", [], {},
               [0, 0, 0, 0], [1, 2, 3], [[1, 2, 3]], [1, 2], {"texture": "missing.png"},
               {"type": "diffuse"}, {"type": "layered", "interfaces": []}, [[0, 0, 0, 1]] * 4]


@dataclass
class Case:
    name: str
    scene: dict | None = None          # a document (serialised with the markers replaced)
    text: str | None = None            # or the scene's text as is
    files: dict = field(default_factory=dict)   # relative path → bytes (written next to the scene)
    copies: dict = field(default_factory=dict)  # relative path → source file to copy


@dataclass
class Outcome:
    case: str
    code: int | None
    seconds: float
    problem: str | None = None
    error: str = ""


# --------------------------------------------------------------------------- base documents

def _camera(distance=5.0):
    return {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -distance], [0, 1, 0, 0.5], [0, 0, 0, 1]],
            "frame": [[0.4, 0.3, -1], [0.4, -0.3, -1], [-0.4, -0.3, -1], [-0.4, 0.3, -1]]}


def _light_at(x, y, z):
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def _exr_bytes(folder: Path) -> bytes:
    """A tiny equirectangular environment (EXR) as bytes."""
    import OpenImageIO as oiio
    path = folder / "sky.exr"
    pix = np.linspace(0.1, 2.0, 8 * 4 * 3, dtype=np.float32).reshape(4, 8, 3)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(8, 4, 3, oiio.FLOAT))
    out.write_image(pix)
    out.close()
    return path.read_bytes()


def base_cases(scratch: Path) -> list[Case]:
    """The documents mutations start from (each renders fine as is)."""
    demo = json.loads((ROOT / "demo" / "demo.json").read_text())
    demo_case = Case("demo", demo, copies={"textures/checker.png": ROOT / "demo" / "textures" / "checker.png"})
    ies = (ROOT / "tests" / "data" / "ies" / "erco_defined_spot_lm95.ies").read_bytes()
    scratch.mkdir(parents=True, exist_ok=True)
    sky = _exr_bytes(scratch)
    floor = {"shape": "rectangle", "size": [6, 6]}
    lights = {"format": "lamina-scene", "version": 1, "film": {"width": 24, "height": 16},
              "camera": _camera(), "render": {"spp": 2, "max_bounces": 3, "seed": 1},
              "materials": {"floor": {"type": "diffuse", "color": {"texture": "tex.png"}},
                            # α 0.05: a caster (backend/caustics.py), so every light type sends photons
                            "metal": {"type": "conductor", "metal": "Au", "roughness": 0.05},
                            "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.05},
                            "glow": {"type": "emission", "color": [1, 0.8, 0.6], "strength": 2}},
              "meshes": {"floor": floor, "ball": {"shape": "sphere", "radius": 0.5, "segments": 12},
                         "box": {"shape": "cube", "size": 0.5},
                         "tri": {"positions": [[0, 0, 0], [1, 0, 0], [0, 0, 1]], "indices": [[0, 1, 2]],
                                 "uvs": [[0, 0], [1, 0], [0, 1]]},
                         "cup": {"file": "cup.npz"}},
              "objects": [{"mesh": "floor", "materials": ["floor"]},
                          {"mesh": "ball", "materials": ["metal"], "to_world": _light_at(-1, 0, 0.5)},
                          {"mesh": "box", "materials": ["glass"], "to_world": _light_at(1, 0, 0.3)},
                          {"mesh": "tri", "materials": ["glow"], "to_world": _light_at(0, 1, 0)},
                          {"mesh": "cup", "materials": ["metal"], "to_world": _light_at(0, -1, 0)}],
              "lights": [{"type": "point", "to_world": _light_at(0, -2, 3), "power": 200, "radius": 0.1},
                         {"type": "spot", "to_world": _light_at(1, -2, 3), "power": 300, "spot_size": 40,
                          "ies": {"file": "lamp.ies"}},
                         {"type": "sun", "to_world": _light_at(0, 0, 5), "strength": 2, "angle": 1},
                         {"type": "area", "to_world": _light_at(-1, -1, 3), "power": 100, "size": 0.5,
                          "shape": "rectangle", "size_y": 0.3, "spread": 90},
                         {"type": "area", "to_world": _light_at(1, 1, 3), "power": 80, "size": 0.4,
                          "cutoff_angle": 40, "beam_width": 20}],
              "world": {"type": "environment", "file": "sky.exr", "strength": 0.5}}
    lights_case = Case("lights", lights, files={"lamp.ies": ies, "sky.exr": sky},
                       copies={"tex.png": ROOT / "demo" / "textures" / "checker.png",
                               "cup.npz": ROOT / "showcase" / "meshes" / "cup.npz"})
    small = {"format": "lamina-scene", "version": 1, "film": {"width": 16, "height": 12},
             "camera": {**_camera(), "dof": {"focus_distance": 5, "aperture_radius": 0.05, "blades": 5}},
             "render": {"spp": 4, "noise_target": 0.05, "min_spp": 2, "clamp": 10,
                        "layered": {"estimator": "uni", "max_vertices": 64}},
             "materials": {"coat": {"type": "layered",
                                    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1},
                                                   {"type": "diffuse", "color": [0.6, 0.3, 0.2]}],
                                    "media": [{"thickness": 0.1, "sigma_t": 1.0, "albedo": [0.9, 0.8, 0.7],
                                               "phase": {"type": "hg", "g": 0.3}}]},
                           "grey": {"type": "diffuse", "color": 0.5}},
             "meshes": {"ball": {"shape": "sphere", "radius": 1, "segments": 10},
                        "floor": {"shape": "disk", "radius": 3, "segments": 12}},
             "objects": [{"mesh": "ball", "materials": ["coat"]},
                         {"mesh": "floor", "materials": ["grey"], "to_world": _light_at(0, 0, -1)}],
             "world": {"type": "constant", "color": [0.6, 0.7, 0.8], "strength": 1}}
    return [demo_case, lights_case, Case("small", small)]


# --------------------------------------------------------------------------- mutations

def _paths(doc, prefix=(), out=None, budget=4000):
    """Every (path to a value) in the document; long lists contribute their first elements."""
    out = [] if out is None else out
    if len(out) >= budget:
        return out
    out.append(prefix)
    if isinstance(doc, dict):
        for k, v in doc.items():
            _paths(v, prefix + (k,), out, budget)
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            _paths(v, prefix + (i,), out, budget)
    return out


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def _set(doc, path, value):
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


TYPES = ("diffuse", "conductor", "dielectric", "emission", "layered", "null", "point", "spot", "sun",
         "area", "constant", "environment", "none", "perspective", "orthographic", "hg", "isotropic",
         "microflake", "sggx", "box", "gaussian", "sphere", "rectangle", "disk", "cube")


def _pick_path(doc, rng: random.Random):
    """A random path; list elements (matrix rows, vector components) weigh less than fields."""
    paths = _paths(doc)[1:] or [()]
    weights = [0.25 if p and isinstance(p[-1], int) else 1.0 for p in paths]
    return rng.choices(paths, weights)[0]


def _mild(value, rng: random.Random):
    """A plausible edit: values a user could write (zero, doubled, negated, tiny, large)."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, (int, float)):
        new = rng.choice((0, value * 2, value * 0.5, -value, value + 1, 1e-6, 1e6, 180, 90, 1,
                          1e-300, 1e29, 1e30, 9.9e11, -9.9e11, 64, 1024))
        return int(new) if isinstance(value, int) and float(new).is_integer() else new
    if isinstance(value, str):
        return rng.choice(TYPES + ("", "Cu", "Au", "missing.png", "sRGB", "linear", "uni", "stochastic"))
    if isinstance(value, list):
        return value[:-1] if value and rng.random() < 0.5 else value + value[:1]
    if isinstance(value, dict) and value:
        out = dict(value)
        out.pop(rng.choice(list(out)))
        return out
    return value


def mutate(doc, rng: random.Random) -> tuple[object, str]:
    """One edit of the document (in place where possible); returns (doc, description)."""
    path = _pick_path(doc, rng)
    value = _get(doc, path)
    where = ".".join(map(str, path))[:80]
    if rng.random() < 0.5:
        new = _mild(value, rng)
        return _set(doc, path, new), f"{where} = {str(new)[:40]!r}"
    op = rng.choice(("replace", "replace", "replace", "delete", "unknown", "scale", "wrap", "list", "swap"))
    if op == "replace" or (op == "scale" and not isinstance(value, (int, float))):
        new = copy.deepcopy(rng.choice(INTERESTING))
        return _set(doc, path, new), f"{where} = {str(new)[:40]!r}"
    if op == "delete" and path:
        parent = _get(doc, path[:-1])
        del parent[path[-1]]
        return doc, f"del {where}"
    if op == "unknown":
        target = value if isinstance(value, dict) else _get(doc, path[:-1]) if path else doc
        if isinstance(target, dict):
            key = rng.choice(("colour", "x" * rng.choice((3, 300, 100_000)), "Type", "_comment", "spp "))
            target[key] = rng.choice((1, "a", [1]))
            return doc, f"{where}: unknown field {key[:20]!r}"
    if op == "scale" and isinstance(value, (int, float)) and not isinstance(value, bool):
        f = rng.choice((-1, 0, 1e10, 1e-10, 1e300, 1e29, 3))
        try:
            new = value * f
        except OverflowError:
            new = float("inf")
        return _set(doc, path, new), f"{where} *= {f:g}"
    if op == "wrap":
        new = value
        for _ in range(rng.choice((1, 2, 70))):
            new = [new]
        return _set(doc, path, new), f"{where} wrapped in lists"
    if op == "list" and isinstance(value, list):
        if value and rng.random() < 0.5:
            return _set(doc, path, value * rng.choice((2, 50))), f"{where} repeated"
        return _set(doc, path, []), f"{where} = []"
    if op == "swap":
        new = (str(value) if isinstance(value, (int, float)) else
               {"0": value} if isinstance(value, list) else
               list(value.values()) if isinstance(value, dict) else 7)
        return _set(doc, path, new), f"{where} type swapped"
    new = copy.deepcopy(rng.choice(INTERESTING))
    return _set(doc, path, new), f"{where} = {str(new)[:40]!r}"


def serialise(doc) -> str:
    text = json.dumps(doc)
    text = text.replace(json.dumps(HUGE_INT), "9" * 5000)
    return text.replace(json.dumps(DEEP_LIST), "[" * 3000 + "1" + "]" * 3000)


def text_mutation(text: str, rng: random.Random) -> tuple[str, str]:
    k = rng.randrange(len(text))
    op = rng.choice(("truncate", "byte", "digits"))
    if op == "truncate":
        return text[:k], f"text truncated at {k}"
    if op == "byte":
        return text[:k] + rng.choice("{}[],:\"\\e9-.\x00\uffff") + text[k + 1:], f"text byte {k} changed"
    return text[:k] + "1e999" + text[k:], f"'1e999' inserted at {k}"


def mutation_cases(seed: int, count: int, bases: list[Case]) -> list[Case]:
    rng = random.Random(seed)
    out = []
    for n in range(count):
        base = bases[n % len(bases)]
        doc = copy.deepcopy(base.scene)
        edits = []
        for _ in range(rng.choice((1, 1, 2, 3))):
            doc, what = mutate(doc, rng)
            edits.append(what)
        text = serialise(doc)
        if rng.random() < 0.125:
            text, what = text_mutation(serialise(base.scene), rng)
            edits = [what]
        out.append(Case(f"{base.name}#{n}: {'; '.join(edits)}", text=text, files=base.files, copies=base.copies))
    return out


# --------------------------------------------------------------------------- truncations

def _ies_scene(ies_field: dict) -> dict:
    return {"format": "lamina-scene", "version": 1, "film": {"width": 8, "height": 6},
            "camera": _camera(), "render": {"spp": 1},
            "materials": {"m": {"type": "diffuse", "color": 0.5}},
            "meshes": {"floor": {"shape": "rectangle", "size": [6, 6]}},
            "objects": [{"mesh": "floor", "materials": ["m"]}],
            "lights": [{"type": "spot", "to_world": _light_at(0, 0, 2), "power": 100, "spot_size": 90,
                        "ies": ies_field}]}


def ies_cases(seed: int) -> list[Case]:
    """Every bundled IES file cut at several points (and once with a byte flipped)."""
    rng = random.Random(seed + 1)
    files = sorted((ROOT / "tests" / "data" / "ies").glob("*.ies")) + [ROOT / "showcase" / "erco_defined_spot_lm95.ies"]
    out = []
    for f in files:
        data = f.read_bytes()
        cuts = sorted({int(len(data) * q) for q in (0.0, 0.05, 0.3, 0.6, 0.9, 0.99)} | {len(data) - 1})
        for c in cuts:
            out.append(Case(f"ies {f.name} cut at {c}/{len(data)}", _ies_scene({"file": "lamp.ies"}),
                            files={"lamp.ies": data[:c]}))
        k = rng.randrange(len(data))
        flipped = data[:k] + bytes([data[k] ^ 0x5A]) + data[k + 1:]
        out.append(Case(f"ies {f.name} byte {k} flipped", _ies_scene({"file": "lamp.ies"}),
                        files={"lamp.ies": flipped}))
    return out


def mesh_cases(seed: int) -> list[Case]:
    """Every bundled .npz mesh cut at several points."""
    out = []
    for f in sorted((ROOT / "showcase" / "meshes").glob("*.npz")):
        data = f.read_bytes()
        for q in (0.0, 0.1, 0.5, 0.9, 0.999):
            c = int(len(data) * q)
            doc = _ies_scene({"file": "lamp.ies"})
            doc["lights"] = [{"type": "point", "to_world": _light_at(0, 0, 2), "power": 100}]
            doc["meshes"]["cup"] = {"file": "mesh.npz"}
            doc["objects"].append({"mesh": "cup", "materials": ["m"]})
            out.append(Case(f"mesh {f.name} cut at {c}/{len(data)}", doc, files={"mesh.npz": data[:c]}))
    return out


# --------------------------------------------------------------------------- running

def run_case(case: Case, folder: Path) -> Outcome:
    """Render one case in this process (backend.cli.main) and judge the outcome."""
    from backend import cli
    from backend.imageio import read_exr
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    for rel, data in case.files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    for rel, src in case.copies.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, folder / rel)
    scene = folder / "scene.json"
    scene.write_text(case.text if case.text is not None else serialise(case.scene), encoding="utf-8")
    out = folder / "out.exr"
    args = ["render", str(scene), "-o", str(out), "--resolution", RESOLUTION, "--spp", "1",
            "--workers", "1", "--progress", "none"]
    err, std = io.StringIO(), io.StringIO()
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    t0 = time.perf_counter()
    code, problem = None, None
    try:
        with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stderr(err), \
                contextlib.redirect_stdout(std):
            warnings.simplefilter("always")
            try:
                code = cli.main(args)
            except SystemExit as exc:           # argparse
                code = exc.code if isinstance(exc.code, int) else 2
        if caught:
            w = caught[0]
            problem = f"Python warning: {w.category.__name__}: {str(w.message)[:120]} ({Path(w.filename).name}:{w.lineno})"
    except BaseException as exc:  # noqa: BLE001 - that is what we look for
        if isinstance(exc, KeyboardInterrupt):
            raise
        import traceback
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        problem = f"traceback: {type(exc).__name__}: {str(exc)[:150]} ({Path(tb.filename).name}:{tb.lineno})"
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
    seconds = time.perf_counter() - t0
    text = err.getvalue()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error: ")]
    others = [ln for ln in lines if not ln.startswith(("error: ", "warning: ", "wrote ", "statistics: "))]
    if problem is None:
        if "Traceback" in text:
            problem = "a traceback on stderr"
        elif code == 0:
            try:
                pixels, _ = read_exr(out)
                if not np.all(np.isfinite(pixels)):
                    problem = "non-finite pixels written"
            except Exception as exc:  # noqa: BLE001
                problem = f"exit 0 but no readable image ({exc})"
        elif code == 2:
            if len(errors) != 1:
                problem = f"exit 2 with {len(errors)} error lines"
            elif _internal_error() in errors[0]:
                # a clear message, but for an exception inside the renderer: a bug all the same
                problem = f"an internal error: {errors[0][:160]}"
            elif others:
                problem = f"unexpected stderr line: {others[0][:120]}"
        else:
            problem = f"exit status {code}"
    if problem is None and seconds > SLOW_CASE:
        problem = f"took {seconds:.1f} s (> {SLOW_CASE:g} s: a hang?)"
    return Outcome(case.name, code, seconds, problem, errors[0][:200] if errors else "")


def _internal_error() -> str:
    from backend.work_items import INTERNAL_ERROR
    return INTERNAL_ERROR


def all_cases(seed: int, mutations: int, ies: bool = True, meshes: bool = True,
              scratch: Path | None = None) -> list[Case]:
    scratch = scratch or Path(__file__).resolve().parent / ".cache" / "fuzz-base"
    cases = mutation_cases(seed, mutations, base_cases(scratch))
    if ies:
        cases += ies_cases(seed)
    if meshes:
        cases += mesh_cases(seed)
    return cases


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.fuzz", description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mutations", type=int, default=500)
    ap.add_argument("--no-ies", action="store_true")
    ap.add_argument("--no-meshes", action="store_true")
    ap.add_argument("--keep", type=Path, default=None, help="work folder (kept)")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    import tempfile
    work = args.keep or Path(tempfile.mkdtemp(prefix="lamina-fuzz-"))
    cases = all_cases(args.seed, args.mutations, not args.no_ies, not args.no_meshes, work / "base")
    t0 = time.perf_counter()
    failures, codes = [], {}
    for i, case in enumerate(cases):
        res = run_case(case, work / "case")
        codes[res.code] = codes.get(res.code, 0) + 1
        if res.problem:
            failures.append(res)
            print(f"FAIL {res.case}\n     {res.problem}", flush=True)
        elif args.verbose:
            print(f"ok   [{res.code}] {res.seconds:5.2f}s {res.case[:100]}  {res.error[:100]}", flush=True)
    print(f"{len(cases)} cases in {time.perf_counter() - t0:.0f} s: exit codes {codes}, "
          f"{len(failures)} failure(s)")
    if args.keep is None:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

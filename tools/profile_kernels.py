#!/usr/bin/env python3
"""Where the compiled kernels spend their time: a sampling profile of one benchmark scene, by
kernel function (and by source line with ``--lines``).

    .venv/bin/python tools/profile_kernels.py [--scene cornell|peer-cornell|peer-everyday|peer-presets|sphere-microflake|demo] [--spp 16] [--lines]

Needs Linux ``perf`` (``perf record`` with the cpu-clock event works in a VM without hardware
counters). Numba's machine code lives in anonymous memory, so perf alone sees addresses only.
This script keeps each kernel library's object file as Numba hands it to the JIT (a hook on
its object cache), reads the object's symbols (``nm``) and the address the JIT gave the
integrator's ``shade``, and maps every perf sample to the function — and, with ``--lines``
(which recompiles with ``NUMBA_DEBUGINFO=1`` into a private cache; debug info changes inlining
a little, so treat lines as a guide), to the source line (``addr2line``).

The child process (``--child``) renders the scene repeatedly under ``perf record``; the parent
reads the samples and prints the shares of the whole process (embree, libm, Python and the
kernels).
"""
from __future__ import annotations

import argparse
import bisect
import collections
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _keep_objects() -> None:
    """Numba gives each library's object file to the JIT once and then drops it: keep a copy on
    the library (``_lamina_object``) so its symbols can be read after loading."""
    from numba.core import codegen
    original = codegen.CPUCodeLibrary._object_getbuffer_hook.__func__

    def hook(cls, ll_module):
        library = getattr(ll_module, "_CPUCodeLibrary__library", None)
        buf = original(cls, ll_module)
        if library is not None and buf:
            library._lamina_object = bytes(buf)
        return buf

    codegen.CPUCodeLibrary._object_getbuffer_hook = classmethod(hook)


def _scene(name: str, spp: int) -> dict:
    if name == "peer-cornell":
        from benchmarks.peers.scenes import cornell
        data = cornell(96)
    elif name == "peer-everyday":
        from benchmarks.peers.scenes import everyday
        data = everyday(96)
    elif name == "peer-presets":
        from benchmarks.peers.scenes import presets
        data = presets(80)
    elif name == "demo":
        # The README's demo (demo/demo.json); its texture paths are made absolute here.
        import json
        data = json.loads((ROOT / "demo" / "demo.json").read_text())

        def absolute(node):
            if isinstance(node, dict):
                for k, v in node.items():
                    if k == "texture" and isinstance(v, str):
                        node[k] = str(ROOT / "demo" / v)
                    else:
                        absolute(v)
            elif isinstance(node, list):
                for v in node:
                    absolute(v)
        absolute(data)
    elif name == "sphere-microflake":
        # benchmarks/layered_throughput.py --render: the one-sphere worst case of issue 16.
        from benchmarks.layered_throughput import STACKS, _sphere_scene
        data = _sphere_scene(STACKS["2 slabs (reference, microflake)"], 128, spp)
    else:
        from benchmarks.scenes import cornell_box
        data = cornell_box(256, 256, spp, 6)
    data["render"]["spp"] = spp
    return data


def child(args) -> int:
    """Render the scene ``args.repeat`` times (after one warm-up render), then write the symbol
    map of the library that holds ``shade`` — the bounce loop's, ``run_item`` — (address, size,
    name per line)."""
    import numpy as np
    _keep_objects()
    from backend.warmup import ensure_compiled, warm_up
    ensure_compiled()
    warm_up()
    from backend.geometry.accel import Accelerator
    from backend.integrator import PathTracer
    from backend.kernels import integrator as ki
    from backend.render import choose_spp_block, plan_round
    from backend.scene.loader import load_scene_data

    scene = load_scene_data(_scene(args.scene, args.spp), "<profile>")
    tracer = PathTracer(scene, Accelerator(scene.soup))
    pixels = np.arange(scene.width * scene.height, dtype=np.int64)
    block = choose_spp_block(pixels.size, args.spp)
    items = []
    for r in range(-(-args.spp // block)):
        items += plan_round(pixels, min(block, args.spp - r * block), r, 1, r * block)

    def render():
        for _key, band, spp, _seed, sample0 in items:
            tracer.render(band, spp, None, sample0)

    render()
    times = []
    for _ in range(args.repeat):
        t = time.process_time()
        render()
        times.append(time.process_time() - t)
    if times:
        print(f"render CPU per pass: min {min(times):.3f} s, max {max(times):.3f} s ({len(times)} passes)")

    # The compiled bounce loop (kernels/item_loop.py run_item) calls shade: its library holds
    # shade's code linked in (shade itself is never called from Python, so it has no overload).
    from backend.kernels import item_loop
    entry_kernel = ki.shade if ki.shade.signatures else item_loop.run_item
    compiled = entry_kernel.overloads[entry_kernel.signatures[0]]
    library = compiled.library
    obj = getattr(library, "_lamina_object", None) or library._compiled_object
    path = Path(args.map).with_suffix(".o")
    path.write_bytes(obj)
    name = compiled.fndesc.mangled_name
    entry = library.get_pointer_to_function(name)
    symbols = _symbols(path)
    base = entry - symbols[name][0]
    with open(args.map, "w") as f:
        f.write(f"{path}\n")
        for sym, (value, size) in symbols.items():
            f.write(f"{base + value:x} {size} {value:x} {sym}\n")
    return 0


def _symbols(obj: Path) -> dict:
    """Code symbols of an object file: name → (offset in its section, size)."""
    out = subprocess.run(["nm", "-S", "--defined-only", str(obj)], capture_output=True, text=True,
                         check=True).stdout
    table = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "TtWw":
            table[parts[3]] = (int(parts[0], 16), int(parts[1], 16))
    return table


def _short(symbol: str) -> str:
    """``backend.kernels.lights.area._sample_whole_rect`` from Numba's mangled name."""
    head = re.sub(r"B\d+v\d+.*$", "", symbol)
    head = re.sub(r"^_ZN", "", head)
    parts = re.findall(r"\d+([A-Za-z_]\w*?)(?=\d|$)", head)
    return ".".join(parts) or symbol[:60]


def report(perf_data: Path, map_file: Path, lines: bool, top: int) -> None:
    text = map_file.read_text().splitlines()
    obj = Path(text[0])
    table = sorted((int(a, 16), int(s), int(off, 16), n) for a, s, off, n in (l.split() for l in text[1:]))
    starts = [t[0] for t in table]
    samples = subprocess.run(["perf", "script", "-i", str(perf_data), "-F", "ip,dso"],
                             capture_output=True, text=True).stdout.splitlines()
    by_dso, by_function, offsets = collections.Counter(), collections.Counter(), collections.Counter()
    total = 0
    for line in samples:
        parts = line.split(None, 1)
        if not parts:
            continue
        total += 1
        ip = int(parts[0], 16)
        dso = parts[1].strip("() ") if len(parts) > 1 else "?"
        k = bisect.bisect_right(starts, ip) - 1
        if k >= 0 and ip < table[k][0] + table[k][1]:
            by_function[_short(table[k][3])] += 1
            offsets[ip - table[k][0] + table[k][2]] += 1
            by_dso["kernels (shade's library)"] += 1
        else:
            by_dso[Path(dso).name if "/" in dso else dso] += 1
    print(f"\n{total} samples; shares of the whole process (start-up included):")
    for name, n in by_dso.most_common(top):
        print(f"  {100 * n / total:5.1f} %  {name}")
    print("\nkernel functions (LLVM inlines most callees into their callers):")
    for name, n in by_function.most_common(top):
        print(f"  {100 * n / total:5.1f} %  {name}")
    if lines and offsets:
        keys = list(offsets)
        out = subprocess.run(["addr2line", "-e", str(obj), "-j", ".ltext", *map(hex, keys)],
                             capture_output=True, text=True).stdout.splitlines()
        by_line = collections.Counter()
        for key, where in zip(keys, out):
            where = re.sub(r" \(discriminator.*", "", re.sub(r".*/backend/", "backend/", where))
            by_line[where] += offsets[key]
        print("\nsource lines:")
        for name, n in by_line.most_common(top):
            print(f"  {100 * n / total:5.2f} %  {name}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=("cornell", "peer-cornell", "peer-everyday", "peer-presets", "sphere-microflake", "demo"), default="cornell")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lines", action="store_true", help="per source line (debug-info build)")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--map", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return child(args)
    with tempfile.TemporaryDirectory(prefix="lamina-profile-") as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        if args.lines:
            env.update(NUMBA_DEBUGINFO="1", LAMINA_KERNEL_CACHE=str(tmp / "kernels"))
            print("compiling the kernels with debug info (a minute or two) ...", flush=True)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--scene", args.scene,
               "--spp", str(args.spp), "--repeat", str(args.repeat), "--map", str(tmp / "map.txt")]
        if args.lines:                     # compile outside the profile
            subprocess.run([*cmd[:-2], "--repeat", "0", "--map", str(tmp / "warm.txt")], env=env, check=True)
        perf = tmp / "perf.data"
        subprocess.run(["perf", "record", "-F", "2000", "-o", str(perf), "--", *cmd], env=env, check=True,
                       cwd=ROOT)
        report(perf, tmp / "map.txt", args.lines, args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

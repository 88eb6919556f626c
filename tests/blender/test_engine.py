"""The LAMINA render engine: pixels and passes, errors, cancel (no orphan processes), real renders."""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from bpy_harness import backend_renders, backend_supports_ies, requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy,
              pytest.mark.skipif(not sys.platform.startswith("linux"),
                                 reason="the fake backend is a shell script and reads /proc")]

FAKE_CASES = ["fake_pixels", "fake_pixels_border", "fake_failure", "fake_crash", "cancel"]


@pytest.fixture(scope="module")
def fake(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("engine")
    return run_cases("engine_cases", ["fake_pixels", "fake_failure", "cancel"], tmp=tmp,
                     args={"cancel": {"after": 1.0}}) | \
        {"border": run_cases("engine_cases", ["fake_pixels"], tmp=tmp_path_factory.mktemp("border"),
                             args={"fake_pixels": {"border": True}})["fake_pixels"],
         "layers": run_cases("engine_cases", ["fake_pixels"], tmp=tmp_path_factory.mktemp("layers"),
                             args={"fake_pixels": {"layers": 2}})["fake_pixels"],
         "crash": run_cases("engine_cases", ["fake_failure"], tmp=tmp_path_factory.mktemp("crash"),
                            args={"fake_failure": {"mode": "crash"}})["fake_failure"],
         "crash_after_partial": run_cases("engine_cases", ["fake_failure"],
                                          tmp=tmp_path_factory.mktemp("crash_after_partial"),
                                          args={"fake_failure": {"mode": "crash_after_partial"}})["fake_failure"]}


@pytest.fixture(scope="module")
def cluster_render(tmp_path_factory):
    """F12 with the Cluster setting (the fake backend records its command line)."""
    return run_cases("engine_cases", ["fake_pixels"], tmp=tmp_path_factory.mktemp("cluster"),
                     args={"fake_pixels": {"cluster": " tcp://127.0.0.1:8786 "}})["fake_pixels"]


def test_cluster_setting_passes_the_scheduler_to_the_backend(cluster_render):
    r = cluster_render
    assert r["error"] is None and r["exists"]
    argv = r["argv"]
    assert argv[argv.index("--cluster") + 1] == "tcp://127.0.0.1:8786"    # stripped
    assert "--workers" not in argv              # the cluster's workers bring their own threads


def read_exr_parts(path):
    """{part/layer name: (H, W, C) array, channel names} of a (multi-part) EXR, top row first."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    parts = {}
    index = 0
    while inp.seek_subimage(index, 0):
        spec = inp.spec()
        pixels = np.asarray(inp.read_image(index, 0, 0, spec.nchannels, oiio.FLOAT))
        parts[spec.get_string_attribute("name", str(index))] = (
            pixels.reshape(spec.height, spec.width, spec.nchannels), list(spec.channelnames))
        index += 1
    inp.close()
    return parts


def channels_named(parts, suffixes):
    """Stack channels whose full name ends with each suffix (searching every part)."""
    out = []
    for suffix in suffixes:
        for pixels, names in parts.values():
            hits = [i for i, n in enumerate(names) if n == suffix or n.endswith("." + suffix)]
            if hits:
                out.append(pixels[:, :, hits[0]])
                break
        else:
            raise AssertionError(f"no channel ending in {suffix!r} in {[n for _, n in parts.values()]}")
    return np.stack(out, axis=2)


def test_result_pixels_orientation_and_passes(fake):
    r = result_of(fake, "fake_pixels")
    assert r["error"] is None and r["exists"]
    assert "--cluster" not in r["argv"]          # no Cluster setting: rendered on this computer
    parts = read_exr_parts(r["path"])
    h, w = 12, 16
    y, x = np.mgrid[0:h, 0:w]
    combined = channels_named(parts, ["Combined.R", "Combined.G", "Combined.B"])
    np.testing.assert_array_equal(combined[:, :, 0], x + 1000 * y)   # EXR row 0 = top, like the backend
    np.testing.assert_array_equal(combined[:, :, 1], 0.5)
    albedo = channels_named(parts, ["Denoising Albedo.R", "Denoising Albedo.G", "Denoising Albedo.B"])
    normal = channels_named(parts, ["Denoising Normal.X", "Denoising Normal.Y", "Denoising Normal.Z"])
    np.testing.assert_allclose(albedo[0, 0], [0.1, 0.2, 0.3], rtol=1e-6)
    np.testing.assert_allclose(normal[0, 0], [0, 0, 1])


def test_every_view_layer_gets_its_pixels(fake):
    r = fake["layers"]
    assert r["error"] is None
    parts = read_exr_parts(r["path"])
    h, w = 12, 16
    y, x = np.mgrid[0:h, 0:w]
    for layer in ("ViewLayer", "Layer2"):
        red = channels_named(parts, [f"{layer}.Combined.R"])[:, :, 0]
        np.testing.assert_array_equal(red, x + 1000 * y)


def test_border_render_places_the_region(fake):
    r = fake["border"]
    assert r["error"] is None
    parts = read_exr_parts(r["path"])
    combined = channels_named(parts, ["Combined.R"])[:, :, 0]
    h, w = 12, 16
    y, x = np.mgrid[0:h, 0:w]
    # Border x ∈ [0.25, 0.75), y ∈ [0, 0.5) from the bottom: columns 4..11, the bottom six rows.
    inside = (x >= 4) & (x < 12) & (y >= 6)
    np.testing.assert_array_equal(combined[inside], (x + 1000 * y)[inside])
    assert np.all(combined[~inside] == 0)


def test_a_cold_kernel_cache_speaks_on_the_console(tmp_path):
    # Under `blender -b` the status bar is not seen: the compile's start and end are printed.
    r = run_cases("engine_cases", ["fake_compiling"], tmp=tmp_path)
    assert result_of(r, "fake_compiling")["render_error"] is None
    lines = (r["_stdout"] + r["_stderr"]).splitlines()
    assert sum(l.startswith("Lamina: compiling render kernels (first run only") for l in lines) == 1, lines
    assert sum(l == "Lamina: compiled render kernels in 12.3 s" for l in lines) == 1, lines


def test_backend_error_makes_render_raise(fake):
    r = result_of(fake, "fake_failure")
    assert r["error"] is not None and "cannot read image (fake)" in r["error"]


def test_backend_crash_makes_render_raise(fake):
    r = fake["crash"]
    assert r["error"] is not None and "ZeroDivisionError: fake crash in the renderer" in r["error"]


def test_a_crash_after_a_partial_result_keeps_that_image(fake):
    """Nothing lost: the renderer dies after it wrote a partial image; the render reports the
    error and says the image is partial, and the Render Result still holds that image (the
    fake's red = x + 1000·y of a 16 × 12 film, so its largest value is 15 + 1000·11)."""
    r = fake["crash_after_partial"]
    assert r["error"] is not None and "MemoryError: fake crash after a partial result" in r["error"]
    assert "the image shows the last partial result" in r["error"]
    assert r["red_max"] == 15 + 1000 * 11


def _alive(pid: int, started: int, settle: float = 2.0) -> bool:
    """Still running ``settle`` seconds later: same PID and start time (PIDs get reused), not a
    zombie. (A SIGKILLed process closes its files first and may look alive for a moment.)"""
    import time
    deadline = time.monotonic() + settle
    while True:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except FileNotFoundError:
            return False
        if fields[0] == "Z" or int(fields[19]) != started:
            return False
        if time.monotonic() > deadline:
            return True
        time.sleep(0.02)


def test_cancel_kills_child_and_workers(fake):
    r = result_of(fake, "cancel")
    assert len(r["pids"]) == 3, "the fake renderer should have started 2 workers"
    assert not [pid for pid, started in r["pids"] if _alive(pid, started)], "orphan processes survived the cancel"
    print(f"\ncancel latency {r['cancel_latency']:.2f} s (child ignores SIGTERM: grace period + kill)")
    assert r["cancel_latency"] < 3.0
    assert r["error"] is None                      # a cancel is not an error


needs_renderer = pytest.mark.skipif(not backend_renders(("diffuse",), ("point",), ("constant",)),
                                    reason="the backend cannot render diffuse + point + constant world yet")


@needs_renderer
def test_corrupt_texture_fails_with_backend_message_when_asked_to(tmp_path):
    r = result_of(run_cases("engine_cases", ["corrupt_texture"], tmp=tmp_path), "corrupt_texture")
    assert r["error"] is not None and "broken.png" in r["error"]


@pytest.mark.skipif(not backend_renders(("diffuse",), ("point", "area"), ("constant",)),
                    reason="the backend cannot render diffuse + point/area + constant world yet")
def test_engine_render_equals_cli_render(tmp_path):
    """The acceptance scene: rendered through LAMINA and written with write_still, then the
    exported scene rendered by the CLI: finite, plausible, equal within noise."""
    import subprocess
    layered = backend_renders(("layered",))
    ies = backend_supports_ies()
    r = result_of(run_cases("engine_cases", ["real_render"], tmp=tmp_path,
                            args={"real_render": {"layered": layered, "ies": ies}}), "real_render")
    print(f"\nacceptance scene (layered stack: {layered}, IES: {ies}) rendered in {r['seconds']:.1f} s")
    assert r["error"] is None, r["error"]
    engine = read_exr_parts(r["path"])
    cli_out = tmp_path / "cli.exr"
    subprocess.run([sys.executable, "-m", "backend", "render", r["scene"], "-o", str(cli_out),
                    "--workers", "1"], check=True, cwd=os.environ.get("LAMINA_ROOT"))
    cli = read_exr_parts(cli_out)
    a = channels_named(engine, ["R", "G", "B"])
    b = channels_named(cli, ["R", "G", "B"])
    var = channels_named(cli, ["variance.R", "variance.G", "variance.B"])
    assert np.isfinite(a).all() and a.min() >= 0 and 0.01 < a.mean() < 50
    # Same seed and samples: identical up to noise (4 standard errors per pixel, plus float slack).
    bound = 4 * np.sqrt(2 * var) + 1e-5
    print(f"max |engine − CLI| = {np.abs(a - b).max():.3g} (mean pixel value {b.mean():.3g})")
    assert np.mean(np.abs(a - b) <= bound) > 0.999


@pytest.mark.skipif(not backend_renders(("diffuse",), ("point", "sun", "area"), ("constant",)),
                    reason="the backend cannot render diffuse + point/sun/area + constant world yet")
def test_brightness_parity_with_cycles(tmp_path):
    """Per-region means of a diffuse scene agree with Cycles within 2 % (plus 4 standard errors)."""
    r = result_of(run_cases("engine_cases", ["cycles_parity"], tmp=tmp_path), "cycles_parity")
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64)
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64)
    assert np.isfinite(lam).all()
    lum_c = cyc @ [0.2126, 0.7152, 0.0722]
    lum_l = lam @ [0.2126, 0.7152, 0.0722]
    h, w = lum_c.shape
    rows, cols = 3, 4
    lines = []
    worst = 0.0
    for i in range(rows):
        for j in range(cols):
            block = (slice(i * h // rows, (i + 1) * h // rows), slice(j * w // cols, (j + 1) * w // cols))
            c, l = lum_c[block], lum_l[block]
            # Standard error of each region mean, estimated from the pixel scatter of the
            # difference image (both renders are noisy; pixels are nearly independent).
            diff = (l - c).ravel()
            se = diff.std(ddof=1) / np.sqrt(diff.size) / max(c.mean(), 1e-9)
            ratio = l.mean() / max(c.mean(), 1e-9)
            worst = max(worst, abs(ratio - 1) - 4 * se)
            lines.append(f"region {i},{j}: Cycles {c.mean():.4f}  Lamina {l.mean():.4f}  ratio {ratio:.4f} ± {se:.4f}")
            assert abs(ratio - 1) <= 0.02 + 4 * se, "\n".join(lines)
    print(f"\nCycles {r['cycles_seconds']:.1f} s, Lamina {r['lamina_seconds']:.1f} s\n" + "\n".join(lines))


def test_saved_file_animation_renders_every_frame(tmp_path):
    r = result_of(run_cases("engine_cases", ["saved_file_animation"], tmp=tmp_path), "saved_file_animation")
    assert r["error"] is None
    assert [p.rsplit("/", 1)[1] for p in r["files"]] == ["f_0001.exr", "f_0002.exr"]
    greens = [channels_named(read_exr_parts(p), ["G"])[0, 0, 0] for p in r["files"]]
    assert greens == [11.0, 12.0]                     # animated seed: seed + frame, per frame

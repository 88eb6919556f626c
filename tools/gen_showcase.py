#!/usr/bin/env python3
"""Generate the showcase scene: showcase/showcase.json and its meshes (deterministic).

    python tools/gen_showcase.py                       # rewrite showcase/showcase.json + meshes/*.npz
    python tools/dev.py showcase [--spp N] [...]       # render it to out/showcase.exr / .png

Four objects on a lacquered table (issue 6, deliverable 6):
  * a sphere with the project's 3-layer anisotropic microflake reference stack;
  * a vase of amber resin: a crisp rough dielectric over a forward-scattering HG medium;
  * a cup of enamelled silver: a textured absorbing medium above a conductor;
  * a ring (torus) of gold under a brushed coat: an anisotropic rough dielectric over a
    homogeneous medium over a very rough conductor;
lit by an IES spot (ERCO "defined spot", from tests/data/ies, copied next to the scene) from
above and a directional area light (cutoff 40°, beam 25°) from the left, with a dim fill.

Materials are referenced by preset name (presets/), so the scene shows the library in use.
Lathe meshes (vase, cup) and the torus carry UVs whose u runs around the axis, so anisotropy
follows the circumference and the enamel pattern wraps around the cup.
"""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "showcase"
sys.path.insert(0, str(ROOT))

from backend.preset_thumbnails import look_at  # noqa: E402  (after the sys.path line)

TABLE_TOP = 0.78   # metres: height of the table surface


# --------------------------------------------------------------------------- meshes

def lathe(profile: np.ndarray, segments: int = 96) -> dict:
    """Revolve an (r, z) profile polyline about +Z. Returns positions/indices/normals/uvs arrays.

    The profile is walked so that its left side (seen along increasing index, looking from +Y
    at the r–z plane) is the outside: counter-clockwise triangles face outwards. u = angle / 2π,
    v = arc length / total. Points at r = 0 collapse the fan; their zero-area triangles are
    removed. Normals are area-weighted vertex normals (smooth shading).
    """
    r, z = profile[:, 0], profile[:, 1]
    m = len(profile)
    ang = np.linspace(0, 2 * np.pi, segments + 1)
    arc = np.concatenate([[0], np.cumsum(np.hypot(np.diff(r), np.diff(z)))])
    v = arc / arc[-1]
    P = np.stack([r[None, :] * np.cos(ang)[:, None], r[None, :] * np.sin(ang)[:, None],
                  np.broadcast_to(z, (segments + 1, m))], axis=-1).reshape(-1, 3)
    UV = np.stack([np.broadcast_to((ang / (2 * np.pi))[:, None], (segments + 1, m)),
                   np.broadcast_to(v[None, :], (segments + 1, m))], axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(segments), np.arange(m - 1), indexing="ij")
    a = (i * m + j).ravel()
    b = a + 1               # next profile point
    c = a + m               # next angle
    d = c + 1
    tris = np.concatenate([np.stack([a, c, d], 1), np.stack([a, d, b], 1)])
    return finish_mesh(P, tris, UV)


def torus(major: float, minor: float, seg_u: int = 96, seg_v: int = 48) -> dict:
    """Torus about +Z; u runs around the major circle (the 'brushing' direction), v around the tube."""
    uu = np.linspace(0, 2 * np.pi, seg_u + 1)
    vv = np.linspace(0, 2 * np.pi, seg_v + 1)
    U, V = np.meshgrid(uu, vv, indexing="ij")
    rho = major + minor * np.cos(V)
    P = np.stack([rho * np.cos(U), rho * np.sin(U), minor * np.sin(V)], -1).reshape(-1, 3)
    UV = np.stack([U / (2 * np.pi), V / (2 * np.pi)], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(seg_u), np.arange(seg_v), indexing="ij")
    a = (i * (seg_v + 1) + j).ravel()
    b = a + 1
    c = a + seg_v + 1
    d = c + 1
    tris = np.concatenate([np.stack([a, c, d], 1), np.stack([a, d, b], 1)])
    return finish_mesh(P, tris, UV)


def finish_mesh(P: np.ndarray, tris: np.ndarray, UV: np.ndarray) -> dict:
    e1 = P[tris[:, 1]] - P[tris[:, 0]]
    e2 = P[tris[:, 2]] - P[tris[:, 0]]
    fn = np.cross(e1, e2)
    area2 = np.linalg.norm(fn, axis=1)
    keep = area2 > 1e-12 * max(area2.max(), 1e-30)
    tris, fn = tris[keep], fn[keep]
    # Seam vertices (u = 0 and u = 1) are distinct: average normals over equal positions.
    key = np.round(P / 1e-7).astype(np.int64)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    acc = np.zeros((inverse.max() + 1, 3))
    for k in range(3):
        np.add.at(acc, inverse[tris[:, k]], fn)
    N = acc[inverse]
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-30)
    return {"positions": P.astype(np.float32), "indices": tris.astype(np.int32),
            "normals": N.astype(np.float32), "uvs": UV.astype(np.float32)}


def rounded(points, radius: float, steps: int = 6) -> np.ndarray:
    """A polyline with its interior corners replaced by circular arcs (lathe profiles)."""
    pts = [np.asarray(p, float) for p in points]
    out = [pts[0]]
    for k in range(1, len(pts) - 1):
        p0, p1, p2 = pts[k - 1], pts[k], pts[k + 1]
        d0 = (p0 - p1) / np.linalg.norm(p0 - p1)
        d2 = (p2 - p1) / np.linalg.norm(p2 - p1)
        rr = min(radius, 0.45 * np.linalg.norm(p0 - p1), 0.45 * np.linalg.norm(p2 - p1))
        a, b = p1 + d0 * rr, p1 + d2 * rr
        for t in np.linspace(0, 1, steps):
            q = (1 - t) ** 2 * a + 2 * (1 - t) * t * p1 + t ** 2 * b   # quadratic Bézier corner
            out.append(q)
    out.append(pts[-1])
    return np.array(out)


def cup_profile() -> np.ndarray:
    """Tumbler, 14 cm tall, 2 mm walls: outer bottom → outer wall → rim → inner wall → inner bottom."""
    return rounded([(0.0, 0.0), (0.05, 0.0), (0.068, 0.14), (0.066, 0.14), (0.048, 0.006),
                    (0.0, 0.006)], 0.004)


def vase_profile() -> np.ndarray:
    """A closed bulbous bottle, 26 cm tall (a solid of revolution: outside surface only)."""
    t = np.linspace(0, 1, 40)
    z = 0.26 * t
    r = 0.035 + 0.065 * np.sin(np.pi * np.clip(t / 0.75, 0, 1)) ** 1.5 + 0.012 * (t > 0.75) * (t - 0.75) / 0.25
    r[0] = 0.05
    prof = [(0.0, 0.0)] + list(zip(r, z)) + [(0.0, 0.26)]
    return np.array(prof)


# --------------------------------------------------------------------------- scene

def translate(x, y, z, s=1.0) -> list:
    return [[s, 0, 0, x], [0, s, 0, y], [0, 0, s, z], [0, 0, 0, 1]]


def box(cx, cy, cz, sx, sy, sz) -> list:
    return [[sx, 0, 0, cx], [0, sy, 0, cy], [0, 0, sz, cz], [0, 0, 0, 1]]


def scene() -> dict:
    eye, target = np.array([0.12, -1.55, 1.3]), np.array([0.03, 0.06, 0.88])
    hw, hh = 0.42, 0.42 * 9 / 16
    spot_at = np.array([0.02, 0.05, 2.05])
    box_at = np.array([-2.1, -0.5, 1.55])
    legs = [(sx * 0.74, sy * 0.36) for sx in (-1, 1) for sy in (-1, 1)]
    return {
        "format": "lamina-scene", "version": 1,
        "_comment": "Lamina showcase (generated by tools/gen_showcase.py; render: python tools/dev.py showcase)",
        "film": {"width": 640, "height": 360},
        "camera": {"type": "perspective", "to_world": look_at(eye, target),
                   "frame": [[hw, hh, -1], [hw, -hh, -1], [-hw, -hh, -1], [-hw, hh, -1]]},
        "render": {"spp": 128, "max_bounces": 10, "seed": 1},
        "materials": {
            "microflake": "reference-microflake-3layer",
            "amber": "amber-resin",
            "enamel": "enamelled-silver",
            "gold": "gold-under-brushed-coat",
            "table": "lacquered-wood",
            "floor": {"type": "diffuse", "color": [0.32, 0.3, 0.28]},
            "wall": {"type": "diffuse", "color": [0.55, 0.55, 0.58]},
        },
        "meshes": {
            "sphere": {"shape": "sphere", "radius": 0.15, "segments": 128},
            "vase": {"file": "meshes/vase.npz"},
            "cup": {"file": "meshes/cup.npz"},
            "ring": {"file": "meshes/ring.npz"},
            "cube": {"shape": "cube", "size": 1.0},
            "plane": {"shape": "rectangle", "size": [12, 12]},
        },
        "objects": [
            {"name": "microflake sphere", "mesh": "sphere",
             "to_world": translate(-0.44, 0.02, TABLE_TOP + 0.15), "materials": ["microflake"]},
            {"name": "amber vase", "mesh": "vase", "to_world": translate(-0.12, 0.2, TABLE_TOP),
             "materials": ["amber"]},
            {"name": "enamel cup", "mesh": "cup", "to_world": translate(0.17, -0.1, TABLE_TOP, 1.35),
             "materials": ["enamel"]},
            {"name": "gold ring", "mesh": "ring", "to_world": translate(0.47, 0.08, TABLE_TOP + 0.045),
             "materials": ["gold"]},
            {"name": "table top", "mesh": "cube", "to_world": box(0, 0, TABLE_TOP - 0.02, 1.7, 0.86, 0.04),
             "materials": ["table"]},
            *[{"name": f"leg {k}", "mesh": "cube", "to_world": box(x, y, (TABLE_TOP - 0.04) / 2, 0.05, 0.05,
                                                                   TABLE_TOP - 0.04),
               "materials": ["table"]} for k, (x, y) in enumerate(legs)],
            {"name": "floor", "mesh": "plane", "materials": ["floor"]},
            {"name": "wall", "mesh": "plane",
             "to_world": [[1, 0, 0, 0], [0, 0, -1, 2.2], [0, 1, 0, 0], [0, 0, 0, 1]], "materials": ["wall"]},
        ],
        "lights": [
            {"type": "point", "_comment": "IES spot straight down onto the table (ERCO defined spot, 1908 lm)",
             "to_world": translate(*spot_at), "power": 0.4, "color": [1.0, 0.9, 0.78],
             "ies": {"file": "erco_defined_spot_lm95.ies"}},
            {"type": "area", "_comment": "directional soft box: full radiance within 25° of its axis, none beyond 40°",
             "to_world": look_at(box_at, target), "shape": "rectangle", "size": 0.9, "size_y": 0.6,
             "power": 12.0, "color": [0.85, 0.92, 1.0], "cutoff_angle": 40.0, "beam_width": 25.0},
        ],
        "world": {"type": "constant", "color": [0.035, 0.04, 0.05], "strength": 1.0},
    }


def main() -> int:
    (OUT / "meshes").mkdir(parents=True, exist_ok=True)
    meshes = {"vase": lathe(vase_profile()), "cup": lathe(cup_profile()), "ring": torus(0.12, 0.045)}
    for name, m in meshes.items():
        np.savez_compressed(OUT / "meshes" / f"{name}.npz", **m)
        print(f"wrote showcase/meshes/{name}.npz ({len(m['indices'])} triangles)")
    ies = ROOT / "tests" / "data" / "ies" / "erco_defined_spot_lm95.ies"
    shutil.copyfile(ies, OUT / ies.name)
    (OUT / "showcase.json").write_text(json.dumps(scene(), indent=1) + "\n", encoding="utf-8")
    print("wrote showcase/showcase.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())

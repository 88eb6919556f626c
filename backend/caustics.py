"""Whether a scene's caustics are light traced, and the tables the photon kernel reads
(backend/kernels/caustics.py explains the method and the partition with the path tracer).

``plan_caustics`` returns a ``CausticPlan``: the kernel's ``CausticTables`` and the path tracer's
three per-light and per-material flags (which lights are covered, which materials are plain,
which are casters), or, where the scene cannot use light tracing, empty ones and the reason (the
path tracer then renders every caustic, as before).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels import materials as km
from .kernels.caustics import (P_CROP, P_DS, P_DT, P_FAR, P_H, P_INV, P_N, P_NEAR, P_O, P_SUPPORT, P_TL, P_W,
                               PROJ_SIZE, CausticTables)
from .kernels.lights import area as _area
from .kernels.lights import mesh as _mesh
from .kernels.lights import point as _point
from .kernels.lights import sun as _sun

#: Added to the scene seed for the photons' keys (a stream of their own).
PHOTON_SEED_SALT = 0xC0FFEE5EED
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


#: Glossy materials at least this sharp (GGX/Beckmann α of the reflecting surface: a metal, the
#: top of a coat) pass photons on as smooth ones do: their caustics (a clear-coated ball's
#: light on the floor) are the light tracer's too. Path tracing finds them by light sampling
#: at the glossy surface, whose lobe weighs the light's points very unequally when it is this
#: narrow. Broader lobes stay with the path tracer: with α ≤ 0.1 the demo's two layered balls
#: (tops α 0.05) were casters, 0.1 photon per sample spread over the floor they light, and the
#: median pixel's noise rose 1.05 → 1.20 % (1.43 % with their walks as casters and receivers).
CAUSTIC_ALPHA = 0.02
#: Metals are casters up to this α. They reflect most of the light, so a gold ball's caustic is
#: bright even where its lobe is ten times wider than a coat's: on the ground beside a gold
#: sphere (α 0.09) under a 5° sun (benchmarks/peers everyday without its clamp, 96², 16 spp,
#: 12 seeds) the ground's summed variance fell 29.0 → 7.9, its median pixel's rose 8 %. A
#: dielectric's 4 % reflection at α 0.09 (the red plastic sphere there) made a faint caustic,
#: whose photons only added noise (ground median +26 % with it a caster too).
CAUSTIC_ALPHA_METAL = 0.1


@dataclass
class CausticPlan:
    tables: CausticTables | None     # None: not light traced
    light: np.ndarray                # (lights,) bool, covered; empty when not light traced
    plain: np.ndarray                # (materials,) bool; empty when not light traced
    caster: np.ndarray               # (materials,) bool: photons pass through; empty likewise
    reason: str                      # why not ("" when light traced)

    @property
    def active(self) -> bool:
        return self.tables is not None


def _off(reason: str) -> CausticPlan:
    return CausticPlan(None, np.zeros(0, np.bool_), np.zeros(0, np.bool_), np.zeros(0, np.bool_), reason)


def plain_materials(mt) -> np.ndarray:
    """Materials the photon kernel and the path tracer's chain flag understand: analytic kinds
    without a mix, a layered stack, a normal map or a bump."""
    kind = np.asarray(mt.kind)
    return (~np.isin(kind, (km.LAYERED, km.MIX, km.ADD))) & (np.asarray(mt.nmode) == 0) & ~np.asarray(mt.bump, bool)


def can_be_delta(mt, plain: np.ndarray) -> np.ndarray:
    """Plain materials that may be a smooth dielectric or conductor somewhere: roughness 0, or
    roughness from a texture (which may be 0 in places)."""
    out = np.zeros(len(mt.kind), np.bool_)
    for m, k in enumerate(mt.kind):
        if not plain[m]:
            continue
        if k == km.DIELECTRIC:
            au, av = km.D_AU, km.D_AV
        elif k == km.CONDUCTOR:
            au, av = km.AU, km.AV
        else:
            continue
        textured = mt.tex[m, au] >= 0 or mt.tex[m, av] >= 0
        out[m] = textured or (mt.values[m, au] <= 0.0 and mt.values[m, av] <= 0.0)
    return out


def sharp_glossy(mt, plain: np.ndarray) -> np.ndarray:
    """Plain glossy materials whose reflecting surface has α ≤ CAUSTIC_ALPHA everywhere
    (untextured roughness; CAUSTIC_ALPHA_METAL for a metal): rough metals and dielectrics, a
    coated kind's top (closed form or table)."""
    from .kernels.bsdf import tabulated as _tab
    out = np.zeros(len(mt.kind), np.bool_)
    for m, k in enumerate(mt.kind):
        if not plain[m]:
            continue
        if k in (km.DIELECTRIC, km.CONDUCTOR, km.COATED_DIFFUSE):
            au, av = {km.DIELECTRIC: (km.D_AU, km.D_AV), km.CONDUCTOR: (km.AU, km.AV),
                      km.COATED_DIFFUSE: (km.CD_AU, km.CD_AV)}[int(k)]
            if mt.tex[m, au] < 0 and mt.tex[m, av] < 0:
                limit = CAUSTIC_ALPHA_METAL if k == km.CONDUCTOR else CAUSTIC_ALPHA
                out[m] = max(mt.values[m, au], mt.values[m, av]) <= limit
        elif k == km.TABULATED:
            out[m] = mt.tables[int(mt.values[m, km.TB_TAB]) + _tab.H_ALPHA] <= CAUSTIC_ALPHA
    return out


def _projection(camera, width: int, height: int, support: float, crop=None) -> np.ndarray | None:
    """The camera as kernels/caustics.py ``project`` reads it (columns P_*), and the pixels that
    are rendered (a crop: the splats stay inside it, as the samples do)."""
    M = np.asarray(camera.to_world, np.float64)
    A = M[:3, :3]
    frame = np.asarray(camera.frame, np.float64)       # tr, br, bl, tl (camera space)
    tl = A @ frame[3]
    a = A @ (frame[0] - frame[3])                       # s: left → right
    b = A @ (frame[2] - frame[3])                       # t: top → bottom
    n = np.cross(a, b)
    g = np.array([[a @ a, a @ b], [a @ b, b @ b]])
    det = g[0, 0] * g[1, 1] - g[0, 1] * g[1, 0]
    if not (np.isfinite(det) and det > 1e-12 * g[0, 0] * g[1, 1]) or not np.isfinite(np.linalg.det(A)) \
            or abs(np.linalg.det(A)) < 1e-300:
        return None                     # a degenerate frame or transform: no projection
    gi = np.array([[g[1, 1], -g[0, 1]], [-g[1, 0], g[0, 0]]]) / det
    ds = gi[0, 0] * a + gi[0, 1] * b
    dt = gi[1, 0] * a + gi[1, 1] * b
    p = np.zeros(PROJ_SIZE)
    p[P_O:P_O + 3] = M[:3, 3]
    p[P_TL:P_TL + 3] = tl
    p[P_N:P_N + 3] = n
    p[P_DS:P_DS + 3] = ds
    p[P_DT:P_DT + 3] = dt
    p[P_INV:P_INV + 9] = np.linalg.inv(A).ravel()
    p[P_NEAR] = camera.clip_start
    p[P_FAR] = camera.clip_end if np.isfinite(camera.clip_end) else np.inf
    p[P_W] = width
    p[P_H] = height
    p[P_SUPPORT] = support
    p[P_CROP:P_CROP + 4] = crop if crop is not None else (0, 0, width, height)
    return p


def plan_caustics(scene, tracer) -> CausticPlan:
    """Decide for ``tracer`` (a PathTracer whose material and light tables exist)."""
    s = scene.settings
    ratio = float(getattr(s, "caustic_photons", 0.0))
    if not ratio > 0.0:
        return _off("caustic_photons is 0")
    cam = scene.camera
    if cam.kind != "perspective":
        return _off("the camera is not perspective")
    if cam.aperture_radius > 0.0 and cam.focus_distance > 0.0:
        return _off("the camera has depth of field")
    if tracer.motion:
        return _off("motion blur")
    if getattr(tracer.accel.queries, "direct", None) is None:
        return _off("embree cannot be called from compiled code here")
    vis = tracer.vis
    if vis.gated or vis.light_linking or vis.filter_shadows or vis.skip_hits or vis.shadow_linked.size:
        return _off("ray visibility, light or shadow linking")
    if float(getattr(s, "clamp", 0.0)) > 0.0:
        return _off("Clamp Indirect is on")
    mt = tracer.materials
    plain = plain_materials(mt)
    caster = can_be_delta(mt, plain) | sharp_glossy(mt, plain)
    soup = tracer.soup
    if soup.count == 0:
        return _off("no triangles")
    casters = caster[np.asarray(soup.material)]
    if not casters.any():
        return _off("no smooth glass, mirror or sharp glossy surface")
    lt = tracer.light_table
    covered = np.zeros(len(tracer.lights), np.bool_)
    for li in range(len(tracer.lights)):
        k = int(lt.kind[li])
        if k == _sun.SUN:
            covered[li] = float(LUMINANCE @ lt.params[li, _sun.S_IRRADIANCE:_sun.S_IRRADIANCE + 3]) > 0.0
        elif k == _area.AREA and lt.iparams[li, _area.I_EMITS] != 0:
            covered[li] = True
        elif k == _mesh.MESH:
            covered[li] = lt.iparams[li, _mesh.I_DIST_OFF] >= 0
        elif k == _point.POINT:
            delta = lt.iparams[li, _point.I_SHAPE] == _point.SHAPE_DELTA
            col = _point.P_INTENSITY if delta else _point.P_RADIANCE
            covered[li] = ((delta or lt.params[li, _point.P_RADIUS] > 0.0)
                           and float(LUMINANCE @ lt.params[li, col:col + 3]) > 0.0)
    if not covered.any():
        return _off("no light the photons can leave (area, point, spot, sun, emissive surface)")
    spheres = caster_spheres(soup, casters)
    allv = np.asarray(soup.vertices, np.float64).reshape(-1, 3)
    mid = 0.5 * (allv.min(axis=0) + allv.max(axis=0))
    far = float(np.sqrt(((allv - mid) ** 2).sum(axis=1)).max()) * 2.02 + 1.0
    area = spheres[:, 3] ** 2
    scdf = np.concatenate([[0.0], np.cumsum(area) / area.sum()])
    scdf[-1] = 1.0
    lights = np.flatnonzero(covered).astype(np.int64)
    weight = np.array([sum(_flux_estimate(lt, int(li), sp[:3], sp[3]) for sp in spheres) for li in lights])
    if not weight.sum() > 0.0:
        return _off("the covered lights send nothing towards the casters")
    cdf = np.concatenate([[0.0], np.cumsum(weight) / weight.sum()])
    cdf[-1] = 1.0
    pf = scene.pixel_filter
    proj = _projection(cam, scene.width, scene.height, pf.support, getattr(scene, "crop", None))
    if proj is None or not np.all(np.isfinite(proj[:P_NEAR])):
        return _off("the camera's frame cannot be inverted")
    tables = CausticTables(lights, cdf, spheres, scdf, far, proj,
                           np.ascontiguousarray(pf._cdf, np.float64), np.int64(tracer.max_segments - 2),
                           np.uint64((int(s.seed) + PHOTON_SEED_SALT) % (1 << 64)))
    return CausticPlan(tables, covered, plain, caster, "")


#: Casters are aimed at per object, each in its own bounding sphere; beyond this many objects,
#: one sphere around them all (every photon then checks fewer spheres).
MAX_SPHERES = 16


def caster_spheres(soup, casters: np.ndarray) -> np.ndarray:
    """(k, 4): centre and radius of a sphere around each object's caster triangles (the centre
    of their bounding box), or one around all of them past MAX_SPHERES objects."""
    objects = np.unique(np.asarray(soup.object_id)[casters])
    groups = [casters & (np.asarray(soup.object_id) == o) for o in objects] if objects.size <= MAX_SPHERES \
        else [casters]
    out = []
    for g in groups:
        v = np.asarray(soup.vertices[g], np.float64).reshape(-1, 3)
        c = 0.5 * (v.min(axis=0) + v.max(axis=0))
        r = float(np.sqrt(((v - c) ** 2).sum(axis=1)).max()) * (1.0 + 1e-6) + 1e-6
        out.append([*c, r])
    return np.array(out, np.float64)


def _cone_solid_angle(radius, dist):
    """Solid angle of the cone a sphere of ``radius`` fills seen from ``dist`` away (2π, half the
    sphere of directions, from inside it: what the flux estimates count there)."""
    dist = np.asarray(dist, np.float64)
    ratio = np.minimum(radius / np.maximum(dist, 1e-300), 1.0)
    return np.where(dist <= radius, 2.0 * np.pi, 2.0 * np.pi * (1.0 - np.sqrt(np.maximum(1.0 - ratio ** 2, 0.0))))


def _flux_estimate(lt, li: int, center: np.ndarray, radius: float) -> float:
    """Roughly the flux light ``li`` sends at a caster sphere (luminance), for choosing which
    light a photon leaves: only the variance depends on it."""
    P = lt.params
    if int(lt.kind[li]) == _sun.SUN:
        return float(LUMINANCE @ P[li, _sun.S_IRRADIANCE:_sun.S_IRRADIANCE + 3]) * np.pi * radius ** 2
    if int(lt.kind[li]) == _point.POINT:
        # radiance × the light's cross-section × the cone the caster fills (grown by the light's
        # radius, as the photons aim), times the spot or IES factor towards the caster's centre
        # (at least 0.1: a spot whose cone only grazes the caster still sends photons there)
        r = float(P[li, _point.P_RADIUS])
        d = center - P[li, _point.P_POS:_point.P_POS + 3]
        dist = float(np.linalg.norm(d))
        R = radius + r
        solid = float(_cone_solid_angle(R, dist))
        f = 1.0
        if dist > 0.0:
            f = float(_point.directional_factor(P, lt.iparams, li, lt.aux, tuple(float(x) for x in d / dist)))
        if lt.iparams[li, _point.I_SHAPE] == _point.SHAPE_DELTA:
            return float(LUMINANCE @ P[li, _point.P_INTENSITY:_point.P_INTENSITY + 3]) * solid * max(f, 0.1)
        lum = float(LUMINANCE @ P[li, _point.P_RADIANCE:_point.P_RADIANCE + 3])
        return lum * np.pi * r * r * solid * max(f, 0.1)
    if int(lt.kind[li]) == _mesh.MESH:
        # every triangle's radiance × area × the cone the caster fills from its centroid × the
        # cosine there (at least 0.05, as for an area light)
        I, A = lt.iparams, lt.aux
        count = int(I[li, _mesh.I_COUNT])
        off = int(I[li, _mesh.I_TRI_OFF])
        T = A[off:off + count * _mesh.TRI_STRIDE].reshape(count, _mesh.TRI_STRIDE)
        cen = T[:, _mesh.T_V0:_mesh.T_V0 + 3] + (T[:, _mesh.T_E1:_mesh.T_E1 + 3] + T[:, _mesh.T_E2:_mesh.T_E2 + 3]) / 3
        d = center - cen
        dist = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        solid = _cone_solid_angle(radius, dist)
        cos = (d * T[:, _mesh.T_N:_mesh.T_N + 3]).sum(axis=1) / dist
        cos = np.where(T[:, _mesh.T_TWO_SIDED] != 0.0, np.abs(cos), cos)
        lum = T[:, _mesh.T_RAD:_mesh.T_RAD + 3] @ LUMINANCE
        return float((lum * T[:, _mesh.T_AREA] * solid * np.maximum(cos, 0.05)).sum())
    c = P[li, _area.A_CENTER:_area.A_CENTER + 3]
    n = P[li, _area.A_N:_area.A_N + 3]
    d = center - c
    dist = float(np.linalg.norm(d))
    solid = float(_cone_solid_angle(radius, dist))
    cos = 0.5 if dist <= radius else max(float(d @ n) / dist, 0.05)
    lum = float(LUMINANCE @ P[li, _area.A_SCALE:_area.A_SCALE + 3])
    return lum * P[li, _area.A_AREA] * solid * cos

"""``Scene.lamina``: sampling and engine settings (written to the scene file's ``render``).

The render settings of the scene file (samples, bounces, seed, ...) are made here from the
backend's one table of them (backend/render_settings.py): their names, ranges, defaults and
descriptions are written there once. The rest (viewport, denoising, workers, ...) are the
add-on's own."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from ...backend.render_settings import INT32_MAX, SETTINGS
from ..constants import ESTIMATORS, PDF_MODES

FILTERS = (
    ("BLACKMAN_HARRIS", "Blackman-Harris", "Cycles' default pixel filter", 0),
    ("GAUSSIAN", "Gaussian", "Gaussian pixel filter", 1),
    ("BOX", "Box", "No filtering (one pixel wide)", 2),
)


class LaminaRenderSettings(PropertyGroup):
    viewport_samples: IntProperty(name="Viewport Samples", default=32, min=0, soft_max=4096, max=1 << 24,
                                  description="Samples per pixel of Rendered shading in the viewport, "
                                              "after which it stops; 0 = until stopped")
    use_animated_seed: BoolProperty(name="Animated Seed", default=False,
                                    description="Add the frame number to the seed (noise changes per frame)")
    workers: IntProperty(name="Workers", default=0, min=0, max=64,
                         description="Parallel render workers (threads of the renderer process); 0 = one per CPU core")
    cluster: StringProperty(name="Cluster", default="",
                            description="Render F12 and animation frames on a Dask cluster: the "
                                        "scheduler's address (tcp://HOST:8786). Empty = this computer. "
                                        "Needs the distributed package for Blender's Python; see "
                                        "docs/cluster.md")
    filter_type: EnumProperty(name="Pixel Filter", items=FILTERS, default="BLACKMAN_HARRIS")
    filter_width: FloatProperty(name="Filter Width", default=1.5, min=0.01, max=10.0, subtype='PIXEL')
    estimator: EnumProperty(name="Layered Estimator", items=ESTIMATORS, default="AUTOMATIC",
                            description="How layered materials are evaluated")
    pdf_mode: EnumProperty(name="Layered PDF", items=PDF_MODES, default="LOBES",
                           description="Which pdf of layered materials is used for MIS weights")
    use_denoising: BoolProperty(
        name="Denoise", default=True,
        description="Denoise the final render with the Open Image Denoise that Blender ships (fed with "
                    "the render's albedo and normal); the image before denoising is kept as the Noisy "
                    "Image pass")
    use_viewport_denoising: BoolProperty(
        name="Denoise Viewport", default=False,
        description="Denoise Rendered shading once it reaches its samples (Viewport Samples), with the "
                    "same denoiser as the final render; the image shows noisy while it samples")
    fail_on_missing_textures: BoolProperty(
        name="Fail on Missing Textures", default=False,
        description="An image texture that cannot be read fails the render (for farms). Off: it "
                    "renders magenta with a warning naming the material, node and file, as in Cycles")
    update_interval: FloatProperty(name="Display Update", default=2.0, min=0.2, max=60.0,
                                   unit='TIME_ABSOLUTE',
                                   description="Seconds between progressive updates of the image")


def _property(st):
    """The Blender property of render setting ``st`` (backend/render_settings.py)."""
    default = st.blender_default if st.blender_default is not None else st.default
    common = {"name": st.label, "description": st.doc, **st.ui}
    if st.kind is int:
        hi = INT32_MAX if st.hi is None else min(int(st.hi), INT32_MAX)
        return IntProperty(default=int(default), min=int(st.lo), max=hi, **common)
    if st.kind is float:
        bounds = {"min": float(st.lo)} if st.lo is not None else {}
        if st.hi is not None:
            bounds["max"] = float(st.hi)
        return FloatProperty(default=float(default), **bounds, **common)
    items = tuple((value.upper(), label, doc, i) for i, (value, label, doc) in enumerate(st.choices))
    return EnumProperty(items=items, default=str(default).upper(), **common)


for _st in SETTINGS:
    if _st.property_name is not None:
        LaminaRenderSettings.__annotations__[_st.property_name] = _property(_st)
del _st

CLASSES = (LaminaRenderSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.lamina = PointerProperty(type=LaminaRenderSettings)


def unregister():
    del bpy.types.Scene.lamina
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)

"""``Scene.lamina``: sampling and engine settings (written to the scene file's ``render``)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from ..constants import ESTIMATORS, PDF_MODES

SAMPLERS = (
    ("SOBOL", "Sobol", "Owen-scrambled Sobol points: stratified per pixel, less noise at equal samples", 0),
    ("INDEPENDENT", "Independent", "Independent random numbers (the reference)", 1),
)

FILTERS = (
    ("BLACKMAN_HARRIS", "Blackman-Harris", "Cycles' default pixel filter", 0),
    ("GAUSSIAN", "Gaussian", "Gaussian pixel filter", 1),
    ("BOX", "Box", "No filtering (one pixel wide)", 2),
)


class LaminaRenderSettings(PropertyGroup):
    samples: IntProperty(name="Samples", default=64, min=1, soft_max=4096, max=1 << 24,
                         description="Samples per pixel (the maximum when a noise threshold is set)")
    viewport_samples: IntProperty(name="Viewport Samples", default=32, min=0, soft_max=4096, max=1 << 24,
                                  description="Samples per pixel of Rendered shading in the viewport, "
                                              "after which it stops; 0 = until stopped")
    time_limit: FloatProperty(name="Time Limit", default=0.0, min=0.0, unit='TIME_ABSOLUTE',
                              description="Stop after this time (after a full sample pass); 0 = no limit")
    noise_threshold: FloatProperty(name="Noise Threshold", default=0.0, min=0.0, max=1.0, precision=4,
                                   description="Adaptive sampling: stop pixels whose relative standard "
                                               "error is below this; 0 = off")
    min_samples: IntProperty(name="Min Samples", default=16, min=1, soft_max=1024,
                             description="Adaptive sampling: samples before a pixel may stop")
    max_bounces: IntProperty(name="Max Bounces", default=12, min=0, max=1024, soft_max=64,
                             description="Maximum number of bounces of a path (as Cycles' Max Bounces)")
    rr_depth: IntProperty(name="Russian Roulette Depth", default=3, min=0, max=1024,
                          description="Bounces before paths may be terminated at random")
    clamp: FloatProperty(name="Clamp Indirect", default=0.0, min=0.0,
                         description="Clamp indirect sample values (trades bias for fireflies); 0 = off")
    glossy_light_samples: IntProperty(name="Glossy Light Samples", default=2, min=1, max=8,
                                      description="Light samples per light at a rough metal's surface "
                                                  "(less noise on glossy reflections of lights, a shadow "
                                                  "ray each)")
    sampler: EnumProperty(name="Sampler", items=SAMPLERS, default="SOBOL",
                          description="How samples are placed in each pixel and path dimension")
    seed: IntProperty(name="Seed", default=0, min=0, description="Random seed; same seed and samples "
                                                               "give the same image")
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


CLASSES = (LaminaRenderSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.lamina = PointerProperty(type=LaminaRenderSettings)


def unregister():
    del bpy.types.Scene.lamina
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)

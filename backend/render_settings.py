"""The render settings, once: each field of a scene's ``render`` object with its type, default,
range and meaning, and what the other layers call it. The loader (backend/scene/loader.py), the
command line (backend/cli/render.py, backend/render.py) and the Blender add-on
(addon/props/scene.py, addon/export/scene.py) all read this table, so a range or a default is
written in one place (docs/scene-format.md, ``render``, is the users' page for it).

No bpy, no Numba: the add-on imports this module (tests/test_architecture.py allows it).

Names: ``name`` is the scene file's field, the loader's attribute and, where the kernels take
the value as it is, their ``Settings`` field too; ``blender`` the Scene.lamina
property that holds it in Blender, where Blender's own word differs (Cycles says Samples, Noise
Threshold, Min Samples: an artist finds them under those names, and a .blend keeps a property's
value under its name, so renaming it would lose saved values); ``kernel`` the field of the
kernels' ``Settings`` (backend/kernels/integrator.py) that receives the value as it is (settings
the kernels need derived, such as max_bounces → max_segments, are converted in
backend/integrator.py and have none); ``cli`` the ``render`` option that overrides it.

A new kernel-visible setting: a row here (with ``kernel``), its field and use in
backend/kernels/integrator.py, and a line in addon/ui/render.py to show it (docs/architecture.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field, make_dataclass

from .limits import MAX_BOUNCES, MAX_GLOSSY_LIGHT_SAMPLES, MAX_SEED, MAX_SPP

INT32_MAX = 2 ** 31 - 1          # Blender's IntProperty range


@dataclass(frozen=True)
class Setting:
    name: str
    kind: type                    # int, float or str (a choice)
    default: object
    doc: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()           # (value, label, description) for a str setting
    label: str = ""               # in Blender's panel
    blender: str | None = None    # Scene.lamina property (None: the same as name; "": not in Blender)
    blender_default: object = None   # where Blender's default differs from the file's
    ui: dict = field(default_factory=dict)   # more Blender property options (soft_max, unit, ...)
    kernel: str | None = None     # the kernels' Settings field that takes the value as it is
    cli: str | None = None        # the render option that overrides it

    @property
    def property_name(self) -> str | None:
        """The Scene.lamina property, or None where Blender has none."""
        if self.blender == "":
            return None
        return self.blender or self.name


SETTINGS: tuple[Setting, ...] = (
    Setting("spp", int, 16, "Samples per pixel (the maximum when a noise threshold is set)",
            lo=1, hi=MAX_SPP, label="Samples", blender="samples", blender_default=64,
            ui={"soft_max": 4096}, cli="--spp"),
    Setting("max_bounces", int, 12, "Maximum number of bounces of a path (as Cycles' Max Bounces)",
            lo=0, hi=MAX_BOUNCES, label="Max Bounces", ui={"soft_max": 64}, cli="--max-bounces"),
    Setting("rr_depth", int, 3, "Bounces before paths may be terminated at random",
            lo=0, hi=MAX_BOUNCES, label="Russian Roulette Depth", kernel="rr_depth"),
    Setting("seed", int, 0, "Random seed; same seed and samples give the same image",
            lo=0, hi=MAX_SEED, label="Seed", cli="--seed"),
    Setting("clamp", float, 0.0, "Clamp indirect light as Cycles does: light gathered after the "
            "first surface a camera ray meets is scaled down to this sum of R, G and B (trades bias "
            "for fireflies); 0 = off",
            lo=0.0, label="Clamp Indirect", kernel="clamp"),
    Setting("noise_target", float, 0.0, "Adaptive sampling: stop pixels whose relative standard error "
            "is below this; 0 = off", lo=0.0, hi=1.0, label="Noise Threshold", blender="noise_threshold",
            ui={"precision": 4}, cli="--noise-target"),
    Setting("min_spp", int, 16, "Adaptive sampling: samples before a pixel may stop",
            lo=1, hi=MAX_SPP, label="Min Samples", blender="min_samples", ui={"soft_max": 1024},
            cli="--min-spp"),
    Setting("time_limit", float, 0.0, "Stop after this time (after a full sample pass); 0 = no limit",
            lo=0.0, label="Time Limit", ui={"unit": "TIME_ABSOLUTE"}, cli="--time-limit"),
    Setting("light_selection", str, "local", "Which light next-event estimation samples",
            choices=(("local", "Local", "by the power each light sends to the shading point"),
                     ("power", "Power", "by each light's total power, the same everywhere")),
            blender=""),
    Setting("sampler", str, "sobol", "How samples are placed in each pixel and path dimension",
            choices=(("sobol", "Sobol", "Owen-scrambled Sobol points: stratified per pixel, less noise "
                      "at equal samples"),
                     ("independent", "Independent", "Independent random numbers (the reference)")),
            label="Sampler", cli="--sampler"),
    Setting("glossy_light_samples", int, 2, "Light samples per light at a rough metal's surface (less "
            "noise on glossy reflections of lights, a shadow ray each)",
            lo=1, hi=MAX_GLOSSY_LIGHT_SAMPLES, label="Glossy Light Samples", kernel="glossy_light_samples"),
    Setting("caustic_photons", float, 0.125, "Caustics through smooth glass, mirrors and polished metals "
            "traced from the lights (area, point and spot lights, suns, emissive surfaces): "
            "photons per camera sample; 0 = path traced only (noisier caustics, the same image on average)",
            lo=0.0, hi=64.0, label="Caustic Photons", ui={"soft_max": 8.0, "precision": 2}),
    # Blender shows it as a checkbox (Fail on Missing Textures, addon/props/scene.py).
    Setting("missing_textures", str, "magenta", "An image texture that cannot be read: rendered "
            "magenta with a warning (as in Cycles), or an error (farms: render --strict)",
            choices=(("magenta", "Magenta", "render it magenta, with a warning"),
                     ("error", "Error", "fail the render")),
            blender="", cli="--strict"),
)

BY_NAME = {s.name: s for s in SETTINGS}

#: The loaded settings (backend/scene/loader.py ``parse_settings``): one attribute per row.
RenderSettings = make_dataclass("RenderSettings", [(s.name, s.kind, field(default=s.default)) for s in SETTINGS])
RenderSettings.__doc__ = "A scene's render settings (backend/render_settings.py ``SETTINGS``)."


def kernel_values(settings) -> dict:
    """The kernels' Settings fields that take a loaded setting as it is, by field name."""
    return {s.kernel: s.kind(getattr(settings, s.name)) for s in SETTINGS if s.kernel}

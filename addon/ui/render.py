"""Render properties: sampling, light paths, film, performance, and Advanced (layered estimator)."""
from __future__ import annotations

import bpy

from .base import LaminaPanel


def _column(layout):
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    return col


def draw_sampling(layout, settings) -> None:
    col = _column(layout)
    col.prop(settings, "viewport_samples")
    col.prop(settings, "samples")
    col.prop(settings, "noise_threshold")
    sub = col.column()
    sub.active = settings.noise_threshold > 0
    sub.prop(settings, "min_samples")
    col.prop(settings, "time_limit")
    row = col.row(align=True)
    row.prop(settings, "seed")
    row.prop(settings, "use_animated_seed", text="", icon="TIME")
    col.prop(settings, "use_denoising")
    col.prop(settings, "use_viewport_denoising")


def draw_light_paths(layout, settings) -> None:
    col = _column(layout)
    col.prop(settings, "max_bounces")
    col.prop(settings, "clamp")


def draw_film(layout, settings) -> None:
    col = _column(layout)
    col.prop(settings, "filter_type")
    sub = col.column()
    sub.active = settings.filter_type != "BOX"
    sub.prop(settings, "filter_width")


def draw_performance(layout, settings) -> None:
    col = _column(layout)
    col.prop(settings, "cluster")
    sub = col.column()
    sub.active = not settings.cluster.strip()     # a cluster's workers bring their own threads
    sub.prop(settings, "workers")
    col.prop(settings, "update_interval")
    col.prop(settings, "fail_on_missing_textures")


def draw_advanced(layout, settings) -> None:
    col = _column(layout)
    col.prop(settings, "sampler")
    col.prop(settings, "glossy_light_samples")
    col.prop(settings, "caustic_photons")
    col.prop(settings, "estimator")
    col.prop(settings, "pdf_mode")
    col.prop(settings, "rr_depth")


class _RenderPanel(LaminaPanel):
    bl_context = "render"


class LAMINA_PT_sampling(_RenderPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        draw_sampling(self.layout, context.scene.lamina)


class LAMINA_PT_light_paths(_RenderPanel, bpy.types.Panel):
    bl_label = "Light Paths"

    def draw(self, context):
        draw_light_paths(self.layout, context.scene.lamina)


class LAMINA_PT_film(_RenderPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_film(self.layout, context.scene.lamina)


class LAMINA_PT_performance(_RenderPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_performance(self.layout, context.scene.lamina)


class LAMINA_PT_advanced(_RenderPanel, bpy.types.Panel):
    bl_label = "Advanced"
    bl_parent_id = "LAMINA_PT_sampling"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_advanced(self.layout, context.scene.lamina)


CLASSES = (LAMINA_PT_sampling, LAMINA_PT_light_paths, LAMINA_PT_film, LAMINA_PT_performance,
           LAMINA_PT_advanced)


register, unregister = bpy.utils.register_classes_factory(CLASSES)

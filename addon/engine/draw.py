"""Drawing a session frame in the 3D viewport with Blender's ``gpu`` module.

The frame (scene-linear RGBA, premultiplied by coverage) becomes a float texture drawn over the
whole region — reduced-resolution frames are stretched — between
``RenderEngine.bind_display_space_shader`` and ``unbind_display_space_shader``, so Blender applies
the scene's view transform, look, exposure and gamma to it as it does to Cycles' viewport.

Headless Blender cannot draw (``gpu`` refuses in background mode), so the viewport takes its
drawer from ``viewport.make_drawer``; tests put a recording stand-in there.
"""
from __future__ import annotations

import numpy as np


class GPUDrawer:
    def __init__(self):
        self.texture = None
        self.size = (0, 0)
        self._data = None          # the pixels the texture was made from (kept with it)

    def upload(self, frame) -> None:
        import gpu
        # GL textures start with the bottom row; frames start with the top one.
        pixels = np.ascontiguousarray(frame.pixels[::-1], dtype=np.float32).reshape(-1)
        buffer = gpu.types.Buffer("FLOAT", pixels.size, pixels)
        texture = gpu.types.GPUTexture((frame.width, frame.height), format="RGBA32F", data=buffer)
        if hasattr(texture, "filter_mode"):
            texture.filter_mode(True)           # reduced passes: bilinear, not blocks
        self.texture, self.size, self._data = texture, (frame.width, frame.height), pixels

    def draw(self, engine, scene, width: int, height: int) -> None:
        if self.texture is None:
            return
        import gpu
        from gpu_extras.presets import draw_texture_2d
        gpu.state.blend_set("ALPHA_PREMULT")
        engine.bind_display_space_shader(scene)
        try:
            draw_texture_2d(self.texture, (0, 0), width, height)
        finally:
            engine.unbind_display_space_shader()
            gpu.state.blend_set("NONE")

    def free(self) -> None:
        self.texture = None
        self._data = None

"""A kernel module imported on first use, for NumPy-side modules that also serve parsing.

Importing any compiled module imports Numba (≈ 0.3–0.5 s) and creates its dispatchers. Parsing a
material or a phase function needs none of that, and some processes only parse: the add-on's
preset check (``presets validate``, run on every Save Preset while Blender waits) and
``validate``. Modules whose classes both parse and evaluate hold ``lazy("...")`` instead of the
module and reach its kernels through it unchanged (``_batch.diffuse_sample(...)``).
"""
from __future__ import annotations

import importlib


class lazy:  # noqa: N801 - used like a module
    """``lazy("bsdf.batch")``: the module ``bsdf.batch`` of this package (relative, so it also
    works where the backend is a subpackage, as in the Blender extension)."""

    def __init__(self, module: str):
        self._name = module
        self._module = None

    def __getattr__(self, attr):
        if self._module is None:
            self._module = importlib.import_module(f".{self._name}", __package__)
        return getattr(self._module, attr)

"""``render --denoise``: Intel Open Image Denoise on the finished image, fed with the film's albedo
and normal (the auxiliary images OIDN's "RT" filter was trained with).

The denoiser is the optional ``pyoidn`` package from PyPI (requirements-denoise.txt), imported
only when asked for: the renderer does not need it, and where PyPI has no wheel for a platform
the render still writes its (noisy) image, with one line saying why it was not denoised. Blender
renders use the OIDN that Blender ships instead (addon/engine/denoise.py), so the extension
carries no denoiser of its own.
"""
from __future__ import annotations

import numpy as np

from .errors import LaminaError

INSTALL_HINT = ("pip install pyoidn (Intel Open Image Denoise for Python; "
                "see requirements-denoise.txt)")


class DenoiserUnavailable(LaminaError):
    """pyoidn cannot be imported on this machine (not installed, or no wheel for it)."""


def available() -> str | None:
    """None if the denoiser can be used, else the reason in one line."""
    try:
        import pyoidn  # noqa: F401
    except ImportError as exc:
        return f"--denoise: the denoiser is not installed ({exc}); {INSTALL_HINT}"
    except OSError as exc:           # a wheel whose shared library does not load here
        return f"--denoise: the denoiser cannot be loaded on this machine ({exc})"
    return None


def denoise(rgb: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None) -> np.ndarray:
    """The denoised (H, W, 3) float32 image. ``rgb`` is scene-linear HDR; ``albedo`` in [0, 1]
    and ``normal`` in [-1, 1] of the same shape (either may be None). Non-finite values are
    treated as 0, as the EXR writer does."""
    problem = available()
    if problem is not None:
        raise DenoiserUnavailable(problem)
    import pyoidn

    def clean(image, lo, hi):
        image = np.nan_to_num(np.asarray(image, np.float32), nan=0.0, posinf=hi, neginf=lo)
        return np.ascontiguousarray(np.clip(image, lo, hi), dtype=np.float32)

    color = clean(rgb, 0.0, 3.0e38)
    aux_albedo = clean(albedo, 0.0, 1.0) if albedo is not None else None
    aux_normal = clean(normal, -1.0, 1.0) if normal is not None else None
    if aux_albedo is None:
        aux_normal = None            # OIDN takes a normal only together with an albedo
    try:
        out = pyoidn.denoise(color, aux_albedo, aux_normal, hdr=True, quality="high")
    except (RuntimeError, ValueError, TypeError) as exc:
        raise LaminaError(f"--denoise: the denoiser failed: {exc}") from None
    return np.asarray(out, np.float32)

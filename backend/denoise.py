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
        device = pyoidn.Device()
        device.commit()
        try:
            # The albedo and normal are themselves noisy (their first hits jitter over the pixel,
            # behind glass they are sampled): denoised on their own first, then given to the
            # colour filter as clean — OIDN's own recipe for the best quality, and what F12's route
            # in Blender does (Cycles' "Accurate" prefilter, addon/engine/denoise.py). Measured on
            # the demo at 32 spp (docs/benchmarks.md): RMSE 0.34× the noisy image's without, 0.2×
            # with.
            if aux_albedo is not None:
                aux_albedo = _filter(pyoidn, device, {"albedo": aux_albedo})
                if aux_normal is not None:
                    aux_normal = _filter(pyoidn, device, {"normal": aux_normal})
            inputs = {"color": color}
            if aux_albedo is not None:
                inputs["albedo"] = aux_albedo
            if aux_normal is not None:
                inputs["normal"] = aux_normal
            out = _filter(pyoidn, device, inputs, hdr=True, clean_aux=aux_albedo is not None)
        finally:
            device.release()
    except (RuntimeError, ValueError, TypeError) as exc:
        raise LaminaError(f"--denoise: the denoiser failed: {exc}") from None
    return out


def _filter(pyoidn, device, inputs: dict, hdr: bool = False, clean_aux: bool = False) -> np.ndarray:
    """One run of OIDN's RT filter (quality high) on float32 (H, W, 3) ``inputs`` by OIDN's image
    names; only an albedo or only a normal denoises that image itself."""
    first = next(iter(inputs.values()))
    out = np.zeros(first.shape, np.float32)
    flt = pyoidn.Filter(device, "RT")
    try:
        for name, image in inputs.items():
            flt.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
        flt.set_image("output", out, pyoidn.OIDN_FORMAT_FLOAT3)
        if hdr:
            flt.set_bool("hdr", True)
        if clean_aux:
            flt.set_bool("cleanAux", True)
        flt.set_quality(pyoidn.OIDN_QUALITY_HIGH)
        flt.commit()
        flt.execute()
        problem = device.get_error()
        if problem:
            raise RuntimeError(problem)
    finally:
        flt.release()
    return out

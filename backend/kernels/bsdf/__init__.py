"""Per-lane BSDFs, one module each, one interface (directions in the local shading frame, both
pointing away from the surface; ``wi`` towards the viewer, ``wo`` the evaluated/sampled one):

* ``eval_pdf(params…, wi, wo[, mode])`` → (f·|cos θo| as an RGB tuple, solid-angle pdf of
  ``sample``), for the non-delta part only;
* ``sample(params…, wi, u…[, mode])`` → (wo, weight = f·|cos θo|/pdf as RGB, pdf, is_delta);
  a failed sample has weight 0 (the path ends);
* ``albedo(params…)`` → RGB for the denoising AOV.

``mode`` is the transport mode (RADIANCE for camera paths: refraction scales by 1/η²; IMPORTANCE
does not). Dispatch on the material type is in ``backend/kernels/materials.py``.
"""
RADIANCE = 0
IMPORTANCE = 1

"""Codes of the microfacet distributions and masking forms, and the roughness clamp: shared by
the compiled kernels (kernels/microfacet.py) and the material parsers, which must not need Numba
(kernels/lazy.py says why)."""
GGX = 0
BECKMANN = 1
HEIGHT_CORRELATED = 0
SEPARABLE = 1
DISTRIBUTION_CODES = {"ggx": GGX, "beckmann": BECKMANN}
MASKING_CODES = {"height-correlated": HEIGHT_CORRELATED, "separable": SEPARABLE}

ALPHA_MIN = 1e-4        # α below this is clamped (microfacet terms lose all precision below)

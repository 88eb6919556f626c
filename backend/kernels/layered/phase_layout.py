"""The layout of a phase function's parameter block and the fiber table's grid: shared by the
per-lane code (kernels/layered/phase.py) and the NumPy phase classes (backend/layered/phase),
which parse without Numba (kernels/lazy.py says why)."""
import math

ISOTROPIC, HG, VMF, FIBER, SGGX, RAYLEIGH = 0, 1, 2, 3, 4, 5
KINDS = {"isotropic": ISOTROPIC, "hg": HG, "vmf": VMF, "microflake": FIBER, "sggx": SGGX, "rayleigh": RAYLEIGH}

# Parameter block (offsets from o)
PK = 0                    # kind
HG_G = 1
VMF_K, VMF_NORM = 1, 2
FB_S, FB_INV_S, FB_QSCALE, FB_LNNORM, FB_AXIS, FB_E1, FB_E2, FB_ROW, FB_CI, FB_W = \
    1, 2, 3, 4, 5, 8, 11, 14, 15, 16
SG_B, SG_DET = 1, 7
SIZE = 20

G_MAX = 0.999             # |g| clamp (pbrt-v4 issue #333: NaNs at g = ±1)

# Fiber table grid (backend/layered/phase/fiber.py reads these)
S_MIN, S_MAX = 1e-3, 4.0
ROWS = 161
COLS = 161
LN_S0 = math.log(S_MIN)
H_S = (math.log(S_MAX) - LN_S0) / (ROWS - 1)
LN_ROW = ROWS + 2         # the row of FT holding ln N(s) (ghosted like the σ rows)
FIRST_MEDIUM_ROW = ROWS + 3
UNIFORM_ABOVE = 0.7       # stddev above which the fiber sampler proposes x uniformly
MAX_CANDIDATES = 509      # 1 + 127 rounds × 4 candidates: the NumPy sampler's 128 rounds
SGGX_ROUGHNESS_MIN = 1e-3

"""The numbers every formula shares (π and its fractions), defined once. A constant module: it
imports nothing compiled, so parsers and NumPy code may use it too."""
from __future__ import annotations

import math

PI = math.pi
TWO_PI = 2.0 * math.pi
INV_PI = 1.0 / math.pi
INV_2PI = 0.5 / math.pi
INV_4PI = 0.25 / math.pi

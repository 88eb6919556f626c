"""Names and enumerations shared by properties, UI and export (no bpy here).

Enum items carry explicit integer ids so that .blend files keep their values if items are
reordered or added later.
"""
from __future__ import annotations

# Named metals of the conductor interface (docs/materials.md, `conductor.metal`).
METALS = (
    ("Ag", "Silver"), ("Al", "Aluminium"), ("Au", "Gold"), ("Be", "Beryllium"), ("Co", "Cobalt"),
    ("Cr", "Chromium"), ("Cu", "Copper"), ("Fe", "Iron"), ("Hg", "Mercury"), ("Mo", "Molybdenum"),
    ("Ni", "Nickel"), ("Pd", "Palladium"), ("Pt", "Platinum"), ("Rh", "Rhodium"), ("Ti", "Titanium"),
    ("V", "Vanadium"), ("W", "Tungsten"), ("Zn", "Zinc"),
)

# (identifier, label, description, icon, id)
INTERFACE_KINDS = (
    ("DIELECTRIC", "Dielectric", "A boundary into a transparent medium (coating, varnish, glass); "
     "its IOR is the index of the medium below it", "MATSPHERE", 0),
    ("CONDUCTOR", "Conductor", "A metal: named metal or complex IOR. Opaque, so it must be the "
     "last interface", "SHADING_RENDERED", 1),
    ("DIFFUSE", "Diffuse", "A Lambertian base. Opaque, so it must be the last interface",
     "SHADING_SOLID", 2),
    ("NULL", "Null", "Index-matched pass-through: separates two media without a boundary",
     "SELECT_SUBTRACT", 3),
    ("MATERIAL", "Nested Material", "The stack of another Lamina material, used as one interface",
     "MATERIAL", 4),
)
OPAQUE_KINDS = {"conductor", "diffuse"}

DISTRIBUTIONS = (
    ("GGX", "GGX", "GGX (Trowbridge-Reitz) microfacets, as Cycles", 0),
    ("BECKMANN", "Beckmann", "Beckmann microfacets", 1),
)

MASKINGS = (
    ("HEIGHT_CORRELATED", "Height-Correlated", "G2 = 1/(1 + Λi + Λo), as Cycles (default)", 0),
    ("SEPARABLE", "Separable", "G1·G1, as Mitsuba 0.6 and Guo et al.'s layered reference", 1),
)

ESTIMATORS = (
    ("AUTOMATIC", "Automatic", "A closed form where the stack has one (a dielectric over a diffuse body: every "
     "non-metallic Principled BSDF), without the random walk's noise; otherwise the bidirectional walk (default)", 2),
    ("BIDIRECTIONAL", "Bidirectional", "The random walk everywhere: connections inside each slab with MIS", 0),
    ("UNIDIRECTIONAL", "Unidirectional", "The random walk everywhere: next-event estimation through the exit "
     "interface only", 1),
)

PDF_MODES = (
    ("LOBES", "Lobes", "Closed-form density of each interface's lobe for MIS weights (fastest; default)", 2),
    ("APPROXIMATE", "Approximate", "Approximate pdf estimated by short walks without media (Guo et al.) for MIS weights", 0),
    ("STOCHASTIC", "Stochastic", "Unbiased stochastic pdf estimate for MIS weights (slower)", 1),
)

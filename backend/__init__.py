"""Lamina rendering backend: a vectorised (wavefront) path tracer with layered BSDFs.

Never imports bpy. Run as ``python -m backend ...`` (see ``backend/cli/__init__.py``).
"""
import os

__version__ = "0.1.0"

# One BLAS thread per process. NumPy's BLAS only ever sees small products here ((n, 3) × (3, 3)
# frame changes), where its thread pool costs more than it saves, and every worker process would
# start one such pool per core (oversubscription). Measured, Cornell 128², 32 spp, one process:
# 3.0 s wall / 5.9 s CPU with the default threads, 2.7 s wall / 2.7 s CPU with one. Effective
# when this package is imported before NumPy (``python -m backend`` and its worker processes,
# which inherit the environment); a user's explicit setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
del _var

"""Benchmarks: scripts that print figures (time, error), never pass/fail tests."""
import backend as _first  # before NumPy: one BLAS thread per process (backend/__init__.py)
del _first

"""Lamina rendering backend: a vectorised (wavefront) path tracer with layered BSDFs.

Never imports bpy. Run as ``python -m backend ...`` (see ``backend/cli.py``).
"""
__version__ = "0.1.0"

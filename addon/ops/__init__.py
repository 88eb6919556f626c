"""Operators: layer-stack editing, presets, scene export."""

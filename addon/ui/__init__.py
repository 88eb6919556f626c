"""Panels and lists. Each panel is thin and calls a module-level ``draw_*(layout, data)`` function."""

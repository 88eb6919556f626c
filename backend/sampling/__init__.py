"""Sampling building blocks: warps from the unit square and discrete distributions."""

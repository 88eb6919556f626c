"""Benchmarks: scripts that print figures (time, error), never pass/fail tests."""

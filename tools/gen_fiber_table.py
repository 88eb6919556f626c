#!/usr/bin/env python3
"""Regenerate backend/layered/phase/fiber_sigma_table.npz, the microflake projected-area table.

The renderer reads the table instead of computing it in every process (~0.5 s of quadrature);
tests/test_phase.py checks that the shipped file equals a fresh computation. Run this after
changing the table's grid or quadrature in backend/layered/phase/fiber.py:

    .venv/bin/python tools/gen_fiber_table.py
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from backend.layered.phase import fiber  # noqa: E402


def main() -> int:
    fiber.write_table()
    print(f"wrote {fiber.TABLE_FILE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``python -m benchmarks.peers [options]`` = ``python -m benchmarks peers [options]``."""
import sys

from ..__main__ import main

if __name__ == "__main__":
    raise SystemExit(main(["peers", *sys.argv[1:]]))

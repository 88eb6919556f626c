import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
DATA = ROOT / "tests" / "data"  # IES files and slab references (provenance: tests/data/ies/README.md)
os.environ.setdefault("LAMINA_ROOT", str(ROOT))
import backend as _first  # before NumPy: one BLAS thread per process (backend/__init__.py)
del _first


def pytest_collection_finish(session):
    # A cold kernel cache is compiled once, by the first-run test's own render (tests/first_run.py).
    import first_run
    first_run.record_if_cold(session.items)


def pytest_sessionfinish(session, exitstatus):
    import first_run
    first_run.clean_up()

"""Where the inspectors' plots go (``bsdf plot``, ``ies plot``): checked before any work, so a
typo in the output path costs an error line, not a long estimation followed by a traceback."""
from __future__ import annotations

import tempfile
from pathlib import Path

from .errors import LaminaError


def check_plot_output(out: str | Path) -> Path:
    """The file's folder exists and is writable and matplotlib writes its format (from the
    extension, which must be given: matplotlib would otherwise add '.png' to a different name
    than the one printed). Returns the path; raises LaminaError."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    out = Path(out)
    if out.is_dir():
        raise LaminaError(f"{out}: is a folder; give a file name such as plot.png")
    folder = out.parent
    if not folder.exists():
        raise LaminaError(f"{folder}: output folder does not exist")
    kinds = FigureCanvasAgg(Figure()).get_supported_filetypes()
    if out.suffix.lower().lstrip(".") not in kinds:
        raise LaminaError(f"{out}: cannot write '{out.suffix or 'no extension'}' plots "
                          f"(use one of: {', '.join('.' + k for k in sorted(kinds))})")
    try:
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        raise LaminaError(f"{folder}: cannot write there ({exc.strerror or exc})") from exc
    return out


def save_figure(fig, out: Path, dpi: int) -> None:
    try:
        fig.savefig(out, dpi=dpi, bbox_inches="tight")
    except OSError as exc:
        raise LaminaError(f"cannot write {out}: {exc.strerror or exc}") from exc

"""The report of a study (``sensorplan report``): figures, an HTML page and a summary.

:func:`write_report` reads a study directory and writes ``report.html``, ``summary.md`` and
the PNG figures of :data:`FIGURES` (:mod:`.figures` draws, :mod:`.document` formats); on a
grid directory (``grid.json``) it writes the grid's heat maps and tables instead
(:mod:`.grid`, :mod:`.grid_figures`).
"""

from __future__ import annotations

from pathlib import Path

from .document import ReportFiles
from .document import write_report as write_study_report
from .figures import FIGURES, OPTIONAL_FIGURES
from .grid import write_grid_report


def write_report(study_dir: str | Path, out: str | Path | None = None) -> ReportFiles:
    """The report of a study directory (:func:`write_study_report`) or of a grid directory
    (:func:`write_grid_report`), into ``out`` (default ``study_dir/report``)."""
    if (Path(study_dir) / "grid.json").exists():
        return write_grid_report(study_dir, out)
    return write_study_report(study_dir, out)


__all__ = ["FIGURES", "OPTIONAL_FIGURES", "ReportFiles", "write_grid_report", "write_report",
           "write_study_report"]

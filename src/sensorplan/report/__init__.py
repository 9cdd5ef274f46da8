"""The report of a study (``sensorplan report``): figures, an HTML page and a summary.

:func:`write_report` reads a study directory and writes ``report.html``, ``summary.md`` and
the PNG figures of :data:`FIGURES` (:mod:`.figures` draws, :mod:`.document` formats).
"""

from .document import ReportFiles, write_report
from .figures import FIGURES, OPTIONAL_FIGURES

__all__ = ["FIGURES", "OPTIONAL_FIGURES", "ReportFiles", "write_report"]

"""The main job's report (issue 9): ``turntable report --out report/``.

* :mod:`.figures` — the thesis's figures recreated by the simulator, with their numbers;
* :mod:`.build` — every section (figures, speed, benchmark, calibration) and the run;
* :mod:`.html` — the self-contained page.
"""

from .build import build_report
from .figures import ReportFigure
from .section import Section

__all__ = ["ReportFigure", "Section", "build_report"]

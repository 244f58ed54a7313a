"""One part of the report page: what :mod:`.build` fills and :mod:`.html` renders."""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any

from .figures import ReportFigure

__all__ = ["Section"]


@dataclass
class Section:
    """One part of the report: id, title, introduction, images (name, PNG/GIF bytes,
    caption, thesis text), tables (Markdown-like rows) and numbers for summary.json."""

    id: str
    title: str
    intro: str
    images: list[dict[str, Any]] = field(default_factory=list)
    tables: list[dict[str, Any]] = field(default_factory=list)
    numbers: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0

    def add_figure(self, f: ReportFigure) -> None:
        buf = io.BytesIO()
        f.fig.savefig(buf, format="png", dpi=90)
        import matplotlib.pyplot as plt

        plt.close(f.fig)
        self.images.append(
            {
                "name": f.key,
                "mime": "image/png",
                "data": buf.getvalue(),
                "caption": f.title,
                "thesis": f.thesis,
                "numbers": f.numbers,
            }
        )
        self.numbers[f.key] = f.numbers

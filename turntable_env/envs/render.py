"""``rgb_array`` rendering of the turntable and its detector (matplotlib, Agg canvas).

Left: side view across the controlled axis — the half sphere on its two driving tubes,
tube deflection exaggerated (:data:`DEFLECTION_SCALE`), each contact coloured by the
fraction of its GMS elements that stick (green all stick, red all slip), the table's
rotation exaggerated so the detector's linear range θ_lin spans ±60°, the target
dashed. Right: the photodiode face with the ±0.2 mm linear range, the reported spot
and the target spot.
"""

from __future__ import annotations

import numpy as np

from .core import TurntableTask

__all__ = ["DEFLECTION_SCALE", "TurntableRenderer"]

DEFLECTION_SCALE = 2.0e6  # drawn mm per m of tube deflection (1.5 µm → 3 mm)
_R = 10.0  # drawn sphere radius [mm]
_TUBE_X = 6.0  # drawn tube positions ±x [mm]
_TUBE_BOTTOM = -24.0  # [mm]
_ROT_SPAN = np.deg2rad(60.0)  # drawn rotation at θ_lin


def _stick_colour(fraction: float) -> tuple[float, float, float]:
    return (1.0 - fraction, 0.75 * fraction, 0.1)


class TurntableRenderer:
    """Draws turntable b of a :class:`TurntableTask` into an (H, W, 3) uint8 array."""

    def __init__(self, task: TurntableTask, size: tuple[int, int] = (640, 320)) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle, Polygon, Rectangle, Wedge

        self.task = task
        dpi = 100
        self.fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        ax, det = self.fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.4, 1.0]})
        self.ax, self.det = ax, det
        ax.set_xlim(-16, 16)
        ax.set_ylim(-26, 6)
        ax.set_aspect("equal")
        ax.axis("off")
        ax.add_patch(Wedge((0, 0), _R, 180, 360, color="0.7"))
        ax.plot([-_R, _R], [0, 0], color="0.4", lw=1)
        self.tubes = []
        self.contacts = []
        for _ in range(2):
            p = Polygon(np.zeros((4, 2)), closed=True, color="#c9a227")
            ax.add_patch(p)
            self.tubes.append(p)
            c = Circle((0, 0), 1.0, color="g", zorder=3)
            ax.add_patch(c)
            self.contacts.append(c)
        (self.pointer,) = ax.plot([], [], color="k", lw=2)
        (self.target_line,) = ax.plot([], [], "k--", lw=1)
        self.title = self.fig.suptitle("", fontsize=9)
        for k, x in enumerate((-_TUBE_X, _TUBE_X)):
            ax.text(x, _TUBE_BOTTOM - 1.5, f"tube {k + 1}", ha="center", fontsize=7)
        lr = task.detector.linear_range * 1e3  # mm
        det.set_xlim(-1.5 * lr, 1.5 * lr)
        det.set_ylim(-1.5 * lr, 1.5 * lr)
        det.set_aspect("equal")
        det.add_patch(Rectangle((-lr, -lr), 2 * lr, 2 * lr, fill=False, ls="--", color="0.5"))
        det.set_xticks([-lr, 0, lr])
        det.set_yticks([])
        det.set_xlabel("spot [mm]", fontsize=8)
        det.tick_params(labelsize=7)
        (self.spot,) = det.plot([], [], "o", color="r", ms=8)
        (self.target_spot,) = det.plot([], [], "x", color="k", ms=8)
        self.det_title = det.set_title("detector", fontsize=8)
        self.fig.subplots_adjust(left=0.02, right=0.98, top=0.86, bottom=0.14, wspace=0.15)

    def draw(self, b: int = 0) -> np.ndarray:
        t = self.task
        snap = t.stepper.snapshot(b)
        top_y = -np.sqrt(_R**2 - _TUBE_X**2)
        for k, (poly, dot) in enumerate(zip(self.tubes, self.contacts, strict=True)):
            x0 = (-1.0 if k == 0 else 1.0) * _TUBE_X
            dx = float(snap["tube_deflection"][k]) * DEFLECTION_SCALE * 1e-3
            dx = float(np.clip(dx, -5.0, 5.0))
            poly.set_xy(
                [[x0 - 1, _TUBE_BOTTOM], [x0 + 1, _TUBE_BOTTOM], [x0 + 1 + dx, top_y],
                 [x0 - 1 + dx, top_y]]
            )  # fmt: skip
            dot.center = (x0 + dx, top_y)
            dot.set_color(_stick_colour(float(snap["stick_fraction"][k])))
        lim = t.angle_range
        for line, th in ((self.pointer, t.angle[b]), (self.target_line, t.target[b])):
            phi = -np.pi / 2 + float(np.clip(th / lim, -1.5, 1.5)) * _ROT_SPAN
            line.set_data([0, 0.95 * _R * np.cos(phi)], [0, 0.95 * _R * np.sin(phi)])
        self.title.set_text(
            f"t = {t.time[b] * 1e3:.0f} ms   θ = {t.angle[b] * 1e6:.1f} µrad   "
            f"θ* = {t.target[b] * 1e6:.1f} µrad"
        )
        det = t.detector
        x_spot = float(t.detector_v[b]) * det.sensitivity * 1e3  # mm
        x_tgt = det.distance * np.tan(2.0 * float(t.target[b])) * 1e3
        self.spot.set_data([x_spot], [0.0])
        self.target_spot.set_data([x_tgt], [0.0])
        self.det_title.set_text(f"detector {t.detector_v[b]:+.3f} V")
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        self.fig.clear()

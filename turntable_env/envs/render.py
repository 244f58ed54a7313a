"""``rgb_array`` rendering of the turntable and its detector (matplotlib, Agg canvas).

Left: the turntable seen along its rotation axis n (§3.1, Fig. 3.1). The tube axes are
orthogonal, so the axis tube is seen end on at the centre, beneath the pole, and the two
driving tubes lie in the plane ⟂ n, 90° apart, their contacts on the table's equator about
n. Each driving tube bends along e_k = n × d_k, tangent to that equator (tube deflection
exaggerated, :data:`DEFLECTION_SCALE`). Contacts are coloured by the fraction of their GMS
elements that stick (green all stick, red all slip; the axis tube's contact only spins,
and is grey where the fidelity does not model it). The table's rotation is exaggerated
so the detector's linear range θ_lin spans ±60°, the target dashed. Right: the
photodiode face with the ±0.2 mm linear range, the reported spot and the target spot.
"""

from __future__ import annotations

import numpy as np

from .core import TurntableTask

__all__ = ["DEFLECTION_SCALE", "TurntableRenderer"]

DEFLECTION_SCALE = 2.0e6  # drawn mm per m of tube deflection (1.5 µm → 3 mm)
_R = 10.0  # drawn table radius [mm]
_TUBE_LENGTH = 9.0  # drawn length of a driving tube, contact to base [mm]
_TUBE_HALF_WIDTH = 1.2  # [mm]
_TUBE_ANGLES = np.deg2rad((-135.0, -45.0))  # directions of d_k in the view (⟂, 90° apart)
_ROT_SPAN = np.deg2rad(60.0)  # drawn rotation at θ_lin
_MAX_DRAWN_DEFLECTION = 4.0  # [mm]


def _stick_colour(fraction: float | None) -> tuple[float, float, float]:
    if fraction is None:
        return (0.6, 0.6, 0.6)
    return (1.0 - fraction, 0.75 * fraction, 0.1)


def _pointer(theta: float, limit: float, r0: float, r1: float) -> tuple[list[float], list[float]]:
    """A radial mark on the table at the drawn angle of θ (counter-clockwise about n)."""
    phi = np.pi / 2 + float(np.clip(theta / limit, -1.5, 1.5)) * _ROT_SPAN
    return [r0 * np.cos(phi), r1 * np.cos(phi)], [r0 * np.sin(phi), r1 * np.sin(phi)]


class TurntableRenderer:
    """Draws turntable b of a :class:`TurntableTask` into an (H, W, 3) uint8 array."""

    def __init__(self, task: TurntableTask, size: tuple[int, int] = (640, 320)) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle, Polygon, Rectangle

        self.task = task
        dpi = 100
        self.fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        ax, det = self.fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.4, 1.0]})
        self.ax, self.det = ax, det
        reach = _R + _TUBE_LENGTH
        ax.set_xlim(-reach - 4, reach + 4)
        ax.set_ylim(-reach - 2, _R + 2)
        ax.set_aspect("equal")
        ax.axis("off")
        snap = task.stepper.snapshot(0)
        ax.add_patch(Circle((0, 0), _R, color="0.78", zorder=1))  # the table's equator about n
        self.axis_contact = Circle((0, 0), 1.6, color="0.6", zorder=4, ec="k", lw=0.6)
        ax.add_patch(self.axis_contact)  # the axis tube, end on, beneath the pole
        ax.text(0, -2.6, f"tube {snap['axis']}\n(axis)", ha="center", va="top", fontsize=6)
        self.tubes = []
        self.contacts = []
        for name, ang in zip(snap["tubes"], _TUBE_ANGLES, strict=True):
            p = Polygon(np.zeros((4, 2)), closed=True, color="#c9a227", zorder=2)
            ax.add_patch(p)
            self.tubes.append(p)
            c = Circle((0, 0), 1.0, color="g", zorder=3)
            ax.add_patch(c)
            self.contacts.append(c)
            d = np.array([np.cos(ang), np.sin(ang)])
            x, y = (reach + 2.5) * d
            ax.text(x, y, f"tube {name}", ha="center", va="center", fontsize=7)
        (self.pointer,) = ax.plot([], [], color="k", lw=2, zorder=5)
        (self.target_line,) = ax.plot([], [], "k--", lw=1, zorder=5)
        ax.set_title(f"seen along the rotation axis (tube {snap['axis']})", fontsize=7)
        self.title = self.fig.suptitle("", fontsize=9)
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
        for k, (poly, dot) in enumerate(zip(self.tubes, self.contacts, strict=True)):
            d = np.array([np.cos(_TUBE_ANGLES[k]), np.sin(_TUBE_ANGLES[k])])  # d_k in view
            e = np.array([-d[1], d[0]])  # e_k = n × d_k, n towards the viewer
            du = float(snap["tube_deflection"][k]) * DEFLECTION_SCALE  # [mm]
            du = float(np.clip(du, -_MAX_DRAWN_DEFLECTION, _MAX_DRAWN_DEFLECTION))
            base, tip = (_R + _TUBE_LENGTH) * d, _R * d + du * e  # clamped base, bent top
            w = _TUBE_HALF_WIDTH * e
            poly.set_xy([base - w, base + w, tip + w, tip - w])
            dot.center = tuple(tip)
            dot.set_color(_stick_colour(float(snap["stick_fraction"][k])))
        self.axis_contact.set_facecolor(_stick_colour(snap["axis_stick_fraction"]))
        lim = t.angle_range
        self.pointer.set_data(*_pointer(float(t.angle[b]), lim, 0.35 * _R, 0.98 * _R))
        self.target_line.set_data(*_pointer(float(t.target[b]), lim, 0.35 * _R, 0.98 * _R))
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

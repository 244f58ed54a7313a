"""The benchmark's tasks: what a practitioner asks of a positioner, episode by episode.

Every task is about one axis and builds, per seed, an :class:`EpisodeSpec`: the start
angle, the commanded reference (the target at each control interval), an optional knock
(a disturbance) and the :class:`~controllers.lab.LabBrief` the controller receives.
Distances are at the table radius R (Eq. 4.2: x = R·θ); the detector reads ±θ_lin
(±5.7 µm at R for the real turntable), the scan offset reaches ±K·u_max (±1.47 µm),
so every task needs stick–slip stepping somewhere (a move inside the scan range would
test only the scan PID that every baseline shares).

=====================  ===========  ========================================================
task                   kind         what
=====================  ===========  ========================================================
``point_2um``          point        2 µm move inside the detector range (start read), 0.8 s
``point_50um``         point        50 µm move from beyond the detector: the lab's
                                    dead-reckoned start is off by up to ±30 %, 1.5 s
``point_200um``        point        200 µm (20 mrad, 40 % of the workspace limit) from
                                    beyond the detector, ±30 % dead reckoning, 2 s: the
                                    fastest stepping, where the amplifier's current limit
                                    binds
``edge_5um``           point        5 µm outwards to 0.93·θ_lin, the detector's edge (an
                                    overshoot saturates the reading), 0.8 s
``scan_ramp``          tracking     constant-velocity scan across 8 µm at 8 µm/s (beyond the
                                    scan range: stepping while tracking), then 0.3 s hold
``waypoints``          tracking     five waypoints 1–5 µm apart, 0.3 s each
``back_forth``         tracking     ±2.5 µm back and forth, six legs of 0.25 s: repeatability
``knock``              disturbance  hold a target; at 0.2 s a knock displaces the table by
                                    3 µm (all contacts slip and re-stick), 0.8 s
=====================  ===========  ========================================================

Start, target and direction are drawn per seed (directions alternate with the seed),
from a generator seeded by (suite seed, task, seed): every controller meets the same
episodes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from turntable_env.detector import Detector

from .lab import LabBrief, dead_reckoned_start

__all__ = ["TASKS", "EpisodeSpec", "Task", "task_names"]

DEAD_RECKONING = 0.3  # stated relative error of a dead-reckoned move [-]


@dataclass(frozen=True)
class EpisodeSpec:
    """One episode of a task: start [rad], reference (K,) target per interval [rad] (index
    k: the target at time k·Δt), knock (time [s], Δθ [rad]) or None, the brief, and the
    sample index from which entry/settling times count."""

    start: float
    reference: np.ndarray
    knock: tuple[float, float] | None
    brief: LabBrief
    event: int = 0

    def options(self) -> dict[str, Any]:
        """The env reset options of this episode (``PiezoTurntable-v0``)."""
        opts: dict[str, Any] = {"start_angle": self.start, "reference": self.reference}
        if self.knock is not None:
            opts["knock"] = self.knock
        return opts


@dataclass(frozen=True)
class Task:
    """A benchmark task: name, kind (point, tracking, disturbance), horizon [intervals], a
    one-line description and the builder of its episodes."""

    name: str
    kind: str
    horizon: int
    description: str
    build: Callable[[np.random.Generator, Detector, int, float], EpisodeSpec]

    def episode(self, seed: int, detector: Detector, suite_seed: int) -> EpisodeSpec:
        """The episode of ``seed`` (the same for every controller; Δt = 0.01 s)."""
        rng = np.random.default_rng([suite_seed, _stable_hash(self.name), seed])
        sign = 1.0 if seed % 2 == 0 else -1.0
        spec = self.build(rng, detector, self.horizon, sign)
        if spec.reference.size != self.horizon + 1:
            raise AssertionError(f"{self.name}: reference length {spec.reference.size}")
        return spec


def _stable_hash(name: str) -> int:
    return sum((i + 1) * ord(c) for i, c in enumerate(name))


def _point(move_m: float, *, from_outside: bool, edge: bool = False) -> Callable:
    def build(rng: np.random.Generator, det: Detector, horizon: int, sign: float) -> EpisodeSpec:
        lim, r = det.angle_range, det.table_radius
        move = sign * move_m / r  # rad
        if edge:  # outwards to the edge on the move's side
            target = sign * 0.93 * lim
        elif from_outside:  # anywhere inside ±½θ_lin: the start is beyond the detector
            target = float(rng.uniform(-0.5, 0.5)) * lim
        else:  # inside ±½θ_lin, on the side that keeps the start inside the detector
            target = -sign * float(rng.uniform(0.0, 0.5)) * lim
        start = target - move
        est = dead_reckoned_start(start, target, DEAD_RECKONING, rng) if from_outside else None
        ref = np.full(horizon + 1, target)
        brief = LabBrief(target, est, DEAD_RECKONING if from_outside else 0.0)
        return EpisodeSpec(start, ref, None, brief)

    return build


def _tracking(levels_um: Callable[[np.random.Generator, float], list[float]], leg: float,
              ramp: float | None = None) -> Callable:  # fmt: skip
    """Waypoints held ``leg`` s each (``ramp``: the first leg is a constant-velocity scan
    from level 0 to level 1 at ``ramp`` m/s, the last level held to the end)."""

    def build(rng: np.random.Generator, det: Detector, horizon: int, sign: float) -> EpisodeSpec:
        r = det.table_radius
        dt = 0.01
        lv = np.array(levels_um(rng, sign)) * 1e-6 / r  # rad
        t = np.arange(horizon + 1) * dt
        if ramp is not None:
            dur = abs(lv[1] - lv[0]) * r / ramp
            frac = np.clip(t / dur, 0.0, 1.0)
            ref = lv[0] + (lv[1] - lv[0]) * frac
        else:
            idx = np.minimum((t / leg + 1e-9).astype(int), lv.size - 1)
            ref = lv[idx]
        brief = LabBrief(float(ref[0]), None, 0.0, tuple(ref))
        return EpisodeSpec(float(ref[0]), ref, None, brief)

    return build


def _waypoints(rng: np.random.Generator, sign: float) -> list[float]:
    out = [float(rng.uniform(-3.0, 3.0))]
    for _ in range(4):  # 1–5 µm apart, inside ±4.5 µm (the detector reads ±5.7 µm)
        step = rng.uniform(1.0, 5.0) * rng.choice((-1.0, 1.0))
        nxt = out[-1] + step
        if abs(nxt) > 4.5:
            nxt = out[-1] - step
        out.append(float(np.clip(nxt, -4.5, 4.5)))
    return out


def _back_forth(rng: np.random.Generator, sign: float) -> list[float]:
    c = float(rng.uniform(-1.5, 1.5))
    return [c + sign * 2.5 * (1 if i % 2 == 0 else -1) for i in range(6)]


def _scan(rng: np.random.Generator, sign: float) -> list[float]:
    return [-sign * 4.0, sign * 4.0]


def _knock(rng: np.random.Generator, det: Detector, horizon: int, sign: float) -> EpisodeSpec:
    lim = det.angle_range
    target = float(rng.uniform(-0.3, 0.3)) * lim
    t_knock = 0.2  # s
    ref = np.full(horizon + 1, target)
    knock = (t_knock, sign * 3e-6 / det.table_radius)
    event = round(t_knock / 0.01)
    return EpisodeSpec(target, ref, knock, LabBrief(target), event)


TASKS: dict[str, Task] = {
    t.name: t
    for t in (
        Task("point_2um", "point", 80, "2 µm move inside the detector range",
             _point(2e-6, from_outside=False)),
        Task("point_50um", "point", 150, "50 µm move from beyond the detector, start "
             "dead-reckoned ±30 %", _point(50e-6, from_outside=True)),
        Task("point_200um", "point", 200, "200 µm move from beyond the detector (current-limit "
             "regime), start dead-reckoned ±30 %", _point(200e-6, from_outside=True)),
        Task("edge_5um", "point", 80, "5 µm outwards to 0.93·θ_lin, the detector's edge",
             _point(5e-6, from_outside=False, edge=True)),
        Task("scan_ramp", "tracking", 130, "constant-velocity scan, 8 µm at 8 µm/s, then hold",
             _tracking(_scan, 1.0, ramp=8e-6)),
        Task("waypoints", "tracking", 150, "five waypoints 1–5 µm apart, 0.3 s each",
             _tracking(_waypoints, 0.3)),
        Task("back_forth", "tracking", 150, "±2.5 µm back and forth, six legs of 0.25 s",
             _tracking(_back_forth, 0.25)),
        Task("knock", "disturbance", 80, "hold; a knock displaces the table by 3 µm at 0.2 s",
             _knock),
    )
}  # fmt: skip


def task_names() -> list[str]:
    return list(TASKS)

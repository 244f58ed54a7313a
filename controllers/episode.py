"""Run a controller through a ``PiezoTurntable-v0`` env; the episode as a response object.

:func:`run_episode` resets the env with a seed and options, lets the controller act
until the episode ends, and returns an :class:`EpisodeResult` (time is axis 0 of every
array; ``.to_pandas()``, ``.plot()``; :meth:`EpisodeResult.metrics` computes the
benchmark's figures).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from turntable_env.envs.config import OBS

from .base import Controller
from .lab import LabBrief

__all__ = ["EpisodeResult", "run_episode"]


@dataclass(frozen=True, eq=False)
class EpisodeResult:
    """One episode; arrays over the steps, time is axis 0 (index 0 = the reset state).

    Attributes:
        time: [s]; angle: true table angle [rad]; measured: detector angle [rad];
        target: [rad]; actions: (n, 5) actions applied before each sample (row 0: zeros);
        energy: electrical energy per interval [J]; steps: flybacks per interval;
        table_radius: R_table [m] (Eq. 4.2); info: controller, seed, parameter factors.
    """

    time: np.ndarray
    angle: np.ndarray
    measured: np.ndarray
    target: float
    actions: np.ndarray
    energy: np.ndarray
    steps: np.ndarray
    table_radius: float
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def error(self) -> np.ndarray:
        """θ − θ* [rad]."""
        return self.angle - self.target

    def metrics(self, band: float = 10e-9) -> dict[str, float]:
        """Benchmark figures (distances at the table radius, Eq. 4.2).

        * ``final_error_nm``: |θ − θ*|·R at the end;
        * ``settle_time_s``: the time after which |θ − θ*|·R stays within ``band`` [m]
          to the end (nan if it is outside at the end);
        * ``steps``: stick–slip periods the generator ran; ``energy_J``: electrical energy;
        * ``overshoot_nm``: largest travel past the target in the direction of the move;
        * ``success``: 1.0 if the final error is within ``band``.
        """
        r = self.table_radius
        err = np.abs(self.error) * r
        inside = err <= band
        if inside[-1]:
            out = np.flatnonzero(~inside)
            settle = float(self.time[out[-1] + 1]) if out.size else 0.0
        else:
            settle = float("nan")
        move = self.target - float(self.angle[0])
        past = (self.angle - self.target) * np.sign(move) if move != 0 else np.zeros(1)
        return {
            "final_error_nm": float(err[-1] * 1e9),
            "settle_time_s": settle,
            "steps": float(self.steps.sum()),
            "energy_J": float(self.energy.sum()),
            "overshoot_nm": float(max(past.max(), 0.0) * r * 1e9),
            "success": float(inside[-1]),
        }

    def to_pandas(self) -> Any:
        """DataFrame indexed by time_s (SI units in the column names)."""
        import pandas as pd

        from turntable_env.envs.config import ACTION_NAMES

        cols = {
            "angle_rad": self.angle,
            "measured_rad": self.measured,
            "target_rad": np.full(self.time.size, self.target),
            "energy_J": self.energy,
            "steps": self.steps,
        }
        for i, n in enumerate(ACTION_NAMES):
            cols[f"action_{n}"] = self.actions[:, i]
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time_s"))

    def plot(self, ax: Any = None, label: str | None = None) -> Any:
        """Error θ − θ* at the table radius [nm] vs time (symlog axis)."""
        import matplotlib.pyplot as plt

        if ax is None:
            _fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(self.time, self.error * self.table_radius * 1e9, label=label)
        ax.set_yscale("symlog", linthresh=10.0)
        ax.axhspan(-10.0, 10.0, color="0.9")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("θ − θ* at R_table [nm]")
        return ax


def run_episode(
    env: Any,
    controller: Controller,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    brief: LabBrief | None = None,
) -> EpisodeResult:
    """Reset ``env`` (seed, options), run ``controller`` until the episode ends.

    The controller gets the observations and ``brief`` (default: the reset target and, for
    a ``reference`` option, the reference; no start estimate) — never the env's info, whose
    ground truth this runner keeps for the result."""
    obs, info = env.reset(seed=seed, options=options)
    if brief is None:
        ref = (options or {}).get("reference")
        brief = LabBrief(float(obs[OBS.target_angle_rad]), reference_rad=ref)
    controller.reset(obs, brief)
    time, angle, measured = [0.0], [float(info["angle_rad"])], [float(obs[OBS.measured_angle_rad])]
    actions, energy, steps = [np.zeros(5)], [0.0], [0]
    done = False
    while not done:
        action = controller.act(obs)
        obs, _reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        time.append(float(info["time_s"]))
        angle.append(float(info["angle_rad"]))
        measured.append(float(obs[OBS.measured_angle_rad]))
        actions.append(np.asarray(action, dtype=float))
        energy.append(float(info["energy_J"]))
        steps.append(int(info["steps"]))
    radius = float(env.unwrapped.config.parameter_set.detector.table_radius)
    return EpisodeResult(
        time=np.array(time),
        angle=np.array(angle),
        measured=np.array(measured),
        target=float(info["target_rad"]),
        actions=np.array(actions),
        energy=np.array(energy),
        steps=np.array(steps),
        table_radius=radius,
        info={"controller": controller.name, "seed": seed},
    )

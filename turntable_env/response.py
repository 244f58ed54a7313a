"""Simulation results as a response object (after python-control's ``TimeResponseData``).

Time is axis 0 of every array. Computation lives here; plotting only in
:meth:`TurntableResponse.plot`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .detector import Detector
from .effects import detector_stage

__all__ = ["ENERGY_TERMS", "SteppingMetrics", "TurntableResponse"]

AXES = ("A", "B", "C", "Z")
TUBES = ("A", "B", "C")

#: stored energies [J] and cumulative flows [J] recorded by the integrator
ENERGY_TERMS = (
    "kinetic",
    "tube_elastic",
    "piezo",
    "contact",
    "gms",
    "potential",
    "electrical_in",
    "friction_dissipated",
    "tube_damping_dissipated",
    "contact_damping_dissipated",
    "electrical_gross",
)
_STORED = ENERGY_TERMS[:6]
_DISSIPATED = ENERGY_TERMS[7:10]


class SteppingMetrics:
    """Detector and step metrics shared by every response about one axis.

    Needs ``time`` [s], ``angle()`` [rad], ``detector``, ``table_radius`` [m] and
    ``period_starts`` [s] on the class that mixes it in.
    """

    time: np.ndarray
    detector: Detector
    table_radius: float
    period_starts: np.ndarray

    def angle(self, axis: str | None = None) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def signals(self) -> dict[str, np.ndarray]:  # pragma: no cover - interface
        """Every recorded signal by name, with its unit in the name; every response has
        ``angle_rad`` (about the axis under test) and ``detector_V``."""
        raise NotImplementedError

    def signal(self, name: str) -> np.ndarray:
        """One signal by name (:meth:`signals`); ValueError naming the known ones."""
        sig = self.signals()
        if name not in sig:
            raise ValueError(f"signal {name!r}: not recorded (signals: {', '.join(sig)})")
        return sig[name]

    def to_pandas(self) -> Any:
        """DataFrame of :meth:`signals` indexed by ``time_s``."""
        import pandas as pd

        return pd.DataFrame(self.signals(), index=pd.Index(self.time, name="time_s"))

    def detector_voltage(self, rng: np.random.Generator | None = None) -> np.ndarray:
        """Detector output about the axis under test [V] (Eq. 4.1 inverted, saturation,
        noise if ``rng`` is given), with the plant's output-stage effects where the response
        carries them (``effect_row``, :func:`~turntable_env.effects.detector_stage`)."""
        row = getattr(self, "effect_row", None)
        if row is None:
            return self.detector.voltage(self.angle(), rng)
        x, _y = detector_stage(self.angle(), self.time - self.time[0], row, self.detector)
        if rng is not None and self.detector.noise_std > 0.0:
            x = x + rng.normal(0.0, self.detector.noise_std, size=x.shape)
        vs = self.detector.saturation_voltage
        return np.clip(x, -vs, vs)

    @property
    def detector_V_net(self) -> float:
        """Detector output at the end minus at the start [V] (noise-free)."""
        v = self.detector_voltage()
        return float(v[-1] - v[0])

    @property
    def net_rotation(self) -> float:
        """Rotation about the axis under test, end minus start [rad]."""
        a = self.angle()
        return float(a[-1] - a[0])

    # --- steps --------------------------------------------------------------------------
    def period_angles(self) -> np.ndarray:
        """Angle about the axis under test at each period start and after the last period
        [rad] (linear interpolation between samples)."""
        if self.period_starts.size == 0:
            return np.empty(0)
        return np.interp(self.period_starts, self.time, self.angle())

    @property
    def steps(self) -> np.ndarray:
        """Signed step per drive period at the table radius [m] (Eq. 4.2: x = θ·R_table)."""
        pa = self.period_angles()
        return np.diff(pa) * self.table_radius

    @property
    def step_size(self) -> float:
        """Mean |step| at the table radius [m] (nan without periods)."""
        s = self.steps
        return float(np.mean(np.abs(s))) if s.size else float("nan")

    def reading(self, t: float) -> float:
        """The laboratory's x_table at time t [m]: the noise-free detector voltage read with
        Eq. 4.1–4.2 (so the mirror's tilt and the photodiode's gain enter, as in the lab)."""
        v = float(np.interp(t, self.time, self.detector_voltage()))
        return float(self.detector.table_displacement(v))

    def angle_reading(self, t: float) -> float:
        """x_table at time t [m] from the angle itself, x = θ·R_table (Eq. 4.2): what the
        detector would read without saturation, tilt or gain."""
        return float(np.interp(t, self.time, self.angle())) * self.table_radius

    @property
    def detector_saturates(self) -> bool:
        """True if the noise-free detector output reaches its saturation voltage anywhere
        (the rotation leaves the linear range, Fig. 4.4)."""
        return bool(np.any(self.detector.is_saturated(self.detector_voltage())))

    def figure_step(
        self, n_per_block: int, two_directional: bool, *, source: str = "auto"
    ) -> dict[str, Any]:
        """The step per period as §4.1.3 reads it from the detector [m] (``source=
        "detector"``), or from the angle (``"angle"``, :meth:`angle_reading`); ``"auto"``
        reads the detector unless it saturates (:attr:`detector_saturates`). The result
        names its ``source``.

        One-directional (Fig. 4.7): x(t₂) − x(t₁) over the ``n_per_block`` periods from
        t₁, the first period's start. Two-directional (Fig. 4.6): t₁ → t₂ is the *last*
        forward block (``n_per_block`` steps after a reversal; a single cycle has none, so
        its block starts from rest) and t₁ → t₃ the whole last cycle: ``return`` is
        x(t₃) − x(t₁), ``excursion`` x(t₂) − x(t₁). Needs the drive's period starts."""
        if source not in ("auto", "detector", "angle"):
            raise ValueError(f"source={source!r}: 'auto', 'detector' or 'angle'")
        if source == "auto":
            source = "angle" if self.detector_saturates else "detector"
        read = self.reading if source == "detector" else self.angle_reading
        ps = self.period_starts
        n = int(n_per_block)
        if ps.size < n + 1:
            raise ValueError(f"n_per_block={n_per_block!r}: the response has {ps.size - 1} periods")
        if not two_directional:
            t1, t2 = ps[0], ps[n]
            exc = read(t2) - read(t1)
            return {"step": exc / n, "excursion": exc, "t1": t1, "t2": t2, "source": source}
        if ps.size < 2 * n + 1:
            raise ValueError(
                f"n_per_block={n_per_block!r}: a two-directional cycle needs {2 * n} periods"
            )
        t1 = ps[ps.size - 1 - 2 * n]
        t2, t3 = t1 + (ps[n] - ps[0]), ps[-1]
        x1, x2, x3 = read(t1), read(t2), read(t3)
        return {
            "step": abs(x2 - x1) / n, "excursion": x2 - x1, "return": x3 - x1,
            "t1": t1, "t2": t2, "t3": t3, "source": source,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class TurntableResponse(SteppingMetrics):
    """Time response of the full turntable model; time is axis 0.

    Attributes:
        time: sample times [s], shape (n,).
        centre_displacement: table-centre displacement from the unloaded pose [m], (n, 3).
        rotation_vector: table orientation as a rotation vector (world frame) [rad], (n, 3).
        angular_velocity: table angular velocity (world) [rad/s], (n, 3).
        channel_voltage: amplifier outputs of channels A, B, C, Z [V], (n, 4).
        normal_force: contact normal forces of tubes A, B, C [N], (n, 3).
        friction_force: friction on the table in each contact plane (x_c, y_c) [N], (n, 3, 2).
        slip_speed: tangential speed ball − table at each contact [m/s], (n, 3).
        n_stick: number of sticking GMS elements per contact, (n, 3).
        overlap: normal overlap of each contact [m], (n, 3).
        tube_displacement: tube-top twists (θx, θy, θz [rad], ux, uy, uz [m]) world, (n, 3, 6).
        energy: name → array [J], see :data:`ENERGY_TERMS` (stored energies at each sample,
            cumulative electrical input and dissipations since the start).
        axis_units: unit vectors of the axes A, B, C, Z (4, 3).
        axis: the axis under test (the detector watches it).
        detector: the detector model.
        table_radius: R_table [m] (Eq. 4.2).
        period_starts: start times of the drive periods [s] (for step detection).
        info: run metadata (parameter set, plant, drive, step size, steps, wall time).
        effect_row: the plant's effects (:data:`~turntable_env.effects.EFFECT_FIELDS`) where
            it has output-stage ones, read by :meth:`detector_voltage`; else None.
    """

    time: np.ndarray
    centre_displacement: np.ndarray
    rotation_vector: np.ndarray
    angular_velocity: np.ndarray
    channel_voltage: np.ndarray
    normal_force: np.ndarray
    friction_force: np.ndarray
    slip_speed: np.ndarray
    n_stick: np.ndarray
    overlap: np.ndarray
    tube_displacement: np.ndarray
    energy: dict[str, np.ndarray]
    axis_units: np.ndarray
    axis: str
    detector: Detector
    table_radius: float
    period_starts: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    effect_row: np.ndarray | None = None

    # --- angles and detector ----------------------------------------------------------
    def angle(self, axis: str | None = None) -> np.ndarray:
        """Rotation about ``axis`` (default: the axis under test) [rad]: the rotation
        vector's component along the axis unit vector."""
        a = self.axis if axis is None else axis
        if a not in AXES:
            raise ValueError(f"axis={axis!r}: must be one of {', '.join(AXES)}")
        return self.rotation_vector @ self.axis_units[AXES.index(a)]

    @property
    def angles(self) -> np.ndarray:
        """Rotation about A, B, C, Z [rad], (n, 4)."""
        return self.rotation_vector @ self.axis_units.T

    # --- energy ---------------------------------------------------------------------------
    @property
    def stored_energy(self) -> np.ndarray:
        """Sum of kinetic, elastic, piezo, contact, GMS and potential energy [J], (n,)."""
        return sum(self.energy[k] for k in _STORED)  # type: ignore[return-value]

    @property
    def dissipated_energy(self) -> np.ndarray:
        """Cumulative friction + tube damping + contact damping dissipation [J], (n,)."""
        return sum(self.energy[k] for k in _DISSIPATED)  # type: ignore[return-value]

    @property
    def energy_residual(self) -> np.ndarray:
        """E_in − ΔE_stored − D [J] over time (zero for an exact energy balance)."""
        e_in = self.energy["electrical_in"]
        return e_in - (self.stored_energy - self.stored_energy[0]) - self.dissipated_energy

    @property
    def energy_closure(self) -> float:
        """max |E_in − ΔE_stored − D| / (gross electrical energy exchanged) [-].

        The amplifier charges and discharges the quadrants every period, so the net
        electrical input is small while the exchanged energy ∫|V dq| is large; the
        residual is measured against the latter.
        """
        gross = float(self.energy["electrical_gross"][-1])
        if gross <= 0.0:
            return float("nan")
        return float(np.max(np.abs(self.energy_residual)) / gross)

    @property
    def energy_closure_vs_dissipation(self) -> float:
        """max |residual| / total dissipation at the end [-] (a stricter measure)."""
        d = float(self.dissipated_energy[-1])
        return float(np.max(np.abs(self.energy_residual)) / d) if d > 0.0 else float("nan")

    # --- export ---------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        """The CLI's JSON numbers (SI unless the key says otherwise)."""
        wall = self.info.get("wall_s", float("nan"))
        sim = float(self.time[-1] - self.time[0])
        return {
            "params": self.info.get("params"),
            "axis": self.axis,
            "step_um": self.step_size * 1e6,
            "steps_um": (self.steps * 1e6).tolist(),
            "net_rotation_rad": self.net_rotation,
            "detector_V_net": self.detector_V_net,
            "energy_closure": self.energy_closure,
            "energy_closure_vs_dissipation": self.energy_closure_vs_dissipation,
            "simulated_s": sim,
            "wall_s": wall,
            "realtime_factor": sim / wall if wall and wall > 0 else float("nan"),
            "n_steps": self.info.get("n_steps"),
            "dt_s": self.info.get("dt"),
        }

    def signals(self) -> dict[str, np.ndarray]:
        """Every recorded signal by name (unit in the name): the angle about the axis under
        test and the detector, the three axes' angles, the centre's displacement, the
        quadrant voltages, each contact's forces, slip speed and sticking elements, and the
        energy terms."""
        cols: dict[str, np.ndarray] = {"angle_rad": self.angle()}
        for i, a in enumerate(AXES):
            cols[f"angle_{a}_rad"] = self.angles[:, i]
        cols["detector_V"] = self.detector_voltage()
        for i, a in enumerate("xyz"):
            cols[f"centre_{a}_m"] = self.centre_displacement[:, i]
        for i, a in enumerate(AXES):
            cols[f"V_{a}_V"] = self.channel_voltage[:, i]
        for k, t in enumerate(TUBES):
            cols[f"normal_force_{t}_N"] = self.normal_force[:, k]
            cols[f"friction_{t}_x_N"] = self.friction_force[:, k, 0]
            cols[f"friction_{t}_y_N"] = self.friction_force[:, k, 1]
            cols[f"slip_speed_{t}_m_s"] = self.slip_speed[:, k]
            cols[f"n_stick_{t}"] = self.n_stick[:, k]
        for name, v in self.energy.items():
            cols[f"energy_{name}_J"] = v
        return cols

    def plot(self, axes: Any = None) -> Any:
        """Angle, quadrant voltage, contact forces and energy residual versus time."""
        import matplotlib.pyplot as plt

        if axes is None:
            _, axes = plt.subplots(4, 1, sharex=True, figsize=(7, 8))
        t_ms = self.time * 1e3
        axes[0].plot(t_ms, self.angle() * self.table_radius * 1e6)
        axes[0].set_ylabel(f"x_table about {self.axis} [µm]")
        for i, a in enumerate(AXES):
            if np.any(self.channel_voltage[:, i] != 0.0):
                axes[1].plot(t_ms, self.channel_voltage[:, i], label=a)
        axes[1].set_ylabel("quadrant voltage [V]")
        axes[1].legend(loc="upper right")
        for k, t in enumerate(TUBES):
            axes[2].plot(t_ms, self.normal_force[:, k], label=f"F_N {t}")
            axes[2].plot(t_ms, np.hypot(*self.friction_force[:, k].T), "--", label=f"|F_t| {t}")
        axes[2].set_ylabel("contact force [N]")
        axes[2].legend(loc="upper right", ncol=3, fontsize="small")
        axes[3].plot(t_ms, self.energy_residual)
        axes[3].set_ylabel("energy residual [J]")
        axes[3].set_xlabel("time [ms]")
        return axes

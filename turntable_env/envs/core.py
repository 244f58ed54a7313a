"""The PiezoTurntable task for N turntables at once: the physics behind both environments.

:class:`TurntableTask` keeps, per turntable, the simulator state (a backend), the
free-running waveform generator (:func:`~turntable_env.drive.generator_segment`), the
start and target angles and the last action; :meth:`TurntableTask.step` advances all
N by one control interval in one compiled call (reduced fidelity). The Gymnasium
classes in :mod:`.piezo_turntable` and :mod:`.vector` are thin adapters over it.

Per step (control interval Δt) and turntable:

1. the clipped action becomes a :class:`~turntable_env.drive.StepSetting` and a scan level;
   the generator emits Δt of amplifier input, the scan level ramping linearly from
   the previous one (:class:`~turntable_env.envs.config.ActionScaling`);
2. the simulator integrates Δt (amplifier slew, tubes, GMS contacts, table);
3. the detector reports the angle (Eq. 4.1 with noise and saturation at ±0.2 mm);
4. reward r = −|θ* − θ|/θ_lin − w·E/E_ref: distance to the target in units of the
   detector's linear range θ_lin (or, with ``reward="log"``, −ln(1 + d/tol)/ln(1 +
   θ_lin/tol)), plus w times the electrical energy E = C∫|V dV| the
   amplifier moved through the channel's quadrants during Δt in units of one
   full-amplitude period, E_ref = C(G·u_max)².
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..drive import (
    StepSetting,
    Waveform,
    capacitive_energy,
    generator_flybacks,
    generator_segment,
    grid_breakpoints,
)
from ..model import TurntableModel
from ..params import ParameterSet
from ..reduced import H_MIN, REDUCED_AXES, ReducedBatch, ReducedModel
from ..reduced_kernel import N_REC
from ..screw import exp_so3, log_so3
from .config import EnvConfig, check_action, sample_parameters

__all__ = ["StepResult", "TurntableTask"]

ANGLE_SAFE = 0.7  # rad, |θ| passed to the detector (< π/4, where the beam leaves it)


@dataclass
class StepResult:
    """Arrays over the N turntables of one step (obs float32, the rest float64/bool)."""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, np.ndarray]


class _ReducedBackend:
    """N reduced per-axis models integrated together (:class:`ReducedBatch`)."""

    def __init__(self, ps: ParameterSet, axis: str, n: int) -> None:
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the reduced model covers {REDUCED_AXES}")
        self.full = TurntableModel(ps)
        self.nominal_params = ps
        self.nominal = ReducedModel(ps, axis, model=self.full)
        self.batch = ReducedBatch([self.nominal] * n)
        self.grid = self.batch.grid
        self.axis = axis
        self._rec = np.zeros((n, 0, N_REC))
        self._n_rec = np.zeros(n, dtype=np.int64)

    def model(self, b: int) -> ReducedModel:
        return self.batch.models[b]

    def reset_row(self, b: int, ps: ParameterSet, angle: float, time: float) -> None:
        if ps is not self.batch.models[b].params:
            if ps is self.nominal_params:
                self.batch.set_model(b, self.nominal)
            else:
                self.batch.set_model(b, ReducedModel(ps, self.axis, model=self.full))
        self.batch.set_state(b, self.batch.models[b].rest_state(angle, 0.0), time)

    def advance(self, waves: list[tuple[np.ndarray, np.ndarray]], n_end: np.ndarray) -> None:
        nbp = max(g.size for g, _ in waves)
        nb = len(waves)
        wg = np.zeros((nb, nbp))
        wv = np.zeros((nb, nbp))
        wn = np.empty(nb, dtype=np.int64)
        for b, (g, v) in enumerate(waves):
            wg[b, : g.size] = g
            wv[b, : g.size] = v
            wn[b] = g.size
        self.batch.advance(wg, wv, wn, n_end, np.maximum(n_end, 1), self._rec, self._n_rec)

    def angles(self) -> np.ndarray:
        return self.batch.y[:, 0].copy()

    def snapshot(self, b: int) -> dict[str, Any]:
        """Render data: tube contact deflections [m] and sticking fraction per contact."""
        st = self.batch.st[b]
        return {
            "tube_deflection": self.batch.y[b, 2:6:2].copy(),
            "stick_fraction": st.sum(axis=1) / st.shape[1],
            "voltage": float(self.batch.volt[b]),
            "tubes": self.nominal.axis_params.tubes,
        }


class _FullBackend:
    """The 3-D model, one turntable after another (resumed from its final state)."""

    def __init__(self, ps: ParameterSet, axis: str, n: int) -> None:
        self.nominal_params = ps
        self.nominal = TurntableModel(ps)
        self.full = self.nominal
        self.models = [self.nominal] * n
        self.states: list[dict[str, np.ndarray]] = [self.nominal.rest_state() for _ in range(n)]
        self.times = np.zeros(n)
        self.axis = axis
        self.c = "ABC".index(axis)
        self.unit = self.nominal.layout.axis_units[self.c]
        self.grid = H_MIN  # s, breakpoint grid shared with the reduced model

    def model(self, b: int) -> TurntableModel:
        return self.models[b]

    def reset_row(self, b: int, ps: ParameterSet, angle: float, time: float) -> None:
        if ps is not self.models[b].params:
            self.models[b] = self.nominal if ps is self.nominal_params else TurntableModel(ps)
        st = self.models[b].rest_state()
        st["rot"] = exp_so3(angle * self.unit)
        self.states[b] = st
        self.times[b] = time

    def advance(self, waves: list[tuple[np.ndarray, np.ndarray]], n_end: np.ndarray) -> None:
        for b, (g, v) in enumerate(waves):
            t1 = float(n_end[b]) * self.grid
            raw = self.models[b].run(
                {self.axis: Waveform(g * self.grid, v)},
                t1 - self.times[b],
                start=self.times[b],
                initial_state=self.states[b],
                coarse_factor=0.5,
                output_dt=t1 - self.times[b],
            )
            self.states[b] = raw["final"]
            self.times[b] = t1

    def angles(self) -> np.ndarray:
        return np.array([float(log_so3(s["rot"]) @ self.unit) for s in self.states])

    def snapshot(self, b: int) -> dict[str, Any]:
        ar = self.models[b]._arrays
        st = self.states[b]
        defl, frac, tubes = [], [], []
        for k in range(3):
            if k == self.c:
                continue
            e = np.cross(self.unit, ar["d_nom"][k])
            defl.append(float(st["xi"][k, 3:6] @ (e / np.linalg.norm(e))))
            frac.append(float(st["gst"][k].mean()))
            tubes.append("ABC"[k])
        return {
            "tube_deflection": np.array(defl),
            "stick_fraction": np.array(frac),
            "voltage": float(st["vch"][self.c]),
            "tubes": tuple(tubes),
        }


class TurntableTask:
    """N PiezoTurntable tasks advanced together (see the module docstring).

    Args:
        config: the environment configuration.
        num: number of turntables.
    """

    def __init__(self, config: EnvConfig, num: int = 1) -> None:
        if num < 1:
            raise ValueError(f"num={num!r}: must be >= 1")
        self.config = config
        self.num = num
        ps = config.parameter_set
        self.nominal = ps
        backend = _ReducedBackend if config.fidelity == "reduced" else _FullBackend
        self.backend = backend(ps, config.axis, num)
        self.grid = self.backend.grid
        self.steps_per_interval = round(config.control_interval / self.grid)
        if abs(self.steps_per_interval * self.grid - config.control_interval) > 1e-12:
            raise ValueError(
                f"control_interval={config.control_interval!r}: must be a multiple of the "
                f"{self.grid * 1e9:.1f} ns integration grid"
            )
        self.scaling = config.scaling
        amp = ps.amplifier
        self.detector = ps.detector
        self.angle_range = self.detector.angle_range  # rad, θ_lin
        self.c_load = self.backend.full.load_capacitance(config.axis)  # F, channel load
        self.e_ref = self.c_load * (amp.gain * amp.input_limit) ** 2  # J, one full period
        self.noise_nominal = config.sensor_noise if config.noise else 0.0
        # per-turntable state
        self.params = [ps] * num
        self.noise_std = np.full(num, self.noise_nominal)  # V
        self.step_index = np.zeros(num, dtype=np.int64)
        self.target = np.zeros(num)  # rad
        self.start = np.zeros(num)  # rad
        self.phase = np.zeros(num)
        self.running = [StepSetting()] * num
        self.offset = np.zeros(num)  # V, scan level at the interval end
        self.last_action = np.zeros((num, 5))
        self.measured = np.zeros(num)  # rad
        self.detector_v = np.zeros(num)  # V
        self.angle = np.zeros(num)  # rad
        self.factors: list[dict[str, float]] = [{} for _ in range(num)]

    # ------------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """Simulated time of each turntable [s]."""
        return self.step_index * self.config.control_interval

    def reset_row(
        self, b: int, rng: np.random.Generator, options: dict[str, Any] | None = None
    ) -> None:
        """New episode for turntable b: parameters (randomised), start and target angles."""
        cfg = self.config
        opts = dict(options or {})
        unknown = set(opts) - {"start_angle", "target_angle"}
        if unknown:
            raise ValueError(f"options: unknown keys {sorted(unknown)}")
        if cfg.ranges:
            ps, factors = sample_parameters(self.nominal, cfg.ranges, rng)
        else:
            ps, factors = self.nominal, {}
        self.factors[b] = factors
        self.params[b] = ps
        self.noise_std[b] = self.noise_nominal * factors.get("sensor_noise", 1.0)
        lim = self.angle_range
        start = rng.uniform(-1.0, 1.0) * cfg.start_range * lim
        target = rng.uniform(-1.0, 1.0) * cfg.target_range * lim
        if cfg.move_range is not None:
            lo, hi = cfg.move_range
            move = math.exp(rng.uniform(math.log(lo), math.log(hi))) * rng.choice((-1.0, 1.0))
            start = target - move
        if "start_angle" in opts:
            start = _option_angle("start_angle", opts["start_angle"], cfg.angle_limit)
        if "target_angle" in opts:
            target = _option_angle("target_angle", opts["target_angle"], lim)
        self.start[b] = start
        self.target[b] = target
        self.step_index[b] = 0
        self.phase[b] = 0.0
        self.running[b] = StepSetting()
        self.offset[b] = 0.0
        self.last_action[b] = 0.0
        self.backend.reset_row(b, ps, start, 0.0)
        self.angle[b] = start
        self._measure(np.array([b]), rng)

    def _measure(self, rows: np.ndarray, rng: np.random.Generator) -> None:
        th = np.clip(self.angle[rows], -ANGLE_SAFE, ANGLE_SAFE)
        v = self.detector.voltage(th)
        noise = rng.normal(0.0, 1.0, size=rows.size) * self.noise_std[rows]
        vs = self.detector.saturation_voltage
        v = np.clip(v + noise, -vs, vs)
        self.detector_v[rows] = v
        self.measured[rows] = self.detector.angle(v)

    def observation(self) -> np.ndarray:
        """(N, 8) float32: measured angle, target, generator phase, last action (5)."""
        obs = np.empty((self.num, 8))
        obs[:, 0] = self.measured
        obs[:, 1] = self.target
        obs[:, 2] = self.phase
        obs[:, 3:] = self.last_action
        return obs.astype(np.float32)

    # ------------------------------------------------------------------------------
    def step(self, actions: np.ndarray, rng: np.random.Generator) -> StepResult:
        """Advance every turntable one control interval under its action (N, 5)."""
        cfg = self.config
        acts = check_action(actions, (self.num, 5))
        dt = cfg.control_interval
        h = self.grid
        waves = []
        energy = np.zeros(self.num)
        flybacks = np.zeros(self.num, dtype=np.int64)
        n0 = self.step_index * self.steps_per_interval
        for b in range(self.num):
            amp_v, freq, a, k, off = self.scaling.decode(acts[b])
            ps = self.params[b]
            amp_in = ps.amplifier
            hold = 0.0
            if k > 0.0 and amp_v != 0.0:
                k = min(k, amp_in.input_limit / abs(amp_v))
                hold = amp_in.adapted_hold_time(abs(amp_v), 0.0, k, self.c_load)
            pending = StepSetting(amp_v, freq, a, k, min(hold, (1.0 - a) / freq))
            t0 = float(n0[b]) * h
            t1 = t0 + dt
            flybacks[b] = generator_flybacks(t0, t1, float(self.phase[b]), self.running[b], pending)
            tt, vv, ph, self.running[b] = generator_segment(
                t0, t1, float(self.phase[b]), self.running[b], pending
            )
            period = 1.0 / self.running[b].frequency
            if ph * period < h or (1.0 - ph) * period < h:  # on a period start (grid)
                ph = 0.0
            self.phase[b] = ph
            vv = vv + self.offset[b] + (off - self.offset[b]) * (tt - t0) / dt
            self.offset[b] = off
            vv = np.clip(vv, -amp_in.input_limit, amp_in.input_limit)
            g, v = grid_breakpoints(tt, vv, h)
            waves.append((g, v))
            energy[b] = capacitive_energy(v * amp_in.gain, self.c_load)
        self.backend.advance(waves, n0 + self.steps_per_interval)
        self.step_index += 1
        self.last_action[:] = acts
        self.angle[:] = self.backend.angles()
        self._measure(np.arange(self.num), rng)
        dist = np.abs(self.target - self.angle)
        if cfg.reward == "log":
            r_dist = -np.log1p(dist / cfg.tolerance) / math.log1p(self.angle_range / cfg.tolerance)
        else:
            r_dist = -dist / self.angle_range
        r_energy = -cfg.energy_weight * energy / self.e_ref
        success = dist <= cfg.tolerance
        r_dist = r_dist + cfg.success_bonus * success
        out = np.abs(self.angle) > cfg.angle_limit
        info = {
            "angle_rad": self.angle.copy(),
            "target_rad": self.target.copy(),
            "distance_rad": dist,
            "energy_J": energy,
            "steps": flybacks,
            "reward_distance": r_dist,
            "reward_energy": r_energy,
            "detector_V": self.detector_v.copy(),
            "is_success": success,
            "out_of_workspace": out,
            "time_s": self.time.astype(float),
        }
        terminated = success if cfg.terminate_on_success else np.zeros(self.num, dtype=bool)
        truncated = out & ~terminated
        return StepResult(self.observation(), r_dist + r_energy, terminated, truncated, info)


def _option_angle(name: str, value: Any, limit: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"options[{name!r}]={value!r}: must be a real number") from None
    if not math.isfinite(x) or abs(x) > limit:
        raise ValueError(
            f"options[{name!r}]={value!r}: must be finite with |angle| <= {limit:.4g} rad"
        )
    return x

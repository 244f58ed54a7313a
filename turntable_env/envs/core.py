"""The PiezoTurntable task for N turntables at once: the env's side of the plant layer.

:class:`TurntableTask` keeps, per turntable, the task (start and target angles, the last
action, the measured angle) and hands the physics to one
:class:`~turntable_env.plant.PlantStepper` for all N. The Gymnasium classes in
:mod:`.piezo_turntable` and :mod:`.vector` are thin adapters over it.

:meth:`TurntableTask.step` runs named phases, as HighwayEnv's ``AbstractEnv.step``:

1. **simulate** — the clipped actions become generator settings
   (:meth:`~turntable_env.envs.config.ActionScaling.decode_batch`: amplitude, frequency, a,
   k, scan level) and the plants advance Δt (generator, piezo effects, amplifier §4.1.2,
   tubes Eq. 2.11, GMS contacts Eq. 2.24–2.26, table: :mod:`turntable_env.plant`);
2. **observe** — the detector reports the angle (Eq. 4.1 with the output-stage effects,
   noise and saturation at ±0.2 mm);
3. **reward** — r = −|θ* − θ|/θ_lin − w·E/E_ref: distance to the target in units of the
   detector's linear range θ_lin (or, with ``reward="log"``, −ln(1 + d/tol)/ln(1 +
   θ_lin/tol)), plus w times the electrical energy E = C∫|V dV| the amplifier moved
   through the channel's quadrants during Δt in units of one full-amplitude period,
   E_ref = C(G·u_max)²;
4. **terminated** (within tolerance), **truncated** (out of the workspace) and **info**.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..plant import IntervalResult, Plant, PlantStepper, load_capacitance
from .config import OBS, OBS_Y, RETARGET_HORIZON, EnvConfig, check_action

__all__ = ["RESET_OPTIONS", "StepResult", "TurntableTask", "retarget_legs"]

RESET_OPTIONS = ("start_angle", "target_angle", "reference", "knock")


@dataclass
class StepResult:
    """Arrays over the N turntables of one step (obs float32, the rest float64/bool)."""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, np.ndarray]


class TurntableTask:
    """N PiezoTurntable tasks advanced together (see the module docstring).

    Args:
        config: the environment configuration (its plant, axis, interval, reward).
        num: number of turntables.

    Attributes:
        plant: the configured plant; plants: the plant of each turntable this episode
        (a draw of ``plant`` under randomisation); stepper: the
        :class:`~turntable_env.plant.PlantStepper` that runs them.
    """

    def __init__(self, config: EnvConfig, num: int = 1) -> None:
        if num < 1:
            raise ValueError(f"num={num!r}: must be >= 1")
        self.config = config
        self.num = num
        self.plant = config.plant
        self.stepper = PlantStepper([self.plant] * num, config.axis, noise=config.noise)
        self.grid = self.stepper.grid
        self.steps_per_interval = round(config.control_interval / self.grid)
        off_grid = abs(self.steps_per_interval * self.grid - config.control_interval) > 1e-12
        if self.steps_per_interval < 1 or off_grid:
            raise ValueError(
                f"control_interval={config.control_interval!r}: must be a multiple of the "
                f"{self.grid * 1e9:.1f} ns integration grid"
            )
        self.scaling = config.scaling
        ps = self.plant.params
        amp = ps.amplifier
        self.detector = ps.detector
        self.angle_range = self.detector.angle_range  # rad, θ_lin
        # the workspace holds every start and target a reset draws; a tolerance is a
        # distance within the detector's range (beyond it every episode succeeds at once)
        reach = max(config.start_range, config.target_range) * self.angle_range
        if config.angle_limit <= reach:
            raise ValueError(
                f"angle_limit={config.angle_limit!r}: must exceed the reset's reach {reach:.3g} "
                "rad (start_range, target_range × the detector's range)"
            )
        if config.tolerance >= self.angle_range:
            raise ValueError(
                f"tolerance={config.tolerance!r}: must be below the detector's range "
                f"{self.angle_range:.3g} rad"
            )
        self.c_load = load_capacitance(ps, config.axis)  # F, channel load
        self.e_ref = self.c_load * (amp.gain * amp.input_limit) ** 2  # J, one full period
        # per-turntable state
        self.plants = [self.plant] * num
        self.draws: list[dict[str, float]] = [{} for _ in range(num)]
        self.step_index = np.zeros(num, dtype=np.int64)
        self.target = np.zeros(num)  # rad
        self.start = np.zeros(num)  # rad
        self.phase = np.zeros(num)
        self.last_action = np.zeros((num, 5))
        self.measured = np.zeros(num)  # rad
        self.detector_v = np.zeros(num)  # V
        self.measured_y = np.zeros(num)  # rad, the y channel's reading (detector_y)
        self.angle = np.zeros(num)  # rad
        self.reference: list[np.ndarray | None] = [None] * num  # rad per interval, or None
        self.knock: list[tuple[int, float] | None] = [None] * num  # (interval, Δθ [rad])

    # ------------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """Simulated time of each turntable [s]."""
        return self.step_index * self.config.control_interval

    def reset_row(
        self,
        b: int,
        rng: np.random.Generator,
        options: dict[str, Any] | None = None,
        *,
        plant: Plant | None = None,
    ) -> None:
        """New episode for turntable b: its plant (randomised, or ``plant`` when given — the
        controller benchmark's held-out plants), start and target angles, reference and knock
        (:data:`RESET_OPTIONS`)."""
        cfg = self.config
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(f"options={options!r}: must be a dict (or None)")
        opts = dict(options or {})
        unknown = set(opts) - set(RESET_OPTIONS)
        if unknown:
            raise ValueError(f"options: unknown keys {sorted(unknown)} (known: {RESET_OPTIONS})")
        if "reference" in opts and "target_angle" in opts:
            raise ValueError("options: give 'reference' or 'target_angle', not both")
        reference = _option_reference(opts.get("reference"), self.angle_range)
        knock = _option_knock(opts.get("knock"), cfg.control_interval, cfg.angle_limit)
        lim = self.angle_range
        # every option checked before anything changes: a refused reset leaves the episode
        start_opt = (_option_angle("start_angle", opts["start_angle"], cfg.angle_limit)
                     if "start_angle" in opts else None)  # fmt: skip
        target_opt = (_option_angle("target_angle", opts["target_angle"], lim)
                      if "target_angle" in opts else None)  # fmt: skip
        if plant is not None:
            if not isinstance(plant, Plant) or plant.fidelity != self.plant.fidelity:
                raise ValueError(
                    f"plant={plant!r}: must be a Plant of fidelity {self.plant.fidelity!r}"
                )
            draw: dict[str, float] = {}
        elif cfg.randomized:
            plant, draw = self.plant.sample(rng, ranges=cfg.ranges or None)
        else:
            plant, draw = self.plant, {}
        self.draws[b] = draw
        if plant is not self.plants[b]:
            self.stepper.set_plant(b, plant)
            self.plants[b] = plant
        start = rng.uniform(-1.0, 1.0) * cfg.start_range * lim
        target = rng.uniform(-1.0, 1.0) * cfg.target_range * lim
        if cfg.move_range is not None:
            lo, hi = cfg.move_range
            move = math.exp(rng.uniform(math.log(lo), math.log(hi))) * rng.choice((-1.0, 1.0))
            start = target - move
        if start_opt is not None:
            start = start_opt
        if target_opt is not None:
            target = target_opt
        fixed = reference is not None or "target_angle" in opts
        if not fixed and cfg.retarget_share > 0.0 and rng.uniform() < cfg.retarget_share:
            reference = retarget_legs(rng, target, cfg.retarget_legs, cfg.target_range * lim)
        if reference is not None:
            target = float(reference[0])
        self.reference[b] = reference
        self.knock[b] = knock
        self.start[b] = start
        self.target[b] = target
        self.step_index[b] = 0
        self.phase[b] = 0.0
        self.last_action[b] = 0.0
        self.stepper.reset(b, start, 0.0)
        self.angle[b] = start
        self._observe(np.array([b]), rng)

    def observation(self) -> np.ndarray:
        """(N, 8) float32: the components of :data:`~.config.OBSERVATION_NAMES` ((N, 9) with
        ``measured_y_rad`` last when the config's ``detector_y``)."""
        obs = np.empty((self.num, len(self.config.observation_names)))
        if self.config.detector_y:
            obs[:, OBS_Y] = self.measured_y
        obs[:, OBS.measured_angle_rad] = self.measured
        obs[:, OBS.target_angle_rad] = self.target
        obs[:, OBS.generator_phase] = self.phase
        obs[:, OBS.last_amplitude : OBS.last_scan_offset + 1] = self.last_action
        return obs.astype(np.float32)

    # --- step: simulate, observe, reward, terminated, truncated, info --------------------
    def step(
        self,
        actions: np.ndarray,
        rng: np.random.Generator,
        normals: np.ndarray | None = None,
    ) -> StepResult:
        """Advance every turntable one control interval under its action (N, 5); the
        detector noise from ``rng``, or from ``normals`` (N,) standard normal draws when
        given (common random numbers: the controller benchmark; (N, 2) with the config's
        ``detector_y``, the x and y channels' draws)."""
        acts = check_action(actions, (self.num, 5))
        interval = self._simulate(acts)
        self._observe(np.arange(self.num), rng, normals)
        dist, r_dist, r_energy, success = self._reward(interval.energy)
        terminated = self._terminated(success)
        truncated = self._truncated(terminated)
        info = self._info(interval, dist, r_dist, r_energy, success)
        return StepResult(self.observation(), r_dist + r_energy, terminated, truncated, info)

    def _simulate(self, acts: np.ndarray) -> IntervalResult:
        """Actions → generator settings → one interval of the plants (module docstring)."""
        result = self.stepper.advance(self.scaling.decode_batch(acts), self.config.control_interval)
        self.phase[:] = result.phase
        self.step_index += 1
        self.last_action[:] = acts
        for b in range(self.num):  # the reference's target and a knock at this interval's end
            ref, knock = self.reference[b], self.knock[b]
            if ref is not None:
                self.target[b] = ref[min(int(self.step_index[b]), ref.size - 1)]
            if knock is not None and knock[0] == self.step_index[b]:
                self.stepper.displace(b, knock[1])
        self.angle[:] = self.stepper.angle
        return result

    def _observe(
        self, rows: np.ndarray, rng: np.random.Generator, normals: np.ndarray | None = None
    ) -> None:
        """The detector's reading (Eq. 4.1 with effects, noise, saturation) and its angle;
        with ``detector_y`` the y channel's too (``normals`` (rows, 2) then)."""
        if self.config.detector_y:
            v, vy = self.stepper.observe_xy(rng, rows, normals)
            self.measured_y[rows] = self.detector.angle(vy)
        else:
            v = self.stepper.observe(rng, rows, normals)
        self.detector_v[rows] = v
        self.measured[rows] = self.detector.angle(v)

    def _reward(self, energy: np.ndarray) -> tuple[np.ndarray, ...]:
        """(distance [rad], distance reward, energy reward, success) (module docstring)."""
        cfg = self.config
        dist = np.abs(self.target - self.angle)
        if cfg.reward == "log":
            r_dist = -np.log1p(dist / cfg.tolerance) / math.log1p(self.angle_range / cfg.tolerance)
        else:
            r_dist = -dist / self.angle_range
        r_energy = -cfg.energy_weight * energy / self.e_ref
        success = dist <= cfg.tolerance
        return dist, r_dist + cfg.success_bonus * success, r_energy, success

    def _terminated(self, success: np.ndarray) -> np.ndarray:
        if self.config.terminate_on_success:
            return success
        return np.zeros(self.num, dtype=bool)

    def _truncated(self, terminated: np.ndarray) -> np.ndarray:
        return (np.abs(self.angle) > self.config.angle_limit) & ~terminated

    def _info(
        self,
        interval: IntervalResult,
        dist: np.ndarray,
        r_dist: np.ndarray,
        r_energy: np.ndarray,
        success: np.ndarray,
    ) -> dict[str, np.ndarray]:
        return {
            "angle_rad": self.angle.copy(),
            "target_rad": self.target.copy(),
            "distance_rad": dist,
            "energy_J": interval.energy,
            "steps": interval.flybacks,
            "reward_distance": r_dist,
            "reward_energy": r_energy,
            "detector_V": self.detector_v.copy(),
            "is_success": success,
            "out_of_workspace": np.abs(self.angle) > self.config.angle_limit,
            "time_s": self.time.astype(float),
        }


def retarget_legs(
    rng: np.random.Generator, first: float, legs: tuple[int, int], half_width: float
) -> np.ndarray:
    """A retargeting episode's reference [rad], :data:`~.config.RETARGET_HORIZON` intervals:
    ``first`` held for a leg of ``legs`` intervals (uniform integers, both ends included),
    then each next target uniform within ±``half_width`` [rad] for a leg of its own
    (``EnvConfig.retarget_share``)."""
    out = np.empty(RETARGET_HORIZON)
    k, target = 0, first
    while k < RETARGET_HORIZON:
        n = int(rng.integers(legs[0], legs[1] + 1))
        out[k : k + n] = target
        k += n
        target = float(rng.uniform(-1.0, 1.0)) * half_width
    return out


def _option_reference(value: Any, limit: float) -> np.ndarray | None:
    """A reference trajectory option: finite angles [rad] within ±``limit``, one per interval."""
    if value is None:
        return None
    try:
        ref = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"options['reference']: {value!r} is not a sequence of angles") from None
    if ref.ndim != 1 or ref.size == 0:
        raise ValueError(f"options['reference']: shape {ref.shape}, expected (n,) with n >= 1")
    bad = np.flatnonzero(~np.isfinite(ref) | (np.abs(ref) > limit))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"options['reference'][{i}]={float(ref[i])!r}: must be finite with "
            f"|angle| <= {limit:.4g} rad"
        )
    ref.setflags(write=False)
    return ref


def _option_knock(value: Any, interval: float, limit: float) -> tuple[int, float] | None:
    """A knock option (time [s], Δθ [rad]) → (interval index at whose end it acts, Δθ)."""
    if value is None:
        return None
    try:
        t, d = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"options['knock']={value!r}: must be (time_s, angle_rad)") from None
    if not (math.isfinite(t) and t > 0.0):
        raise ValueError(f"options['knock']={value!r}: time must be finite and > 0 s")
    if not (math.isfinite(d) and abs(d) <= limit):
        raise ValueError(f"options['knock']={value!r}: |angle| must be <= {limit:.4g} rad")
    return max(round(t / interval), 1), d


def _option_angle(name: str, value: Any, limit: float) -> float:
    if isinstance(value, str | bytes | bool):  # '0' is text, True is not an angle
        raise ValueError(f"options[{name!r}]={value!r}: must be a real number")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):  # 10**400: not a float either
        raise ValueError(f"options[{name!r}]={value!r}: must be a real number") from None
    if not math.isfinite(x) or abs(x) > limit:
        raise ValueError(
            f"options[{name!r}]={value!r}: must be finite with |angle| <= {limit:.4g} rad"
        )
    return x

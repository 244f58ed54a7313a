"""What an agent may learn of its plant while it acts: online step gains as features.

An agent trained on one plant distribution meets plants that step differently for the
same action (the thesis calibration's turntable steps 1.24–5.23× the nominal plant from
2 V up; ``python experiments/step_gain_survey.py``). One interval's features do not say
which plant it is on, so a policy trained on several learns one compromise for all
(docs/rl.md). :class:`StepIdentifier` gives it what the closed-loop baseline measures
(:mod:`controllers.closed_loop`), from the same observations a lab has: after every
stepping interval whose readings before and after are valid,

    ρ = (Δθ_measured − K·Δu_scan) / (m·s_map(A, f)),

the measured displacement less the scan offset's share (K the stick plant's scan gain
[rad/V], Δu the offset's change [V]) over the nominal step map's m = f·Δt steady steps
per period s_map [rad] at the interval's amplitude A [V] and frequency f [Hz] (linear
in |A|, in ln f between the map's frequencies). ρ updates the per-direction,
per-amplitude gains γ[d, A] of :class:`~controllers.step_gain.StepGains` (forgetting
factor 1 − λ, the first measurement replacing the prior 1), and the agent sees

    log₁₀ γ[d, A] / ``LOG_RANGE``, clipped at ±1,   d = +1, −1;  A = ``AMPLITUDES``

(0 before anything is measured: the map's own gain). The interval's setting is read
from the observation's ``last_*`` components, so the gains learn from what ran, after
any safety filter, not from what the policy asked for.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.base import MIN_LEARN, SATURATION_FRACTION, ControllerContext
from controllers.step_gain import StepGains
from controllers.step_map import StepMap
from turntable_env.envs.config import OBS

__all__ = ["AMPLITUDES", "LOG_RANGE", "StepIdentifier"]

AMPLITUDES = (2.0, 6.0, 10.0)  # V, input amplitudes whose gains the agent sees
LOG_RANGE = 1.0  # decades of gain that span a feature's [-1, 1]


class StepIdentifier:
    """Online step gains of one turntable as agent features (module docstring).

    Args:
        ctx: the plant context the agent acts on (axis, Δt, scaling, scan gain, detector).
        ramp_ratio, slew_adaptation: the waveform family the agent steps with (a, k; the
            map must hold it).
        step_map: the nominal map (default: the shipped one).
        learning_rate: λ of :class:`~controllers.step_gain.StepGains` [-].
    """

    n_features = 2 * len(AMPLITUDES)

    def __init__(
        self,
        ctx: ControllerContext,
        ramp_ratio: float,
        slew_adaptation: float,
        step_map: StepMap | None = None,
        *,
        learning_rate: float = 0.5,
    ) -> None:
        smap = step_map if step_map is not None else StepMap.load()
        if abs(smap.control_interval - ctx.control_interval) > 1e-12:
            raise ValueError(
                f"step_map.control_interval={smap.control_interval!r}: the agent runs at "
                f"{ctx.control_interval!r} s"
            )
        self.ctx = ctx
        freqs = np.unique(smap.frequency)
        # steady step per period [rad] on the map's grid: direction → (|A| (n,), s (n, F))
        self._grid: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for d in (1, -1):
            fams = [smap.family(ctx.axis, float(f), ramp_ratio, slew_adaptation, d) for f in freqs]
            amps = np.abs(smap.amplitude[fams[0]])
            if any(not np.allclose(np.abs(smap.amplitude[i]), amps) for i in fams):
                raise ValueError("step_map: the frequencies do not share one amplitude grid")
            self._grid[d] = (amps, np.stack([smap.step[i] for i in fams], axis=1))
        self._log_f = np.log(freqs)
        self._sat = ctx.angle_range * SATURATION_FRACTION
        self.gains = StepGains(rate=learning_rate)
        self._prev: tuple[float, float] | None = None  # (reading [rad], scan offset [V])

    def nominal_step(self, amplitude: float, frequency: float) -> float:
        """The map's steady step per period [rad] at a signed amplitude [V] and frequency
        [Hz], clamped to the map's amplitude and frequency ranges."""
        amps, steps = self._grid[1 if amplitude > 0 else -1]
        per_f = np.array([np.interp(abs(amplitude), amps, col) for col in steps.T])
        return float(np.interp(math.log(frequency), self._log_f, per_f))

    def _reading(self, obs: np.ndarray) -> tuple[float, float] | None:
        """(table angle [rad], scan offset [V]) of an observation; None if saturated."""
        o = self.ctx.lab_observation(obs)
        meas = float(o[OBS.measured_angle_rad])
        if abs(meas) >= self._sat:
            return None
        return meas, float(o[OBS.last_scan_offset]) * self.ctx.input_limit

    def reset(self, obs: np.ndarray) -> None:
        """A new episode (a new turntable): forget the gains; ``obs`` the reset observation."""
        self.gains.reset()
        self._prev = self._reading(obs)

    def update(self, obs: np.ndarray) -> None:
        """Learn from the interval that ``obs`` (the observation after it) closes."""
        now = self._reading(obs)
        prev, self._prev = self._prev, now
        if now is None or prev is None:
            return
        amp, freq, *_ = self.ctx.scaling.decode(np.asarray(obs)[OBS.last_amplitude :][:5])
        if amp == 0.0:  # the generator was idle: a scan interval
            return
        m = round(freq * self.ctx.control_interval)  # whole periods in the interval
        nominal = m * self.nominal_step(amp, freq)
        if abs(nominal) < MIN_LEARN:
            return
        moved = now[0] - prev[0] - self.ctx.scan_gain * (now[1] - prev[1])
        d = 1 if nominal > 0 else -1
        # a move against the map's direction is no gain: clipped to the lowest ratio
        self.gains.update(d, amp, max(moved / nominal, 0.0))

    def features(self) -> np.ndarray:
        """(6,) float32: log₁₀ γ / LOG_RANGE for d = +1 then −1 at each of AMPLITUDES."""
        out = [self.gains.estimate(d, np.asarray(AMPLITUDES))[0] for d in (1, -1)]
        g = np.log10(np.concatenate(out)) / LOG_RANGE
        return np.clip(g, -1.0, 1.0).astype(np.float32)

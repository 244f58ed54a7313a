"""Online step-size gains: how far the plant really steps, against what the map predicts.

A controller built on the nominal step map (:mod:`controllers.step_map`) meets plants that
step differently, and not by one factor: the thesis calibration's turntable (``turntable
benchmark``'s ``calibrated`` set) steps 1.24–5.23× the nominal plant from 2 V up,
depending on amplitude and frequency (``python experiments/step_gain_survey.py``). So the
gain is kept per direction d and amplitude A (pooled over the frequencies and over moves
from rest and running):

    ρ = (Δθ_measured − Δθ_scan) / D_map(A, f, d),     γ[d, A] ← γ[d, A] + λ·(clip(ρ) − γ[d, A])

(the first measurement of an amplitude replaces the prior 1; λ the forgetting rate). A
measured amplitude's gain bounds its moves at the frequencies it was measured at; at its
other frequencies (:meth:`StepGains.estimate` with ``frequency``) the bound is the larger
of it and the kernel average of the *other* measured amplitudes (below): a plant whose step
depends on the frequency can make one setting's gain unlike its neighbours' (held-out seed
0 of the benchmark, piezo creep: −7 V stepped 0.48 of the map in one period at 100 Hz,
where −5.5 V had stepped 1.18, ``python experiments/replay_episode.py closed_loop
held_out back_forth 0``; at 500 Hz −7 V stepped about the map's step, and a plan that
took 0.48 as the bound there passed the target). An
amplitude not yet measured takes a kernel average over its direction's measured ones,
geometric, weighted by exp(−½(ΔA/σ_A)²) + ε in amplitude (σ_A = ``width``, 1 V; the gain
of a plant that differs from the map varies mostly with the amplitude; ε = 10⁻³ lets
distant amplitudes decide where no near one is measured); 1 when nothing is measured.
Its **upper bound** is ``spread``× the larger of that average and 1 (2: the calibrated
plant's gain varies about 2× between neighbouring amplitudes; and the map itself stays a
bound, because a small gain near the stick–slip onset, where a plant with more friction
barely slips, says nothing about the larger amplitudes) or, with nothing measured in
that direction, ``caution``× 1 (4). A
planner that lets no move's upper bound pass the target makes its first moves small
enough for such a plant, and grows them as it learns.

An amplitude whose measured gain is below ``STALL`` (0.2) is **stalled**: the plant
barely steps there (a plant with more friction below its onset). It is left out of the
kernel average, and :meth:`StepGains.stalled` tells a planner not to use it: a stalled
amplitude must not win as the only "known" move while the table stands still.

**Direction.** A plant can step *backwards* at a setting: with a friction asymmetry the
slip during the flyback and the re-stick after it are unequal, and from some amplitude and
frequency on the drag of the flyback outweighs the ramp's travel (held-out seed 18 of the
benchmark, α = 0.24: +0.11 µm per period at 4 V, 1 kHz, −0.38 µm at 6 V, 1 kHz,
``python experiments/held_out_directions.py``). Since the drag grows with the drive's
amplitude and frequency, a setting (A, f) measured backwards (:meth:`StepGains.record`: a
move against its direction by more than ``REVERSED`` of the map's and ``REVERSE_MIN``)
rules out every setting of its direction with A' ≥ A and f' ≥ f
(:meth:`StepGains.reversed`), and its amplitude is stalled at once (not averaged with an
earlier forward measurement). A setting measured forward (ρ ≥ ``STALL``, further than
``CONFIRM_MIN``) *confirms* every
setting with A' ≤ A and f' ≤ f (:meth:`StepGains.confirmed`): a weaker drive keeps the
direction or stalls. A planner makes an unconfirmed move only where a reversal of it
would keep the spot on the detector (:class:`~controllers.feedforward.MapPlanner`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["StepGains"]

KERNEL_FLOOR = 1e-3  # ε, the weight every measured setting keeps [-]
STALL = 0.2  # a measured gain below it: the plant barely steps at that amplitude [-]
REVERSED = 0.5  # a move against its direction by more than this share of the map's ...
REVERSE_MIN = 3e-5  # rad, ... and by more than this (300 nm at R_table = 10 mm: five times
# a floor vibration's swing between two readings, 2 × 3 µrad, and beyond the relaxation
# of a tube after a long stepping run) is a reversed setting
CONFIRM_MIN = 1e-5  # rad, a forward move (ρ ≥ STALL) longer than this confirms its setting
# (100 nm at R_table = 10 mm: above a floor vibration's swing between two readings)


class StepGains:
    """Per-direction, per-amplitude step-size gains (module docstring).

    Args:
        rate: λ, the forgetting rate of repeated measurements [-].
        bounds: clip of a single ratio ρ [-].
        caution: the upper bound of a gain with nothing measured in its direction, × 1 [-].
        spread: the upper bound of an unmeasured amplitude's gain, × max(its kernel
            average, 1) [-].
        width: σ_A, the kernel's width in amplitude [V].
    """

    def __init__(
        self,
        *,
        rate: float = 0.5,
        bounds: tuple[float, float] = (0.1, 10.0),
        caution: float = 4.0,
        spread: float = 2.0,
        width: float = 1.0,
    ) -> None:
        bad_bounds = not 0.0 < bounds[0] < bounds[1]
        if not 0.0 < rate <= 1.0 or min(caution, spread) < 1.0 or bad_bounds or width <= 0.0:
            raise ValueError(
                f"StepGains: rate={rate!r}, bounds={bounds!r}, caution={caution!r}, "
                f"spread={spread!r}, width={width!r}"
            )
        self.rate, self.bounds = rate, bounds
        self.caution, self.spread, self.width = caution, spread, width
        self.reset()

    def reset(self) -> None:
        """Forget every measurement (γ = 1, nothing known)."""
        self.gain: dict[int, dict[float, float]] = {1: {}, -1: {}}
        # the settings (|A| [V], f [Hz]) each gain was measured at, per direction
        self.measured_at: dict[int, set[tuple[float, float]]] = {1: set(), -1: set()}
        # settings (|A| [V], f [Hz]) measured stepping forward / backwards, per direction (sets:
        # bounded by the settings a planner has, however long a run)
        self.forward: dict[int, set[tuple[float, float]]] = {1: set(), -1: set()}
        self.backward: dict[int, set[tuple[float, float]]] = {1: set(), -1: set()}

    @staticmethod
    def _key(amplitude: float) -> float:
        return round(abs(float(amplitude)), 6)

    def update(
        self, direction: int, amplitude: float, ratio: float, frequency: float | None = None
    ) -> None:
        """One measured ratio ρ = measured / map displacement at amplitude A [V] (measured at
        ``frequency`` [Hz], where given)."""
        d = 1 if direction > 0 else -1
        cells = self.gain[d]
        key = self._key(amplitude)
        r = float(np.clip(ratio, *self.bounds))
        cells[key] = r if key not in cells else cells[key] + self.rate * (r - cells[key])
        if frequency is not None:
            self.measured_at[d].add((key, float(frequency)))

    def record(
        self, direction: int, amplitude: float, frequency: float, moved: float, nominal: float
    ) -> None:
        """One stepping interval at the setting (A [V], f [Hz]) of direction d that moved the
        table ``moved`` [rad] where the map predicts ``nominal`` [rad] (both signed): the gain
        ρ = moved/nominal (:meth:`update`, a backward move counting 0), and the setting's
        direction (module docstring: reversed, or forward and confirmed)."""
        d = 1 if direction > 0 else -1
        rho = moved / nominal
        key = (self._key(amplitude), float(frequency))
        if rho < -REVERSED and abs(moved) > REVERSE_MIN:  # stepped backwards: stall it now
            self.backward[d].add(key)
            self.gain[d][key[0]] = self.bounds[0]
            return
        self.update(d, amplitude, max(rho, 0.0), frequency)
        if rho >= STALL and abs(moved) > CONFIRM_MIN:
            self.forward[d].add(key)

    def reversed(
        self, direction: int, amplitude: np.ndarray | float, frequency: np.ndarray | float
    ) -> np.ndarray:
        """Whether each setting (A [V], f [Hz]) of direction d is at or beyond (in amplitude
        and frequency) one measured stepping backwards."""
        return self._dominated(self.backward[1 if direction > 0 else -1], amplitude, frequency, 1)

    def confirmed(
        self, direction: int, amplitude: np.ndarray | float, frequency: np.ndarray | float
    ) -> np.ndarray:
        """Whether each setting (A [V], f [Hz]) of direction d is at or below (in amplitude
        and frequency) one measured stepping forward, and not :meth:`reversed`."""
        d = 1 if direction > 0 else -1
        ok = self._dominated(self.forward[d], amplitude, frequency, -1)
        return ok & ~self.reversed(d, amplitude, frequency)

    def forget_reversals(self, direction: int) -> None:
        """Forget the settings of direction d measured stepping backwards (and un-stall their
        amplitudes): a planner left with no usable move tries them again rather than stop."""
        d = 1 if direction > 0 else -1
        for amp, _f in self.backward[d]:
            self.gain[d].pop(amp, None)
        self.backward[d].clear()

    def _dominated(
        self,
        points: set[tuple[float, float]],
        amplitude: np.ndarray | float,
        frequency: np.ndarray | float,
        sign: int,
    ) -> np.ndarray:
        """Whether each (|A|, f) is ≥ (``sign`` 1) or ≤ (−1) some point in both coordinates."""
        a = np.round(np.abs(np.atleast_1d(np.asarray(amplitude, dtype=float))), 6)
        f = np.broadcast_to(np.asarray(frequency, dtype=float), a.shape)
        if not points:
            return np.zeros(a.shape, dtype=bool)
        pa, pf = (np.array(c, dtype=float) for c in zip(*points, strict=True))
        da = sign * (a[:, None] - pa[None, :]) >= -1e-9
        df = sign * (f[:, None] - pf[None, :]) >= -1e-9
        return (da & df).any(axis=1)

    def _measured(self, direction: int, amplitude: np.ndarray | float) -> tuple[np.ndarray, ...]:
        """(|A| (n,), measured (n,) bool, measured gain (n,), NaN where none) of direction d."""
        cells = self.gain[1 if direction > 0 else -1]
        a = np.abs(np.atleast_1d(np.asarray(amplitude, dtype=float)))
        keys = np.round(a, 6)
        amps = np.fromiter(cells, dtype=float, count=len(cells))
        vals = np.fromiter(cells.values(), dtype=float, count=len(cells))
        hit = keys[:, None] == amps[None, :]
        known = hit.any(axis=1)
        g = np.where(known, vals[hit.argmax(axis=1)] if cells else np.nan, np.nan)
        return a, known, g

    def estimate(
        self,
        direction: int,
        amplitude: np.ndarray | float,
        frequency: np.ndarray | float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(γ, upper bound) for each amplitude [V] of direction d (module docstring); with
        ``frequency`` [Hz], for each setting (A, f): a measured amplitude's bound at a
        frequency it was not measured at is the larger of its gain and the kernel average
        of the other measured amplitudes."""
        d = 1 if direction > 0 else -1
        a, known, g = self._measured(d, amplitude)
        cells = self.gain[d]
        live = {k: v for k, v in cells.items() if v >= STALL}
        if not cells:
            est, upper = np.ones(a.shape), np.full(a.shape, self.caution)
        elif not live:  # every measured amplitude stalled: the map, bounded by ``spread``
            return np.ones(a.shape), np.full(a.shape, self.spread)
        else:
            est = self._kernel(live, a)
            upper = np.maximum(est, 1.0) * self.spread  # evidence never bounds below the map
        bound = g
        if frequency is not None and known.any():
            f = np.broadcast_to(np.asarray(frequency, dtype=float), a.shape)
            seen = self.measured_at[d]
            at = np.array([(self._key(x), float(y)) in seen for x, y in zip(a, f, strict=True)])
            others = self._kernel(live, a, exclude_own=True)  # NaN: no other amplitude
            bound = np.where(known & ~at, np.fmax(g, others), g)
        return np.where(known, g, est), np.where(known, bound, upper)

    def _kernel(
        self, live: dict[float, float], a: np.ndarray, exclude_own: bool = False
    ) -> np.ndarray:
        """The kernel average (module docstring) of the ``live`` gains at each |A| [V]
        (``exclude_own``: without A's own gain; NaN where no other is measured)."""
        amps = np.array(list(live))
        logs = np.log(np.array(list(live.values())))
        w = np.exp(-0.5 * ((a[:, None] - amps[None, :]) / self.width) ** 2) + KERNEL_FLOOR
        if exclude_own:
            w = np.where(np.round(a, 6)[:, None] == amps[None, :], 0.0, w)
        total = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(total > 0.0, np.exp((w * logs).sum(axis=1) / total), np.nan)

    def stalled(self, direction: int, amplitude: np.ndarray | float) -> np.ndarray:
        """Whether each amplitude [V] of direction d has a measured gain below ``STALL``."""
        _a, known, g = self._measured(direction, amplitude)
        return known & (np.nan_to_num(g, nan=1.0) < STALL)

    def learned(self, direction: int) -> bool:
        """Whether any amplitude of direction d has been measured."""
        return bool(self.gain[1 if direction > 0 else -1])

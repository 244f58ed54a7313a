"""The plant stepper: N plants about one axis advanced together, the one way the physics
is run (see :mod:`turntable_env.plant`). Two backends behind one :class:`Backend`
protocol — the reduced per-axis model batched in one compiled call, the 3-D model one
turntable after another — and the stages around them (generator, input stage, friction
segments, detector)."""

from __future__ import annotations

import functools
import time as _time
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np
from numba import njit

from ..drive import Waveform
from ..effects import (
    CATALOGUE,
    EFFECT_FIELDS,
    FRICTION_SEGMENT,
    detector_stage,
    friction_active,
    friction_scale,
    input_active,
    input_capacity,
    input_rest,
    input_stage_nb,
    pack_effects,
    sliding_asymmetry,
)
from ..generator import (
    MODE_ADAPTED,
    MODE_RAMP,
    GeneratorState,
    generate_interval,
    grid_points_nb,
    interval_capacity,
)
from ..kernel_cache import CACHE
from ..kernel_types import DriveArrays
from ..params import ParameterSet
from ..reduced import H_MIN, REDUCED_AXES, ReducedBatch
from ..reduced_kernel import N_REC
from ..screw import exp_so3, log_so3
from ..validation import check_finite, check_int, check_nonnegative, check_positive
from .independent import IndependentBackend, Records
from .models import load_capacitance, output_capacitance, reduced_model, turntable_model
from .value import Plant

__all__ = ["Backend", "IntervalResult", "PlantStepper", "Records"]

MAX_PLANTS = 8192  # turntables of one stepper at most (~62 kB each; the vector env's bound)
MAX_INTERVAL = 10.0  # s, one advance or waveform run at most (the env's longest interval)
MAX_TIME = 1e6  # s, a reset's time and an explicit waveform's duration at most
MAX_RECORDS = 20_000_000  # records of one waveform run (simulation.MAX_OUTPUT_SAMPLES)
MAX_FREQUENCY = 1e5  # Hz, a generator setting's frequency at most
ANGLE_SAFE = 0.7  # rad, |θ| passed to the detector (< π/4, where the beam leaves it)
_OUTPUT_COLUMNS = [
    i for i, f in enumerate(EFFECT_FIELDS) if CATALOGUE[f.split(".")[0]].stage == "output"
]


class IntervalResult(NamedTuple):
    """What one control interval of :meth:`PlantStepper.advance` produced (arrays over N).

    Attributes:
        angle: true table angle at the interval's end [rad]; flybacks: stick–slip steps the
        generator started; energy: electrical energy C∫|V dV| [J]; phase: generator phase.
    """

    angle: np.ndarray
    flybacks: np.ndarray
    energy: np.ndarray
    phase: np.ndarray


class Backend(Protocol):
    """What :class:`PlantStepper` asks of a fidelity's integrator (N turntables, one axis;
    times on the integer grid of ``grid`` seconds)."""

    grid: float

    def set_params(self, b: int, ps: ParameterSet) -> None: ...
    def reset(self, b: int, angle: float, time: float, voltage: float) -> None: ...
    def displace(self, b: int, delta: float) -> None: ...
    def grid_time(self) -> np.ndarray: ...
    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None: ...
    def set_friction_asymmetry(self, rows: np.ndarray, alpha: np.ndarray) -> None: ...
    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]: ...
    def angles(self) -> np.ndarray: ...
    def snapshot(self, b: int) -> dict[str, Any]: ...


class _ReducedBackend:
    """N reduced per-axis models integrated together (:class:`~.reduced.ReducedBatch`)."""

    def __init__(
        self, params: Sequence[ParameterSet], axis: str, translation: bool = False
    ) -> None:
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the reduced model covers {', '.join(REDUCED_AXES)}")
        self.axis = axis
        self.translation = translation
        self.batch = ReducedBatch([reduced_model(ps, axis, translation) for ps in params])
        self.grid = self.batch.grid

    def set_params(self, b: int, ps: ParameterSet) -> None:
        if ps != self.batch.models[b].params:
            self.batch.set_model(b, reduced_model(ps, self.axis, self.translation))

    def reset(self, b: int, angle: float, time: float, voltage: float) -> None:
        self.batch.set_state(b, self.batch.models[b].rest_state(angle, voltage), time)

    def displace(self, b: int, delta: float) -> None:
        st = self.batch.state
        rest = self.batch.models[b].rest_state(
            float(self.batch.angle[b]) + delta, float(st.volt[b])
        )
        st.y[b], st.f[b], st.st[b] = rest["y"], rest["f"], rest["st"]  # amplifier state kept

    def grid_time(self) -> np.ndarray:
        return self.batch.state.n

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        self.batch.set_friction_scale(rows, scale)

    def set_friction_asymmetry(self, rows: np.ndarray, alpha: np.ndarray) -> None:
        self.batch.set_friction_asymmetry(rows, alpha)

    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        nb = n_end.size
        if out_every <= 0:  # no records
            rec = np.zeros((nb, 0, N_REC))
            self.batch.advance(drive, n_end, np.maximum(n_end, 1), rec, np.zeros(nb, np.int64))
            return []
        n0 = self.batch.state.n
        n_out = int(np.max((n_end - n0) // out_every)) + 2
        rec = np.zeros((nb, n_out, N_REC))
        n_rec = np.zeros(nb, dtype=np.int64)
        self.batch.advance(drive, n_end, np.full(nb, out_every, np.int64), rec, n_rec)
        out = []
        for b in range(nb):  # the records, and the end where it is off the record grid
            t, a = rec[b, : n_rec[b], 0], rec[b, : n_rec[b], 1]
            t_end = n_end[b] * self.grid
            if t.size == 0 or t[-1] < t_end - 1e-15:
                t, a = np.append(t, t_end), np.append(a, self.batch.angle[b])
            out.append(Records(t.copy(), a.copy()))
        return out

    def angles(self) -> np.ndarray:
        return self.batch.angle.copy()

    def snapshot(self, b: int) -> dict[str, Any]:
        st = self.batch.stick[b]
        return {
            "tube_deflection": self.batch.tube_displacement[b].copy(),
            "stick_fraction": st.sum(axis=1) / st.shape[1],
            "voltage": float(self.batch.volt[b]),
            "tubes": self.batch.models[b].axis_params.tubes,
            "axis": self.axis,
            "axis_stick_fraction": None,  # the axis tube's contact only spins: not modelled
        }


class _FullBackend:
    """The 3-D model, one turntable after another (each resumed from its final state)."""

    def __init__(self, params: Sequence[ParameterSet], axis: str) -> None:
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the env and the plant layer turn about A, B or C")
        self.axis = axis
        self.c = "ABC".index(axis)
        self.models = [turntable_model(ps) for ps in params]
        self.unit = self.models[0].layout.axis_units[self.c]
        self.states = [m.rest_state() for m in self.models]
        self.n = np.zeros(len(params), dtype=np.int64)
        self.grid = H_MIN  # s, breakpoint grid shared with the reduced model
        self.scale = np.ones(len(params))
        self.alpha = np.zeros(len(params))  # sliding-direction asymmetry per turntable

    def set_params(self, b: int, ps: ParameterSet) -> None:
        if ps != self.models[b].params:
            self.models[b] = turntable_model(ps)

    def reset(self, b: int, angle: float, time: float, voltage: float) -> None:
        vch = np.zeros(4)
        vch[self.c] = voltage
        self.states[b] = self.models[b].rest_state(vch, exp_so3(angle * self.unit))
        self.n[b] = round(time / self.grid)

    def displace(self, b: int, delta: float) -> None:
        volt = float(self.states[b].vch[self.c])
        self.reset(b, self.angle(b) + delta, self.n[b] * self.grid, volt)

    def grid_time(self) -> np.ndarray:
        return self.n

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        self.scale[rows] = scale

    def set_friction_asymmetry(self, rows: np.ndarray, alpha: np.ndarray) -> None:
        self.alpha[rows] = alpha

    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        out = []
        for b in range(n_end.size):
            t0, t1 = self.n[b] * self.grid, float(n_end[b]) * self.grid
            if t1 <= t0:
                out.append(Records(np.array([t0]), np.array([self.angle(b)])))
                continue
            nw = drive.count[b]
            wave = Waveform(drive.times[b, :nw] * self.grid, drive.values[b, :nw])
            odt = out_every * self.grid if out_every > 0 else t1 - t0
            raw = self.models[b].run(
                {self.axis: wave}, t1 - t0, start=t0, initial_state=self.states[b],
                coarse_factor=0.5, output_dt=odt, friction_scale=float(self.scale[b]),
                friction_asymmetry=float(self.alpha[b]), asymmetry_axis=self.unit,
            )  # fmt: skip
            self.states[b] = raw["final"]
            self.n[b] = n_end[b]
            if out_every > 0:
                st = raw["state"]
                out.append(Records(st[:, 0].copy(), st[:, 4:7] @ self.unit))
        return out

    def angle(self, b: int) -> float:
        return float(log_so3(self.states[b].rot) @ self.unit)

    def angles(self) -> np.ndarray:
        return np.array([self.angle(b) for b in range(len(self.states))])

    def snapshot(self, b: int) -> dict[str, Any]:
        model = self.models[b]
        ar = model.packed
        r_ball = model.params.tube.outer_radius  # m
        st = self.states[b]
        defl, frac, tubes = [], [], []
        for k in range(3):
            if k == self.c:
                continue
            d = ar["d_nom"][k]
            e = np.cross(self.unit, d)
            e /= np.linalg.norm(e)
            r_c = ar["r0"][k] - r_ball * d  # tube top → contact point [m]
            defl.append(float(st.xi[k, :3] @ np.cross(r_c, e) + st.xi[k, 3:6] @ e))  # u_c = aᵀξ
            frac.append(float(st.gst[k].mean()))
            tubes.append("ABC"[k])
        return {
            "tube_deflection": np.array(defl),
            "stick_fraction": np.array(frac),
            "voltage": float(st.vch[self.c]),
            "tubes": tuple(tubes),
            "axis": self.axis,
            "axis_stick_fraction": float(st.gst[self.c].mean()),
        }


@njit(cache=CACHE)
def _input_stage_batch(drive, rows, active, plays, creep, ref, grid, out, scr_t, scr_v):
    """The input stage on every active row of a grid-unit drive, re-gridded into ``out``."""
    for b in range(drive.count.shape[0]):
        n = drive.count[b]
        if not active[b]:
            for i in range(n):
                out.times[b, i] = drive.times[b, i]
                out.values[b, i] = drive.values[b, i]
            out.count[b] = n
            continue
        m = input_stage_nb(drive.times[b], drive.values[b], n, grid, rows[b], plays[b],
                           creep[b], ref[b:b + 1], scr_t, scr_v)  # fmt: skip
        out.count[b] = grid_points_nb(scr_t, scr_v, m, 1.0, out.times[b], out.values[b])


def _check_settings(settings: Any, n: int, interval: Any) -> np.ndarray:
    """:meth:`PlantStepper.advance`'s settings as a float (n, 5) array and its interval,
    each checked (ValueError naming the column and the turntable): finite, frequency in
    (0, :data:`MAX_FREQUENCY`], 0 < a < 1, k ≥ 0, 0 < interval ≤ :data:`MAX_INTERVAL`."""
    if not 0.0 < check_finite("interval", interval) <= MAX_INTERVAL:
        raise ValueError(f"interval={interval!r}: must be in (0, {MAX_INTERVAL:g}] s")
    try:
        s = np.asarray(settings, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"settings={settings!r}: must be ({n}, 5) numbers") from None
    if s.shape != (n, 5):
        raise ValueError(f"settings: shape {s.shape}, expected ({n}, 5)")
    bad = ~np.isfinite(s).all(axis=1)
    bad |= (s[:, 1] <= 0.0) | (s[:, 1] > MAX_FREQUENCY)
    bad |= (s[:, 2] <= 0.0) | (s[:, 2] >= 1.0) | (s[:, 3] < 0.0)
    if bad.any():
        b = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"settings[{b}]={s[b].tolist()}: (amplitude V, frequency in (0, {MAX_FREQUENCY:g}] "
            "Hz, 0 < a < 1, k >= 0, offset V), all finite"
        )
    return s


class PlantStepper:
    """N plants about one axis, advanced together (see the module docstring).

    Args:
        plants: one :class:`Plant` per turntable, all of one fidelity.
        axis: "A", "B" or "C".
        noise: detector noise on (each plant's ``sensor_noise``) or off.

    Attributes:
        plants: the plants in use.
        kernel_seconds: wall time spent in the compiled integrator so far [s]
            (``turntable bench`` reports its share).
    """

    def __init__(self, plants: Sequence[Plant], axis: str = "B", *, noise: bool = True) -> None:
        if isinstance(plants, Plant) or not isinstance(plants, Sequence) or not plants:
            raise ValueError("plants: need a non-empty list of Plants")
        if len(plants) > MAX_PLANTS:  # before anything is allocated (~60 kB a turntable)
            raise ValueError(f"plants: {len(plants)} turntables, more than {MAX_PLANTS}")
        for b, p in enumerate(plants):
            if not isinstance(p, Plant):
                raise ValueError(f"plants[{b}]={p!r}: must be a Plant")
        fid = {p.fidelity for p in plants}
        if len(fid) > 1:
            raise ValueError(f"plants: one fidelity per stepper, got {sorted(fid)}")
        self.plants = list(plants)
        self.axis = axis
        self.noise = bool(noise)
        n = len(plants)
        params = [p.params for p in plants]
        backend = {"reduced": _ReducedBackend, "full": _FullBackend,
                   "translation": functools.partial(_ReducedBackend, translation=True),
                   "independent": IndependentBackend}[plants[0].fidelity]  # fmt: skip
        self._physics: Backend = backend(params, axis)
        self.grid = self._physics.grid
        self.kernel_seconds = 0.0
        # per-plant constants
        self._rows = np.stack([p.effect_row for p in plants])
        self._neutral_row = pack_effects({})
        self._amp = np.empty((n, 8))
        self._c_load = np.empty(n)
        self._radius = np.empty(n)
        self._noise_std = np.empty(n)
        self._detector = params[0].detector
        for b, p in enumerate(plants):
            self._constants(b, p)
        self._refresh_flags()
        # per-plant state
        self._phase = np.zeros(n)  # generator phase in the running period
        self._running = np.zeros((n, 6))  # running setting (idle)
        self._running[:, 1] = 100.0
        self._offset = np.zeros(n)  # V, scan level at the last interval's end
        self._n_start = np.zeros(n, dtype=np.int64)  # grid time of the last reset
        self._plays, self._creep, self._ref = input_rest(np.zeros(n), n)
        self._travel = np.zeros(n)  # m travelled at the table radius (friction stage)

    def __len__(self) -> int:
        return len(self.plants)

    def _refresh_flags(self) -> None:
        """Which rows have input- and friction-stage effects, whether any has an output one."""
        self._input_on = input_active(self._rows)
        self._friction_on = friction_active(self._rows)  # friction segments (wear)
        out = _OUTPUT_COLUMNS
        self._output_on = bool((self._rows[:, out] != self._neutral_row[out]).any())

    def _constants(self, b: int, plant: Plant) -> None:
        ps = plant.params
        if ps.detector != self._detector:
            raise ValueError(f"plants[{b}]: its detector differs from the others'")
        self._rows[b] = plant.effect_row
        # the friction asymmetry acts phase by phase inside the integrator
        self._physics.set_friction_asymmetry(np.array([b]), sliding_asymmetry(plant.effect_row))
        self._c_load[b] = load_capacitance(ps, self.axis)  # the energy's load
        self._amp[b] = ps.amplifier.kernel_row(output_capacitance(ps, self.axis))
        self._radius[b] = ps.table.radius
        self._noise_std[b] = plant.sensor_noise if self.noise else 0.0

    # --- per-turntable setup ---------------------------------------------------------------
    def _index(self, b: Any) -> int:
        """Turntable index b, an integer in 0…N−1 (ValueError otherwise)."""
        return check_int("b", b, 0, len(self) - 1)

    def set_plant(self, b: int, plant: Plant) -> None:
        """Replace turntable b's plant (domain randomisation); call :meth:`reset` after."""
        b = self._index(b)
        if not isinstance(plant, Plant):
            raise ValueError(f"plant={plant!r}: must be a Plant")
        if plant.fidelity != self.plants[0].fidelity:
            raise ValueError(f"plant: fidelity {plant.fidelity!r} differs from the stepper's")
        self._physics.set_params(b, plant.params)
        self._constants(b, plant)
        self.plants[b] = plant
        self._refresh_flags()

    def reset(self, b: int, angle: float = 0.0, time: float = 0.0, level: float = 0.0) -> None:
        """Turntable b at rest at ``angle`` [rad] and ``time`` [s] with the amplifier input at
        ``level`` [V] (tubes bent by it, every element stuck), the generator idle, the
        effects' states at rest and the detector's time origin here."""
        b = self._index(b)
        angle, level = check_finite("angle", angle), check_finite("level", level)
        if check_nonnegative("time", time) > MAX_TIME:
            raise ValueError(f"time={time!r}: must be <= {MAX_TIME:g} s")
        amp = self._amp[b]
        lv = float(np.clip(level, -amp[3], amp[3]))
        self._physics.reset(b, float(angle), float(time), lv * amp[0])
        self._phase[b] = 0.0
        self._running[b] = (0.0, 100.0, 0.95, 0.0, 0.0, MODE_RAMP)
        self._offset[b] = lv
        self._n_start[b] = round(time / self.grid)
        plays, creep, ref = input_rest(np.array([lv]), 1)
        self._plays[b], self._creep[b], self._ref[b] = plays[0], creep[0], ref[0]
        self._travel[b] = 0.0

    def displace(self, b: int, delta: float) -> None:
        """A knock: turntable b's table jumps by ``delta`` [rad] now and every contact sticks
        again at the new angle; the tubes keep the bend of the present amplifier voltage, the
        generator, the amplifier and the effects' states run on (a disturbance for the
        controller benchmark)."""
        self._physics.displace(b, check_finite("delta", delta))

    # --- stepping --------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """(N,) simulated time [s]."""
        return self._physics.grid_time() * self.grid

    @property
    def angle(self) -> np.ndarray:
        """(N,) true table angles [rad] (evaluation only: a controller sees :meth:`observe`)."""
        return self._physics.angles()

    def advance(self, settings: np.ndarray, interval: float) -> IntervalResult:
        """Advance every turntable one control interval of ``interval`` [s] (a multiple of
        the grid) under its generator setting.

        Args:
            settings: (N, 5) amplitude [V input] (signed; 0 idles the generator), frequency
                [Hz], ramp ratio a, slew adaptation k (> 0: the Fig. 4.3 adapted flyback), scan
                offset at the interval's end [V input] (ramped from the last one).
        """
        n = len(self)
        s = _check_settings(settings, n, interval)
        n_steps = round(interval / self.grid)
        pending = np.empty((n, 6))
        pending[:, :4] = s[:, :4]
        pending[:, 4] = 0.0
        pending[:, 5] = np.where(s[:, 3] > 0.0, MODE_ADAPTED, MODE_RAMP)
        cap = interval_capacity(float(max(s[:, 1].max(), self._running[:, 1].max())), interval)
        drive = DriveArrays(np.zeros((n, cap)), np.zeros((n, cap)), np.zeros(n, np.int64))
        flybacks = np.zeros(n, dtype=np.int64)
        energy = np.zeros(n)
        n0 = self._physics.grid_time().copy()
        offset1 = s[:, 4].copy()
        generate_interval(
            n0, float(interval), self.grid,
            GeneratorState(self._phase, self._running, self._offset), pending, offset1,
            self._amp, self._c_load, drive, flybacks, energy,
        )  # fmt: skip
        self._offset[:] = offset1
        drive = self._input_stage(drive, float(interval))
        self._integrate(drive, n0 + n_steps, 0)
        return IntervalResult(self.angle, flybacks, energy, self._phase.copy())

    def run_waveform(
        self, waves: Sequence[Waveform], duration: float, output_dt: float
    ) -> list[Records]:
        """Drive every turntable with an explicit input (``waves``, times from its current
        time [s], values [V]) for ``duration`` [s]; the true angle every ``output_dt`` [s]
        (the last record at the end)."""
        n = len(self)
        if not isinstance(waves, Sequence) or len(waves) != n:
            raise ValueError(f"waves: need a list of {n} Waveforms, one per plant")
        for b, w in enumerate(waves):
            if not isinstance(w, Waveform):
                raise ValueError(f"waves[{b}]={w!r}: must be a Waveform")
        if not 0.0 < check_finite("duration", duration) <= MAX_TIME:
            raise ValueError(f"duration={duration!r}: must be in (0, {MAX_TIME:g}] s")
        check_positive("output_dt", output_dt)
        if duration / max(output_dt, self.grid) > MAX_RECORDS:  # before the records' arrays
            raise ValueError(
                f"output_dt={output_dt!r}: {duration / max(output_dt, self.grid):.3g} records "
                f"over {duration:g} s, more than {MAX_RECORDS:g}"
            )
        nbp = max(w.times.size for w in waves) * 2
        drive = DriveArrays(np.zeros((n, nbp)), np.zeros((n, nbp)), np.zeros(n, np.int64))
        n0 = self._physics.grid_time().copy()
        for b, w in enumerate(waves):
            t = w.times / self.grid + n0[b]  # the kernel clips to the input range
            drive.count[b] = grid_points_nb(t, w.values, t.size, 1.0, drive.times[b],
                                            drive.values[b])  # fmt: skip
        drive = self._input_stage(drive, duration)
        out_every = max(round(output_dt / self.grid), 1)
        return self._integrate(drive, n0 + round(duration / self.grid), out_every)

    def _input_stage(self, drive: DriveArrays, span: float) -> DriveArrays:
        active = self._input_on
        if not active.any():
            return drive
        cap = max(
            input_capacity(int(drive.count[b]), span, self._rows[b]) for b in np.flatnonzero(active)
        )
        n = len(self)
        cap = max(cap, drive.times.shape[1])
        out = DriveArrays(np.zeros((n, cap)), np.zeros((n, cap)), np.zeros(n, np.int64))
        _input_stage_batch(drive, self._rows, active, self._plays, self._creep, self._ref,
                           self.grid, out, np.empty(cap), np.empty(cap))  # fmt: skip
        return out

    def _integrate(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        """The kernel to grid time n_end, in friction segments where friction effects act."""
        fric = self._friction_on
        phys = self._physics
        if not fric.any():
            return self._kernel(drive, n_end, out_every)
        seg = max(round(FRICTION_SEGMENT / self.grid), 1)
        if out_every > 0:
            seg = out_every * max(round(seg / out_every), 1)
        rows = np.flatnonzero(fric)
        parts: list[list[Records]] = []
        while True:
            n_now = phys.grid_time()
            if (n_now >= n_end).all():
                break
            k = (n_now - self._n_start) // seg + 1
            seg_end = np.where(fric, np.minimum(n_end, self._n_start + k * seg), n_end)
            phys.set_friction_scale(rows, friction_scale(self._rows[rows], self._travel[rows]))
            before = self.angle
            parts.append(self._kernel(drive, seg_end, out_every))
            dth = self.angle - before
            self._travel[fric] += np.abs(dth[fric]) * self._radius[fric]
        if out_every <= 0:
            return []
        return [_join([p[b] for p in parts]) for b in range(len(self))]

    def _kernel(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        t = _time.perf_counter()
        out = self._physics.advance(drive, n_end, out_every)
        self.kernel_seconds += _time.perf_counter() - t
        return out

    # --- detector ----------------------------------------------------------------------------
    def observe(
        self,
        rng: np.random.Generator | None = None,
        rows: np.ndarray | None = None,
        normals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Detector x voltage [V] of turntables ``rows`` (default all) now: the output-stage
        effects (time since the last reset), then noise (one standard normal draw per row,
        times the plant's ``sensor_noise``; ``normals`` gives the draws instead of ``rng``,
        for common random numbers across runs) and saturation (Eq. 4.1, §4.1.3)."""
        r = np.arange(len(self)) if rows is None else np.asarray(rows)
        x, _y = self._channels(r, y=False)
        return self._noisy(x, r, rng, normals, "normals")

    def observe_xy(
        self,
        rng: np.random.Generator | None = None,
        rows: np.ndarray | None = None,
        normals: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Detector (x, y) voltages [V] of turntables ``rows`` now, as :meth:`observe` per
        channel: the x noise drawn first (the same draws as :meth:`observe`'s), then the
        y noise; ``normals`` (rows, 2) gives both."""
        r = np.arange(len(self)) if rows is None else np.asarray(rows)
        x, y = self._channels(r, y=True)
        z = None if normals is None else np.asarray(normals, dtype=float)
        if z is not None and z.shape != (r.size, 2):
            raise ValueError(f"normals: shape {z.shape}, expected ({r.size}, 2), finite")
        nx = None if z is None else z[:, 0]
        ny = None if z is None else z[:, 1]
        return self._noisy(x, r, rng, nx, "normals[:, 0]"), self._noisy(
            y, r, rng, ny, "normals[:, 1]"
        )

    def _channels(self, r: np.ndarray, y: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """(x, y) voltages [V] before noise, saturated (y None when not asked for and the
        output stage is off)."""
        th = np.clip(self.angle[r], -ANGLE_SAFE, ANGLE_SAFE)
        det = self._detector
        vs = det.saturation_voltage
        if self._output_on or y:
            t = (self._physics.grid_time()[r] - self._n_start[r]) * self.grid
            xv, yv = detector_stage(th, t, self._rows[r], det)
        else:  # Eq. 4.1, as detector_stage gives it with every output effect neutral
            xv, yv = det.unclipped_voltage(th), None
        # the photodiode saturates, its electronics add the noise
        return np.clip(xv, -vs, vs), (None if yv is None else np.clip(yv, -vs, vs))

    def _noisy(
        self,
        v: np.ndarray,
        r: np.ndarray,
        rng: np.random.Generator | None,
        normals: np.ndarray | None,
        name: str,
    ) -> np.ndarray:
        """``v`` [V] with the rows' noise (``normals`` or ``rng``) and saturation."""
        vs = self._detector.saturation_voltage
        if normals is not None:
            z = np.asarray(normals, dtype=float)
            if z.shape != (r.size,) or not np.isfinite(z).all():
                raise ValueError(f"{name}: shape {z.shape}, expected ({r.size},), finite")
            return np.clip(v + z * self._noise_std[r], -vs, vs)
        if rng is not None:
            return np.clip(v + rng.normal(0.0, 1.0, size=r.size) * self._noise_std[r], -vs, vs)
        return v

    def observe_trace(
        self, b: int, t: np.ndarray, theta: np.ndarray, rng: np.random.Generator | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Detector (x, y) voltages [V] of a recorded angle trace of turntable b at times t
        [s] since its reset: output-stage effects, noise on both channels, saturation."""
        b = self._index(b)
        t, theta = np.asarray(t, dtype=float), np.asarray(theta, dtype=float)
        if t.ndim != 1 or t.shape != theta.shape or not (np.isfinite(t).all()
                                                          and np.isfinite(theta).all()):
            raise ValueError(f"t, theta: shapes {t.shape}, {theta.shape}: need two finite 1-D "
                             "arrays of one length")  # fmt: skip
        x, y = detector_stage(theta, t, self._rows[b], self._detector)
        vs = self._detector.saturation_voltage
        x, y = np.clip(x, -vs, vs), np.clip(y, -vs, vs)
        std = self._noise_std[b]
        if rng is not None and std > 0.0:
            x = np.clip(x + rng.normal(0.0, 1.0, size=x.shape) * std, -vs, vs)
            y = np.clip(y + rng.normal(0.0, 1.0, size=y.shape) * std, -vs, vs)
        return x, y

    def snapshot(self, b: int) -> dict[str, Any]:
        """Render data of turntable b: the driving tubes' contact deflections along their
        bending directions e_k = n × d_k [m] and sticking fractions, channel voltage [V],
        the driving tubes' names, the rotation axis (the third tube's name) and that tube's
        sticking fraction (None where the fidelity does not model its spinning contact)."""
        return self._physics.snapshot(b)


def _join(parts: list[Records]) -> Records:
    """Records of consecutive segments, repeated boundary times dropped."""
    t = np.concatenate([p.time for p in parts])
    a = np.concatenate([p.angle for p in parts])
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = t[1:] > t[:-1] + 1e-15
    return Records(t[keep], a[keep])

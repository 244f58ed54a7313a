"""Simulate a measured trace: drive samples in, detector voltages out, with effects.

:func:`simulate_trace` runs the measurement chain of the catalogue
(:mod:`.effects`): parameter-stage effects change the parameter set, input-stage
effects the drive, friction-stage effects scale μ_s and μ_c between segments of
``segment`` seconds (by the table's motion in the previous segment and its travel so
far), and output-stage effects the detector's view; then detector noise and
saturation. The physics is the reduced per-axis model (:mod:`turntable_env.reduced`,
rotation about A, B or C) driven by the watched axis's channel, with the drive taken as
piecewise linear through its samples — as the laboratory commanded it.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..drive import Waveform
from ..model import TurntableModel
from ..params import ParameterSet
from ..reduced import ReducedBatch, ReducedModel, _waveform_arrays
from ..reduced_kernel import N_REC
from .effects import (
    CATALOGUE,
    apply_input,
    apply_output,
    apply_parameters,
    check_effects,
    friction_factor,
)

__all__ = ["TraceResult", "reduced_model", "simulate_trace"]

OUTPUT_DT_MAX = 5e-5  # s, coarsest internal sampling (then interpolated to the samples)
_FULL_MODELS: dict[tuple, TurntableModel] = {}


def reduced_model(ps: ParameterSet, axis: str) -> ReducedModel:
    """The reduced model of ``ps``, condensed from a cached 3-D model of its table and tubes
    (friction, preload and amplifier come from ``ps``); the last 64 are cached (a fit
    evaluates the same parameters under several drives and effects)."""
    return _reduced_model(ps, axis)


@functools.lru_cache(maxsize=64)
def _reduced_model(ps: ParameterSet, axis: str) -> ReducedModel:
    key = (ps.table, ps.tube, ps.name)
    if key not in _FULL_MODELS:
        _FULL_MODELS[key] = TurntableModel(ps)
    return ReducedModel(ps, axis, model=_FULL_MODELS[key])


@dataclass(frozen=True, eq=False)
class TraceResult:
    """time [s]; theta: true table angle [rad]; detector_v, detector_y_v [V] (with effects,
    noise and saturation). Time is axis 0."""

    time: np.ndarray
    theta: np.ndarray
    detector_v: np.ndarray
    detector_y_v: np.ndarray


def _corners(t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices of the breakpoints a piecewise-linear signal needs: the ends and every
    sample where the slope changes (collinear samples add nothing but integrator steps)."""
    if t.size < 3:
        return np.arange(t.size)
    slope = np.diff(u) / np.diff(t)
    bend = np.abs(np.diff(slope)) * np.minimum(np.diff(t)[:-1], np.diff(t)[1:])
    scale = 1e-12 * max(float(np.max(np.abs(u))), 1.0)
    inner = np.flatnonzero(bend > scale) + 1
    return np.concatenate([[0], inner, [t.size - 1]])


def simulate_trace(
    params: ParameterSet,
    axis: str,
    time: np.ndarray,
    drive: np.ndarray,
    effects: Mapping[str, Mapping[str, float]] | None = None,
    *,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    segment: float = 5e-3,
    model: ReducedModel | None = None,
) -> TraceResult:
    """The detector trace of a drive (module docstring).

    Args:
        params: the nominal parameter set; axis: "A", "B" or "C";
        time: sample times [s] (strictly increasing); drive: amplifier input at them [V];
        effects: {name: {parameter: value}} from the catalogue;
        noise_std: detector voltage noise [V]; rng: its generator;
        segment: length of the friction-update segments [s];
        model: a prebuilt reduced model of the (effect-modified) parameters.
    """
    eff = check_effects(effects or {})
    t = np.asarray(time, dtype=float)
    u = np.asarray(drive, dtype=float)
    if t.shape != u.shape or t.ndim != 1 or t.size < 2:
        raise ValueError(
            f"time/drive: need equal 1-D shapes of >= 2 samples, got {t.shape}, {u.shape}"
        )
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("time: must be strictly increasing")
    ps = apply_parameters(params, eff)
    mdl = model if model is not None else reduced_model(ps, axis)
    t0 = t[0]
    u_eff = apply_input(t - t0, u, eff)
    keep = _corners(t - t0, u_eff)
    wave = Waveform(t[keep] - t0, u_eff[keep])
    batch = ReducedBatch([mdl])
    h = batch.grid
    amp = ps.amplifier
    batch.set_state(
        0, mdl.initial_state(float(np.clip(u_eff[0], -amp.input_limit, amp.input_limit)) * amp.gain)
    )
    wg, wv, wn = _waveform_arrays([wave], h)
    # record at the trace's typical sample spacing (each recording stops the integrator)
    dt_med = float(np.median(np.diff(t)))
    out_every = max(round(min(dt_med, OUTPUT_DT_MAX) / h), 1)
    n_total = round((t[-1] - t0) / h)
    friction = any(CATALOGUE[n].stage == "friction" for n in eff)
    seg_n = max(round(segment / h), out_every) if friction else n_total
    mu0 = batch._arr["gms"][0, 1:3].copy()
    radius = ps.table.radius
    times, angles = [0.0], [float(batch.y[0, 0])]
    direction, travel = 0.0, 0.0
    n_now = 0
    while n_now < n_total:
        n_next = min(n_now + seg_n, n_total)
        if friction:
            batch._arr["gms"][0, 1:3] = mu0 * friction_factor(eff, direction, travel)
        n_out = (n_next - n_now) // out_every + 2
        rec = np.zeros((1, n_out, N_REC))
        n_rec = np.zeros(1, dtype=np.int64)
        theta_before = float(batch.y[0, 0])
        batch.advance(wg, wv, wn, np.array([n_next]), np.array([out_every]), rec, n_rec)
        r = rec[0, : n_rec[0]]
        keep = r[:, 0] > times[-1] + 1e-15
        times.extend(r[keep, 0])
        angles.extend(r[keep, 1])
        if r.size == 0 or r[-1, 0] < n_next * h - 1e-15:
            times.append(n_next * h)
            angles.append(float(batch.y[0, 0]))
        dth = float(batch.y[0, 0]) - theta_before
        if abs(dth) > 1e-9:
            direction = np.sign(dth)
        travel += abs(dth) * radius
        n_now = n_next
    theta = np.interp(t - t0, np.array(times), np.array(angles))
    x, y = apply_output(t - t0, theta, eff, ps.detector)
    if noise_std > 0.0:
        g = rng if rng is not None else np.random.default_rng()
        x = x + g.normal(0.0, noise_std, x.size)
        y = y + g.normal(0.0, noise_std, y.size)
    vs = ps.detector.saturation_voltage
    return TraceResult(t, theta, np.clip(x, -vs, vs), np.clip(y, -vs, vs))

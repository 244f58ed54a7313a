"""Simulate a measured trace: drive samples in, detector voltages out, through a plant.

:func:`simulate_trace` runs a :class:`~turntable_env.plant.Plant` (its parameter set,
fidelity and effects, :mod:`turntable_env.effects`) under the drive a measurement file
records on the watched axis's channel, taken as piecewise linear through its samples — as
the laboratory commanded it — and returns the true angle and the detector's two channels
at the samples. The physics runs through :class:`~turntable_env.plant.PlantStepper`, the
layer the environment runs too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..drive import Waveform
from ..plant import Plant, PlantStepper

__all__ = ["TraceResult", "drive_corners", "simulate_trace"]

OUTPUT_DT_MAX = 5e-5  # s, coarsest internal sampling (then interpolated to the samples)


@dataclass(frozen=True, eq=False)
class TraceResult:
    """time [s]; theta: true table angle [rad]; detector_v, detector_y_v [V] (with effects,
    noise and saturation). Time is axis 0."""

    time: np.ndarray
    theta: np.ndarray
    detector_v: np.ndarray
    detector_y_v: np.ndarray


def drive_corners(t: np.ndarray, u: np.ndarray) -> np.ndarray:
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
    plant: Plant,
    axis: str,
    time: np.ndarray,
    drive: np.ndarray,
    *,
    rng: np.random.Generator | None = None,
    breakpoints: tuple[np.ndarray, np.ndarray] | None = None,
) -> TraceResult:
    """The detector trace of a drive (module docstring).

    Args:
        plant: the plant to run (its ``sensor_noise`` is the detector noise when ``rng``
            is given).
        axis: "A", "B" or "C".
        time: sample times [s] (strictly increasing); drive: amplifier input at them [V].
        rng: generator of the detector noise (None: no noise).
        breakpoints: (times [s], values [V]) of the drive as read
            (:class:`~turntable_env.calibration.segments.DriveReading`) instead of the
            samples taken as piecewise linear; ``time`` then only sets the output samples.
    """
    t = np.asarray(time, dtype=float)
    u = np.asarray(drive, dtype=float)
    if t.shape != u.shape or t.ndim != 1 or t.size < 2:
        raise ValueError(
            f"time/drive: need equal 1-D shapes of >= 2 samples, got {t.shape}, {u.shape}"
        )
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("time: must be strictly increasing")
    stepper = PlantStepper([plant], axis, noise=rng is not None)
    stepper.reset(0, 0.0, 0.0, level=float(u[0]))
    t_rel = t - t[0]
    if breakpoints is None:
        keep = drive_corners(t_rel, u)
        wave = Waveform(t_rel[keep], u[keep])
    else:
        bt, bu = (np.asarray(a, dtype=float) for a in breakpoints)
        keep = drive_corners(bt - t[0], bu)
        wave = Waveform(bt[keep] - t[0], bu[keep])
    # record at the trace's typical sample spacing (each recording stops the integrator)
    dt_med = float(np.median(np.diff(t)))
    rec = stepper.run_waveform([wave], float(t_rel[-1]), min(dt_med, OUTPUT_DT_MAX))[0]
    theta = np.interp(t_rel, rec.time, rec.angle)
    x, y = stepper.observe_trace(0, t_rel, theta, rng)
    return TraceResult(t, theta, x, y)

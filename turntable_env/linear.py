"""The small-signal plant in stick (scan mode) as python-control models, and its check.

Chain, amplifier input u [V] → table angle θ [rad] (and detector voltage):

* the HVA 900 amplifier as a first-order stage G/(τs + 1) (§4.1.2; gain G = 45,
  τ from the measured 0.9 V/µs; its slew and current limits do not act on small
  signals), times 1/(τ_o s + 1) where it has an output lag (``amplifier_lag``), or the
  gain G alone for an ideal source (the fast path's share is not modelled here);
* the per-axis mechanics with every GMS element stuck
  (:meth:`~turntable_env.reduced.ReducedModel.stick_matrices`): two condensed tube
  bending modes driven by the quadrant voltages (Eq. 2.11, 3.16), the table on the
  contacts' stuck tangential stiffness Σk_i with the micro-damping β_t·k_i (Eq. 2.24
  in stick), and the gravity pendulum of its centre of mass (App. C);
* the detector, Eq. 4.1 linearised at θ = 0: V_d = (2L/S)·θ.

:func:`scan_plant` samples it the way the environment applies a scan offset (a linear
ramp over each control interval), :func:`sine_sweep` measures the same frequency
response on the nonlinear simulator (small amplitude, every element stuck).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import control as ct
import numpy as np

from .drive import Waveform
from .params import ParameterSet
from .plant import parameter_set
from .reduced import ReducedModel, simulate_batch
from .validation import check_positive

__all__ = ["SweepResult", "scan_plant", "sine_sweep", "stick_plant"]

STATE_NAMES = ("V_amp", "theta", "omega", "u1", "du1", "u2", "du2")


def stick_plant(
    params: ParameterSet | Literal["real", "thesis"] = "real",
    axis: str = "B",
    *,
    model: ReducedModel | None = None,
) -> ct.StateSpace:
    """Continuous small-signal plant in stick, amplifier input [V] → angle [rad], detector [V].

    States: amplifier output V_amp [V] (absent for an ideal source; with an output lag
    preceded by its stage's V_stage [V]), θ [rad], θ̇ [rad/s], contact-point deflections
    u1, u2 [m] of the two driving tubes and their rates [m/s].
    Inputs: ``u_in_V``. Outputs: ``angle_rad``, ``detector_V``. Every number comes from
    the parameter set through the reduced model (see the module docstring).
    """
    mdl = model if model is not None else ReducedModel(params, axis)
    ps = mdl.params
    a6, b6 = mdl.stick_matrices()
    amp = ps.amplifier
    det = ps.detector
    c_th = np.zeros((2, 6))
    c_th[0, 0] = 1.0  # rad
    c_th[1, 0] = 2.0 * det.distance / det.sensitivity  # V/rad, Eq. 4.1 at θ = 0
    if amp.ideal:
        a, b, c = a6, (b6 * amp.gain)[:, None], c_th
        states = list(STATE_NAMES[1:])
    else:
        a = np.zeros((7, 7))
        a[0, 0] = -1.0 / amp.tau
        a[1:, 1:] = a6
        a[1:, 0] = b6
        b = np.zeros((7, 1))
        b[0, 0] = amp.gain / amp.tau
        c = np.hstack([np.zeros((2, 1)), c_th])
        states = list(STATE_NAMES)
        if amp.output_lag > 0.0:  # V_stage → V_amp through the lag τ_o
            a = np.pad(a, ((1, 0), (1, 0)))
            a[0, 0] = -1.0 / amp.tau
            a[1, 0] = 1.0 / amp.output_lag
            a[1, 1] = -1.0 / amp.output_lag
            b = np.pad(b, ((1, 0), (0, 0)))
            b[0, 0], b[1, 0] = amp.gain / amp.tau, 0.0
            c = np.hstack([np.zeros((2, 1)), c])
            states = ["V_stage", *states]
    return ct.ss(
        a,
        b,
        c,
        np.zeros((2, 1)),
        inputs=["u_in_V"],
        outputs=["angle_rad", "detector_V"],
        states=states,
        name=f"stick_plant_{ps.name}_{mdl.axis}",
    )


def scan_plant(plant: ct.StateSpace, control_interval: float) -> ct.StateSpace:
    """The plant as the environment's scan offset sees it, sampled every control interval.

    The environment ramps the offset linearly from its previous value u_{k−1} to the new
    action's u_k over the interval and observes at its end, so the input is the
    triangle (first-order) hold of the sequence delayed by one sample:
    P_env(z) = z⁻¹·P_foh(z), with P_foh python-control's ``'foh'`` discretisation.
    Output y_{k+1} then answers u_k (for a quasi-static plant, y_{k+1} = P(0)·u_k).
    """
    dt = check_positive("control_interval", control_interval)
    p_foh = ct.sample_system(plant, dt, method="foh")
    delay = ct.ss(ct.tf([1.0], [1.0, 0.0], dt))
    out = ct.series(delay, p_foh)
    return ct.ss(out, inputs=plant.input_labels, outputs=plant.output_labels, name="scan_plant")


@dataclass(frozen=True, eq=False)
class SweepResult:
    """Frequency response measured on the simulator by sine excitation.

    Attributes:
        frequencies: [Hz]; response: complex θ/u [rad/V] at each frequency (amplifier
        input to table angle); amplitude: input amplitude [V]; all_stuck: True if every
        GMS element stuck throughout (small-signal condition); fidelity: simulator used.
    """

    frequencies: np.ndarray
    response: np.ndarray
    amplitude: float
    all_stuck: bool
    fidelity: str
    info: dict = field(default_factory=dict)

    @property
    def magnitude(self) -> np.ndarray:
        """|θ/u| [rad/V]."""
        return np.abs(self.response)

    def frd(self) -> ct.FrequencyResponseData:
        """As a python-control FRD (ω in rad/s), for ``ct.bode_plot``."""
        return ct.frd(
            self.response,
            2.0 * math.pi * self.frequencies,
            inputs=["u_in_V"],
            outputs=["angle_rad"],
            name=f"sine sweep ({self.fidelity})",
        )

    def to_pandas(self) -> Any:
        import pandas as pd

        return pd.DataFrame(
            {
                "magnitude_rad_per_V": self.magnitude,
                "phase_deg": np.degrees(np.angle(self.response)),
            },
            index=pd.Index(self.frequencies, name="frequency_Hz"),
        )

    def plot(self, plant: ct.StateSpace | None = None, ax: Any = None) -> Any:
        """Magnitude of the sweep, and of ``plant`` (angle output) if given, vs frequency."""
        import matplotlib.pyplot as plt

        if ax is None:
            _fig, ax = plt.subplots(figsize=(7, 4))
        if plant is not None:
            f = np.logspace(
                math.log10(self.frequencies.min() / 2), math.log10(self.frequencies.max() * 2), 400
            )
            resp = ct.frequency_response(plant[0, 0], 2.0 * math.pi * f)
            ax.loglog(f, np.abs(resp.complex).ravel(), label="python-control stick plant")
        ax.loglog(self.frequencies, self.magnitude, "o", label=f"sine sweep, {self.fidelity} model")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("|θ / u_in| [rad/V]")
        ax.legend()
        return ax


def sine_sweep(
    params: ParameterSet | Literal["real", "thesis"] = "real",
    axis: str = "B",
    frequencies: np.ndarray | None = None,
    *,
    amplitude: float = 0.02,
    settle: float = 0.08,
    periods: int = 5,
    fidelity: Literal["reduced", "full"] = "reduced",
    points_per_period: int = 64,
) -> SweepResult:
    """Measure θ/u on the nonlinear simulator with sine inputs u = A·sin(2πft) [V].

    Each frequency runs from rest for ``settle`` seconds (transients of the lightly
    damped table mode decay) and then ``periods`` whole periods (at least 10 ms), over
    which θ(t) and the input u(t) are fitted by least squares with a·sin + b·cos + c:
    H = (a_θ + jb_θ)/(a_u + jb_u).

    Args:
        frequencies: [Hz] (default: 12 points from 10 Hz to 4 kHz).
        amplitude: input amplitude A [V] (small: no element may slip).
        fidelity: ``"reduced"`` (all frequencies in one batched compiled call) or
            ``"full"`` (the 3-D model, one run per frequency).
    """
    ps = parameter_set(params) if isinstance(params, str) else params
    freqs = np.logspace(1.0, math.log10(4000.0), 12) if frequencies is None else frequencies
    freqs = np.asarray(freqs, dtype=float)
    for f in freqs:
        check_positive("frequencies", float(f))
    amp_in = check_positive("amplitude", amplitude)
    waves, spans = [], []
    for f in freqs:
        n_per = max(periods, math.ceil(0.01 * f))
        t_end = settle + n_per / f
        n = math.ceil(t_end * f * points_per_period)
        t = np.linspace(0.0, n / (f * points_per_period), n + 1)
        waves.append(Waveform(t, amp_in * np.sin(2.0 * math.pi * f * t)))
        spans.append((t_end - n_per / f, t_end))
    resp = np.empty(freqs.size, dtype=complex)
    stuck = True
    if fidelity == "reduced":
        model = ReducedModel(ps, axis)
        ne = model.packed["kk"].size
        dur = max(s[1] for s in spans)
        runs = simulate_batch(
            [model] * freqs.size, waves, dur, output_dt=model.grid * 16
        )  # 1 µs samples
        series = []
        for r in runs:
            series.append((r.time, r.angle_rad))
            stuck &= bool((r.n_stick == ne).all())
    elif fidelity == "full":
        from .simulation import simulate

        series = []
        ne = len(ps.friction.k) if ps.friction is not None else 0
        for w, (_, t_end) in zip(waves, spans, strict=True):
            r = simulate(
                ps, {axis: w}, duration=t_end, axis=axis, coarse_factor=0.5, output_dt=1e-5
            )
            series.append((r.time, r.angle(axis)))
            loaded = r.normal_force > 0.0  # the watching tube's contact carries no drive
            stuck &= bool((r.n_stick[loaded] == ne).all())
    else:
        raise ValueError(f"fidelity={fidelity!r}: must be 'reduced' or 'full'")
    for i, (f, (t, th)) in enumerate(zip(freqs, series, strict=True)):
        t0, t1 = spans[i]
        sel = (t >= t0) & (t <= t1)
        w = 2.0 * math.pi * f
        basis = np.column_stack([np.sin(w * t[sel]), np.cos(w * t[sel]), np.ones(sel.sum())])
        # fundamental of the output over that of the piecewise-linear input (whose
        # fundamental is sinc²(π/points) of the sine's)
        c_out, *_ = np.linalg.lstsq(basis, th[sel], rcond=None)
        c_in, *_ = np.linalg.lstsq(basis, waves[i](t[sel]), rcond=None)
        resp[i] = (c_out[0] + 1j * c_out[1]) / (c_in[0] + 1j * c_in[1])
    return SweepResult(freqs, resp, amp_in, stuck, fidelity, {"params": ps.name, "axis": axis})

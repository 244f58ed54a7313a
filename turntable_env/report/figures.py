"""The thesis's figures recreated by the simulator, each with its numbers.

Every function returns a :class:`ReportFigure`: the matplotlib figure, the numbers it
shows (SI units in the key names) and what the thesis says or measured beside it.
Computation and plotting stay together here because each figure *is* a check; the
numbers go to ``summary.json`` and the README's component table
(``python experiments/component_figures.py`` prints them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..amplifier import Amplifier, measure_slew_rate
from ..calibration.thesis_data import thesis_step_sizes
from ..drive import DriveSignal, sawtooth
from ..friction import GMS, StribeckParams
from ..friction.experiments import drift_test, presliding_hysteresis, thesis_drift_models
from ..params import real_parameters
from ..simulation import simulate, stepping_drive

__all__ = [
    "ReportFigure",
    "amplifier_figure",
    "drift_figure",
    "hysteresis_figure",
    "sawtooth_figure",
    "stepping_figure",
    "stribeck_figure",
]


@dataclass
class ReportFigure:
    """One recreated figure: ``key`` (file stem), title, the thesis's description or
    measured value, the numbers shown, and the matplotlib figure."""

    key: str
    title: str
    thesis: str
    numbers: dict[str, Any] = field(default_factory=dict)
    fig: Any = None


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def stribeck_figure(quick: bool = False) -> ReportFigure:
    """Fig. 2.8: GMS steady sliding against the Stribeck curve s(v) (Eq. 2.13)."""
    gms = GMS(stribeck=StribeckParams(0.3, 0.05, 0.8, 2.0, 0.0))
    vs = np.geomspace(1e-3, 5.0, 6 if quick else 12)  # m/s
    steady = []
    for v in vs:
        n = max(30000, int(np.ceil(5 * 7.5e-3 / v / 1e-4)))
        steady.append(gms.simulate_velocity(np.full(n, v), 1e-4, 100.0).force[-1])
    curve = gms.stribeck.curve(vs, 100.0)
    err = float(np.max(np.abs(np.array(steady) / curve - 1)))
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    vv = np.linspace(-1.05 * vs[-1], 1.05 * vs[-1], 1601)  # the curve spans the GMS points
    ax.plot(vv, gms.stribeck.curve(vv, 100.0), label="Stribeck s(v), Eq. 2.13")
    ax.plot(vs, steady, "o", label="GMS steady sliding")
    ax.set(xlabel="v [m/s]", ylabel="F [N]", title="Fig. 2.8: Stribeck curve")
    ax.legend()
    fig.tight_layout()
    return ReportFigure(
        "fig2_8_stribeck",
        "Fig. 2.8 — Stribeck curve",
        "The friction force falls from static (μ_s = 0.3) to Coulomb (μ_c = 0.05) friction "
        "with velocity; in steady sliding GMS must follow it (§2.3.2, Table D.2 friction).",
        {"gms_vs_stribeck_max_rel_error": err},
        fig,
    )


def hysteresis_figure(quick: bool = False) -> ReportFigure:
    """Fig. 2.9: presliding hysteresis with nonlocal memory (an inner loop closes)."""
    h = presliding_hysteresis(steps_per_delta=500 if quick else 2000)
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    h.with_inner_loop.plot(ax, x="displacement")
    for line in ax.lines:
        line.set_label("GMS, with the inner loop")
    n = len(ax.lines)
    h.reference.plot(ax, x="displacement")
    for line in ax.lines[n:]:  # the loop without the excursion, drawn beneath, dashed
        line.set(label="GMS, outer loop only (reference)", linestyle="--", color="0.5", zorder=0)
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))  # one entry per curve
    ax.legend(unique.values(), unique.keys(), fontsize=8)
    ax.set_title("Fig. 2.9: presliding hysteresis, inner loop")
    fig.tight_layout()
    return ReportFigure(
        "fig2_9_hysteresis",
        "Fig. 2.9 — presliding hysteresis with nonlocal memory",
        "In presliding the force–displacement curve is a hysteresis loop; an inner loop "
        "closes where it started and the outer curve resumes as if it had not happened "
        "(nonlocal memory, §2.3.2).",
        {
            "loop_closure_error_N": h.loop_closure_error,
            "outer_curve_error_N": h.outer_curve_error,
            "hysteresis_width_N": h.hysteresis_width,
        },
        fig,
    )


def drift_figure() -> ReportFigure:
    """Fig. 2.10: drift under an oscillating force in stick, Breedveld vs GMS."""
    breedveld, gms = thesis_drift_models()
    b, g = drift_test(breedveld), drift_test(gms)
    plt = _plt()
    fig, axs = plt.subplots(2, 1, sharex=True, figsize=(6, 4))
    axs[0].plot(b.response.time, b.response.applied_force)
    axs[0].set_ylabel("applied force [N]")
    axs[1].plot(b.response.time, b.response.displacement, label="Breedveld")
    axs[1].plot(g.response.time, g.response.displacement, label="GMS")
    axs[1].set(xlabel="time [s]", ylabel="displacement [m]")
    axs[1].legend()
    axs[0].set_title("Fig. 2.10: drift test")
    fig.tight_layout()
    return ReportFigure(
        "fig2_10_drift",
        "Fig. 2.10 — drift test, Breedveld vs GMS",
        "Under a force oscillating below the breakaway force, a model without presliding "
        "memory (Breedveld) drifts; GMS does not (§2.3.2).",
        {
            "drift_per_cycle_breedveld_m": b.drift_per_cycle,
            "drift_per_cycle_gms_m": g.drift_per_cycle,
        },
        fig,
    )


def sawtooth_figure() -> ReportFigure:
    """Fig. 3.14: the sawtooth generator, 100 V, 1 Hz, from 1 s to 4 s, a = 0.95."""
    ts = np.linspace(0, 5, 5001)
    v = sawtooth(ts, 100.0, 1.0, 0.95, 1.0, 4.0)
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.plot(ts, v)
    ax.set(xlabel="time [s]", ylabel="V", title="Fig. 3.14: sawtooth 100 V, 1 Hz, a = 0.95")
    fig.tight_layout()
    return ReportFigure(
        "fig3_14_sawtooth",
        "Fig. 3.14 — sawtooth input",
        "100 V, 1 Hz, starting at 1 s, stopping at 4 s, maximum at a = 0.95 of the period.",
        {"peak_V": float(v.max()), "periods": 3},
        fig,
    )


def amplifier_figure() -> ReportFigure:
    """Figs. 4.2 and 4.3: HVA 900 step responses and the adapted flyback (§4.1.2)."""
    p = real_parameters()
    amp = Amplifier()
    c2 = 2 * p.tube.quadrant.capacitance  # two quadrants per channel [F]
    nums: dict[str, Any] = {"amplifier_tau_s": amp.tau}
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for step in (1.0, 3.0):
        r = amp.step_response(0.0, step, load_capacitance=c2)
        nums[f"slew_{step:g}V_step_V_per_s"] = measure_slew_rate(r.time, r.output, 0, 45 * step)
        ax.plot(r.time * 1e6, r.output, label=f"{step:g} V input step")
    r = amp.step_response(-10.0, 10.0, duration=400e-6)
    nums["slew_900V_V_per_s"] = measure_slew_rate(r.time, r.output, -450, 450)
    nums["slew_900V_peak_V_per_s"] = float(np.max(np.diff(r.output) / np.diff(r.time)))
    d = DriveSignal(amplitude=2.0, frequency=100.0, a=0.95, n_periods=2, slew_adaptation=1.0)
    t = np.arange(0.0, 0.02, 1e-8)
    ra = amp.simulate(t, d.input_voltage(t, amp, c2), c2)
    m = (t >= 0.0095) & (t < 0.0105)
    nums["slew_adapted_90V_V_per_s"] = measure_slew_rate(t[m], ra.output[m], 90, 0)
    ax.plot((t[m] - 0.0095) * 1e6, ra.output[m], label="adapted flyback 90 V → 0 (Fig. 4.3)")
    for step, rate in ((1.0, 0.9), (3.0, 2.7)):  # the thesis's measured slew rates [V/µs]
        ax.plot([0, 45 * step / rate], [0, 45 * step], "k:", lw=1)
        ax.annotate(f"measured {rate:g} V/µs", (45 * step / rate, 45 * step), fontsize=7,
                    xytext=(3, -10), textcoords="offset points")  # fmt: skip
    model = ", ".join(
        f"{k.removeprefix('slew_').removesuffix('_V_per_s')} {v / 1e6:.2g}"
        for k, v in nums.items() if k.startswith("slew_") and "peak" not in k
    )  # fmt: skip
    ax.text(0.99, 0.02, f"model [V/µs]: {model}\nmeasured: 0.9, 2.7, 12, 8.0",
            transform=ax.transAxes, ha="right", va="bottom", fontsize=7)  # fmt: skip
    ax.set(xlabel="time [µs]", ylabel="output [V]", xlim=(0, 100), title="Figs. 4.2/4.3: HVA 900")
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    return ReportFigure(
        "fig4_2_amplifier",
        "Figs. 4.2 and 4.3 — amplifier slew rate and the adapted signal",
        "Measured: 0.9 V/µs for a 1 V and 2.7 V/µs for a 3 V input step (the time to the "
        "end value is constant); 12 V/µs at the full 900 V swing; 8.0 V/µs with the adapted "
        "input, which jumps past the end value and back (§4.1.2).",
        nums,
        fig,
    )


def stepping_figure(params: str, signal: str, *, periods: int = 5) -> ReportFigure:
    """Figs. 4.6/4.7 (real or calibrated set, 2 V → 90 V, 100 Hz, adapted flyback) and
    4.8/4.10 (Table D.2, ideal source, 2 Hz): rotation about B on the full 3-D model; the
    step as the figure reads it (:meth:`~turntable_env.response.SteppingMetrics.figure_step`,
    t₁, t₂, t₃ marked)."""
    quoted = thesis_step_sizes()  # m per step, §4.1.3
    measured = {"one": quoted["one_directional"], "two": quoted["two_directional"]}
    lab = params in ("real", "calibrated")
    if lab:
        drive, ps = stepping_drive(params, periods=periods, signal=signal)  # type: ignore[arg-type]
        output_dt = 1e-5
        fig_no = "4.7" if signal == "one" else "4.6"
    else:
        drive, ps = stepping_drive("thesis", periods=periods, signal=signal, frequency=2.0)  # type: ignore[arg-type]
        output_dt = 1e-3
        fig_no = "4.8" if signal == "one" else "4.10"
    r = simulate(ps, drive, axis="B", output_dt=output_dt)
    plt = _plt()
    fig, axs = plt.subplots(2, 1, sharex=True, figsize=(6, 4))
    det_v = r.detector_voltage()
    saturated = bool(np.any(ps.detector.is_saturated(det_v)))  # r.detector_saturates, once
    if saturated:  # a flat line shows nothing: draw the drive (Fig. 4.5) and say why
        axs[0].plot(r.time, r.channel_voltage[:, "ABC".index("B")], lw=0.8)
        axs[0].set_ylabel("channel B [V]")
        theta_max = float(np.max(np.abs(r.angle("B"))))  # rad
        fig.text(0.01, 0.01, f"Detector not drawn: θ reaches {theta_max * 1e3:.1f}"
                 f" mrad, beyond its linear range of ±{ps.detector.angle_range * 1e3:.2f} mrad "
                 f"(±{ps.detector.saturation_voltage:.2f} V); steps read as x = θ·R_table.",
                 fontsize=6.5)  # fmt: skip
    else:
        axs[0].plot(r.time, det_v, lw=0.8)
        axs[0].set_ylabel("detector [V]")
    theta = r.angle("B")
    big = np.max(np.abs(theta)) > 1e-3  # rad: plot in mrad, as the thesis does for its set
    axs[1].plot(r.time, theta * (1e3 if big else 1e6), lw=0.8)
    axs[1].set(xlabel="time [s]", ylabel="θ_B [mrad]" if big else "θ_B [µrad]")
    word = "one" if signal == "one" else "two"
    axs[0].set_title(f"Fig. {fig_no}: {word}-directional about B, {params} parameters")
    fig.tight_layout(rect=(0.0, 0.04 if saturated else 0.0, 1.0, 1.0))
    source = "angle" if saturated else "detector"  # figure_step's "auto", det_v reused
    reading = r.figure_step(periods, signal == "two", source=source)
    nums: dict[str, Any] = {
        "step_m": reading["step"],  # as the figure reads it (Eq. 4.1-4.2), or x = θ·R_table
        "step_read_from": reading["source"],
        "mean_abs_step_m": r.step_size,
        "steps_m": [float(s) for s in r.steps],
        "net_rotation_rad": r.net_rotation,
        "detector_V_net": r.detector_V_net,
        "detector_saturated": saturated,
        "wall_s": float(r.info.get("wall_s", float("nan"))),
    }
    if "return" in reading:
        nums["return_m"] = reading["return"]
        nums["excursion_m"] = reading["excursion"]
    if lab:
        for ax in axs:
            for key in ("t1", "t2", "t3"):
                if key in reading:
                    ax.axvline(reading[key], color="0.6", lw=0.6, ls=":")
        nums["measured_step_m"] = measured[signal]
        nums["model_over_measured"] = reading["step"] / measured[signal]
        axs[1].text(0.01, 0.9, f"step: model {reading['step'] * 1e6:.3f} µm, measured "
                    f"{measured[signal] * 1e6:.3f} µm (§4.1.3)", transform=axs[1].transAxes,
                    fontsize=7, va="top")  # fmt: skip
        thesis = f"Measured (§4.1.3, Fig. {fig_no}): " + (
            "1.19 V in 9 steps, 3.4 µm, 0.37 µm per step."
            if signal == "one"
            else "0.53 V in 5 steps, 1.5 µm, 0.30 µm per step; the table returns to its start."
        )
    else:
        thesis = (
            f"The thesis's own simulation (§4.2.2, Fig. {fig_no}) on the scaled parameters of "
            "Table D.2, ideal source: compared with the measurements only qualitatively."
        )
    return ReportFigure(
        f"fig{fig_no.replace('.', '_')}_{params}_{signal}",
        f"Fig. {fig_no} — {word}-directional rotation about B, {params} parameters",
        thesis,
        nums,
        fig,
    )

"""Calibrate and diagnose: the entry point on traces and the report.

:func:`calibrate` fits measurement files (:mod:`.measurement`): the nominal model first
(global stage, then least squares with priors), effects only after it fits, judged on
held-out segments interleaved by drive condition and against the data's noise floor —
:mod:`.trace_fit` says how. Summary-level figures (the thesis's chapter 4) go through
:mod:`.summary`; both return a :class:`~.result.CalibrationResult` (:mod:`.result`).
:func:`write_report` writes what a lab engineer acts on: ``report.json``, ``report.md``
(the noise floor beside every error, parameters with uncertainties and flags, warnings),
``overlay.png`` (measured and model over time with the drive) and ``residual.png``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..files import output_directory, plain_json
from ..plant import calibrated_set_toml
from ..provenance import code_label, provenance
from ..threads import one_blas_thread
from .measurement import Measurement
from .result import CalibrationResult
from .trace_fit import calibrate_traces

__all__ = ["CalibrationResult", "calibrate", "write_report"]

def calibrate(files: Sequence[str | Path | Measurement], **options: Any) -> CalibrationResult:
    """Calibrate measurement files: :func:`~.trace_fit.calibrate_traces` with its keyword
    arguments (base, candidates, max_effects, min_improvement, global_points, starts,
    hops, workers, seed, progress).

    Runs with one BLAS thread: its linear algebra is small and dense, where OpenBLAS's
    worker threads only spin and slow every simulation down."""
    with one_blas_thread():
        return calibrate_traces(files, **options)


def plot_residual(result: CalibrationResult, path: Path) -> None:
    """Held-out residual over samples with the noise floor (traces), or per-target
    relative errors before and after (summary-level data)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result.diagnosis.get("targets")
    if rows:
        fig, ax = plt.subplots(figsize=(7, 3.2))
        y = np.arange(len(rows))
        ax.barh(y - 0.2, [100 * r["error_before"] for r in rows], 0.4, label="before")
        ax.barh(y + 0.2, [100 * r["error_after"] for r in rows], 0.4, label="after")
        ax.set_yticks(y, [r["target"] for r in rows], fontsize=7)
        ax.axvline(0.0, color="k", lw=0.5)
        ax.set_xlabel("relative error [%]")
        ax.legend(fontsize=7)
    else:
        fig, ax = plt.subplots(figsize=(7, 3))
        ax.plot(result.residuals["after"], lw=0.5, label="held-out residual")
        floor = result.diagnosis.get("noise_floor")
        if floor:
            for sgn in (-3, 3):
                ax.axhline(sgn * floor, color="r", lw=0.6, ls="--")
            ax.plot([], [], color="r", ls="--", label="±3× noise floor")
        ax.set_xlabel("held-out sample")
        ax.set_ylabel(f"residual [{result.error_unit}]")
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_overlay(result: CalibrationResult, path: Path) -> bool:
    """Measured and model traces [nm at R_table] over time with the drive [V] below
    (held-out segments shaded); False when the result has no trace to show."""
    r = result.residuals
    if "overlay_time" not in r:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = r["overlay_time"] - r["overlay_time"][0]
    fig, (ax, axd) = plt.subplots(
        2, 1, figsize=(8, 4.6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    held = r["overlay_heldout"]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], held.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color="0.92", lw=0)
    ax.plot(t, r["overlay_measured"], lw=0.6, label="measured")
    ax.plot(t, r["overlay_model"], lw=0.6, label="model (re-anchored per segment)")
    ax.set_ylabel(f"displacement [{result.error_unit}]")
    ax.legend(fontsize=7, title="grey: held-out segments", title_fontsize=7)
    axd.plot(t, r["overlay_drive"], lw=0.6, color="k")
    axd.set_ylabel("drive [V]")
    axd.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def _ratio(x: float, floor: float) -> str:
    """x / floor to one decimal; "—" for a noise-free trace (floor 0)."""
    return f"{x / floor:.1f}" if floor > 0 else "—"


def _verdict(result: CalibrationResult) -> str:
    """met / not met against the target; "untested" where the data identify no nominal
    parameter (the diagnosis's ``identified``, absent in reports before it)."""
    d = result.diagnosis
    met = "met" if result.error_after <= d["target"] else "not met"
    if d.get("identified", 1) == 0:
        return f"{met}, but untested: the data identify no nominal parameter"
    return met


def _md_trace_sections(result: CalibrationResult) -> list[str]:
    """report.md lines of a trace calibration: floor, starts, parameters, diagnosis."""
    d = result.diagnosis
    if "noise_floor" not in d:
        return []
    u = result.error_unit
    floor = d["noise_floor"]
    lines = [
        "",
        f"## Errors beside the noise floor ({floor:.3g} {u}, {d['noise_floor_source']})",
        "",
        f"| model | held-out error [{u}] | × floor |",
        "|---|---:|---:|",
        f"| prior (before) | {result.error_before:.3g} | {_ratio(result.error_before, floor)} |",
        f"| nominal fit | {d['error_nominal']:.3g} | {_ratio(d['error_nominal'], floor)} |",
        f"| final | {result.error_after:.3g} | {_ratio(result.error_after, floor)} |",
        "",
        f"Target max(3× floor, 2 % of the RMS motion {d['rms_motion']:.4g} {u}) = "
        f"{d['target']:.3g} {u}: {_verdict(result)}.",
        *(["", f"Amplifier (fitted in the nominal stage): {d['amplifier']['text']}."]
          if "amplifier" in d else []),
        "",
        f"## Global stage: {d['starts']['agreeing']} of {d['starts']['total']} local fits "
        "reach the optimum (within 2σ or 1 % of its cost)",
        "",
        f"| start | cost | held-out [{u}] | max distance [σ] |",
        "|---:|---:|---:|---:|",
        *[
            f"| {k} | {f['cost']:.5g} | {f['heldout_rms']:.3g} | {f['max_distance_sigma']:.2g} |"
            for k, f in enumerate(d["starts"]["fits"])
        ],
        *_md_hops(d["starts"].get("hops"), "the best start", u),
        *_md_second(d["starts"].get("second"), u),
        *_md_profile(d["starts"].get("amplifier_profile"), u),
        "",
        "## Parameters",
        "",
        "| owner | parameter | value | std | identified | at bound | meaning |",
        "|---|---|---:|---:|---|---|---|",
    ]
    for o, ps in result.parameters.items():
        for p, v in ps.items():
            unit = f" {v['unit']}" if v.get("unit") else ""
            lines.append(
                f"| {o} | {p} | {v['value']:.4g}{unit} | {v['std']:.2g} | "
                f"{'yes' if v.get('identified', True) else 'no (prior)'} | "
                f"{'**yes**' if v.get('at_bound') else 'no'} | {v.get('meaning', '')} |"
            )
    lines += _md_signatures(d.get("signatures"), u)
    lines += ["", "## Effects the protocol can identify", ""]
    lines += [f"- {k}: {v}" for k, v in d["identifiability"].items()]
    lines += ["", "## Residual", ""]
    lines.append(d.get("signature", f"at the noise floor ({result.error_after:.3g} {u})"))
    lines += _md_by_condition(d.get("error_by_condition"), u)
    if d["warnings"]:
        lines += ["", "## Warnings", "", *[f"- {w}" for w in d["warnings"]]]
    return lines


def _md_by_condition(parts: list[dict[str, Any]] | None, u: str) -> list[str]:
    """report.md lines: the final model's held-out squared error by drive condition
    (:func:`~.residual.condition_shares`), per trace."""
    lines: list[str] = []
    for part in parts or []:
        lines += [
            "", f"Held-out error of {part['trace']} by drive condition (a hold under the "
            "motion before it; largest share of the squared error first):", "",
            f"| condition | held-out samples | RMS [{u}] | share |", "|---|---:|---:|---:|",
            *[f"| {r['condition']} | {r['samples']} | {r['rms']:.3g} | {r['share']:.0%} |"
              for r in part["rows"]],
        ]  # fmt: skip
    return lines


def _md_hops(rows: list[dict[str, Any]] | None, start: str, u: str) -> list[str]:
    """report.md lines of a basin-hopping table (:func:`~.trace_fit._basin_hops`) from
    ``start``; none when no hop ran."""
    if not rows:
        return []
    return [
        "", f"Basin hopping from {start} (cost under the same data weight):", "",
        f"| hop | radius [σ] | cost before | costs reached | kept | held-out [{u}] |",
        "|---:|---:|---:|---|---|---:|",
        *[f"| {k} | {h['radius_sigma']:g} | {h['cost_before']:.5g} | "
          f"{', '.join(f'{c:.5g}' for c in h['costs'])} | "
          f"{'yes' if h['accepted'] else 'no'} | {h['heldout_rms']:.3g} |"
          for k, h in enumerate(rows)],
    ]  # fmt: skip


def _md_second(row: dict[str, Any] | None, u: str) -> list[str]:
    """report.md lines of the second global stage (:func:`~.trace_fit._second_stage`);
    none when the nominal fit met its target without it."""
    if not row:
        return []
    head = (f"Second global stage (the nominal fit, {row['heldout_before']:.3g} {u}, stayed "
            f"above the target): the design doubled to {row['points']} Sobol points over "
            f"±{row['box_sigma']:g} prior σ, {row['new_starts']} of its best starts "
            "new")  # fmt: skip
    if not row["new_starts"]:
        return ["", f"{head}: the search would repeat the first stage's, not run."]
    costs = ", ".join(f"{c:.5g}" for c in row["costs"])
    return [
        "", f"{head}; its starts (the prior first) reached costs {costs}, hopped to "
        f"{row['cost_after']:.5g} against the first stage's {row['cost_before']:.5g} under "
        f"the same data weight; {'kept' if row['kept'] else 'not kept'} (held-out "
        f"{row['heldout_rms']:.3g} {u}).",
        *_md_hops(row.get("hops"), "the second stage's best start", u),
    ]  # fmt: skip


def _md_profile(row: dict[str, Any] | None, u: str) -> list[str]:
    """report.md lines of the amplifier profile (:func:`~.trace_fit._amplifier_profile`);
    none where the nominal fit met its target without it."""
    if not row:
        return []
    freed = ", ".join(f"{c:.5g}" for c in row["freed_costs"])
    amp = row["amplifier"]
    return [
        "", f"Amplifier profile (the nominal fit, {row['heldout_before']:.3g} {u}, stayed "
        "above the target): the amplifier's slew and current factors held at each point "
        "while the other nominal factors are fitted (cost under the same data weight):", "",
        f"| slew factor | current factor | cost | held-out [{u}] |", "|---:|---:|---:|---:|",
        *[f"| {p['amplifier_slew']:.3g} | {p['amplifier_current']:.3g} | {p['cost']:.5g} | "
          f"{p['heldout_rms']:.3g} |" for p in row["points"]],
        "", f"The lowest freed reached costs {freed} (best at slew {amp['amplifier_slew']:.3g}, "
        f"current {amp['amplifier_current']:.3g}) against the nominal fit's "
        f"{row['cost_before']:.5g}; {'kept' if row['kept'] else 'not kept'} (held-out "
        f"{row['heldout_rms']:.3g} {u}).",
        *_md_hops(row.get("hops"), "the amplifier profile's best fit", u),
    ]  # fmt: skip


def _md_signatures(sig: dict[str, Any] | None, u: str = "nm") -> list[str]:
    """report.md lines of the identification by signature (:mod:`.identify`)."""
    if not sig:
        return []
    lines = ["", "## Effects by signature (features each effect must explain)", ""]
    for ln in sig.get("lines", []):
        f = ln.get("frequency_Hz")
        lines.append(
            f"- spectral line in the holds: {f:.1f} Hz, {ln['amplitude_nm']:.3g} nm, χ² "
            f"{ln['chi2']:.1f} against a false-alarm level of {ln['threshold_chi2']:.1f} "
            f"({'found' if ln['chi2'] >= ln['threshold_chi2'] else 'none'}; searched "
            f"{ln.get('searched', 0)} frequencies from {ln.get('lowest_Hz', float('nan')):.1f} Hz)"
            if f == f else "- no hold long enough to search for a spectral line"
        )
    lines += _md_coverage(sig.get("coverage"))
    for rnd in sig.get("rounds", []):
        dec = rnd["decision"]
        named = dec["named"] or (
            f"undecided between {', '.join(dec['undecided'])}" if dec["undecided"] else "none"
        )
        margin = dec["margin_nats"]
        lead = f" (lead {margin:.1f} nats)" if dec["named"] and margin != float("inf") else ""
        test = rnd.get("trace_test")
        if dec["named"] and test and not dec.get("rejected"):
            lead += (f"; on the held-out trace {test['rms_with']:.3g} against "
                     f"{test['rms_without']:.3g} {u} without it, z {test['z']:+.1f} over "
                     f"{test['blocks']} blocks (vetoed at ≤ {test['z_min']:g})")  # fmt: skip
        if dec["named"] and rnd.get("on_trace") and not dec.get("rejected"):
            lead += f"; parameters {rnd['on_trace']}"
        if dec.get("rejected"):
            lead += f", then not named: {dec['rejected']}"
        lines += [
            "",
            f"Round {rnd['round']}: led by {named}{lead}." if dec.get("rejected") else
            f"Round {rnd['round']}: named {named}{lead}.",
            "",
            "| candidate | groups | gain on them [nats] | least, one feature left out [nats] "
            "| over all [nats] | best at neutral | values |",
            "|---|---|---:|---:|---:|---|---|",
        ]
        for c in rnd["candidates"]:
            vals = ", ".join(f"{k}={v:.4g}" for k, v in c["values"].items())
            lines.append(
                f"| {c['effect']} | {'+'.join(c['declared_groups'])} | "
                f"{c['declared_nats']:.1f} | {c['declared_nats_leave_one_out']:.1f} | "
                f"{c['total_nats']:.1f} | "
                f"{'yes' if c['at_neutral'] else 'no'} | {vals}"
                f"{'; ' + c['note'] if c['note'] else ''} |"
            )
        hops = rnd.get("hops", {})
        lines += _md_hops(hops.get("joint_refit"), f"{dec['named']}'s joint refit", u)
        lines += _md_hops(hops.get("current_refit"), "the current model's refit", u)
        if rnd.get("unsupported"):
            lines += ["", "Not backed by their signature search (the held-out trace error "
                      "names one only if it leaves at most half of the structured residual, "
                      "or, for an effect whose level the nominal fit absorbs, if its "
                      "features back it on the refits the trace compares): "
                      + "; ".join(f"{k}: {v}" for k, v in
                                  rnd["unsupported"].items()) + "."]  # fmt: skip
        lines += _md_trace_verdicts(rnd.get("trace_verdicts"), u)
    return lines


def _md_coverage(cov: dict[str, Any] | None) -> list[str]:
    """report.md lines: what the protocol can test by signature
    (:func:`~.signatures.coverage`), and what a lab would add where it cannot."""
    if not cov:
        return []
    lines = ["", "What this protocol can test by signature (features on the data, and the "
             "least a group is scored with):", "",
             "| effect | its groups: features (needed) | by signature | to test it, add |",
             "|---|---|---|---|"]  # fmt: skip
    for e, c in cov.items():
        groups = ", ".join(f"{g}: {r['features']} ({r['needed']})" for g, r in c["groups"].items())
        can = {True: "yes", False: "**no**", None: "no group of its own (the step sizes)"}
        lines.append(f"| {e} | {groups or '—'} | {can[c['testable']]} | "
                     f"{'; '.join(c['add']) or '—'} |")
    if any(c["testable"] is False for c in cov.values()):
        lines += ["", "An effect this protocol gives no signature can still be named by the "
                  "held-out trace error, but only where it leaves at most half of the "
                  "structured residual; a trace of the protocol the last column asks for "
                  "tests it by its features."]  # fmt: skip
    return lines


def _md_trace_verdicts(rows: list[dict[str, Any]] | None, u: str) -> list[str]:
    """report.md lines of the held-out trace error's rules on a round's best screened
    candidates (:func:`~.trace_fit._accept_one`): why each was or was not named."""
    if not rows:
        return []
    out = ["", "By the held-out trace error (the best screened candidates, each refitted "
           "jointly from two starts; named when every rule holds on the lowest-cost refit "
           "and equally good refits agree, else undecided):", "",
           f"| candidate | held-out [{u}] | model without it [{u}] | gain | held-out z "
           "(signed ranks) | portions agree | main parameter at a bound | named |",
           "|---|---:|---:|---:|---|---|---|---|"]  # fmt: skip
    for v in rows:
        agree = "—" if v["consistent"] is None else ("yes" if v["consistent"] else "no")
        note = f" ({v['note'].strip()})" if v.get("note", "").strip() else ""
        dist = f"; {v['from_neutral']}" if v.get("from_neutral") else ""
        starts = v.get("starts") or []
        if len(starts) > 1:  # the joint refit's starts, lowest cost first
            dist += "; starts: " + ", ".join(
                f"z {r['z']:+.1f} at {r['heldout_rms']:.3g} {u}" + ("" if r["tied"] else
                                                                   " (worse fit)")
                for r in starts)  # fmt: skip
        named = "**yes**" if v["named"] else ("undecided" if v.get("undecided") else "no")
        out.append(
            f"| {v['effect']} | {v['heldout_rms']:.3g} | {v['baseline_rms']:.3g} | "
            f"{v['gain']:+.1%} (≥ {v['min_improvement']:.0%}) | "
            f"{v['z']:+.1f} (≥ {v['z_min']:g}: {'yes' if v['significant'] else 'no'}; "
            f"{v['blocks']} blocks{dist}) | {agree}{note} | "
            f"{v['pinned'] or 'no'} | {named} |"
        )
    backing = [f"{v['effect']}: {v['refit_backing']}" for v in rows if v.get("refit_backing")]
    if backing:
        out += ["", "Features on the refits (for a candidate its signature search did not "
                "back): " + "; ".join(backing) + "."]  # fmt: skip
    return out


def write_report(result: CalibrationResult, out: str | Path) -> dict[str, Path]:
    """``report.json``, ``report.md``, ``residual.png`` (and ``overlay.png`` for traces)
    in ``out``, the JSON with where it ran under ``provenance`` (the commit and the
    machine, :func:`~turntable_env.provenance.provenance`) and the Markdown with a line of
    it; with a rig fit also ``calibrated.toml``, the calibrated parameter set
    (:func:`~turntable_env.plant.calibrated_set_toml`). The directory is complete or
    untouched (:func:`~turntable_env.files.output_directory`)."""
    final = Path(out)
    with output_directory(final) as d:
        names = _write_report_files(result, d, final)
    return {k: final / v for k, v in names.items()}


def _write_report_files(result: CalibrationResult, d: Path, final: Path) -> dict[str, str]:
    pj = d / "report.json"
    # strict JSON: a figure that could not be computed (no line searched, say) is null
    # where it ran: the commit and the machine (a fit's basin may move with either)
    prov = provenance()
    data = {**result.to_json(), "provenance": prov}
    pj.write_text(json.dumps(plain_json(data), indent=2, allow_nan=False))
    plot_residual(result, d / "residual.png")
    has_overlay = plot_overlay(result, d / "overlay.png")
    floor = result.diagnosis.get("noise_floor")
    fl = f" (noise floor {floor:.3g} {result.error_unit})" if floor else ""
    lines = [
        "# Calibration report",
        "",
        f"- selected effects: {', '.join(result.selected_effects) or 'none'}",
        f"- {result.error_label} before: {result.error_before:.3g} {result.error_unit}, after: "
        f"{result.error_after:.3g} {result.error_unit}{fl}",
        f"- residual structured: {result.residual_structured}"
        + (f" — {result.diagnosis.get('signature', '')}" if result.residual_structured else ""),
        f"- wall time: {result.wall_s:.1f} s",
        f"- code: turntable_env {prov['code']['package']}, commit "
        f"{code_label(prov['code'])}; machine: {prov['machine']['cpu']}, numpy "
        f"{prov['machine']['numpy']}, numba {prov['machine']['numba']}",
        "",
        "| round | candidate | held-out error |",
        "|---:|---|---:|",
        *[
            f"| {c['round']} | {c['effect']} | {c['heldout_error']:.3g} |"
            for c in result.candidates
        ],
    ]
    trace_lines = _md_trace_sections(result)
    if trace_lines:
        lines += trace_lines
    else:
        lines += [
            "",
            "| owner | parameter | value | std |",
            "|---|---|---:|---:|",
            *[
                f"| {o} | {p} | {v['value']:.4g} | {v['std']:.2g} |"
                for o, ps in result.parameters.items()
                for p, v in ps.items()
            ],
        ]
    lines += [*result.sections, ""]
    if has_overlay:
        lines += ["![measured and model](overlay.png)", ""]
    lines.append("![residual](residual.png)")
    pm = d / "report.md"
    pm.write_text("\n".join(lines) + "\n", encoding="utf-8")
    paths = {"json": pj.name, "md": pm.name, "png": "residual.png"}
    if has_overlay:
        paths["overlay"] = "overlay.png"
    if result.plant is not None and result.plant.rig is not None:
        paths["parameters"] = "calibrated.toml"
        (d / "calibrated.toml").write_text(
            calibrated_set_toml(result.plant, source=f"turntable calibrate --report {final}"),
            encoding="utf-8",
        )
    return paths

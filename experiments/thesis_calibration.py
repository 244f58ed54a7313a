"""The thesis calibration as docs/calibration.md states it: the page's block printed from a
calibration report, and the spread of its figures and decisions over perturbed starts.

    python experiments/thesis_calibration.py
        the block, from experiments/results/thesis_calibration/report.json (the run that
        wrote turntable_env/data/calibrated.toml: `turntable calibrate --thesis --report
        experiments/results/thesis_calibration`)
    python experiments/thesis_calibration.py --seeds 1 2 3 --out SPREAD_MD
        runs `turntable calibrate --thesis --seed S` for each seed (every start perturbed
        differently), each in a fresh process with a cold numba cache, and prints how far
        each figure and decision moves from the committed report: the machine-to-machine
        spread one should expect (about 5 minutes a seed on this project's 2-core machine);
        SPREAD_MD is experiments/results/thesis_calibration/spread.md
    python experiments/thesis_calibration.py --reports S1/report.json S2/report.json ...
        the same table from reports already written (each `turntable calibrate --thesis
        --seed S --report S`), in the order given; their seeds from the file names' digits

The tests hold the page to this script: ``tests/test_thesis_calibration_docs.py`` checks the
block against the committed report (default tier) and a fresh run against the committed
report (slow tier).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
REPORT = ROOT / "experiments" / "results" / "thesis_calibration" / "report.json"
SPREAD = ROOT / "experiments" / "results" / "thesis_calibration" / "spread.md"
UNITS = {"V/s": (1e-6, "V/µs"), "V": (1.0, "V"), "rad": (1e6, "µrad")}


def load(path: Path | str = REPORT) -> dict[str, Any]:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def _fmt(value: float | None, unit: str) -> str:
    scale, shown = UNITS.get(unit, (1.0, unit))
    if value is None:  # a report's non-finite number (plain_json writes NaN and ±inf as null)
        return f"not finite {shown}"
    if value != value or abs(value) == float("inf"):
        return f"{value} {shown}"
    return f"{value * scale:.4g} {shown}"


def decisions(report: Mapping[str, Any]) -> dict[str, Any]:
    """The calibration's decisions: the amplifier's per round, the rig's per choice."""
    amp = report["diagnosis"]["amplifier_selection"]
    rig = report["diagnosis"].get("rig", {})
    return {
        "selected_effects": list(report["selected_effects"]),
        "amplifier_rounds": [
            (h["decision"]["effect"], h["decision"]["decision"])
            for h in amp["history"]
            if "decision" in h
        ],
        "rig_choices": [
            (c["choice"], c["decision"], str(c["kept"]))
            for c in rig.get("decision", {}).get("choices", [])
        ],
        "rig": rig.get("best"),
    }


def figure_sigma(report: Mapping[str, Any]) -> dict[str, float]:
    """Each figure's stated resolution for reproduction [its unit]: three times the quoted
    resolution for the amplifier's figures, the rig fit's σ (quoted resolution ⊕ the 5 %
    model error) for the stepping figures."""
    rig_sigma = report["diagnosis"].get("rig", {})
    best = next(
        (f for f in rig_sigma.get("fits", []) if f["hypothesis"] == rig_sigma.get("best")), {}
    )
    out = {}
    for row in report["diagnosis"]["targets"]:
        out[row["target"]] = best.get("sigma", {}).get(row["target"], 3.0 * row["resolution"])
    return out


def block(report: Mapping[str, Any]) -> str:
    """docs/calibration.md's block: what the calibration decided and how each figure ends."""
    d = report["diagnosis"]
    rows = d["targets"]
    within = sum(r["within_10_percent"] for r in rows)
    amp = [h["decision"] for h in d["amplifier_selection"]["history"] if "decision" in h]
    rig = d.get("rig", {})
    sig = figure_sigma(report)
    lines = [
        f"- RMS relative error over the {len(rows)} figures: {report['error_before']:.1f} % before "
        f"(Table D.1 as the thesis simulated it), {report['error_after']:.1f} % after; "
        f"**{within} of the {len(rows)} figures within ±10 %**.",
        "- Amplifier: " + "; ".join(
            f"{x['decision']} {x['effect']} (held-out {x['heldout_rms']:.1f} % against "
            f"{x['heldout_needed']:.1f} % needed, {x['starts_agree']}/{x['starts']} starts "
            "agree)" for x in amp
        ) + ".",
    ]  # fmt: skip
    if rig:
        for c in rig.get("decision", {}).get("choices", []):
            kept = "" if c["decision"] == "decided" else f"; the prior's {c['kept']} kept"
            lines.append(
                f"- Rig, {c['choice'].replace('_', ' ')}: {c['decision']} — on the 3-D model "
                f"{c['leader']} leads {c['runner_up']} by {c['margin_nats']:.2f} nats of log "
                f"posterior ({c['margin_nats_jackknife_low']:.2f} with its most helpful start "
                f"left out), on the per-axis model {c['per_axis_leader']} by "
                f"{c['per_axis_margin_nats']:.2f} ({c['per_axis_margin_nats_jackknife_low']:.2f}); "
                f"needs {c['needed_nats']:g} on both{kept}."
            )
        best = next(f for f in rig["fits"] if f["hypothesis"] == rig["best"])
        est = ", ".join(
            f"{k} × {v:.2f} ± {best['std'][k]:.2f}" for k, v in best["values"].items()
        )
        lines.append(
            f"- Calibrated rig: {rig['best']}; {est} ({best['starts_agree']}/{best['starts']} "
            f"starts reach this mode; {len(best['modes'])} modes found)."
        )
    lines += [
        "",
        "| figure | measured | before | after | error after | ±10 % | resolution for "
        "reproduction |",
        "|---|---:|---:|---:|---:|---|---:|",
        *[
            f"| {r['target']} | {_fmt(r['measured'], r['unit'])} | "
            f"{_fmt(r['predicted_before'], r['unit'])} | {_fmt(r['predicted_after'], r['unit'])} "
            f"| {r['error_after']:+.1%} | {'yes' if r['within_10_percent'] else 'no'} | "
            f"{_fmt(sig[r['target']], r['unit'])} |"
            for r in rows
        ],
    ]
    return "\n".join(lines)


def compare(reference: Mapping[str, Any], other: Mapping[str, Any]) -> dict[str, Any]:
    """How far ``other``'s figures and decisions lie from ``reference``'s: per figure the
    difference after calibration in units of its resolution for reproduction, and
    whether every decision is the same."""
    sig = figure_sigma(reference)
    ref = {r["target"]: r for r in reference["diagnosis"]["targets"]}
    oth = {r["target"]: r for r in other["diagnosis"]["targets"]}
    moved = {
        k: abs(oth[k]["predicted_after"] - ref[k]["predicted_after"]) / sig[k] for k in ref
    }
    return {
        "same_decisions": decisions(reference) == decisions(other),
        "decisions": decisions(other),
        "figures_in_resolution_units": moved,
        "within_10_percent": sum(r["within_10_percent"] for r in oth.values()),
    }


def documented_spread(path: Path | str = SPREAD) -> dict[str, float]:
    """Per figure, the largest move [resolutions] the committed spread table records."""
    rows = Path(path).read_text(encoding="utf-8").split("\n\n", 1)[1].splitlines()[2:]
    out = {}
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        out[cells[0]] = max(float(c) for c in cells[1:])
    return out


def run_seed(seed: int, out: Path) -> dict[str, Any]:
    """`turntable calibrate --thesis --seed SEED` in a fresh process with a cold numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "turntable_env.cli", "calibrate", "--thesis", "--seed",
             str(seed), "--report", str(out)],
            check=True, env=env, stdout=subprocess.DEVNULL,
        )  # fmt: skip
        wall = time.perf_counter() - t0
    rep = load(out / "report.json")
    rep["_wall_s"] = wall
    return rep


def spread_markdown(reference: Mapping[str, Any], runs: Mapping[int, Mapping[str, Any]]) -> str:
    names = [r["target"] for r in reference["diagnosis"]["targets"]]
    cmp = {s: compare(reference, r) for s, r in runs.items()}
    lines = [
        "| seed | same decisions | figures within ±10 % | largest figure move "
        "[resolutions] | wall [s] |",
        "|---:|---|---:|---:|---:|",
        *[
            f"| {s} | {'yes' if c['same_decisions'] else 'no: ' + json.dumps(c['decisions'])} "
            f"| {c['within_10_percent']} | {max(c['figures_in_resolution_units'].values()):.2f} "
            f"| {runs[s].get('_wall_s', runs[s].get('wall_s', float('nan'))):.0f} |"
            for s, c in cmp.items()
        ],
        "",
        "| figure | " + " | ".join(f"seed {s}" for s in cmp) + " |",
        "|---|" + "---:|" * len(cmp),
        *[
            f"| {n} | " + " | ".join(
                f"{c['figures_in_resolution_units'][n]:.2f}" for c in cmp.values()
            ) + " |"
            for n in names
        ],
    ]  # fmt: skip
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", default=str(REPORT), help="the calibration report to print")
    ap.add_argument("--seeds", type=int, nargs="*", default=[],
                    help="run the calibration with these seeds and print the spread")  # fmt: skip
    ap.add_argument("--reports", nargs="*", default=[],
                    help="spread from these reports instead of new runs")  # fmt: skip
    ap.add_argument("--out", default=None, help="write the spread's Markdown here too")
    args = ap.parse_args(argv)
    reference = load(args.report)
    if not args.seeds and not args.reports:
        print(block(reference))
        return 0
    runs = {}
    for r in args.reports:
        digits = "".join(ch for ch in Path(r).parent.name if ch.isdigit())
        runs[int(digits) if digits else len(runs)] = load(r)
    with tempfile.TemporaryDirectory() as tmp:
        for s in args.seeds:
            runs[s] = run_seed(s, Path(tmp) / f"seed{s}")
            print(f"seed {s}: {runs[s]['_wall_s']:.0f} s", file=sys.stderr)
    text = spread_markdown(reference, runs)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

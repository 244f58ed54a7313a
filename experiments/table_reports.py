"""What the independent tables' reports say beyond their rows (issue 31): the margins of
the signature decisions, what a stricter significance level would have named, and whose
mode a ring after the flybacks is.

    python experiments/table_reports.py DIR [DIR ...] [--rows | --margins | --refitted |
        --compare OLD_DIR ...]

``--rows`` prints the table's rows instead, one per trace, from every DIR's
``results.json`` (a later DIR's row replaces an earlier one's for the same trace: a
table run in parts, or rows re-run), with the count of rows that pass and of the rows
at each commit the calibrator ran at (a row's own record, else its report's
``provenance``; ``—`` for a run made before stop 85, which recorded neither).
``--compare OLD_DIR ...`` prints the rows the DIRs and the earlier runs share side by
side: nominal and final held-out error, the effects named and the verdict, old → new.

``--refitted`` lists, per trace, the rounds where wear (an effect whose level the nominal
fit absorbs) was not backed by its signature and ranked among the two best screened
(dropped before stop 77, refitted and judged since).

``--margins`` prints, per round of every trace (merged as ``--rows`` merges), how far
each rule of the signature route was from deciding otherwise (a decision has a margin):
for the effect a round names, its margin on every rule it passed; for a round that names
nothing, the nearest candidate's shortfall on the rules that kept it out (:func:`margins`).
A margin is *thin* within :data:`THIN`'s reach of its bar (3 nats, a factor 2 on the
trace-size ratio, one unit of z, 10 % of the error target: the first two are the largest
shifts two changes of the nominal fit have moved the same rows' margins by); the last
lines count the passing traces whose verdict rests on a thin margin and list the failing
ones. A second table does the same for the held-out trace route (:func:`trace_margins`,
since stop 85): each refitted candidate's gain and z beyond their bars and the yes/no rules
that blocked it; a candidate that missed only graded rules, each within reach, is *nearly
named*, and a passing trace with such a candidate, or with a trace-route name near its
bar, counts as resting on a thin margin.

Each DIR is an ``--out`` directory of ``experiments/independent_calibration.py`` (its
``results.json`` and one report directory per trace). For every round of every trace it
prints the leading significant candidate (or the best one when none is), its degrees of
freedom (the parameters its search moves, :func:`~turntable_env.calibration.identify.
free_parameters`), its gain over the signature groups and on its own groups [nats], its
lead over the runner-up, the candidates searched in the round, and whether it would pass:

* ``now``: the rule the report applied: ≥ its ``significance_nats`` on both (since stop 64
  the 3σ level of its own degrees of freedom, as ``k``; before, ``SIGNIFICANT_NATS``, χ² 9,
  3σ for one degree of freedom, for every candidate);
* ``k``: the χ² quantile of its own degrees of freedom at the 3σ level (p = 0.0027);
* ``k, m``: the same with Bonferroni's correction over the m candidates searched in the
  round (p = 0.0027/m) — the family-wise level of a round that picks the best of m.

and whether the effect is the truth (a catalogue effect the plant injected; "amp" for an
amplifier effect, which every plant's amplifier warrants). Only the first round of a
trace is exact under another level: a round after a name the stricter level rejects
would not have run as it did. The last lines count, over the first rounds, the true and
false names under each level.

A second table gives, per trace, the final residual's ring after the flybacks: its ratio
to the residual elsewhere, its frequency, the frequencies the data and the fitted model
ring at (:func:`~turntable_env.calibration.residual.own_ring`), and whether the report
counts it (ratio > 2, as the diagnosis does) — issue 31's item 4: a residual dominated by
the model's own table mode.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter
from pathlib import Path

from turntable_env.calibration.identify import (
    SIGNIFICANT_NATS,
    TIE_NATS,
    free_parameters,
    significance_nats,
)
from turntable_env.calibration.trace_fit import Z_HELDOUT, Z_TRACE
from turntable_env.provenance import code_label

AMPLIFIER = {"amplifier_dynamics", "amplifier_fast_path", "amplifier_lag"}


def _num(x: float | None, default: float = math.nan) -> float:
    """A report.json number: null (how strict JSON writes a NaN or an infinity, since
    stop 69) or absent read as ``default``."""
    return default if x is None else float(x)


def _searched(rnd: dict) -> list[dict]:
    """A round's candidates whose signature search ran (scored, with an objective)."""
    return [c for c in rnd["candidates"] if c.get("total_nats") is not None
            and not math.isnan(_num(c.get("objective")))]  # fmt: skip


def rounds(report: dict) -> list[dict]:
    """Per round: the leader's name, k, gains, lead, the number searched, the decision."""
    out = []
    for rnd in report["diagnosis"].get("signatures", {}).get("rounds", []):
        searched = _searched(rnd)
        if not searched:
            continue
        sig = sorted((c for c in searched if c["significant"]), key=lambda c: -c["total_nats"])
        lead = sig[0] if sig else max(searched, key=lambda c: min(c["declared_nats"],
                                                                   c["total_nats"]))  # fmt: skip
        others = [c["total_nats"] for c in sig[1:]]
        dec = rnd["decision"]
        out.append({
            "round": rnd.get("round", len(out) + 1),
            "effect": lead["effect"],
            "k": len(free_parameters(lead["effect"])),
            "total": lead["total_nats"],
            "declared": lead["declared_nats"],
            "size": _num(lead.get("size_over_floor")),
            "significant": lead["significant"],
            "level": lead.get("significance_nats", SIGNIFICANT_NATS),  # the report's rule
            "lead": lead["total_nats"] - max(others) if others else math.inf,
            "m": len(searched),
            "named": dec.get("named"),
            "rejected": dec.get("rejected", ""),
        })  # fmt: skip
    return out


# how near its bar a margin is thin: nats, a factor on the trace-size ratio, z units,
# share of the error target. The nats and the factor are the largest shifts two changes
# of the nominal fit moved the same rows' margins by (stop 63's split by direction and
# stop 64's anchor, second plant): the friction asymmetry's leave-one-out gain 5.5 → 2.6
# nats, contact wear's 6.6 → 3.8, the clean trace's hysteresis 0.65 → 1.12× the floor
THIN = {"nats": 3.0, "size": 2.0, "z": 1.0, "error": 0.10}
RULE_NATS = ("own", "loo", "all")  # the significance rules, each ≥ the candidate's level


def _rule_margins(c: dict) -> dict[str, float]:
    """A candidate's margin on each signature rule (identify.CandidateFit): own groups,
    leave-one-out (only where a direction pair was left out), all signature groups [nats
    above the candidate's significance level: the report's ``significance_nats``, or for a
    report made before stop 64 (which held every candidate to 4.5) the rule in force], and
    the trace-size ratio's excess over 1 [-]."""
    own, tot = c["declared_nats"], c["total_nats"]
    loo = c.get("declared_nats_leave_one_out", own)
    level = c.get("significance_nats") or significance_nats(len(free_parameters(c["effect"])))
    out = {"own": own - level, "all": tot - level,
           "size": _num(c.get("size_over_floor")) - 1.0}  # fmt: skip
    if loo is not None and not math.isnan(loo) and loo != own:
        out["loo"] = loo - level
    return out


def _shortfall(m: dict[str, float]) -> dict[str, float]:
    """Per rule, how far the margin lies from its bar in units of :data:`THIN` (a factor
    THIN["size"] on the size ratio is one unit): < 1 is thin."""
    unit = {"z": "z", "lead": "nats", **{r: "nats" for r in RULE_NATS}}
    out = {r: abs(v) / THIN[unit[r]] for r, v in m.items() if r in unit}
    if "size" in m and m["size"] > -1.0:
        out["size"] = abs(math.log(m["size"] + 1.0)) / math.log(THIN["size"])
    elif "size" in m:
        out["size"] = math.inf
    return out


def _distance(m: dict[str, float]) -> float:
    """How far a candidate lies from being significant: its largest shortfall on the rules it
    failed, in units of THIN (0 when it passed them all)."""
    units = _shortfall(m)
    return max((units[r] for r, v in m.items() if r in units and v < 0.0), default=0.0)


def _thin(m: dict[str, float], role: str) -> list[str]:
    """The rules the round's verdict rests on whose margin lies within THIN of its bar: a
    named effect's passed rules; a rejected one's trace verdict (z); for the nearest
    unnamed candidate the rules it failed, only when it failed every one of them within
    THIN (a candidate far below one bar is out whatever the others say)."""
    units = _shortfall(m)
    if role == "named":
        return [r for r in units if units[r] < 1.0]
    if role == "rejected":
        return ["z"] if units.get("z", math.inf) < 1.0 else []
    failed = [r for r, v in m.items() if r in units and v < 0.0]
    return failed if failed and _distance(m) < 1.0 else []


def margins(report: dict) -> list[dict]:
    """Per round of the signature route: the candidate the round turns on and its margin on
    each rule — the named effect's on the rules it passed (and the trace's verdict, z
    against −Z_TRACE in the first round, +Z_TRACE after), or, where nothing is named, the
    nearest candidate (the least largest shortfall in units of THIN; not one whose best fit
    is its neutral value) with its shortfall on the rules that kept it out."""
    out = []
    for rnd in report["diagnosis"].get("signatures", {}).get("rounds", []):
        k = rnd.get("round", len(out) + 1)
        cands = [c for c in _searched(rnd) if not c.get("at_neutral")]
        if not cands:
            continue
        dec = rnd["decision"]
        named = dec.get("named")
        if named:
            c = next(c for c in cands if c["effect"] == named)
            m = _rule_margins(c)
            if math.isfinite(_num(dec.get("margin_nats"), math.inf)):
                m["lead"] = dec["margin_nats"] - TIE_NATS
            test = rnd.get("trace_test")
            if test:
                m["z"] = test["z"] - (-Z_TRACE if k == 1 else Z_TRACE)
            role = "rejected" if dec.get("rejected") else "named"
        else:  # the candidate nearest to significance (its largest shortfall, THIN units)
            c = min(cands, key=lambda c: _distance(_rule_margins(c)))
            m, role = _rule_margins(c), "nearest"
        out.append({"round": k, "effect": c["effect"], "role": role, "margins": m,
                    "thin": _thin(m, role)})  # fmt: skip
    return out


def trace_margins(report: dict) -> list[dict]:
    """Per round, each candidate the held-out trace route refitted (``trace_verdicts``,
    ``trace_fit._accept_one``): its margin on the two graded rules, the gain over the model
    without it against ``min_improvement`` (a fraction) and z against ``z_min``, and the
    yes/no rules that blocked it (portions disagree, main parameter at a bound, its
    features not backed on the refits, equally good refits undecided). A named
    candidate's verdict is thin where a rule it passed lies within its bar's reach (one
    unit of z; the gain within half of ``min_improvement`` of its bar); an unnamed one is
    *nearly named* where every graded rule it failed lies within that reach and nothing
    else blocked it."""
    out = []
    for rnd in report["diagnosis"].get("signatures", {}).get("rounds", []):
        for v in rnd.get("trace_verdicts") or []:
            z, gain = _num(v.get("z")), _num(v.get("gain"))
            bar = _num(v.get("min_improvement"), 0.05)
            m = {"gain": gain - bar, "z": z - _num(v.get("z_min"), Z_HELDOUT)}
            reach = {"gain": bar / 2.0, "z": THIN["z"]}
            blocked = [why for why, hit in (
                ("portions disagree", v.get("consistent") is False),
                ("main parameter at a bound", bool(v.get("pinned"))),
                ("features not backed", str(v.get("refit_backing", "")).endswith("not backed")),
                ("refits undecided", bool(v.get("undecided"))),
            ) if hit]  # fmt: skip
            close = [r for r in m if abs(m[r]) < reach[r]]
            failed = [r for r in m if not m[r] >= 0.0]  # nan fails
            if v.get("named"):
                role, thin = "named", [r for r in close if m[r] >= 0.0]
            else:
                role = "not named"
                near = failed and not blocked and set(failed) <= set(close)
                thin = failed if near else []
            out.append({"round": rnd.get("round", 1), "effect": v["effect"], "role": role,
                        "margins": m, "blocked": blocked, "thin": thin})  # fmt: skip
    return out


def _fmt(m: dict[str, float], r: str) -> str:
    if r not in m:
        return "—"
    return f"{m[r] + 1.0:.2f}×" if r == "size" else f"{m[r]:+.2f}"


def _margins(dirs: list[Path]) -> int:
    print("| trace | round | candidate | role | own | leave-one-out | all | size/floor | "
          "lead | trace z | thin |")  # fmt: skip
    print("|---|---:|---|---|---:|---:|---:|---:|---:|---:|---|")
    thin_rows, n, failing = [], 0, []
    merged = {row["trace"]: (label, row, rep) for label, row, rep in _reports(dirs)}
    for label, row, rep in merged.values():  # a later DIR's trace replaces an earlier one's
        ratio = row["after_nm"] / row["target_nm"]  # held-out error over its target
        near = abs(ratio - 1.0) < THIN["error"]
        if not row["pass"]:
            failing.append(f"{label} (after/target {ratio:.2f})")
        n += bool(row["pass"])
        rows = margins(rep)
        thin = sorted({f"round {r['round']} {t}" for r in rows for t in r["thin"]})
        if near:
            thin.append("error")
        if thin and row["pass"]:
            thin_rows.append(label)
        for r in rows:
            m = r["margins"]
            cells = " | ".join(_fmt(m, x) for x in ("own", "loo", "all", "size", "lead", "z"))
            print(f"| {label} | {r['round']} | {r['effect']} | {r['role']} | {cells} | "
                  f"{', '.join(r['thin']) or '—'} |")  # fmt: skip
        print(f"| {label} | error | after/target {ratio:.2f} | "
              f"{'passes' if row['pass'] else 'fails'} | | | | | | | "
              f"{'error' if near else '—'} |")  # fmt: skip
    nearly = _trace_route(merged, thin_rows)
    print("\nnats above the candidate's significance level (own, leave-one-out, all), the "
          "trace-size ratio, "
          f"the lead above {TIE_NATS} nats, z beyond the trace's bar; thin: within "
          f"{THIN['nats']:g} nats, a factor {THIN['size']:g} of the size floor, "
          f"{THIN['z']:g} z, {THIN['error']:.0%} of the target; the trace route: the "
          "held-out gain over the model without it beyond its bar (thin within half the "
          "bar), z beyond its bar")  # fmt: skip
    print(f"{len(thin_rows)} of {n} passing traces rest on a thin margin: "
          f"{', '.join(thin_rows) or 'none'}")  # fmt: skip
    print(f"failing: {', '.join(failing) or 'none'}")
    print(f"nearly named by the held-out trace route (every graded rule it failed within "
          f"reach, nothing else blocking): {', '.join(nearly) or 'none'}")  # fmt: skip
    return 0


def _trace_route(merged: dict[str, tuple[str, dict, dict]], thin_rows: list[str]) -> list[str]:
    """The held-out trace route's verdicts of every trace (:func:`trace_margins`), as a
    second table; a passing trace whose trace verdict is thin joins ``thin_rows``. Returns
    the candidates nearly named on the traces (label: effect, the rules it missed)."""
    nearly = []
    print("\n| trace | round | candidate (held-out trace route) | verdict | gain over its bar | "
          "z beyond its bar | blocked by | thin |")  # fmt: skip
    print("|---|---:|---|---|---:|---:|---|---|")
    for label, row, rep in merged.values():
        for r in trace_margins(rep):
            m = r["margins"]
            print(f"| {label} | {r['round']} | {r['effect']} | {r['role']} | "
                  f"{100.0 * m['gain']:+.1f} % | {m['z']:+.2f} | "
                  f"{', '.join(r['blocked']) or '—'} | {', '.join(r['thin']) or '—'} |")
            if r["thin"] and row["pass"] and label not in thin_rows:
                thin_rows.append(label)
            if r["thin"] and r["role"] == "not named":
                nearly.append(f"{label} ({r['effect']}: {', '.join(r['thin'])})")
    return nearly


def passes(r: dict, level: float) -> bool:
    return bool(r["significant"] and min(r["total"], r["declared"]) >= level)


def _reports(dirs: list[Path]) -> list[tuple[str, dict, dict]]:
    """(label, results row, report) per trace with a report."""
    out = []
    for d in dirs:
        for row in json.loads((d / "results.json").read_text()):
            rep = d / row["trace"] / "report.json"
            if rep.exists():
                out.append((f"{d.name}/{row['trace']}", row, json.loads(rep.read_text())))
    return out


def _ring_table(reports: list[tuple[str, dict, dict]]) -> None:
    print("| trace | ring ratio | residual rings at [Hz] | data [Hz] | model [Hz] | counted |")
    print("|---|---:|---:|---:|---:|---|")
    for label, _row, rep in reports:
        g = rep["diagnosis"].get("ringing")
        if not g:
            print(f"| {label} | — | — | — | — | no flyback |")
            continue
        print(
            f"| {label} | {g['ratio']:.2f} | {g['frequency_Hz']:.0f} | "
            f"{_num(g.get('data_ring_Hz')):.0f} | {_num(g.get('model_ring_Hz')):.0f} | "
            f"{'yes' if g['ratio'] > 2.0 else 'no'} |"
        )


def _merged(dirs: list[Path]) -> dict[str, dict]:
    """Each trace's row from the DIRs' results.json, a later DIR's replacing an earlier's;
    a row that does not record its code (made before stop 85) takes its report's."""
    rows: dict[str, dict] = {}
    for d in dirs:
        for row in json.loads((d / "results.json").read_text()):
            code = row.get("code") or _report_code(d / row["trace"] / "report.json")
            rows[row["trace"]] = {**row, "run": d.name, "code": code}
    return rows


def _report_code(path: Path) -> dict | None:
    """The commit a report.json says it ran at (its ``provenance``), None where it does not
    say (a report made before stop 85) or is not there."""
    if not path.exists():
        return None
    return (json.loads(path.read_text()).get("provenance") or {}).get("code")


def _compare(old: list[Path], new: list[Path]) -> int:
    """The rows both sets have: nominal and final held-out error and the verdict, old → new."""
    a, b = _merged(old), _merged(new)
    print("| trace | nominal [nm] | after [nm] | target [nm] | selected | passes |")
    print("|---|---:|---:|---:|---|---|")
    for t in (t for t in b if t in a):
        r0, r1 = a[t], b[t]
        sel = [", ".join(r["selected"]) or "none" for r in (r0, r1)]
        print(f"| {t} | {r0['nominal_nm']:.1f} → {r1['nominal_nm']:.1f} | "
              f"{r0['after_nm']:.1f} → {r1['after_nm']:.1f} | {r1['target_nm']:.1f} | "
              f"{sel[0]} → {sel[1]} | {'yes' if r0['pass'] else 'no'} → "
              f"{'yes' if r1['pass'] else 'no'} |")  # fmt: skip
    return 0


def _unseen(dirs: list[Path]) -> int:
    """Per trace: the candidates a round's signature did not back (``unsupported``) that
    leave at most ``UNSEEN_SHARE`` of the structured held-out residual in that round's
    screening — those the trace error may still name (a run made before that rule would
    differ only there)."""
    from turntable_env.calibration.residual import structured_rms
    from turntable_env.calibration.trace_fit import UNSEEN_SHARE

    for label, _row, rep in _reports(dirs):
        floor, hist = rep["diagnosis"]["noise_floor"], rep["history"]
        allowed = []
        for rnd in rep["diagnosis"]["signatures"]["rounds"]:
            k, uns = rnd["round"], rnd.get("unsupported") or {}
            cur = hist[min(k - 1, len(hist) - 1)]["heldout_rms"]
            left = structured_rms(cur, floor)
            allowed += [
                f"round {k} {c['effect']} ({structured_rms(c['heldout_error'], floor) / left:.0%})"
                for c in rep["candidates"]
                if c["round"] == k and c["effect"] in uns and left > 0
                and structured_rms(c["heldout_error"], floor) <= UNSEEN_SHARE * left
            ]  # fmt: skip
        print(f"{label}: {', '.join(allowed) or 'none'}")
    return 0


def _refitted(dirs: list[Path]) -> int:
    """Per trace: the rounds where an effect whose level the nominal fit absorbs
    (``identify.CONFOUNDED_NOMINAL``: wear) was not backed by its signature, left more than
    ``UNSEEN_SHARE`` of the structured held-out residual in the screening and ranked among
    the two best screened — dropped before stop 77, refitted and judged since (its features
    then back it or not on the two refits the trace compares,
    ``trace_fit._refit_backing``); and how many traces have one. A report made before stop
    77 screened wear with the friction level held, so this is where such a report's round
    would have differed at least."""
    from turntable_env.calibration.identify import CONFOUNDED_NOMINAL
    from turntable_env.calibration.residual import structured_rms
    from turntable_env.calibration.trace_fit import UNSEEN_SHARE

    exposed = 0
    reports = _reports(dirs)
    for label, _row, rep in reports:
        floor, hist = rep["diagnosis"]["noise_floor"], rep["history"]
        hits = []
        for rnd in rep["diagnosis"]["signatures"]["rounds"]:
            k, uns = rnd["round"], rnd.get("unsupported") or {}
            left = structured_rms(hist[min(k - 1, len(hist) - 1)]["heldout_rms"], floor)
            screened = sorted((c for c in rep["candidates"] if c["round"] == k),
                              key=lambda c: c["heldout_error"])[:2]  # fmt: skip
            hits += [
                f"round {k} {c['effect']} ({c['heldout_error']:.1f} nm screened)"
                for c in screened
                if c["effect"] in uns and c["effect"] in CONFOUNDED_NOMINAL and left > 0
                and structured_rms(c["heldout_error"], floor) > UNSEEN_SHARE * left
            ]  # fmt: skip
        exposed += bool(hits)
        print(f"{label}: {', '.join(hits) or 'none'}")
    print(f"\n{exposed} of {len(reports)} traces have such a round")
    return 0


def _rows(dirs: list[Path]) -> int:
    from independent_calibration import HEADER, print_row  # the table's own format

    rows = _merged(dirs)
    print(HEADER)
    done = [print_row(r) for r in rows.values()]
    n = sum(r["pass"] for r in done)
    print(f"\n{n} of {len(done)} rows pass ({100.0 * n / max(len(done), 1):.0f} %)")
    at = Counter(code_label(r["code"]) for r in done)
    print("rows by the code they ran at (a commit, + with uncommitted changes, — not "
          "recorded): " + ", ".join(f"{c} × {k}" for c, k in sorted(at.items())))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=Path)
    ap.add_argument("--rows", action="store_true", help="print the merged table's rows")
    ap.add_argument("--compare", nargs="+", type=Path, default=None, metavar="OLD_DIR",
                    help="print the DIRs' rows beside these earlier runs' (merged alike)")
    ap.add_argument("--margins", action="store_true",
                    help="per round, each rule's margin: the named effect's, or the nearest "
                    "unnamed candidate's shortfall")
    ap.add_argument("--unseen", action="store_true",
                    help="per trace, the candidates without their signature's backing that "
                    "the trace error may still name (they leave at most half the structure)")
    ap.add_argument("--refitted", action="store_true",
                    help="per trace, the rounds where wear without its signature's backing "
                    "ranks among the two best screened (refitted since stop 77)")
    args = ap.parse_args(argv)
    for d in [*args.dirs, *(args.compare or [])]:
        if not (d / "results.json").exists():
            print(f"{d}: no results.json (an --out directory of independent_calibration.py)",
                  file=sys.stderr)  # fmt: skip
            return 2
    if args.unseen:
        return _unseen(args.dirs)
    if args.refitted:
        return _refitted(args.dirs)
    if args.margins:
        return _margins(args.dirs)
    if args.compare:
        return _compare(args.compare, args.dirs)
    if args.rows:
        return _rows(args.dirs)
    reports = _reports(args.dirs)
    print("| trace | round | leader | k | m | gain all / own [nats] | lead [nats] | named | "
          "truth | now | k | k, m |")  # fmt: skip
    print("|---|---:|---|---:|---:|---:|---:|---|---|---|---|---|")
    tally = {lv: {"true": 0, "false": 0} for lv in ("now", "k", "k, m")}
    for label, row, rep in reports:
        truth = set(row["expected"]) - {"none", "outside"}
        for r in rounds(rep):
            is_true = r["effect"] in truth or r["effect"] in AMPLIFIER
            levels = {"now": r["level"], "k": significance_nats(r["k"]),
                      "k, m": significance_nats(r["k"], r["m"])}  # fmt: skip
            verdicts = {lv: passes(r, x) for lv, x in levels.items()}
            cells = " | ".join(
                f"{'yes' if verdicts[lv] else 'no'} ({levels[lv]:.1f})" for lv in levels
            )
            if r["round"] == 1:
                for lv, ok in verdicts.items():
                    if ok:
                        tally[lv]["true" if is_true else "false"] += 1
            truth_txt = "amp" if r["effect"] in AMPLIFIER else ("yes" if is_true else "no")
            named = r["named"] or ("rejected: " + r["rejected"] if r["rejected"] else "—")
            print(
                f"| {label} | {r['round']} | {r['effect']} | {r['k']} | "
                f"{r['m']} | {r['total']:.1f} / {r['declared']:.1f} | {r['lead']:.1f} | "
                f"{named} | {truth_txt} | {cells} |"
            )
    print()
    for lv, t in tally.items():
        print(f"first rounds, level {lv}: {t['true']} true names, {t['false']} false ones")
    print()
    _ring_table(reports)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

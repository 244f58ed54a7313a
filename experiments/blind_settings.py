"""Which stepping frequencies keep their direction across a plant family (issue 32).

A move made blind (the reading saturated: the table beyond the detector) cannot be
checked: a setting that steps backwards on the plant at hand runs the table away until the
blind budget is spent. So a blind move should use only settings whose *direction* does not
depend on the plant. This survey measures that, per frequency of the map planner's family
(a = 0.9, k = 1, amplitudes 2–9.5 V, both directions): over a grid of plants whose friction
and preload span ×0.5–2 and whose amplifier (slew per input volt and current limit) spans
×0.5–1.5 around Table D.1 — the scatter a lab should expect between units, wider than the
agents' training ranges and not drawn from any benchmark plant set — the share of
(plant, amplitude, direction) whose steady step per period goes against the commanded
direction, and the worst step over the nominal map's.

    python experiments/blind_settings.py [--axis B] [--out controllers/data/blind_settings.csv]

With ``--fidelity translation --asymmetry 0.3`` the survey runs the env's default model on
the box's corners with the catalogue's friction asymmetry at α = ±0.3 and ``--drawn``
plants inside the box with α drawn: the table ``controllers/data/blind_asymmetry.csv``
(:data:`controllers.blind.ASYMMETRY_PATH`), which keeps its direction on such plants and
steps only at the slowest settings of the planner's waveform; ``--ramp-ratios 0.6,0.9``
adds the step map's a = 0.6 waveform (k = 1), whose 2 kHz settings keep their direction up
to 4.5 V there, and ``--workers`` runs the plants over processes
(:func:`turntable_env.scale.map_tasks`: the survey of 32 plants and two waveforms took
382 s over two).

It writes the worst ratio and the backward share per setting to the file the map
controllers read (:mod:`controllers.blind`): blind, they step only with settings whose
worst ratio is at least −``BLIND_TOLERANCE``.
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from controllers.blind import BLIND_PATH, BLIND_TOLERANCE, BlindSettings
from controllers.step_map import StepMap
from turntable_env.envs.config import EnvConfig
from turntable_env.envs.core import TurntableTask
from turntable_env.plant import Plant
from turntable_env.scale import map_tasks

AMPLITUDES = tuple(float(a) for a in np.arange(2.0, 10.01, 0.5))  # V, the planner's (≥ 2 V)
FRICTION = (0.5, 0.7, 1.0, 1.4, 2.0)  # × μ_s and μ_c
PRELOAD = (0.5, 0.7, 1.0, 1.4, 2.0)  # × F_N
AMPLIFIER = (0.5, 0.7, 1.0, 1.5)  # × slew per input volt and current limit
INTERVALS = 4  # control intervals per case; the first (from rest) is not counted
RANDOM_PLANTS = 60  # plants drawn log-uniformly inside the grid's box, besides the grid
MARGIN = 0.1  # a robust setting's worst step is at least this share of the map's


def corners(fidelity: str, asymmetry: float = 0.0) -> list[tuple[Plant, dict[str, float]]]:
    """The factor box's eight corners on a plant of ``fidelity`` (``--check``); with
    ``asymmetry`` > 0 each corner twice, with the catalogue's friction asymmetry at
    α = −``asymmetry`` and +``asymmetry`` (sliding forward harder, then easier)."""
    base = Plant("real", fidelity=fidelity)
    alphas = (-asymmetry, asymmetry) if asymmetry > 0.0 else (None,)
    boxes = [
        {"friction": fr, "preload": pl, "amplifier": am}
        for fr, pl, am in itertools.product(
            (FRICTION[0], FRICTION[-1]), (PRELOAD[0], PRELOAD[-1]), (AMPLIFIER[0], AMPLIFIER[-1])
        )
    ]
    effects = [{} if al is None else {"friction_asymmetry": {"alpha": al}} for al in alphas]
    return [(base.replace(factors=f, effects=e), f) for e in effects for f in boxes]


def family(
    fidelity: str = "reduced", asymmetry: float = 0.0, drawn: int = RANDOM_PLANTS
) -> list[tuple[Plant, dict[str, float]]]:
    """The survey's plants on a plant of ``fidelity``. Without ``asymmetry``: every
    combination of the factor grids, and ``drawn`` plants drawn log-uniformly inside their
    box (the step is not monotone in the factors). With ``asymmetry`` > 0 (the catalogue's
    friction asymmetry, |α| up to it): the box's eight corners at α = ±``asymmetry``
    (:func:`corners`), and ``drawn`` plants inside the box with α drawn uniformly in
    ±``asymmetry`` (the 32 plants took 490 s on one core, as the survey prints: the grid's
    100 would take about 25 minutes at that rate)."""
    box = {"friction": FRICTION, "preload": PRELOAD, "amplifier": AMPLIFIER}
    rng = np.random.default_rng(2026)
    factors = [
        {k: float(np.exp(rng.uniform(np.log(v[0]), np.log(v[-1])))) for k, v in box.items()}
        for _ in range(drawn)
    ]
    base = Plant("real", fidelity=fidelity)
    if asymmetry > 0.0:
        alphas = rng.uniform(-asymmetry, asymmetry, drawn)
        inside = [
            (base.replace(factors=f, effects={"friction_asymmetry": {"alpha": float(al)}}),
             {**f, "alpha": float(al)})
            for f, al in zip(factors, alphas, strict=True)
        ]  # fmt: skip
        return corners(fidelity, asymmetry) + inside
    grid = [
        {"friction": fr, "preload": pl, "amplifier": am}
        for fr, pl, am in itertools.product(FRICTION, PRELOAD, AMPLIFIER)
    ]
    return [(base.replace(factors=f), f) for f in grid + factors]


def steady_steps(
    plants: list[tuple[Plant, dict[str, float]]],
    frequencies: np.ndarray,
    axis: str,
    ramp_ratios: tuple[float, ...] = (0.9,),
    workers: int | None = 1,
) -> tuple[np.ndarray, list[dict]]:
    """(plants, ramp ratios, frequencies, amplitudes, 2 directions) steady step per period
    [rad], noise off, from rest at 0, of ``plants`` (one fidelity; k = 1), one job per
    plant over ``workers`` processes (:func:`turntable_env.scale.map_tasks`); and the
    plants' factors."""
    jobs = [(plant, tuple(float(f) for f in frequencies), axis, tuple(ramp_ratios))
            for plant, _f in plants]  # fmt: skip
    if workers == 1:
        out = [_plant_steps(j) for j in jobs]
    else:
        out = map_tasks(_plant_steps, jobs, backend="processes", workers=workers)
    shape = (len(plants), len(ramp_ratios), len(frequencies), len(AMPLITUDES), 2)
    return np.array(out).reshape(shape), [f for _p, f in plants]


def _plant_steps(job: tuple[Plant, tuple[float, ...], str, tuple[float, ...]]) -> np.ndarray:
    """One plant's steady step per period [rad] over the cases (ramp ratio, frequency,
    amplitude, direction), k = 1: INTERVALS intervals from rest, the first not counted."""
    plant, frequencies, axis, ramp_ratios = job
    cfg = EnvConfig(plant=Plant("real", fidelity=plant.fidelity), axis=axis, noise=False)
    cases = [(d * amp, f, a) for a in ramp_ratios for f in frequencies for amp in AMPLITUDES
             for d in (1.0, -1.0)]  # fmt: skip
    rng = np.random.default_rng(0)
    task = TurntableTask(cfg, len(cases))
    for b in range(len(cases)):
        task.reset_row(b, rng, {"start_angle": 0.0, "target_angle": 0.0}, plant=plant)
    acts = np.array([cfg.scaling.encode(amp, f, a, 1.0) for amp, f, a in cases])
    angles = [task.angle.copy()]
    for _ in range(INTERVALS):
        task.step(acts, rng)
        angles.append(task.angle.copy())
    disp = np.diff(np.array(angles), axis=0)[1:].mean(axis=0)  # rad per interval
    per = np.array([f * cfg.control_interval for _amp, f, _a in cases])
    return disp / per


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--axis", default="B", choices=("A", "B", "C"))
    ap.add_argument("--out", default=str(BLIND_PATH), help="the table's file")
    ap.add_argument("--asymmetry", type=float, default=0.0,
                    help="the catalogue's friction asymmetry, |α| <= ALPHA (at most 0.4): "
                         "with --check each corner at ±ALPHA; in a survey the corners at "
                         "±ALPHA and --drawn plants with α drawn")  # fmt: skip
    ap.add_argument("--fidelity", default="reduced",
                    choices=("reduced", "translation", "full", "independent"),
                    help="the survey's model (default: the per-axis one the shipped table "
                         "was made on)")  # fmt: skip
    ap.add_argument("--drawn", type=int, default=RANDOM_PLANTS,
                    help=f"plants drawn inside the box (default {RANDOM_PLANTS})")
    ap.add_argument("--check", choices=("reduced", "translation", "full", "independent"),
                    default=None,
                    help="only step the box's eight corners on a plant of this fidelity and "
                         "compare the shipped blind set with the other settings (no file "
                         "written)")  # fmt: skip
    ap.add_argument("--ramp-ratios", default="0.9",
                    help="the waveform families surveyed, ramp ratios a (k = 1) of the step "
                         "map, comma-separated (default 0.9: the map planner's own)")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes over the plants (turntable_env.scale.map_tasks)")
    args = ap.parse_args()
    if not 0.0 <= args.asymmetry <= 0.4:
        ap.error(f"--asymmetry={args.asymmetry!r}: must be in 0–0.4")
    if args.drawn < 0:
        ap.error(f"--drawn={args.drawn!r}: must be >= 0")
    if args.workers < 1:
        ap.error(f"--workers={args.workers!r}: must be >= 1")
    smap = StepMap.load()
    try:
        ratios = tuple(float(x) for x in args.ramp_ratios.split(","))
        for a in ratios:
            smap.family(args.axis, 1000.0, a, 1.0, 1)
    except ValueError:
        ap.error(f"--ramp-ratios={args.ramp_ratios!r}: must be ramp ratios of the step map "
                 f"({', '.join(f'{a:g}' for a in np.unique(smap.a))})")
    if args.check and 0.9 not in ratios:
        ap.error("--check compares the planner's family: --ramp-ratios must hold 0.9")
    freqs = np.unique(smap.frequency)
    t0 = time.perf_counter()
    plants = (corners(args.check, args.asymmetry) if args.check
              else family(args.fidelity, args.asymmetry, args.drawn))  # fmt: skip
    steps, factors = steady_steps(plants, freqs, args.axis, ratios, args.workers)
    sign = np.array([1.0, -1.0])  # the commanded direction of the last axis
    nominal = np.array(
        [[[[smap.step_size(args.axis, d * amp, f, a, 1.0) for d in sign] for amp in AMPLITUDES]
          for f in freqs] for a in ratios]
    )  # fmt: skip
    along = steps * sign  # > 0: the commanded direction
    print(
        f"{len(factors)} plants (friction ×{FRICTION[0]}–{FRICTION[-1]}, preload "
        f"×{PRELOAD[0]}–{PRELOAD[-1]}, amplifier ×{AMPLIFIER[0]}–{AMPLIFIER[-1]}"
        + (f", friction asymmetry |α| ≤ {args.asymmetry:g}" if args.asymmetry else "")
        + f"), {plants[0][0].fidelity} model, axis {args.axis}, a = "
        f"{', '.join(f'{a:g}' for a in ratios)}, k = 1, amplitudes "
        f"{', '.join(f'{a:g}' for a in AMPLITUDES)} V, both directions; "
        f"{time.perf_counter() - t0:.0f} s over {args.workers} process(es)"
    )
    ratio = along / (nominal * sign)  # the plant's step over the map's, > 0: forwards
    worst = ratio.min(axis=(0, 4))  # (ramp ratios, frequencies, amplitudes)
    if args.check:
        label = args.check + (f", friction asymmetry ±{args.asymmetry:g}" if args.asymmetry
                              else "")  # fmt: skip
        for r, a in enumerate(ratios):
            _check(worst[r], freqs, label, a)
        _reversals(ratio[:, ratios.index(0.9)], freqs)
        return
    back = along < 0.0
    cells = list(itertools.product(range(len(ratios)), range(freqs.size), range(len(AMPLITUDES))))
    for r, a in enumerate(ratios):
        print(f"a = {a:g}: worst step over the map's, over plants and both directions "
              "(rows: amplitude [V])")  # fmt: skip
        print("   V | " + " | ".join(f"{f:6.0f} Hz" for f in freqs))
        for i, amp in enumerate(AMPLITUDES):
            print(f"{amp:4.1f} | "
                  + " | ".join(f"{worst[r, j, i]:9.2f}" for j in range(freqs.size)))  # fmt: skip
        print(
            "share of (plant, amplitude, direction) stepping backwards: "
            + ", ".join(f"{f:.0f} Hz {back[:, r, j].mean():.3f}" for j, f in enumerate(freqs))
        )
    for label, bound in ((f"robust settings (worst step ≥ {MARGIN:g} of the map's)", MARGIN),
                         (f"blind settings (worst ≥ −{BLIND_TOLERANCE:g})", -BLIND_TOLERANCE)):
        chosen = [f"{AMPLITUDES[i]:g} V at {freqs[j]:.0f} Hz, a = {ratios[r]:g}"
                  for r, j, i in cells if worst[r, j, i] >= bound]  # fmt: skip
        print(f"{label}: " + ("; ".join(chosen) or "none"))
    key = {(r, j, i): (float(freqs[j]), AMPLITUDES[i], ratios[r], 1.0) for r, j, i in cells}
    table = {key[c]: float(worst[c]) for c in cells}
    shares = {key[c]: float(back[:, c[0], c[1], c[2]].mean()) for c in cells}
    path = BlindSettings(table).save(args.out, shares, _header(args, len(factors), ratios))
    print(f"written to {path}")
    r, j, i = np.unravel_index(int(np.argmax(worst)), worst.shape)
    print(
        f"most robust: {AMPLITUDES[i]:g} V at {freqs[j]:.0f} Hz, a = {ratios[r]:g}, worst "
        f"{worst[r, j, i]:.2f} of the map's step"
    )


def _header(args: argparse.Namespace, plants: int, ratios: tuple[float, ...]) -> str:
    """The table file's comment: what was surveyed and the command that regenerates it."""
    waveform = f"a = {', '.join(f'{a:g}' for a in ratios)}, k = 1"
    default = (args.fidelity == "reduced" and not args.asymmetry
               and args.drawn == RANDOM_PLANTS and ratios == (0.9,))  # fmt: skip
    if default:
        return (
            f"worst steady step over the map's, over {plants} plants and both "
            f"directions (axis {args.axis}, {waveform})\nfriction and preload "
            f"x{FRICTION[0]}-{FRICTION[-1]}, amplifier x{AMPLIFIER[0]}-{AMPLIFIER[-1]} "
            f"(grid and {RANDOM_PLANTS} drawn)\n"
            "regenerate: python experiments/blind_settings.py"
        )
    family = (f"corners at alpha = +-{args.asymmetry:g} and {args.drawn} drawn with |alpha| "
              f"<= {args.asymmetry:g}" if args.asymmetry
              else f"grid and {args.drawn} drawn")  # fmt: skip
    return (
        f"worst steady step over the map's, over {plants} plants and both directions "
        f"(axis {args.axis}, {waveform}), {args.fidelity} model\nfriction and preload "
        f"x{FRICTION[0]}-{FRICTION[-1]}, amplifier x{AMPLIFIER[0]}-{AMPLIFIER[-1]}; "
        f"{family}\nregenerate: python experiments/blind_settings.py --fidelity "
        f"{args.fidelity} --asymmetry {args.asymmetry:g} --drawn {args.drawn} --axis "
        f"{args.axis} --ramp-ratios {','.join(f'{a:g}' for a in ratios)} --out {args.out}"
    )


def _check(worst: np.ndarray, freqs: np.ndarray, fidelity: str, a: float = 0.9) -> None:
    """Print the default blind set's worst step on the corners against the others', for
    the waveform of ramp ratio ``a`` (k = 1)."""
    survey = BlindSettings.load()
    grid = [(j, i) for j in range(freqs.size) for i in range(len(AMPLITUDES))]
    inside = [survey.robust(np.array([AMPLITUDES[i]]), np.array([freqs[j]]), a=a)[0]
              for j, i in grid]  # fmt: skip
    for label, keep in (("blind set", True), ("other settings", False)):
        pairs = zip(grid, inside, strict=True)
        cells = [(worst[j, i], AMPLITUDES[i], freqs[j]) for (j, i), k in pairs if k == keep]
        if not cells:
            print(f"a = {a:g}, {label}: none")
            continue
        back = sum(w < 0.0 for w, _a, _f in cells)
        w, amp, f = min(cells)
        print(
            f"a = {a:g}, {label} on the {fidelity} corners: {len(cells)} settings, {back} "
            f"step backwards on a corner; worst {w:.2f} of the map's step ({amp:g} V at "
            f"{f:.0f} Hz)"
        )
    if a == 0.9:
        for amp in (6.0, 6.5):
            j = int(np.flatnonzero(np.isclose(freqs, 1000.0))[0])
            print(f"  {amp:g} V at 1 kHz: worst {worst[j, AMPLITUDES.index(amp)]:.2f}")


def _reversals(ratio: np.ndarray, freqs: np.ndarray) -> None:
    """Print, per frequency, how far the cases that step backwards (ratio < −0.05 of the
    map's step) go: the median and 90th percentile of |ratio| over plants, amplitudes and
    directions (what ``controllers.feedforward.REVERSAL`` sizes an unconfirmed move for)."""
    print("backward steps over the map's, among the cases stepping backwards (median, 90th "
          "percentile, cases):")  # fmt: skip
    for j, f in enumerate(freqs):
        back = -ratio[:, j][ratio[:, j] < -0.05]
        if back.size:
            print(f"  {f:6.0f} Hz: {np.median(back):.2f}, {np.percentile(back, 90):.2f} "
                  f"({back.size} of {ratio[:, j].size})")  # fmt: skip
        else:
            print(f"  {f:6.0f} Hz: none of {ratio[:, j].size}")


if __name__ == "__main__":
    main()

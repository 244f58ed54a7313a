"""``turntable report``: one command that shows what the environment knows.

:func:`build_report` runs every section below (a tqdm bar over them), then writes
``index.html`` — self-contained, every image embedded as a data URI — and
``summary.json``, which holds every number the page shows (section → numbers), so a run
can be compared with the last. ``quick=True`` shortens each computation for tests of the
command; its numbers are not the reported ones.

Sections: the thesis's component figures (2.8, 2.9, 2.10, 3.14, 4.2/4.3), rotation about
B on the real parameters against the measured 0.37 and 0.30 µm per step (4.6, 4.7) and on
the thesis's simulation parameters (4.8, 4.10), a rendered frame of the turntable (4.9)
and an animation (GIF), the speed table (``turntable bench``), the controller benchmark
with trajectory plots, and the calibration loop on the thesis's figures.
"""

from __future__ import annotations

import io
import json
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..files import check_writable, output_directory, plain_json
from .figures import (
    amplifier_figure,
    drift_figure,
    hysteresis_figure,
    sawtooth_figure,
    stepping_figure,
    stribeck_figure,
)
from .html import render_html
from .section import Section

__all__ = ["Section", "build_report"]


def _friction(quick: bool) -> Section:
    s = Section(
        "friction",
        "Friction models (chapter 2)",
        "The GMS friction model at the contacts (§2.3.2, Table D.2 friction parameters): "
        "steady sliding, presliding hysteresis and drift, each against the thesis's figure.",
    )
    for f in (stribeck_figure(quick), hysteresis_figure(quick), drift_figure()):
        s.add_figure(f)
    return s


def _drive(quick: bool) -> Section:
    s = Section(
        "drive",
        "Drive and amplifier (§3.4, §4.1.2)",
        "The sawtooth generator and the HVA 900 amplifier model (gain 45, first order with "
        "τ from the measured 0.9 V/µs per input volt, 12 V/µs and 25 mA limits).",
    )
    s.add_figure(sawtooth_figure())
    s.add_figure(amplifier_figure())
    return s


def _stepping(params: str, quick: bool) -> Section:
    lab = params in ("real", "calibrated")
    title = {
        "real": "Rotation about B, real parameters (Figs. 4.6, 4.7)",
        "calibrated": "Rotation about B, the calibrated set (Figs. 4.6, 4.7)",
        "thesis": "Rotation about B, the thesis's simulation parameters (Figs. 4.8, 4.10)",
    }[params]
    text = {
        "real": "Table D.1 as the thesis describes the rig (asymmetric drive, Eq. 4.1 reading the "
        "table's rotation), unlisted values of data/real_unlisted.toml",
        "calibrated": "the real turntable with the rig the thesis's figures ask for "
        "(turntable calibrate --thesis, data/calibrated.toml)",
        "thesis": "Table D.2 (the scaled set the thesis could run), ideal source, 2 Hz. It "
        "turns by mrad, beyond the detector's linear range, so the figures draw the drive "
        "instead of a saturated detector and read the steps from the angle (x = θ·R_table).",
    }[params]
    s = Section(
        f"stepping_{params}",
        title,
        "Full 3-D model (three tubes, 2-D GMS contacts, amplifier) from static equilibrium, "
        + text
        + (
            "; 2 V input (90 V on the tubes), 100 Hz, a = 0.95, adapted flyback — the "
            "measurement's input; the step is read from the detector as the figure reads it."
            if lab
            else ""
        ),
    )
    for signal, n in (("one", 9), ("two", 5)):
        s.add_figure(stepping_figure(params, signal, periods=2 if quick else n))
    if lab:
        rows = [
            [
                f"{w}-directional",
                f"{s.numbers[k]['step_m'] * 1e6:.3f}",
                f"{s.numbers[k]['measured_step_m'] * 1e6:.2f}",
                f"{s.numbers[k]['model_over_measured']:.2f}",
            ]
            for w, k in (("one", f"fig4_7_{params}_one"), ("two", f"fig4_6_{params}_two"))
        ]
        s.tables.append(
            {
                "caption": "Step per period at R_table as the figures read it: model vs "
                "measured (§4.1.3)",
                "header": ["input", "model [µm]", "measured [µm]", "model / measured"],
                "rows": rows,
            }
        )
    return s


def _render(quick: bool) -> Section:
    """Fig. 4.9: a frame of the environment's renderer, and a GIF of one episode."""
    import gymnasium as gym
    from PIL import Image

    import turntable_env  # noqa: F401  (registers the env)
    from controllers.lab import LabBrief
    from controllers.registry import make

    s = Section(
        "render",
        "The turntable rendered (Fig. 4.9) and animated",
        "PiezoTurntable-v0's rgb_array renderer, seen along the rotation axis: the axis tube "
        "end on at the centre, the two driving tubes bent (exaggerated) and their contacts "
        "(green: stick, red: slip), and the detector spot, during a fuzzy-controller move of 8 µm "
        "about B (the frame is taken during the move). The thesis showed two frames of its "
        "20-sim 3-D animation.",
    )
    env = gym.make("PiezoTurntable-v0", render_mode="rgb_array", terminate_on_success=False)
    ctl = make("fuzzy", env.unwrapped)
    # an 8 µm move at R_table: from −0.4 to +0.4 mrad, inside the detector's ±0.57 mrad
    obs, info = env.reset(seed=0, options={"start_angle": -4e-4, "target_angle": 4e-4})
    ctl.reset(obs, LabBrief(float(info["target_rad"])))
    frames = [env.render()]
    n = 10 if quick else 30
    for _ in range(n):
        obs, _r, term, trunc, info = env.step(ctl.act(obs))
        frames.append(env.render())
        if term or trunc:
            break
    env.close()
    buf = io.BytesIO()
    Image.fromarray(frames[min(2, len(frames) - 1)]).save(buf, format="PNG")  # mid-move
    s.images.append(
        {
            "name": "fig4_9_frame",
            "mime": "image/png",
            "data": buf.getvalue(),
            "caption": "Fig. 4.9 — a frame of the rendered turntable",
            "thesis": "Two frames of the 3-D animation accompanying Fig. 4.8 (§4.2.2).",
        }
    )
    gif = io.BytesIO()
    ims = [Image.fromarray(f) for f in frames]
    fps = env.metadata.get("render_fps", 100)
    ims[0].save(gif, format="GIF", save_all=True, append_images=ims[1:], duration=100, loop=0)
    s.images.append(
        {
            "name": "animation",
            "mime": "image/gif",
            "data": gif.getvalue(),
            "caption": f"Animation: {len(frames)} control steps at {fps} Hz, shown at 10 frames/s",
            "thesis": "",
        }
    )
    s.numbers = {"frames": len(frames), "render_fps": fps, "final_angle_rad": info["angle_rad"]}
    return s


def _speed(quick: bool) -> Section:
    from ..bench import format_table, run_bench

    res = run_bench(duration=0.05, batch=8, quick=True) if quick else run_bench()
    s = Section(
        "speed",
        "Speed (turntable bench)",
        "Every simulation path on the standard scenario (real set, axis B, one-directional "
        "2 V → 90 V, 100 Hz, a = 0.95, adapted flyback): real-time factor (simulated / wall "
        "time), step error against a converged reference, peak memory.",
    )
    s.tables.append({"caption": "turntable bench", "text": format_table(res)})
    s.numbers = _json(res)
    return s


def _benchmark(quick: bool, progress: bool = False) -> Section:
    from controllers.benchmark import QUICK, plot_trajectories, run_benchmark

    # the page runs the held-out set (about 2 min on one core); turntable benchmark all five
    kw: dict[str, Any] = dict(QUICK) if quick else {"plant_sets": ("held_out",)}
    if quick:
        kw["controllers"] = ["feedforward", "fuzzy", "closed_loop", "scan_pid"]
    res = run_benchmark(progress=progress, **kw)  # a bar over its control intervals
    s = Section(
        "benchmark",
        "Controller benchmark",
        "Every registered controller (feed-forward, fuzzy, closed-loop step counting, the "
        "scan PID alone, and the pretrained RL agents where torch is installed) on point "
        "moves that need stepping, tracking tasks and a knock, on the held-out plants "
        "(turntable benchmark adds the nominal, randomised, calibrated and 3-D sets); "
        "controllers see only what a lab sees. Cells: success rate · the task's primary "
        "metric, mean [95 % bootstrap interval] over paired seeds.",
    )
    s.tables.append({"caption": "turntable benchmark", "text": res.leaderboard()})
    s.numbers = _json(res.to_json()["results"])
    with tempfile.TemporaryDirectory() as tmp:
        paths = plot_trajectories(res, Path(tmp))
        for name, p in sorted(paths.items()):
            s.images.append(
                {
                    "name": name,
                    "mime": "image/png",
                    "data": Path(p).read_bytes(),
                    "caption": f"Trajectories: {name.removeprefix('trajectories_')} plants",
                    "thesis": "",
                }
            )
    return s


def _calibration(quick: bool, progress: bool = False) -> Section:
    from ..calibration.calibrate import plot_residual
    from ..calibration.rig import hypotheses
    from ..calibration.summary import calibrate_summary

    say = None
    if progress:  # each calibration stage as a line above the report's bar
        from tqdm import tqdm

        def say(msg: str) -> None:
            tqdm.write(f"  calibration: {msg}")

    if quick:  # one amplifier effect, the best hypothesis on the per-axis model only
        best = [h for h in hypotheses() if h.drive_mode == "symmetric" and h.mirror_tilt < 0.99]
        res = calibrate_summary(candidates=["amplifier_dynamics"], rig_hypotheses=best,
                                rig_fidelity="reduced", progress=say)  # fmt: skip
    else:
        res = calibrate_summary(progress=say)
    rig = res.diagnosis.get("rig", {})
    s = Section(
        "calibration",
        "Calibration on the thesis's measurements",
        "The thesis's chapter-4 figures against the model as the thesis simulated it (ideal "
        "source, Table D.1 as printed), then the amplifier on its own figures (the catalogue's "
        "amplifier effects ranked by leave-one-out error) and the rig on the stepping figures "
        "(drive mode, mirror, large-signal d31, contacts, with priors; 3-D model): turntable "
        "calibrate --thesis. " + (rig.get("explanation", "") + "." if rig else ""),
    )
    s.tables.append(
        {
            "caption": "RMS relative error over the figures before and after",
            "header": [
                "selected effects", "rig", "before [%]", "after [%]", "any figure off ±10 %"
            ],
            "rows": [
                [
                    ", ".join(res.selected_effects) or "none",
                    rig.get("best", "not fitted"),
                    f"{res.error_before:.1f}",
                    f"{res.error_after:.1f}",
                    str(res.residual_structured),
                ]
            ],
        }
    )
    decisions = [
        [f"amplifier, round {i + 1}", d["decision"], d["effect"],
         f"held-out {d['heldout_rms']:.1f} % vs {d['heldout_needed']:.1f} % needed "
         f"(± {d['heldout_tolerance']:.1f}); {d['starts_agree']}/{d['starts']} starts agree"]
        for i, d in enumerate(h["decision"] for h in res.history if "decision" in h)
    ] + [
        [f"rig, {c['choice'].replace('_', ' ')}", c["decision"], c["kept"],
         f"{c['leader']} leads {c['runner_up']} by {c['margin_nats']:.2f} nats "
         f"({c['margin_nats_jackknife_low']:.2f} with its best start left out; needs "
         f"{c['needed_nats']:g})"]
        for c in rig.get("decision", {}).get("choices", [])
    ]  # fmt: skip
    s.tables.append(
        {
            "caption": "Decisions and their margins (a margin within its uncertainty is "
            "undecided; turntable calibrate --thesis --seed N perturbs every start)",
            "header": ["decision", "outcome", "kept", "margin"],
            "rows": decisions,
        }
    )
    rows = res.diagnosis.get("targets", [])
    s.tables.append(
        {
            "caption": "Per figure, before and after (relative error; slew rates as transition "
            "time)",
            "header": [
                "figure", "measured", "before", "after", "unit", "error before",
                "error after", "source",
            ],
            "rows": [
                [
                    r["target"],
                    f"{r['measured']:.4g}",
                    f"{r['predicted_before']:.4g}",
                    f"{r['predicted_after']:.4g}",
                    r["unit"],
                    f"{r['error_before']:+.1%}",
                    f"{r['error_after']:+.1%}",
                    r["source"],
                ]
                for r in rows
            ],
        }
    )
    with tempfile.TemporaryDirectory() as d:
        png = Path(d) / "residual.png"
        plot_residual(res, png)
        data = png.read_bytes()
    s.images.append(
        {
            "name": "calibration_residual",
            "mime": "image/png",
            "data": data,
            "caption": "Relative error per figure before and after the selected effects",
            "thesis": "The thesis found the amplifier's slew rate too low (§4.1.2).",
        }
    )
    s.numbers = _json(res.to_json())
    return s


def _machine() -> str:
    """The machine the sections ran on, as the page states it."""
    import os
    import platform

    cpu = platform.processor() or platform.machine()
    return f"{cpu}, {os.cpu_count()} CPUs, Python {platform.python_version()}"


def build_report(out: str | Path, *, quick: bool = False, progress: bool = True) -> dict[str, Path]:
    """Run every section and write ``index.html`` and ``summary.json`` into ``out`` (both
    or neither: the output is checked writable before the sections run, and written
    through :func:`~turntable_env.files.output_directory`)."""
    from tqdm import tqdm

    d = check_writable("out", out, directory=True)
    jobs: list[tuple[str, Callable[[], Section]]] = [
        ("friction", lambda: _friction(quick)),
        ("drive", lambda: _drive(quick)),
        ("stepping (real)", lambda: _stepping("real", quick)),
        ("stepping (calibrated)", lambda: _stepping("calibrated", quick)),
        ("stepping (thesis)", lambda: _stepping("thesis", quick)),
        ("render", lambda: _render(quick)),
        ("speed", lambda: _speed(quick)),
        ("benchmark", lambda: _benchmark(quick, progress)),
        ("calibration", lambda: _calibration(quick, progress)),
    ]
    sections: list[Section] = []
    t_all = time.perf_counter()
    bar = tqdm(jobs, desc="report", unit="section", disable=not progress)
    for name, job in bar:
        bar.set_postfix_str(name)
        t0 = time.perf_counter()
        sec = job()
        sec.wall_s = time.perf_counter() - t0
        sections.append(sec)
    wall = time.perf_counter() - t_all
    summary = {
        "quick": quick,
        "wall_s": wall,
        "machine": _machine(),
        "sections": {
            s.id: {"title": s.title, "wall_s": s.wall_s, **_json(s.numbers)} for s in sections
        },
    }
    html = render_html(sections, summary)
    with output_directory(d) as tmp:
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
        (tmp / "index.html").write_text(html, encoding="utf-8")
    return {"html": d / "index.html", "json": d / "summary.json"}


def _json(x: Any) -> Any:
    """Plain JSON types (NaN and infinities as strings)."""
    return plain_json(x, "string")

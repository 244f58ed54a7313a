"""The controller benchmark: information boundary, metrics, intervals, tasks, plant sets."""

import functools
import json
import math

import gymnasium as gym
import numpy as np
import pytest
import yaml

import turntable_env  # registers the env; its version is the provenance test's
from agents.train import HYPERPARAMS_DIR
from controllers import available, make
from controllers.benchmark import QUICK, run_benchmark, write_outputs
from controllers.lab import LabBrief
from controllers.metrics import BAND, episode_metrics, mean_ci, paired_difference
from controllers.plant_sets import HELD_OUT_RANGES, PLANT_SETS, TRAIN_RANGES
from controllers.registry import load_plugins, register, unregister
from controllers.tasks import TASKS
from turntable_env.envs.config import OBS
from turntable_env.params import real_parameters

DET = real_parameters().detector
R = DET.table_radius


def _controllers():
    load_plugins()
    return available()


# --- the information boundary -------------------------------------------------------------
@pytest.mark.parametrize("name", _controllers())
def test_true_start_and_plant_draw_do_not_reach_the_controller(name):
    """Two episodes that differ only in evaluation-only values — the true start 2 mrad
    apart, both beyond the detector, and the randomisation draw — with the same lab brief:
    the controller acts identically as long as its observations agree."""
    actions = []
    observations = []
    for start, rnd in ((-3e-3, {"friction": (1.0, 1.0)}), (-5e-3, {"friction": (1.2, 1.2)})):
        env = gym.make("PiezoTurntable-v0", noise=False, randomize=rnd, max_episode_steps=20)
        ctl = make(name, env)
        obs, _info = env.reset(seed=0, options={"start_angle": start, "target_angle": 1e-4})
        ctl.reset(obs, LabBrief(1e-4, start_estimate_rad=-4e-3, start_error=0.3))
        acts, seen = [], []
        for _ in range(20):
            seen.append(obs.copy())
            a = ctl.act(obs)
            acts.append(a)
            obs, *_ = env.step(a)
        actions.append(np.array(acts))
        observations.append(np.array(seen))
    same = np.all(observations[0] == observations[1], axis=1)
    n = int(np.argmin(same)) if not same.all() else same.size
    assert n >= 1  # the readings agree at least at the start (both saturated)
    assert observations[0][0, OBS.measured_angle_rad] <= -0.99 * DET.angle_range
    np.testing.assert_array_equal(actions[0][:n], actions[1][:n])


def test_a_controller_refuses_the_env_info():
    env = gym.make("PiezoTurntable-v0")
    obs, info = env.reset(seed=0)
    for name in ("feedforward", "fuzzy", "closed_loop", "scan_pid"):
        with pytest.raises(ValueError, match="LabBrief"):
            make(name, env).reset(obs, info)


def test_cell_results_do_not_depend_on_the_other_controllers():
    """Common random numbers: scan_pid's per-seed metrics are the same run alone or beside
    another controller (same plants, episodes and noise per seed, whatever the row)."""
    kw = {"plant_sets": ["held_out"], "tasks": ["knock"], "seeds": 3}
    alone = run_benchmark(["scan_pid"], **kw).cell("held_out", "knock", "scan_pid")
    beside = run_benchmark(["fuzzy", "scan_pid"], **kw).cell("held_out", "knock", "scan_pid")
    for m, v in alone.metrics.items():
        np.testing.assert_array_equal(v, beside.metrics[m], err_msg=m)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--runs", "x=/nonexistent"], "--runs x: /nonexistent: model.zip missing"),
        (["--runs", "x=agents/pretrained/ppo_residual", "--suite-seed", "-1"], "--suite-seed -1"),
        (["--runs", "x=agents/pretrained/ppo_residual", "--baselines", "nope"], "'nope'"),
    ],
)
def test_agent_seeds_refuses_bad_arguments_before_any_work(args, match, monkeypatch, capsys):
    """experiments/agent_seeds.py: a missing run file, a suite seed out of range or an
    unknown baseline exits 2 with one line naming it, before the benchmark starts."""
    from conftest import experiment

    mod = experiment("agent_seeds")
    monkeypatch.setattr(mod, "run_benchmark", lambda *a, **k: pytest.fail("work started"))
    monkeypatch.setattr("sys.argv", ["agent_seeds.py", *args])
    with pytest.raises(SystemExit) as exc:
        mod.main()
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert match in err


def test_agent_seeds_paired_comparison_is_the_benchmarks_own():
    """experiments/agent_seeds.py --baselines: the mean success difference it prints is the
    difference of the two controllers' mean successes over the tasks (paired seeds), and
    it lists exactly the task × metric differences the benchmark marks separated."""
    from conftest import experiment

    paired_against = experiment("agent_seeds").paired_against
    kw = {"plant_sets": ["held_out"], "tasks": ["knock", "point_2um"], "seeds": 3}
    summ = run_benchmark(["closed_loop", "scan_pid"], **kw).summary()["held_out"]
    got = paired_against(summ, "closed_loop", "scan_pid")
    means = {c: np.mean([summ[t]["controllers"][c]["success"]["mean"] for t in summ])
             for c in ("closed_loop", "scan_pid")}  # fmt: skip
    assert got["success"] == pytest.approx(means["closed_loop"] - means["scan_pid"])
    assert got["success"] > 0.5  # the scan PID alone cannot step: it fails both tasks
    want = [
        (t, m)
        for t in summ
        for m, d in summ[t]["paired"]["closed_loop - scan_pid"].items()
        if d["separated"] and m in ("success", "settle_time_s", "tracking_rms_nm", "runaway_um")
    ]
    listed = [tuple(x.split(" ")[:2]) for x in got["separated"]]  # "task: metric diff"
    assert want and listed == [(f"{t}:", m) for t, m in want]


@pytest.mark.parametrize(  # one local Ray instance at a time (xdist: one worker for "ray")
    "backend",  # slow: two worker processes import the stack (10 s of CPU), Ray its own
    [pytest.param("processes", marks=pytest.mark.slow),
     pytest.param("ray", marks=[pytest.mark.slow, pytest.mark.xdist_group("ray")])],
)
def test_cells_as_tasks_equal_the_serial_run(backend):
    """The sweep over cells as processes (or Ray tasks) gives the serial run's episodes,
    run-time registrations included: a cell depends only on the suite seed and the cell."""
    if backend == "ray":
        pytest.importorskip("ray")
    # registered at run time (as --agent does), not by a plugin
    register("scan_pid_again", functools.partial(make, "scan_pid"), "test", overwrite=True)
    kw = {"plant_sets": ["nominal", "held_out"], "tasks": ["knock"], "seeds": 2}
    names = ["feedforward", "scan_pid_again"]
    try:
        serial = run_benchmark(names, **kw)
        tasks = run_benchmark(names, backend=backend, workers=2, **kw)
    finally:
        unregister("scan_pid_again")
    assert [(c.plant_set, c.task, c.controller) for c in tasks.cells] == [
        (c.plant_set, c.task, c.controller) for c in serial.cells
    ]
    for a, b in zip(serial.cells, tasks.cells, strict=True):
        for m, v in a.metrics.items():
            np.testing.assert_array_equal(v, b.metrics[m], err_msg=m)
    assert set(tasks.settings["cell_wall_s"]) == {"nominal/knock", "held_out/knock"}


# --- metrics ------------------------------------------------------------------------------
def test_metric_definitions_on_a_hand_made_episode():
    t = np.arange(8) * 0.1
    # errors at R [nm]: 1000, 400, 20, -50, 10, 5, 0, 0 (target 0, approach from above)
    err_nm = np.array([1000.0, 400.0, 20.0, -50.0, 10.0, 5.0, 0.0, 0.0])
    angle = (err_nm * 1e-9 / R)[None, :]
    ref = np.zeros_like(angle)
    steps = np.array([[0, 3, 1, 0, 0, 0, 0, 0]])
    energy = np.array([[0.0, 2e-3, 1e-3, 0, 0, 0, 0, 0]])
    m = episode_metrics(
        t, angle, ref, steps, energy, radius=R, noise_floor=np.array([2e-9]), hold=0.25
    )
    assert m["time_to_band_s"][0] == pytest.approx(0.2)  # 20 nm ≤ 30 nm band at sample 2
    assert m["settle_time_s"][0] == pytest.approx(0.4)  # −50 nm at 0.3 s, inside after
    # the approach is downwards: 50 nm below the target is the overshoot
    assert m["overshoot_nm"][0] == pytest.approx(50.0)
    assert m["runaway_um"][0] == 0.0  # never farther from the target than at the start
    assert m["success"][0] == 1.0
    hold = np.sqrt(np.mean(np.array([5.0, 0.0, 0.0]) ** 2))  # last 0.25 s: samples 5–7
    assert m["hold_rms_nm"][0] == pytest.approx(hold)
    assert m["hold_rms_rel"][0] == pytest.approx(hold / 2.0)
    assert m["slips_per_um"][0] == pytest.approx(4 / 1.0)  # 4 periods over 1 µm
    assert m["energy_per_um_mJ"][0] == pytest.approx(3.0)
    # never inside: both times censored at the window, no success
    far = episode_metrics(t, angle + 1e-5, ref, steps, energy, radius=R,
                          noise_floor=np.array([2e-9]))  # fmt: skip
    assert far["time_to_band_s"][0] == far["settle_time_s"][0] == pytest.approx(0.7)
    assert far["success"][0] == 0.0
    # a table that runs 60 µm away from a target 1 µm off: 59 µm beyond its start's distance
    away = np.array([[1.0, 5.0, 20.0, 60.0, 60.0, 60.0, 60.0, 60.0]]) * 1e-6 / R
    run = episode_metrics(t, away, ref, steps, energy, radius=R, noise_floor=np.array([2e-9]))
    assert run["runaway_um"][0] == pytest.approx(59.0)


def test_times_count_from_the_event():
    t = np.arange(6) * 0.1
    err = np.array([0.0, 0.0, 500.0, 100.0, 0.0, 0.0]) * 1e-9 / R  # a knock at sample 2
    m = episode_metrics(t, err[None], np.zeros((1, 6)), np.zeros((1, 6)), np.zeros((1, 6)),
                        radius=R, noise_floor=np.ones(1) * 1e-9, event=2)  # fmt: skip
    assert m["time_to_band_s"][0] == pytest.approx(0.2)  # inside again at sample 4
    assert m["settle_time_s"][0] == pytest.approx(0.2)


def test_paired_difference_and_interval_contracts():
    a = np.linspace(0.0, 1.0, 20)
    d = paired_difference(a, a + 1.0)  # every pair differs by exactly −1
    assert d["mean"] == pytest.approx(-1.0) and d["ci_low"] == d["ci_high"] == pytest.approx(-1.0)
    assert d["separated"]
    assert not paired_difference(a, a[::-1])["separated"]  # symmetric: mean 0


def test_bootstrap_interval_covers_the_mean_about_95_percent_of_the_time():
    rng = np.random.default_rng(1)
    hits = 0
    n = 200
    for i in range(n):
        ci = mean_ci(rng.normal(3.0, 2.0, size=20), seed=i)
        hits += ci["ci_low"] <= 3.0 <= ci["ci_high"]
    assert 0.86 <= hits / n <= 0.99  # BCa at n = 20 under-covers slightly


# --- tasks and plant sets -----------------------------------------------------------------
@pytest.mark.parametrize("name", list(TASKS))
def test_every_task_needs_stepping_and_stays_in_the_workspace(name):
    task = TASKS[name]
    scan_range_m = 1.47e-6  # K·u_max at R for the real turntable (test_controllers)
    for seed in range(6):
        spec = task.episode(seed, DET, 2026)
        ref = spec.reference
        assert ref.size == task.horizon + 1
        assert np.abs(ref).max() <= DET.angle_range  # commanded targets are readable
        travel = abs(ref[0] - spec.start) + np.abs(np.diff(ref)).sum()
        knock = abs(spec.knock[1]) if spec.knock else 0.0
        assert max(travel, knock) * R > scan_range_m  # beyond the scan: needs steps
        if spec.brief.start_estimate_rad is not None:  # dead reckoning within ±30 %
            move, est = (
                spec.brief.target_rad - spec.start,
                spec.brief.target_rad - spec.brief.start_estimate_rad,
            )
            assert abs(est / move - 1.0) <= 0.3 + 1e-12
        same = task.episode(seed, DET, 2026)  # the same episode for every controller
        np.testing.assert_array_equal(same.reference, ref)


def test_held_out_plants_lie_outside_the_training_ranges_and_carry_an_effect():
    for key in ("sac", "ppo"):
        hp = yaml.safe_load((HYPERPARAMS_DIR / f"{key}.yml").read_text(encoding="utf-8"))
        for entry in hp.values():  # every env id the agents train on
            rnd = entry["env_kwargs"]["randomize"]
            assert {k: tuple(v) for k, v in rnd.items() if k in TRAIN_RANGES} == TRAIN_RANGES
    ps = PLANT_SETS["held_out"]()
    effects = set()
    for seed in range(16):
        plant, draw = ps.plant(seed, 2026)
        for key, (lo, hi) in TRAIN_RANGES.items():
            assert not lo <= draw[key] <= hi, (key, draw[key])
            bands = HELD_OUT_RANGES[key]
            assert any(b[0] <= draw[key] <= b[1] for b in bands)
        assert len(plant.effects) == 1
        effects |= set(plant.effects)
    assert len(effects) == 8


# --- the whole run --------------------------------------------------------------------------
def test_quick_benchmark_output_holds_intervals_tracking_and_held_out(tmp_path):
    res = run_benchmark(["closed_loop", "scan_pid"], **QUICK)
    paths = write_outputs(res, tmp_path)
    doc = json.loads(paths["json"].read_text())
    assert doc["version"] and doc["settings"]["seeds"] == QUICK["seeds"]
    assert doc["provenance"]["code"]["package"] == turntable_env.__version__  # where it ran
    assert {"nominal", "held_out"} <= set(doc["results"])
    kinds = {doc["settings"]["tasks"][t]["kind"] for t in doc["results"]["held_out"]}
    assert {"point", "tracking", "disturbance"} <= kinds
    entry = doc["results"]["held_out"]["scan_ramp"]
    for name in ("closed_loop", "scan_pid"):
        v = entry["controllers"][name]["tracking_rms_nm"]
        assert v["ci_low"] <= v["mean"] <= v["ci_high"]
    # the scan PID alone cannot follow an 8 µm scan (its range is ±1.47 µm): stepping can
    diff = entry["paired"]["closed_loop - scan_pid"]["tracking_rms_nm"]
    assert diff["ci_high"] < 0.0 and diff["separated"]
    assert doc["settings"]["band_m"] == BAND
    for key in ("episodes", "leaderboard_md", "leaderboard_html", "trajectories_held_out"):
        assert paths[key].stat().st_size > 0
    assert "<table>" in paths["leaderboard_html"].read_text()


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"plant_sets": ["lunar"]}, "plant_sets"),
        ({"tasks": ["moonwalk"]}, "tasks"),
        ({"seeds": 1}, "seeds"),
        ({"controllers": ["pid9000"]}, "controllers"),
        ({"backend": "slurm"}, "backend"),
        ({"backend": "processes", "address": "auto"}, "address"),
        ({"backend": "processes", "workers": 0}, "workers"),
    ],
)
def test_bad_arguments_are_refused_before_any_work(kw, match):
    names = kw.pop("controllers", ["scan_pid"])
    with pytest.raises(ValueError, match=match):
        run_benchmark(names, **kw)


@pytest.mark.slow
def test_full_benchmark_separates_the_controllers_tied_before():
    """fuzzy, closed_loop and feedforward all scored 100 % in the old benchmark; on the
    nominal and held-out plants with 20 paired seeds each pair differs somewhere."""
    res = run_benchmark(["feedforward", "fuzzy", "closed_loop"],
                        plant_sets=["nominal", "held_out"], seeds=20)  # fmt: skip
    sep = res.separations()
    for pair in ("feedforward - fuzzy", "feedforward - closed_loop", "fuzzy - closed_loop"):
        assert sum(sep[pair].values()) > 0, pair
    assert math.isfinite(res.settings["wall_s"])


@pytest.mark.slow
def test_step_controllers_meet_the_calibrated_plant_without_running_away():
    """Issue 32: on the thesis calibration's plant (steps 1.2–5× the nominal map, a
    detector reading 0.82 of the table angle) every step controller built on the nominal
    map succeeds in ≥ 90 % of the episodes, the best in ≥ 95 %, and none runs the table
    away by more than the benchmark's bound."""
    from controllers.metrics import RUNAWAY_LIMIT

    res = run_benchmark(["feedforward", "fuzzy", "closed_loop"], plant_sets=["calibrated"],
                        seeds=20)  # fmt: skip
    df = res.to_pandas()
    success = df.groupby("controller")["success"].mean()
    assert success.min() >= 0.9, success.to_dict()
    assert success.max() >= 0.95, success.to_dict()
    assert df["runaway_um"].max() <= RUNAWAY_LIMIT * 1e6


@pytest.mark.slow
@pytest.mark.parametrize("suite_seed", [2026, 1, 2, 3])
def test_step_controllers_do_not_run_away_on_held_out_draws(suite_seed, monkeypatch):
    """Issue 32: no run-away beyond the bound in any cell, on the committed draw of the
    held-out plants and on three others, on the per-axis model the blind set was surveyed
    on. Draw 1's seed 5 steps backwards at 2 kHz beyond the detector, where the map
    controllers used to step blind (59.9 µm at stop 43); they now step blind only with the
    settings a plant survey found direction-robust (controllers/blind.py), and their
    largest run-away is 14.8 µm over the four draws."""
    from controllers import plant_sets
    from controllers.metrics import RUNAWAY_LIMIT

    monkeypatch.setattr(plant_sets, "FIDELITY", "reduced")  # the sets read it when built
    res = run_benchmark(["feedforward", "fuzzy", "closed_loop"], plant_sets=["held_out"],
                        seeds=20, suite_seed=suite_seed)  # fmt: skip
    df = res.to_pandas()
    assert df["runaway_um"].max() <= RUNAWAY_LIMIT * 1e6, df.nlargest(3, "runaway_um")


@pytest.mark.slow
def test_step_controllers_do_not_run_away_on_the_default_models_held_out_moves():
    """Issue 32's bound on the benchmark's own held-out set (the env's default model),
    the moves from beyond the detector. A known failure from stop 95 to stop 100 (a strict
    xfail): held-out seed 18 (friction asymmetry 0.24) stepped backwards with the first
    blind set's 6 V at 1 kHz (experiments/held_out_directions.py); the asymmetry-robust
    default (controllers/blind.py) keeps its direction there."""
    from controllers.metrics import RUNAWAY_LIMIT

    res = run_benchmark(["feedforward", "fuzzy", "closed_loop"], plant_sets=["held_out"],
                        tasks=["point_50um", "point_200um"], seeds=20)  # fmt: skip
    df = res.to_pandas()
    assert df["runaway_um"].max() <= RUNAWAY_LIMIT * 1e6, df.nlargest(3, "runaway_um")


def test_the_3d_and_independent_sets_run_every_task_with_fewer_seeds():
    """Issue 32: the 3-D and the independent plant sets meet every task, at most
    FULL_3D_SEEDS and INDEPENDENT_SEEDS seeds a cell; both are in the default run."""
    from controllers.benchmark import DEFAULT_PLANT_SETS, FULL_3D_SEEDS, INDEPENDENT_SEEDS, _seeds

    assert _seeds("full_3d", 20) == FULL_3D_SEEDS < 20 and _seeds("calibrated", 20) == 20
    assert _seeds("independent", 20) == INDEPENDENT_SEEDS < 20
    assert {"full_3d", "independent"} <= set(DEFAULT_PLANT_SETS)
    assert PLANT_SETS["independent"]().base.fidelity == "independent"


def test_the_sets_a_lab_plant_stands_for_run_the_env_default_and_the_agents_trained_apart():
    """Issue 32: the controllers are judged on the env's default model (the per-axis model
    with the sphere's translation, within 5 % of the 3-D step over the bench's sweep), not
    on the faster per-axis form the agents were trained on; that form stays a named set
    outside the default run, and every training config says which form it trained on."""
    from controllers.benchmark import DEFAULT_PLANT_SETS
    from turntable_env.envs.config import DEFAULT_FIDELITY

    assert DEFAULT_FIDELITY == "translation"
    for name in ("nominal", "randomized", "held_out", "calibrated"):
        assert PLANT_SETS[name]().base.fidelity == DEFAULT_FIDELITY, name
    assert PLANT_SETS["calibrated_per_axis"]().base.fidelity == "reduced"
    assert "calibrated_per_axis" not in DEFAULT_PLANT_SETS
    assert PLANT_SETS["calibrated"]().base.replace(fidelity="reduced") == (
        PLANT_SETS["calibrated_per_axis"]().base
    )
    for path in sorted(HYPERPARAMS_DIR.glob("*.yml")):
        for entry, cfg in yaml.safe_load(path.read_text(encoding="utf-8")).items():
            kw = cfg.get("env_kwargs", {}) if isinstance(cfg, dict) else {}
            if "params" in kw:
                assert kw.get("fidelity") == "reduced", (path.name, entry)


def test_closed_loop_meets_the_held_out_back_and_forth_it_missed():
    """Held-out seeds 0 (piezo creep) and 1 (piezo hysteresis) of the back-and-forth task,
    which closed_loop missed at benchmark 2.4 (stop 96) by entering the last leg's band 2–3
    intervals late: −7 V's gain measured in one period at 100 Hz no longer bounds its
    500 Hz move (it passed the target), and the hand-over adds the offset the table did
    not follow after the last stepping in that direction (1.0–1.5 V there:
    ``python experiments/replay_episode.py closed_loop held_out back_forth 1``)."""
    res = run_benchmark(["closed_loop"], plant_sets=["held_out"], tasks=["back_forth"],
                        seeds=2)  # fmt: skip
    df = res.to_pandas()
    assert df["success"].tolist() == [1.0, 1.0], df[["seed", "success", "hold_rms_nm"]]

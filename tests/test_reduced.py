"""Reduced per-axis model, batched runs, the SciPy baseline and the bench's convergence rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from turntable_env.baseline import simulate_scipy
from turntable_env.bench import converge
from turntable_env.drive import Waveform
from turntable_env.params import real_parameters
from turntable_env.reduced import ReducedModel, simulate_batch, simulate_reduced
from turntable_env.simulation import simulate, stepping_drive


@pytest.fixture(scope="module")
def reduced_b() -> ReducedModel:
    return ReducedModel("real", "B")


@pytest.mark.parametrize("axis", ["A", "B", "C"])
def test_axis_parameters_follow_the_thesis_geometry(axis: str) -> None:
    ap = ReducedModel("real", axis).axis_params
    ps = real_parameters()
    # a half sphere about its centre: J = 2/5 m R² for every axis (Eq. C.8)
    assert ap.inertia == pytest.approx(0.4 * ps.table.mass * ps.table.radius**2, rel=1e-9)
    assert ap.lever == (ps.table.radius, ps.table.radius)
    assert axis not in ap.tubes
    # both driving tubes turn the table the same way, by the free travel of §3.3.2
    assert ap.tube_gain[0] == pytest.approx(ap.tube_gain[1], rel=1e-9) and ap.tube_gain[0] > 0


def test_reduced_model_rejects_axis_z() -> None:
    with pytest.raises(ValueError, match="axis='Z'"):
        ReducedModel("real", "Z")


def test_sticking_table_follows_the_tubes(reduced_b: ReducedModel) -> None:
    """Below breakaway the contacts stick: θ = g V / R_table, and a triangle leaves no step."""
    v_in = 0.02  # V input → 0.9 V on the tubes, far below breakaway
    w = Waveform(np.array([0.0, 5e-3, 10e-3, 15e-3]), np.array([0.0, v_in, 0.0, 0.0]))
    r = simulate_reduced("real", w, 15e-3, model=reduced_b, output_dt=1e-5)
    ap = reduced_b.axis_params
    i_top = np.argmin(abs(r.time - 5e-3))
    expected = ap.tube_gain[0] * v_in * 45.0 / ap.lever[0]
    assert r.angle_rad[i_top] == pytest.approx(expected, rel=0.02)
    assert abs(r.angle_rad[-1]) < 1e-2 * expected  # only the decaying table ring is left
    assert np.all(r.n_stick == 5)


def test_reduced_step_converges(reduced_b: ReducedModel) -> None:
    """The default steps against the step halved (the bench's converged-reference rule)."""
    drive, ps = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=2, a=0.95)
    fast = simulate_reduced(ps, drive, model=reduced_b).step_size
    half = ReducedModel(ps, "B", step_scale=0.5, model=reduced_b.full)
    ref = simulate_reduced(ps, drive, model=half).step_size
    assert abs(fast - ref) < 0.01 * ref


@pytest.mark.parametrize("amplifier", ["adapted", "ideal"])
def test_reduced_agrees_with_full_model_averaged_over_direction(amplifier: str) -> None:
    """Second-period step, averaged over both directions, within 8 % of the full model.

    The full model steps further backwards than forwards (225 vs 154 nm in the sweep table:
    stuck-contact pre-stress from 3-D motion the 1-D model lacks); the reduced model is
    symmetric and lies between.
    """
    full_steps, red_steps = [], []
    model = None
    for sign in (1.0, -1.0):
        drive, ps = stepping_drive(
            "real", amplitude=2.0 * sign, frequency=100.0, periods=2, a=0.95, amplifier=amplifier
        )
        model = model or ReducedModel(ps, "B")
        f = simulate(model.params, drive, axis="B", model=model.full, coarse_factor=0.5)
        f = f.steps[1]
        r = simulate_reduced(ps, drive, model=model).steps[1]
        assert math.copysign(1.0, f) == math.copysign(1.0, r) == sign
        full_steps.append(abs(f))
        red_steps.append(abs(r))
    assert np.mean(red_steps) == pytest.approx(np.mean(full_steps), rel=0.08)


def test_batch_equals_single_runs_bit_for_bit(reduced_b: ReducedModel) -> None:
    ps2 = real_parameters(overrides={"normal_force": 2.0})
    other = ReducedModel(ps2, "B")
    d1, _ = stepping_drive("real", amplitude=2.0, frequency=200.0, periods=3, a=0.95)
    d2, _ = stepping_drive("real", amplitude=-1.5, frequency=500.0, periods=4, a=0.9)
    d3, _ = stepping_drive("real", amplitude=3.0, frequency=100.0, periods=1, a=0.99)
    models = [reduced_b, other, reduced_b]
    drives = [d1, d2, d3]
    batch = simulate_batch(models, drives, 0.012, output_dt=1e-5)
    for m, d, rb in zip(models, drives, batch, strict=True):
        single = simulate_batch([m], [d], 0.012, output_dt=1e-5)[0]
        assert np.array_equal(single.angle_rad, rb.angle_rad)
        assert np.array_equal(single.n_stick, rb.n_stick)
    assert not np.array_equal(batch[0].angle_rad, batch[2].angle_rad)


def test_batch_validates_lengths(reduced_b: ReducedModel) -> None:
    d, _ = stepping_drive("real", periods=1)
    with pytest.raises(ValueError, match="models/drives"):
        simulate_batch([reduced_b, reduced_b], [d], 0.01)


def test_scipy_baseline_integrates_the_same_equations(reduced_b: ReducedModel) -> None:
    """solve_ivp on the reduced equations gives the first step within 5 % (its GMS switching
    is stateless, the kernel's event-located)."""
    drive, ps = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=1, a=0.95)
    t, th = simulate_scipy(reduced_b, drive, 0.011, rtol=1e-4)
    step_sp = (np.interp(0.01, t, th) - th[0]) * ps.table.radius
    step_red = simulate_reduced(ps, drive, 0.011, model=reduced_b).steps[0]
    assert step_sp == pytest.approx(step_red, rel=0.05)


def test_converge_halves_until_the_change_is_small() -> None:
    calls: list[float] = []

    def first_order(h: float) -> float:
        calls.append(h)
        return 1.0 + h

    value, hist = converge(first_order, 0.064, tol=1e-3)
    assert hist[-1][0] == pytest.approx(0.001)  # |Δ| = 0.001 < 1e-3 · 1.001 first there
    assert value == pytest.approx(1.001)
    assert calls == [h for h, _ in hist]


# --- the analytic all-stick step and the output setting (issue "Speed") -------------------
@pytest.mark.parametrize(
    ("amplifier", "amplitude"),
    [("ideal", 2.0), ("adapted", 2.0), ("adapted", -0.45), ("unadapted", 2.0), ("adapted", 4.4)],
)
def test_analytic_step_agrees_with_the_ladder(amplifier: str, amplitude: float) -> None:
    """Both propagators integrate the same linear system between transitions: the same
    transitions and steps (to 1 %, the bench's accuracy target), including the unadapted
    amplifier's ringing re-sticks that a sampled event search must not skip."""
    drive, ps = stepping_drive(
        "real", amplitude=amplitude, frequency=100.0, periods=3, a=0.95, amplifier=amplifier
    )
    full = ReducedModel(ps, "B").full
    steps = {}
    for analytic in (False, True):
        m = ReducedModel(ps, "B", model=full, analytic=analytic)
        r = simulate_reduced(ps, drive, 0.03, model=m, output_dt=1e-4)
        steps[analytic] = r.steps
        if analytic:
            assert r.info["analytic_evaluations"] > 0
    np.testing.assert_allclose(steps[True], steps[False], rtol=1e-2, atol=1e-12)


@pytest.mark.parametrize("analytic", [False, True])
@pytest.mark.parametrize(("amplifier", "amplitude"), [("adapted", 2.0), ("ideal", -2.0)])
def test_step_does_not_depend_on_the_output_setting(
    amplifier: str, amplitude: float, analytic: bool
) -> None:
    """Outputs are samples, not step bounds: recording every 1 µs or once per run gives the
    same steps (0.5 %) — the amplifier's lag transient is stepped short either way."""
    drive, ps = stepping_drive(
        "real", amplitude=amplitude, frequency=100.0, periods=3, a=0.95, amplifier=amplifier
    )
    m = ReducedModel(ps, "B", analytic=analytic)
    fine = simulate_reduced(ps, drive, 0.03, model=m, output_dt=1e-6)
    coarse = simulate_reduced(ps, drive, 0.03, model=m, output_dt=1e-4)
    np.testing.assert_allclose(coarse.steps, fine.steps, rtol=5e-3)
    # the records of the analytic step are the same solution the ladder lands on
    fi = np.interp(coarse.time, fine.time, fine.angle_rad)
    scale = np.max(np.abs(fine.angle_rad))
    assert np.max(np.abs(fi - coarse.angle_rad)) < 5e-3 * scale


@pytest.mark.parametrize(
    ("amplifier", "amplitude"), [("adapted", 2.0), ("ideal", -2.0), ("unadapted", 2.0)]
)
def test_a_resumed_rung_takes_fewer_steps_to_the_same_steps(
    amplifier: str, amplitude: float
) -> None:
    """``resume_rung``: a landing on an output time shortens only its own step. Recorded
    every 50 µs (a 20 kHz trace), the integrator takes fewer steps (each landing no longer
    restarts the rung from the shortened one) and steps the table as the default rule
    does, to 1 % (the bench's accuracy target), on every amplifier."""
    drive, ps = stepping_drive(
        "real", amplitude=amplitude, frequency=100.0, periods=3, a=0.95, amplifier=amplifier
    )
    full = ReducedModel(ps, "B").full
    runs = {
        resume: simulate_reduced(
            ps, drive, 0.03, output_dt=5e-5,
            model=ReducedModel(ps, "B", model=full, resume_rung=resume),
        )
        for resume in (False, True)
    }  # fmt: skip
    assert runs[True].info["steps"] < 0.8 * runs[False].info["steps"]
    np.testing.assert_allclose(runs[True].steps, runs[False].steps, rtol=1e-2)


def test_parallel_batch_is_bit_identical_to_serial_runs() -> None:
    """The prange batch (N > 1) equals N batches of one (the serial kernel) bit for bit."""
    cases = [
        ("adapted", 2.0, 100.0),
        ("unadapted", -2.0, 100.0),
        ("adapted", 0.45, 500.0),
        ("ideal", 4.0, 50.0),
    ]
    models, drives = [], []
    for amp, amplitude, freq in cases:
        d, ps = stepping_drive(
            "real", amplitude=amplitude, frequency=freq, periods=2, amplifier=amp
        )
        models.append(ReducedModel(ps, "B"))
        drives.append(d)
    together = simulate_batch(models, drives, 0.02, output_dt=1e-4)
    for m, d, r in zip(models, drives, together, strict=True):
        alone = simulate_batch([m], [d], 0.02, output_dt=1e-4)[0]
        np.testing.assert_array_equal(alone.angle_rad, r.angle_rad)
        np.testing.assert_array_equal(alone.friction, r.friction)


_ULP = 2.0**-52


@settings(max_examples=300, deadline=None)
@given(
    q=st.floats(1e-12, 1e-3),
    angle=st.floats(0.0, 2.0 * math.pi),
    ulps=st.integers(-6, 6),
    far=st.sampled_from([1.0, 1e-6, 0.5, 2.0, 1e6]),
)
def test_the_ringing_test_on_the_square_answers_as_abs(q, angle, ulps, far) -> None:
    """The ladder's ringing cap decides |c·z| > q on |c·z|² where that is clear by far more
    than rounding (reduced_kernel._exceeds, issue 31's speed): the same answer as abs(z) > q
    a few ulps either side of q, far from it, and for non-finite parts."""
    from turntable_env.reduced_kernel import _exceeds

    lo, hi = q * q * (1.0 - 1e-12), q * q * (1.0 + 1e-12)
    r = q * far * (1.0 + ulps * _ULP)
    z = complex(r * math.cos(angle), r * math.sin(angle))
    assert _exceeds(z, q, lo, hi) == (abs(z) > q)
    for bad in (complex(math.inf, 0.0), complex(math.nan, q), complex(0.0, -math.inf)):
        assert _exceeds(bad, q, lo, hi) == (abs(bad) > q)


def test_the_bodies_condense_as_the_sized_model_and_refuse_3d_dynamics() -> None:
    """A 3-D model built without sizing its preload spring (the reduced model's bodies,
    plant.models._bodies: a calibration builds one per evaluation) condenses onto every
    axis exactly as the sized model does — the sizing moves the spring, not the bodies —
    and refuses the 3-D dynamics it cannot serve (ValueError naming size_preload)."""
    from turntable_env.model import TurntableModel
    from turntable_env.reduced import AxisParameters

    ps = real_parameters()
    sized, bodies = TurntableModel(ps), TurntableModel(ps, size_preload=False)
    for axis in ("A", "B", "C"):
        assert AxisParameters.from_model(bodies, axis) == AxisParameters.from_model(sized, axis)
        assert bodies.output_capacitance(axis) == sized.output_capacitance(axis)
    for call in (lambda: bodies.kernel_arrays, bodies.static_equilibrium,
                 lambda: bodies.preload_force):  # fmt: skip
        with pytest.raises(ValueError, match="size_preload=False"):
            call()
    assert sized.preload_force > 0.0


@pytest.mark.parametrize("lag_ratio", [0.0, 0.5, 1.0])
def test_reduced_kernel_drives_the_amplifier_as_its_module_does(lag_ratio: float) -> None:
    """The kernel's amplifier (ramp steps, the analytic all-stick stretches where the output
    is linear in time) against :meth:`Amplifier.simulate` on the same input sampled at 10 ns:
    within 0.15 V of the 90 V swing over three adapted periods, with an output lag too."""
    from dataclasses import replace

    from turntable_env.plant.stepper import output_capacitance

    drive, ps = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=3, a=0.95)
    ps = replace(ps, amplifier=replace(ps.amplifier, lag_ratio=lag_ratio))
    red = simulate_reduced(ps, drive, output_dt=1e-6)
    c = output_capacitance(ps, "B")
    t = np.arange(0.0, red.time[-1], 1e-8)
    ref = ps.amplifier.simulate(t, drive.input_voltage(t, ps.amplifier, c), c).output
    assert np.max(np.abs(red.voltage - np.interp(red.time, t, ref))) < 0.15

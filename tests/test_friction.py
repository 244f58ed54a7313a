"""Friction library (§2.2, §3.3.2, §4.2.1): measured properties of every model."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from turntable_env.friction import (
    GMS,
    Breedveld,
    Classical,
    Dahl,
    ElastoPlastic,
    FrictionState,
    Karnopp,
    Leuven,
    LuGre,
    StribeckCurve,
    StribeckParams,
)
from turntable_env.friction.experiments import (
    drift_test,
    presliding_hysteresis,
    thesis_drift_models,
)

FN = 100.0  # N, Table D.2 normal force
ST = StribeckParams(mu_s=0.3, mu_c=0.05, v_s=0.8, delta=2.0, sigma2=0.0)
F_S, F_C = ST.mu_s * FN, ST.mu_c * FN


def test_stribeck_curve_limits_and_symmetry():
    v = np.array([1e-9, 0.8, 100.0])
    s = ST.curve(v, FN)
    assert s[0] == pytest.approx(F_S, rel=1e-9)  # break-away force at v → 0⁺
    assert s[1] == pytest.approx(F_C + (F_S - F_C) / math.e)  # at v = v_S, δ = 2
    assert s[2] == pytest.approx(F_C)
    assert np.allclose(ST.curve(-v, FN), -s)
    assert ST.curve(0.0, FN) == 0.0


@pytest.mark.parametrize("v", [-2.0, -0.3, -1e-3, 1e-3, 0.05, 0.3, 0.8, 2.0, 5.0])
def test_gms_steady_sliding_equals_stribeck(v):
    gms = GMS(stribeck=StribeckParams(0.3, 0.05, 0.8, 2.0, sigma2=3.0))
    # slide past the presliding distance (δ_max = 7.5 mm) five times over, and for 20 of the
    # slowest relaxation times of Eq. 2.25 (|s|/C ≤ F_s/C = 0.15 s)
    n = max(30000, math.ceil(5 * 7.5e-3 / abs(v) / 1e-4))
    r = gms.simulate_velocity(np.full(n, v), 1e-4, FN)
    expected = gms.stribeck.curve(v, FN) + 3.0 * v
    assert r.force[-1] == pytest.approx(float(expected), rel=1e-6)
    assert (r.flags[-1] == 0).all()  # every element slips in gross sliding


STEADY = [
    (StribeckCurve(ST), lambda v: ST.curve(v, FN)),
    (Classical(ST), lambda v: ST.curve(v, FN)),
    (Karnopp(ST), lambda v: ST.curve(v, FN)),
    (Breedveld(ST, v_preslip=1e-3), lambda v: F_C * np.sign(v)),
    (Dahl(ST, sigma0=1e4), lambda v: F_C * np.sign(v)),
    (LuGre(ST, sigma0=1e5, sigma1=50.0), lambda v: ST.curve(v, FN)),
    (ElastoPlastic(ST, sigma0=1e5, sigma1=50.0), lambda v: ST.curve(v, FN)),
    (Leuven(ST), lambda v: ST.curve(v, FN)),
    (GMS(ST), lambda v: ST.curve(v, FN)),
]


@pytest.mark.parametrize(("model", "expected"), STEADY, ids=[type(m).__name__ for m, _ in STEADY])
@pytest.mark.parametrize("v", [-0.4, 0.05, 0.9])
def test_every_model_slides_on_its_steady_curve(model, expected, v):
    r = model.simulate_velocity(np.full(40000, v), 5e-5, FN)
    assert r.force[-1] == pytest.approx(float(expected(v)), rel=1e-4)


def test_presliding_hysteresis_has_nonlocal_memory():
    """Fig. 2.9: closing an inner loop returns the force onto the outer curve."""
    coarse = presliding_hysteresis(steps_per_delta=200)
    fine = presliding_hysteresis(steps_per_delta=2000)
    f_st = fine.force_scale
    assert fine.inner_loop_slips  # the inner loop really moves asperities (not purely elastic)
    assert fine.hysteresis_width > 0.5 * f_st  # a genuine hysteresis loop
    assert fine.loop_closure_error < 1e-3 * f_st
    assert fine.outer_curve_error < 1e-3 * f_st
    # the residual is discretisation error: it shrinks with the step
    assert fine.outer_curve_error < 0.1 * coarse.outer_curve_error


def test_drift_breedveld_drifts_gms_does_not():
    """Fig. 2.10: oscillating force in stick after slip."""
    breedveld, gms = thesis_drift_models()
    b = drift_test(breedveld)
    g = drift_test(gms)
    print(f"\ndrift per cycle: Breedveld {b.drift_per_cycle:.3e} m, GMS {g.drift_per_cycle:.3e} m")
    # Breedveld creeps at v = F v_preslip / F_st in its preslip band: mean F = 0.4 F_c
    expected = 0.4 * F_C / F_S * 1e-3 * (1 / 5.0)
    assert b.drift_per_cycle == pytest.approx(expected, rel=0.02)
    assert abs(g.drift_per_cycle) < 1e-9  # m per cycle, GMS tolerance
    assert abs(g.drift_per_cycle) < 1e-4 * abs(b.drift_per_cycle)
    assert g.slip_displacement > 1e-3  # both really slipped first
    assert b.slip_displacement > 1e-3


velocity_steps = st.lists(
    st.floats(min_value=-1.0, max_value=1.0, allow_nan=False), min_size=2, max_size=12
)


@settings(max_examples=60, deadline=None)
@given(vs=velocity_steps, hold=st.integers(min_value=1, max_value=400))
def test_gms_is_passive(vs, hold):
    """∫F·v dt ≥ energy still stored ≥ 0 from rest, for any velocity history."""
    gms = GMS(stribeck=StribeckParams(0.3, 0.05, 0.8, 2.0, sigma2=0.5))
    v = np.repeat(np.asarray(vs), hold)
    dt = 1e-4
    r = gms.simulate_velocity(v, dt, FN)
    work = float(np.sum(0.5 * (r.force[:-1] + r.force[1:]) * v * dt))  # trapezoid, matches Euler
    stored = gms.stored_energy(FrictionState(r.states[-1], r.flags[-1]))
    assert work >= stored - 1e-12 * (1 + abs(work))
    # a closed displacement cycle (there and back) dissipates
    closed = np.concatenate([v, -v[::-1]])
    rc = gms.simulate_velocity(closed, dt, FN)
    assert float(np.sum(0.5 * (rc.force[:-1] + rc.force[1:]) * closed * dt)) >= -1e-12


@pytest.mark.parametrize("angle", [0.0, 0.7, math.pi / 2, 2.5, -2.0])
def test_gms_2d_equals_1d_for_collinear_motion(angle):
    gms = GMS(stribeck=StribeckParams(0.3, 0.05, 0.8, 2.0, sigma2=1.0))
    rng = np.random.default_rng(3)
    v1 = np.repeat(rng.uniform(-0.05, 0.05, 20), 300)
    r1 = gms.simulate_velocity(v1, 1e-4, FN)
    u = np.array([math.cos(angle), math.sin(angle)])
    f2, _, stick2 = gms.simulate_velocity_2d(v1[:, None] * u[None, :], 1e-4, FN)
    assert np.allclose(f2, r1.force[:, None] * u[None, :], rtol=1e-9, atol=1e-9)
    assert np.array_equal(stick2, r1.flags)


@pytest.mark.parametrize("angle", [0.0, 0.7, math.pi / 2, 2.5, -2.0])
@pytest.mark.parametrize("stuck", [1, 0])
def test_planar_element_step_is_the_1d_step_for_collinear_motion(angle, stuck):
    """The translating reduced model's element step in its contact plane
    (``gms_element_step2``) is the per-axis one (``gms_element_step``) turned by the angle
    of a collinear motion: force, target and displacement along one direction. Loading
    along the force is capped at the element spring in both."""
    from turntable_env.friction.kernels import gms_element_step, gms_element_step2

    u = np.array([math.cos(angle), math.sin(angle)])
    for f, dx, target, decay in [(0.3, 2e-7, 0.8, 0.4), (0.3, 1e-9, 0.8, 0.1),
                                 (-0.5, -3e-8, -0.2, 0.7), (0.0, 1e-8, 0.5, 0.5)]:  # fmt: skip
        one = gms_element_step(f, stuck, 1e6, dx, target, decay)
        fx, fy = gms_element_step2(f * u[0], f * u[1], stuck, 1e6, dx * u[0], dx * u[1],
                                   target * u[0], target * u[1], decay)  # fmt: skip
        assert (fx, fy) == pytest.approx((one * u[0], one * u[1]), abs=1e-12)


def test_planar_element_turns_toward_the_sliding_direction():
    """A slipping element loaded across its sliding direction (force along x, sliding
    along y) relaxes toward ν s along y: its x part decays by the step's factor and its
    y part grows toward the target, where a per-direction law would keep the x load."""
    from turntable_env.friction.kernels import gms_element_step2

    fx, fy = gms_element_step2(0.4, 0.0, 0, 1e6, 0.0, 1e-6, 0.0, 0.5, 0.25)
    assert fx == pytest.approx(0.1)
    assert fy == pytest.approx(0.375)


def test_gms_2d_isotropic_sliding():
    """Circular sliding at constant speed: every slipping element tracks ν_i s(|v|) v̂ with
    time constant τ = |s|/C (Eq. 2.25 in the plane), so the total force is a first-order lag of
    a rotating vector: magnitude s/√(1+(ωτ)²), lagging the velocity by atan(ωτ)."""
    gms = GMS(ST)
    n, dt, speed = 40000, 1e-4, 0.3
    phi = np.linspace(0, 2 * np.pi, n)
    vel = speed * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    f, _, _ = gms.simulate_velocity_2d(vel, dt, FN)
    s = float(ST.curve(speed, FN))
    omega = (phi[1] - phi[0]) / dt
    wt = omega * s / gms.C
    mag = np.hypot(f[-1, 0], f[-1, 1])
    assert mag == pytest.approx(s / math.sqrt(1 + wt**2), rel=2e-3)
    lag = math.atan2(vel[-1, 0] * f[-1, 1] - vel[-1, 1] * f[-1, 0], vel[-1] @ f[-1])
    assert -lag == pytest.approx(math.atan(wt), rel=2e-2)


def test_gms_rules_section_4_2_1():
    g = GMS.from_rules(ST, FN, n_elements=5, presliding_distance=1e-7, noise_level=2e-8, C=200.0)
    nu = np.asarray(g.nu)
    assert nu.sum() == pytest.approx(1.0)
    assert np.allclose(np.diff(nu), nu[0])  # equally spaced, starting at one step
    w = nu * F_S
    delta = w / np.asarray(g.k)
    assert np.allclose(delta, np.linspace(2e-8, 1e-7, 5))
    # very slow pulling past the presliding distance reaches F_st (all elements slip)
    r = g.simulate_velocity(np.full(3000, 1e-6), 1e-4, FN)
    assert r.force[-1] == pytest.approx(F_S, rel=1e-3)


def test_karnopp_holds_below_breakaway_and_slides_above():
    k = Karnopp(ST, dv=1e-4)
    hold = k.simulate_mass(np.full(10000, 0.8 * F_S), 1e-4, 1.0, FN)
    assert np.max(np.abs(hold.displacement)) == 0.0
    slide = k.simulate_mass(np.full(10000, 1.2 * F_S), 1e-4, 1.0, FN)
    assert slide.displacement[-1] > 0.1


def test_breedveld_slip_flag_eq_2_17():
    b = Breedveld(ST, v_preslip=1e-3)
    s = b.initial_state()
    b.update(s, 2e-3, FN)
    assert s.flags[0] == 1  # |v| > v_preslip → slip
    b.update(s, 0.5e-3, FN)
    assert s.flags[0] == 1  # in between: unchanged
    assert b.force(s, 0.5e-3, FN) == pytest.approx(F_C)  # slipping: Coulomb
    b.update(s, 0.05e-3, FN)
    assert s.flags[0] == 0  # |v| < 0.1 v_preslip → stick
    assert b.force(s, 0.5e-3, FN) == pytest.approx(F_S * 0.5)  # preslip branch F_st v / v_pre


def test_elastoplastic_has_no_presliding_drift_lugre_does():
    """Eq. 2.21–2.22: below z_ba the elasto-plastic model is a pure spring (no drift)."""
    force = 0.3 * F_C + 0.2 * F_C * np.sin(2 * np.pi * 5 * np.arange(0, 2, 1e-5))
    lugre = LuGre(ST, sigma0=1e5, sigma1=0.0).simulate_mass(force, 1e-5, 1.0, FN)
    ep = ElastoPlastic(ST, sigma0=1e5, sigma1=0.0, z_ba_ratio=0.9).simulate_mass(
        force, 1e-5, 1.0, FN
    )
    per = 20000  # one 5 Hz cycle

    def drift(r):
        m = r.displacement[-4 * per :].reshape(4, per).mean(axis=1)
        return (m[-1] - m[0]) / 3

    assert abs(drift(ep)) < 1e-3 * abs(drift(lugre))
    assert drift(lugre) > 0


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: StribeckParams(mu_s=-0.1), "mu_s"),
        (lambda: StribeckParams(mu_s=0.1, mu_c=0.2), "mu_c"),
        (lambda: StribeckParams(v_s=0.0), "v_s"),
        (lambda: StribeckParams(sigma2=float("nan")), "sigma2"),
        (lambda: GMS(nu=(0.5, 0.4)), "nu"),
        (lambda: GMS(nu=(0.5, 0.5), k=(1.0, -1.0)), "k"),
        (lambda: GMS(nu=(0.5, 0.5), k=(1.0,)), "k"),
        (lambda: GMS(C=0.0), "C"),
        (lambda: Breedveld(v_preslip=-1.0), "v_preslip"),
        (lambda: ElastoPlastic(z_ba_ratio=1.5), "z_ba_ratio"),
        (lambda: Leuven(nu=(1.0,), k=(float("inf"),)), "k"),
        (lambda: GMS.from_rules(ST, FN, 0, 1e-7, 1e-8, 200.0), "n_elements"),
        (lambda: GMS.from_rules(ST, FN, 5, 1e-8, 1e-7, 200.0), "noise_level"),
        (lambda: GMS().simulate_velocity(np.array([0.1, np.nan]), 1e-4, FN), "velocity"),
        (lambda: GMS().simulate_velocity(np.array([0.1]), -1e-4, FN), "dt"),
        (lambda: GMS().simulate_velocity(np.array([0.1]), 1e-4, 0.0), "normal_force"),
        (lambda: GMS().simulate_mass(np.array([1.0]), 1e-4, -1.0, FN), "mass"),
        (lambda: GMS().simulate_velocity_2d(np.zeros((3, 3)), 1e-4, FN), "velocity"),
    ],
)
def test_friction_rejects_bad_input(factory, field):
    with pytest.raises(ValueError, match=field):
        factory()

"""SE(3) helpers (§3.2.1), the spatial tube spring (§3.2), Hertz–Mindlin contact (§3.3)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from turntable_env.contact import ContactParams, ElasticMaterial, HertzContact
from turntable_env.params import load_unlisted, real_parameters
from turntable_env.screw import adjoint, exp_so3, homogeneous, log_so3, merge_stiffness
from turntable_env.tube import TubeParams

vec3 = st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3).map(np.array)


@settings(max_examples=50, deadline=None)
@given(vec3)
def test_exp_log_roundtrip(w):
    r = exp_so3(w)
    assert np.allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(log_so3(r), w, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(vec3, vec3, vec3, vec3)
def test_adjoint_composes_and_power_is_frame_invariant(w1, p1, w2, p2):
    h1 = homogeneous(exp_so3(w1), p1)
    h2 = homogeneous(exp_so3(w2), p2)
    assert np.allclose(adjoint(h1 @ h2), adjoint(h1) @ adjoint(h2), atol=1e-9)
    rng = np.random.default_rng(0)
    twist_a, wrench_b = rng.normal(size=6), rng.normal(size=6)
    twist_b = adjoint(h1) @ twist_a
    wrench_a = adjoint(h1).T @ wrench_b
    assert wrench_b @ twist_b == pytest.approx(wrench_a @ twist_a, rel=1e-9, abs=1e-12)


def test_merging_offset_axial_springs_gives_parallel_axis_bending():
    """Eq. 3.18: two axial springs k at ±y add k·2y² of bending stiffness about x."""
    k, y = 1e6, 0.01
    kq = np.diag([0, 0, 0, 0, 0, k]).astype(float)
    hs = [homogeneous(np.eye(3), np.array([0.0, -s * y, 0.0])) for s in (1, -1)]
    kk = merge_stiffness([kq, kq], hs)
    assert kk[0, 0] == pytest.approx(2 * k * y * y)
    assert kk[5, 5] == pytest.approx(2 * k)
    assert np.allclose(kk, kk.T)


def test_merge_rejects_bad_input():
    with pytest.raises(ValueError, match="stiffnesses"):
        merge_stiffness([np.eye(6)], [])
    with pytest.raises(ValueError, match="rotation"):
        homogeneous(np.ones((3, 3)), np.zeros(3))


# --- the tube as a variable spatial spring ---------------------------------------------
def test_merged_quadrant_springs_equal_centre_stiffness():
    t = TubeParams()
    assert np.allclose(t.spring_stiffness, t.centre_stiffness, rtol=1e-12)


def _tip_stiffness(t: TubeParams) -> np.ndarray:
    """Spring seen at the tube top (Aᵀ K A with the top → centre offset)."""
    r = np.array([0.0, 0.0, -t.stiffness_centre_offset])
    a = np.eye(6)
    a[3:, :3] = -np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    return a.T @ t.spring_stiffness @ a


def test_centre_spring_reproduces_app_b_tip_stiffness():
    """A lateral force at the top meets K_x = 3EI/L³ (Eq. B.6, Table D.1 2.471e7 N/m)."""
    t = TubeParams()
    compliance = np.linalg.inv(_tip_stiffness(t))
    k_tip = 1.0 / np.diag(compliance)  # stiffness against a single force or moment
    assert k_tip[3] == pytest.approx(2.471e7, rel=1e-3)
    assert k_tip[5] == pytest.approx(7.728e7, rel=1e-3)
    assert k_tip[2] == pytest.approx(253.6, rel=1e-3)


@pytest.mark.parametrize("volts", [10.0, 90.0, -150.0])
def test_rest_twist_bends_free_tip_like_eq_2_11(volts):
    """Free tube (no load): tip deflection L²/(2R_bending), tip angle L/R_bending."""
    t = TubeParams()
    g = t.rest_twist_per_volt[:, 0] * volts  # quadrant 0 bends towards +x
    r = np.array([0.0, 0.0, -t.stiffness_centre_offset])
    theta = g[:3]
    u_top = g[3:] + np.cross(r, theta)  # the top point follows the rest frame
    q = t.quadrant
    assert u_top[0] == pytest.approx(q.tip_deflection(volts), rel=1e-9)
    assert np.linalg.norm(theta) == pytest.approx(abs(q.tip_angle(volts)), rel=1e-9)
    assert u_top[2] == pytest.approx(0.25 * q.free_elongation(volts), rel=1e-9)


def test_blocked_capacitance_is_passive_and_below_free():
    t = TubeParams()
    cs = t.blocked_capacitance_matrix
    assert np.allclose(cs, cs.T)
    assert np.linalg.eigvalsh(cs).min() > 0.0
    assert np.all(np.diag(cs) < t.quadrant.capacitance)


def test_damping_coefficient_gives_quality_factor_at_first_mode():
    t = TubeParams(quality_factor=100.0)
    zeta = 0.5 * t.damping_coefficient * t.first_bending_frequency
    assert zeta == pytest.approx(1.0 / (2 * 100.0))
    assert TubeParams().damping_coefficient == 0.0


# --- Hertz–Mindlin ------------------------------------------------------------------
@pytest.fixture
def hertz():
    steel = ElasticMaterial("steel", 200e9, 0.3)
    alumina = ElasticMaterial("alumina", 370e9, 0.22)
    return HertzContact(3.175e-3, alumina, 0.01, steel)


@pytest.mark.parametrize("force", [0.1, 1.0, 2.0, 10.0])
def test_hertz_force_law_and_stiffness(hertz, force):
    d = hertz.approach(force)
    assert hertz.hertz_constant * d**1.5 == pytest.approx(force, rel=1e-12)
    # tangent stiffness dF/dδ = 1.5 K_H δ^0.5 = 2E*a
    tangent = 1.5 * hertz.hertz_constant * d**0.5
    assert tangent == pytest.approx(hertz.normal_stiffness(force), rel=1e-12)
    # Mindlin: full slip at 1.5× the linear extrapolation of the initial stiffness
    mu = 0.3
    assert hertz.slip_displacement(force, mu) == pytest.approx(
        1.5 * mu * force / hertz.tangential_stiffness(force), rel=1e-12
    )


def test_real_gms_matches_mindlin_within_rules():
    """§4.2.1 rules on Mindlin's slip distance: Σk_i = 2n/(n+1)·F_st/δ, vs Mindlin's 1.5·F_st/δ."""
    ps = real_parameters()
    u = ps.unlisted
    fst = u.mu_static * u.normal_force
    hz = HertzContact(ps.tube.outer_radius, u.ball_material, ps.table.radius, u.table_material)
    delta = hz.slip_displacement(u.normal_force, u.mu_static)
    n = len(ps.friction.k)
    assert sum(ps.friction.k) == pytest.approx(2 * n / (n + 1) * fst / delta, rel=1e-12)
    assert sum(ps.friction.k) / hz.tangential_stiffness(u.normal_force) == pytest.approx(
        (2 * n / (n + 1)) / 1.5, rel=1e-12
    )
    assert 0.05e-6 < delta < 0.3e-6  # the presliding distance is of order 0.1 µm


def test_contact_params_validation_and_preload():
    with pytest.raises(ValueError, match="normal_exponent"):
        ContactParams(normal_exponent=3.0)
    with pytest.raises(ValueError, match="tangential_damping"):
        ContactParams(tangential_damping=-1.0)
    c = ContactParams(preload=1.0)
    assert c.preload_spring_force(0.1, 1 / math.sqrt(3)) == pytest.approx(math.sqrt(3) - 0.1)
    with pytest.raises(ValueError, match="preload"):
        c.preload_spring_force(10.0, 1 / math.sqrt(3))


# --- the unlisted-parameter file ------------------------------------------------------
def _write(tmp_path, text):
    p = tmp_path / "u.toml"
    p.write_text(text, encoding="utf-8")
    return p


def _good_text():
    from turntable_env.params import UNLISTED_FILE

    return UNLISTED_FILE.read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda s: s.replace('unit = "Pa"', 'unit = "GPa"', 1), "table_youngs_modulus.*unit"),
        (lambda s: s.replace("value = 0.3\n", 'value = "x"\n', 1), "mu_static.*value"),
        (lambda s: s + '\n[warp_drive]\nvalue = 1\nunit = "-"\nsource = "x"\n', "warp_drive"),
        (lambda s: s.replace("[viscous]", "[viscous_gone]"), "viscous"),
        (lambda s: s.replace("value = 0.9\n", "value = 1.5\n"), "contact_restitution"),
        (lambda s: s.replace("[mu_static", "mu_static"), "cannot read"),
    ],
)
def test_unlisted_loader_names_file_and_entry(tmp_path, edit, match):
    p = _write(tmp_path, edit(_good_text()))
    with pytest.raises(ValueError, match=match) as exc:
        load_unlisted(p)
    assert str(p) in str(exc.value)


def test_unlisted_overrides_and_sources():
    u = load_unlisted(overrides={"normal_force": 3.0})
    assert u.normal_force == 3.0 and u.sources["normal_force"] == "override"
    assert all(u.sources[k] for k in u.sources)
    with pytest.raises(ValueError, match="nope"):
        load_unlisted(overrides={"nope": 1.0})

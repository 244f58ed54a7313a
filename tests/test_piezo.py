"""Piezo quadrant: the 2-port C element (Eq. 2.2–2.3, App. A) and bending (Eq. 2.10–2.12)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from turntable_env.piezo import PiezoMaterial, PiezoQuadrant

Q = PiezoQuadrant()
CASES = [(0.0, 1.0), (1.0, 0.0), (3.0, -90.0), (-50.0, 200.0), (0.2, 45.0)]  # (F [N], V [V])


def test_maxwell_reciprocity_matrix_symmetric():
    m = Q.compliance_matrix
    assert m[0, 1] == m[1, 0]  # ∂z/∂V = ∂q/∂F
    assert m[0, 1] == pytest.approx(-210e-12 * 6.35e-3 / 0.508e-3)


@pytest.mark.parametrize(("force", "voltage"), CASES)
def test_coenergy_gradient_is_displacement_and_charge(force, voltage):
    z, q = Q.displacement_charge(force, voltage)
    hf, hv = 1e-3, 1e-3
    dEdF = (Q.coenergy(force + hf, voltage) - Q.coenergy(force - hf, voltage)) / (2 * hf)
    dEdV = (Q.coenergy(force, voltage + hv) - Q.coenergy(force, voltage - hv)) / (2 * hv)
    assert dEdF == pytest.approx(z, rel=1e-6, abs=1e-22)
    assert dEdV == pytest.approx(q, rel=1e-6, abs=1e-22)


@pytest.mark.parametrize(("force", "voltage"), CASES)
def test_reciprocity_from_coenergy_mixed_derivatives(force, voltage):
    h = 0.5

    def z_of(v):
        return Q.displacement_charge(force, v)[0]

    def q_of(f):
        return Q.displacement_charge(f, voltage)[1]

    dz_dV = (z_of(voltage + h) - z_of(voltage - h)) / (2 * h)
    dq_dF = (q_of(force + h) - q_of(force - h)) / (2 * h)
    assert dz_dV == pytest.approx(dq_dF, rel=1e-9)


# efforts whose energy is representable (a subnormal voltage squares to zero)
finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).filter(
    lambda x: x == 0.0 or abs(x) > 1e-30
)


@given(force=finite, voltage=finite)
def test_stored_energy_positive_for_any_effort(force, voltage):
    e_star = Q.coenergy(force, voltage)
    if force == 0.0 and voltage == 0.0:
        assert e_star == 0.0
        return
    assert e_star > 0.0
    z, q = Q.displacement_charge(force, voltage)
    # Legendre transform (Eq. A.2): E(z, q) = Fz + Vq − E*; for a quadratic form E = E*
    assert Q.energy(z, q) == pytest.approx(e_star, rel=1e-6)


def test_inverse_constitutive_law_roundtrip():
    for f, v in CASES:
        z, q = Q.displacement_charge(f, v)
        f2, v2 = Q.force_voltage(z, q)
        assert f2 == pytest.approx(f, abs=1e-9)
        assert v2 == pytest.approx(v, abs=1e-9)


def test_coupling_and_capacitance():
    k2 = Q.material.coupling_k2
    assert 0.10 < k2 < 0.12  # PIC 151, k31 ≈ 0.33
    assert Q.capacitance == pytest.approx(
        2400 * 8.8541878128e-12 * math.pi * 5.842e-3 * 6.35e-3 / 4 / 0.508e-3
    )
    assert Q.blocked_capacitance == pytest.approx(Q.capacitance * (1 - k2))


def test_neutral_plane_eq_2_8():
    assert Q.neutral_plane_offset / Q.diameter == pytest.approx(0.555, abs=1e-3)


@pytest.mark.parametrize("voltage", [1.0, 45.0, -90.0, 200.0])
def test_asymmetric_bending_is_half_symmetric(voltage):
    assert Q.radius_of_curvature(voltage, "asymmetric") == pytest.approx(
        2 * Q.radius_of_curvature(voltage, "symmetric")
    )
    assert Q.tip_deflection(voltage, "asymmetric") == pytest.approx(
        0.5 * Q.tip_deflection(voltage, "symmetric")
    )
    # Eq. 2.11: Δy = 2√2 d31 V L²/(πDh) in the symmetric mode
    sym = 2 * math.sqrt(2) * 210e-12 * abs(voltage) * 6.35e-3**2 / (math.pi * 5.842e-3 * 0.508e-3)
    assert abs(Q.tip_deflection(voltage, "symmetric")) == pytest.approx(sym)


@pytest.mark.parametrize("voltage", [1.0, 90.0, -150.0])
def test_bending_lever_links_eq_2_2_and_2_12(voltage):
    # tip rotation from the radius of curvature equals quadrant elongation over the lever
    theta = abs(Q.tip_angle(voltage))
    assert theta == pytest.approx(abs(Q.free_elongation(voltage)) / Q.bending_lever, rel=1e-12)
    assert Q.bending_lever == pytest.approx(2 * Q.neutral_plane_offset)


def test_real_tube_deflection_at_90_volt():
    # the measured stepping input (2 V × 45) deflects a tube tip by about 0.12 µm
    assert Q.tip_deflection(90.0) == pytest.approx(1.156e-7, rel=2e-3)
    assert np.isinf(Q.radius_of_curvature(0.0)) and Q.tip_deflection(0.0) == 0.0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"d31": 0.0}, "d31"),
        ({"d31": float("nan")}, "d31"),
        ({"s33E": -1.0}, "s33E"),
        ({"eps11T_rel": 0.0}, "eps11T_rel"),
        ({"poisson": 0.7}, "poisson"),
        ({"d31": -1e-9}, "d31"),  # coupling ≥ 1: indefinite energy
    ],
)
def test_material_rejects_bad_input(kwargs, field):
    with pytest.raises(ValueError, match=field):
        PiezoMaterial(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"length": -1.0}, "length"),
        ({"outer_radius": float("inf")}, "outer_radius"),
        ({"inner_radius": 4e-3}, "inner_radius"),
        ({"diameter_convention": "inner"}, "diameter_convention"),
    ],
)
def test_quadrant_rejects_bad_input(kwargs, field):
    with pytest.raises(ValueError, match=field):
        PiezoQuadrant(**kwargs)


def test_efforts_must_be_finite():
    with pytest.raises(ValueError, match="voltage"):
        Q.coenergy(1.0, float("nan"))
    with pytest.raises(ValueError, match="mode"):
        Q.radius_of_curvature(1.0, "diagonal")  # type: ignore[arg-type]

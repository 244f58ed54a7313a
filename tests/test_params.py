"""Parameter sets reproduce Table D.1 and the derived quantities of App. B, C and §3.1."""

import dataclasses
import json
import math

import pytest

from turntable_env.cli import main
from turntable_env.geometry import TurntableGeometry, com_stability
from turntable_env.params import ContactParams, get_parameter_set, real_parameters
from turntable_env.table import TableParams
from turntable_env.tube import TubeParams, TubeStiffness

TABLE_D1 = [
    ("K_x", lambda p: p.tube.K_bending, 2.471e7),
    ("K_z", lambda p: p.tube.K_axial, 7.728e7),
    ("K_phi", lambda p: p.tube.K_torsion, 253.6),
    ("m_tube", lambda p: p.tube.mass, 9.954e-4),
    ("I_tube_xx", lambda p: p.tube.inertia[0], 1.500e-8),
    ("I_tube_yy", lambda p: p.tube.inertia[1], 1.500e-8),
    ("I_tube_zz", lambda p: p.tube.inertia[2], 6.121e-9),
    ("R_bending_V", lambda p: p.tube.quadrant.bending_radius_times_voltage, 1.570e4),
    ("E", lambda p: p.tube.material.youngs_modulus, 5.263e10),
    ("h", lambda p: p.tube.wall_thickness, 0.508e-3),
]


@pytest.mark.parametrize(("name", "getter", "table_value"), TABLE_D1, ids=[c[0] for c in TABLE_D1])
def test_table_d1_to_three_significant_figures(real, name, getter, table_value):
    # rounding both to 3 significant figures gives the same digits
    assert f"{getter(real):.2e}" == f"{table_value:.2e}"


def test_r_bending_needs_mean_diameter(real):
    mean = real.tube.quadrant.bending_radius_times_voltage
    outer = dataclasses.replace(
        real.tube, diameter_convention="outer"
    ).quadrant.bending_radius_times_voltage
    assert mean == pytest.approx(1.570e4, rel=1e-3)
    assert outer == pytest.approx(1.706e4, rel=1e-3)  # Eq. 2.12 with 2R_o does not match Table D.1


def test_table_mass_conventions():
    half = TableParams(radius=0.01, density=8e3)
    listed = TableParams(radius=0.01, density=8e3, mass_convention="table_D1")
    assert half.mass == pytest.approx(2 / 3 * math.pi * 1e-6 * 8e3)  # Eq. C.1
    assert half.mass == pytest.approx(0.01676, rel=1e-3)
    assert listed.mass == pytest.approx(0.0335, rel=1e-3)  # Table D.1 = full sphere
    assert listed.inertia == pytest.approx(1.340e-6, rel=1e-3)  # Table D.1 I_table
    assert half.inertia == pytest.approx(0.5 * listed.inertia)


def test_physical_parallel_axis_is_lower(real):
    phys = dataclasses.replace(real.tube, parallel_axis="physical")
    mc, L = real.tube.mass_cylinder, real.tube.length
    assert real.tube.inertia[0] - phys.inertia[0] == pytest.approx((7 / 12 - 1 / 3) * mc * L**2)
    assert phys.inertia[2] == real.tube.inertia[2]


def test_geometry_eq_3_1_to_3_3(real):
    g = real.geometry
    assert g.tube_dist == pytest.approx(math.sqrt(2) * 0.01)
    assert g.R_contact == pytest.approx(math.sqrt(2 / 3) * 0.01)  # §3.1
    assert math.degrees(g.alpha) == pytest.approx(35.264, abs=1e-3)
    # orthogonal tubes: the contact points are mutually sqrt(2) R apart and R from the centre
    assert g.contact_plane_depth**2 + g.R_contact**2 == pytest.approx(0.01**2)
    assert g.z_table == pytest.approx(g.R_contact * math.tan(g.alpha) + 6.35e-3 * math.sin(g.alpha))


def test_com_check_current_design_unstable(real):
    c = com_stability(real.table.radius)
    assert c.R_CoM == pytest.approx(math.sqrt(55 / 64) * 0.01)  # Eq. C.17
    assert c.R_contact == pytest.approx(math.sqrt(2 / 3) * 0.01)
    assert not c.stable and c.margin < 0  # §3.1: CoM above the contact plane


@pytest.mark.parametrize(
    ("depth_fraction", "stable"), [(0.375, False), (0.55, False), (0.60, True), (0.9, True)]
)
def test_com_check_flips_at_contact_plane(depth_fraction, stable):
    # contact plane is at R/sqrt(3) = 0.577 R below the centre
    assert com_stability(1.0, depth_fraction).stable is stable


def test_thesis_set_keeps_given_values_and_shows_formula(thesis):
    assert thesis.table.mass == 15.0
    assert thesis.tube.mass == 0.5
    assert thesis.tube.stiffness.translational == (1e5, 1e5, 1e5)
    # K_o,x/y: the listed 100 N*m/rad is printed; the beam value K_t L^2/3 is used
    assert thesis.tube.stiffness.rotational == pytest.approx((1e5 * 4 / 3, 1e5 * 4 / 3, 1e5))
    notes = {q.name: q.value for q in thesis.describe()}
    assert notes["thesis.K_o_xy_listed"] == 100.0
    assert notes["thesis.contact_lateral_stiffness_listed"] < 50.0  # N/m: could never slip
    # Table D.2's constant R_bending = 2 m is the Eq. 3.16 lever: the scaled tube gives 2.04 m
    assert thesis.tube.bending_lever == 2.0
    assert thesis.tube.quadrant.bending_lever == pytest.approx(2.0, rel=0.03)
    # the listed R_contact differs from Eq. 3.1
    assert thesis.contact.listed_contact_radius == 2.0
    assert thesis.geometry.R_contact == pytest.approx(2.572, rel=1e-3)
    assert thesis.friction is not None and sum(thesis.friction.nu) == pytest.approx(1.0)


def test_parameter_objects_are_immutable(real):
    with pytest.raises(dataclasses.FrozenInstanceError):
        real.tube.length = 1.0  # type: ignore[misc]


@pytest.mark.parametrize("name", ["real", "thesis"])
def test_cli_params_json_prints_full_set(capsys, name):
    assert main(["params", "--set", name, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["set"] == name
    params = data["parameters"]
    ps = get_parameter_set(name)
    assert set(params) == {q.name for q in ps.describe()}
    for key, entry in params.items():
        assert set(entry) == {"value", "unit", "kind", "source"}, key
        assert entry["kind"] in ("given", "derived")
        assert entry["unit"], key
    assert params["geometry.R_contact"]["value"] == pytest.approx(ps.geometry.R_contact)
    if name == "real":
        assert params["tube.K_x_eqB6"]["value"] == pytest.approx(2.471e7, rel=1e-3)
        assert params["geometry.com_stable"]["value"] is False


def test_cli_bad_set_is_rejected():
    with pytest.raises(SystemExit):
        main(["params", "--set", "imaginary"])
    with pytest.raises(ValueError, match="set='imaginary'"):
        get_parameter_set("imaginary")  # type: ignore[arg-type]


def test_geometry_validates():
    with pytest.raises(ValueError, match="table_radius"):
        TurntableGeometry(-1.0, 1.0)
    with pytest.raises(ValueError, match="inner_radius"):
        TubeParams(outer_radius=1e-3, inner_radius=2e-3)


@pytest.mark.parametrize(
    ("factory", "field"),
    [
        (lambda: TableParams(radius=0.0), "radius"),
        (lambda: TableParams(density=-8e3), "density"),
        (lambda: TableParams(density=None), "density"),
        (lambda: TableParams(mass_given=-1.0), "mass_given"),
        (lambda: TableParams(mass_convention="cube"), "mass_convention"),
        (lambda: TubeParams(length=float("nan")), "length"),
        (lambda: TubeParams(density=0.0), "density"),
        (lambda: TubeParams(mass_given=0.0), "mass_given"),
        (lambda: TubeParams(parallel_axis="diagonal"), "parallel_axis"),
        (lambda: TubeParams(bending_lever_given=-2.0), "bending_lever_given"),
        (lambda: TubeStiffness((1.0, -1.0, 1.0), (1.0, 1.0, 1.0)), "translational"),
        (lambda: ContactParams(preload=0.0), "preload"),
        (lambda: ContactParams(normal_damping=-1.0), "normal_damping"),
        (lambda: dataclasses.replace(real_parameters(), ramp_ratio=1.0), "ramp_ratio"),
        (lambda: com_stability(1.0, 1.5), "com_depth"),
    ],
)
def test_parameters_reject_bad_input(factory, field):
    with pytest.raises(ValueError, match=field):
        factory()

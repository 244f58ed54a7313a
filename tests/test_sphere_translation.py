"""The per-axis model with the sphere's translation (``experiments/sphere_translation.py``,
issue 32 item 1): a fixed-step prototype checked against the per-axis kernel it extends and
against the 3-D model it is derived from."""

from __future__ import annotations

import pytest
from conftest import experiment


@pytest.fixture(scope="module")
def script():
    return experiment("sphere_translation")


@pytest.mark.parametrize("amplitude", [90.0, -90.0])
def test_held_translation_is_the_per_axis_model(script, amplitude):
    """With the translation held the prototype is the per-axis model: its explicit fixed
    step and the kernel's exact ladder (turntable_env.reduced_kernel) give one step."""
    r = script.run(amplitude, 2000.0, 0.95, variant="frozen")
    assert r["prototype_nm"] == pytest.approx(r["per_axis_nm"], rel=0.005)
    assert r["ramp_end_normal_N"] == pytest.approx([2.5, 2.5])


def test_translation_carries_the_direction_asymmetry(script):
    """At ±90 V, 2 kHz, a = 0.95 the 3-D model steps 139 / 203 nm; the per-axis model steps
    164 nm both ways (18–19 % off). The translation, the normal forces and the axial stroke
    bring both directions within 7 %, and the normal force falls where the stroke pulls the
    balls away (positive channel volts) and rises the other way."""
    for amplitude in (90.0, -90.0):
        r = script.run(amplitude, 2000.0, 0.95)
        full = script.full_step(amplitude, 2000.0, 0.95)
        assert abs(r["per_axis_nm"] / full - 1.0) > 0.15
        assert r["prototype_nm"] == pytest.approx(full, rel=0.07)
        fn = r["ramp_end_normal_N"]
        assert all((f < 2.5) if amplitude > 0 else (f > 2.5) for f in fn)


def test_the_stroke_is_the_quadrant_drive(script):
    """The tubes' axial stroke per channel volt is the 3-D model's (0.656 nm/V, as
    experiments/axial_stroke.py prints), and the normal stiffness is the Hertz contact's at
    the preload, 1.5 F_N/δ_0, in series with the tube's axial stiffness."""
    from turntable_env.reduced import ReducedModel
    from turntable_env.simulation import stepping_drive

    _drive, ps = stepping_drive("real", amplitude=1.0, frequency=100.0, amplifier="adapted")
    d = script.build(ReducedModel(ps, "B"))["derived"]
    assert d["stroke_m_V"] == pytest.approx(0.65625e-9, rel=1e-6)
    series = 1.0 / (1.0 / d["k_hertz_N_m"] + 1.0 / d["k_axial_N_m"])
    assert d["k_n_N_m"] == pytest.approx(series)
    c = ps.contact
    delta0 = (c.preload / c.normal_stiffness) ** (1.0 / c.normal_exponent)
    assert d["k_hertz_N_m"] == pytest.approx(1.5 * c.preload / delta0)


@pytest.mark.parametrize("argv", [["--a", "1.2"], ["--amplitude", "-5"], ["--dt", "1e-6"]])
def test_bad_input_exits_2(script, argv, capsys):
    with pytest.raises(SystemExit) as exc:
        script.main(argv)
    assert exc.value.code == 2
    assert argv[0] in capsys.readouterr().err

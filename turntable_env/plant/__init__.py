"""One plant layer: the turntable every consumer runs — env, virtual lab, calibrator, benchmark.

A :class:`Plant` is what a laboratory would call "the turntable as we know it": a
parameter set (Table D.1, D.2 or a calibrated one) with multiplicative factors on its
uncertain values (friction, preload, amplifier), a fidelity (``"reduced"`` per-axis
model, ``"translation"`` the same with the sphere's translation and tilts and the contacts' normal
forces, ``"full"`` 3-D model, or ``"independent"``: the independent test plant,
:mod:`turntable_env.plant.independent`), the effects of the catalogue (:mod:`turntable_env.effects`)
with their parameters, the detector noise and the amplifier setting. It is immutable,
hashable and picklable; :meth:`Plant.from_report` reads the plant a calibration report
describes, :meth:`Plant.sample` draws a randomised one.

:class:`PlantStepper` runs N plants about one axis, together, and is the only way the
physics is run by the environment (:mod:`turntable_env.envs`), the calibrator and the
virtual lab (:mod:`turntable_env.calibration`) and the controller benchmark. The data
path runs one way; for the drive amplitude of an env action it is:

1. **action → config**: :class:`~turntable_env.envs.config.ActionScaling` turns the
   normalised action into a generator setting (amplitude u_A [V input], f, a, k, scan
   offset u_0);
2. **config → plant stepper**: :meth:`PlantStepper.advance` takes the N settings;
3. **generator** (compiled, :func:`~turntable_env.generator.generate_interval`): the
   free-running generator turns them into piecewise-linear amplifier inputs for the
   interval (Fig. 3.14 / Fig. 4.3 periods, the Fig. 4.3 hold from the amplifier, the scan
   offset ramp, the ±10 V input clip, the integration grid), the flybacks and the energy;
4. **input stage** (compiled, :func:`~turntable_env.effects.input_stage_nb`): the piezo's
   hysteresis and creep, where a plant has them;
5. **kernel**: the reduced integrator (:func:`~turntable_env.reduced_kernel.run_reduced_batch`,
   one compiled call for all N) or the 3-D one (:func:`~turntable_env.integrator.run_full_model`,
   one call per turntable) with the amplifier (§4.1.2), the tubes (Eq. 2.11), the GMS
   contacts (Eq. 2.24–2.26) and the table; friction-stage effects rescale μ between
   segments of ``FRICTION_SEGMENT``;
6. **output stage** (:meth:`PlantStepper.observe`): the detector (Eq. 4.1) with the
   output-stage effects, noise and saturation.

Nothing flows back up: the stepper never reads the env, the kernels never read the
stepper. Explicit drives (a measured trace) enter at step 4 (:meth:`PlantStepper.run_waveform`).

Which effects each fidelity supports: all of them. Parameter, input and output stages are
independent of the mechanics; the friction stage rescales μ_s and μ_c of the reduced
model's 1-D GMS, of the 3-D model's three 2-D GMS contacts or of the independent plant's
LuGre contacts.

Modules: :mod:`.value` (the :class:`Plant` value and the named sets it resolves),
:mod:`.store` (named plants as TOML files, reports read back), :mod:`.models` (the models
of a parameter set, cached), :mod:`.stepper` (:class:`PlantStepper` and its backends).
"""

from __future__ import annotations

from ..params import FACTORS
from .models import load_capacitance, output_capacitance, reduced_model, turntable_model
from .stepper import Backend, IntervalResult, PlantStepper, Records
from .store import CALIBRATED_FILE, NAMED_PLANTS, plant_toml
from .value import (
    DEFAULT_RANDOMIZATION,
    FIDELITIES,
    MAX_SENSOR_NOISE,
    PARAMETER_SETS,
    SENSOR_NOISE,
    Plant,
    as_plant,
    calibrated_parameters,
    parameter_set,
    set_or_plant,
)

__all__ = [
    "CALIBRATED_FILE",
    "DEFAULT_RANDOMIZATION",
    "FACTORS",
    "FIDELITIES",
    "MAX_SENSOR_NOISE",
    "NAMED_PLANTS",
    "PARAMETER_SETS",
    "SENSOR_NOISE",
    "Backend",
    "IntervalResult",
    "Plant",
    "PlantStepper",
    "Records",
    "as_plant",
    "calibrated_parameters",
    "calibrated_set_toml",
    "load_capacitance",
    "output_capacitance",
    "parameter_set",
    "plant_toml",
    "reduced_model",
    "set_or_plant",
    "turntable_model",
]


def calibrated_set_toml(plant: Plant, source: str, name: str = "calibrated") -> str:
    """The file of a calibrated parameter set: :func:`.store.plant_toml` of a plant."""
    return plant_toml(plant.to_dict(), source, name)

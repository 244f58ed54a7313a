"""Independent test benches for the calibration tools.

:mod:`.independent_plant` is a piezo stick–slip turntable simulator written from the
thesis's physics and the measurement file format only; it shares no model code with the
rest of the package, so data from it can judge the calibrator fairly.
:mod:`.second_plant` is a second one, from a different formulation (elasto-plastic
friction, two table modes, a slewing amplifier); its names overlap the first's, so it is
exported as a module.
"""

from . import second_plant
from .independent_plant import (
    PROTOCOLS,
    Burst,
    Effects,
    Hold,
    PlantParams,
    Protocol,
    Ramp,
    build_drive,
    simulate,
    write_trace,
)

__all__ = [
    "PROTOCOLS",
    "Burst",
    "Effects",
    "Hold",
    "PlantParams",
    "Protocol",
    "Ramp",
    "build_drive",
    "second_plant",
    "simulate",
    "write_trace",
]

"""Gymnasium environments over the turntable simulator.

* :class:`PiezoTurntableEnv` — ``PiezoTurntable-v0``, one turntable;
* :class:`PiezoTurntableVectorEnv` — its native vector env (``vector_entry_point``);
* :mod:`.config` — arguments, action scaling, domain randomisation;
* :mod:`.core` — the task for N turntables (physics backends, generator, reward);
* :mod:`.render` — ``rgb_array`` drawing.
"""

from .config import ACTION_NAMES, DEFAULT_RANDOMIZATION, OBSERVATION_NAMES, ActionScaling, EnvConfig
from .piezo_turntable import PiezoTurntableEnv
from .vector import PiezoTurntableVectorEnv

__all__ = [
    "ACTION_NAMES",
    "DEFAULT_RANDOMIZATION",
    "OBSERVATION_NAMES",
    "ActionScaling",
    "EnvConfig",
    "PiezoTurntableEnv",
    "PiezoTurntableVectorEnv",
]

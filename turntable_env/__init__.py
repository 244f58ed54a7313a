"""piezo-turntable: simulator and controller environment for the piezo stick–slip turntable.

Specification: M. Schepers, *Modeling a Piezoelectric Inertial Stepping Turntable
Using Bond Graphs* (M.Sc. thesis, U. Twente). Physics parts: :mod:`.piezo`,
:mod:`.tube`, :mod:`.table`, :mod:`.geometry`, :mod:`.friction`, :mod:`.drive`,
:mod:`.amplifier`, :mod:`.detector`; parameter sets in :mod:`.params`; the Gymnasium
environment ``PiezoTurntable-v0`` (registered on import) in :mod:`.envs`.
"""

__version__ = "0.1.0"

from .kernel_cache import CACHE_DIR as KERNEL_CACHE  # noqa: F401  (before any kernel module)

ENV_ID = "PiezoTurntable-v0"
MAX_EPISODE_STEPS = 200  # 2 s at the default 10 ms control interval

# Registered variants (as highway-env and panda-gym register theirs): id → (kwargs, what).
ENV_VARIANTS: dict[str, tuple[dict, str]] = {
    ENV_ID: ({}, "the real turntable (Table D.1), reduced per-axis model, nominal plant"),
    "PiezoTurntableFull-v0": (
        {"fidelity": "full"},
        "the same task on the full 3-D model (contacts in 3-D, about 100x slower)",
    ),
    "PiezoTurntableCalibrated-v0": (
        {"params": "calibrated"},
        "the real turntable as the thesis's measured figures calibrate it (turntable "
        "calibrate --thesis): symmetric drive, mirror facing the axis, fitted contacts, the "
        "amplifier's fast path; the per-axis model steps 25-33 % more than the 3-D one "
        "the figures were fitted on (report.md's correction; fidelity='full' to match them)",
    ),
    "PiezoTurntableRandomized-v0": (
        {"randomize": True},
        "a plant drawn per episode: friction and preload x0.8-1.2, amplifier x0.9-1.1, "
        "detector noise x0.5-2 (DEFAULT_RANDOMIZATION)",
    ),
}


def _register() -> None:
    """Register the variants with Gymnasium (once: re-imports are no-ops)."""
    from gymnasium.envs.registration import register, registry

    for env_id, (kwargs, _doc) in ENV_VARIANTS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point="turntable_env.envs:PiezoTurntableEnv",
                vector_entry_point="turntable_env.envs:PiezoTurntableVectorEnv",
                max_episode_steps=MAX_EPISODE_STEPS,
                kwargs=kwargs,
            )


_register()

"""piezo-turntable: simulator and controller environment for the piezo stick–slip turntable.

Specification: M. Schepers, *Modeling a Piezoelectric Inertial Stepping Turntable
Using Bond Graphs* (M.Sc. thesis, U. Twente). Physics parts: :mod:`.piezo`,
:mod:`.tube`, :mod:`.table`, :mod:`.geometry`, :mod:`.friction`, :mod:`.drive`,
:mod:`.amplifier`, :mod:`.detector`; parameter sets in :mod:`.params`; the Gymnasium
environment ``PiezoTurntable-v0`` (registered on import) in :mod:`.envs`.
"""

__version__ = "0.1.0"

ENV_ID = "PiezoTurntable-v0"
MAX_EPISODE_STEPS = 200  # 2 s at the default 10 ms control interval


def _register() -> None:
    """Register ``PiezoTurntable-v0`` with Gymnasium (once: re-imports are no-ops)."""
    from gymnasium.envs.registration import register, registry

    if ENV_ID not in registry:
        register(
            id=ENV_ID,
            entry_point="turntable_env.envs:PiezoTurntableEnv",
            vector_entry_point="turntable_env.envs:PiezoTurntableVectorEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
        )


_register()

"""``PiezoTurntable-v0``: position the stick–slip turntable at a target angle."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..plant import Plant
from ..validation import check_int
from .config import ACTION_NAMES, check_action, make_config
from .core import TurntableTask

__all__ = ["PiezoTurntableEnv", "action_space", "observation_space"]


def action_space() -> spaces.Box:
    """Box(-1, 1, (5,), float32): see :class:`~turntable_env.envs.config.ActionScaling`."""
    return spaces.Box(-1.0, 1.0, shape=(len(ACTION_NAMES),), dtype=np.float32)


def observation_space(task: TurntableTask | float) -> spaces.Box:
    """Box of (measured angle, target, phase, last action[, measured y]) with the detector's
    bounds (a task's, with the y channel when its config has ``detector_y``; or the linear
    range θ_lin [rad] itself)."""
    lim = float(task) if isinstance(task, int | float) else task.angle_range
    low = [-lim, -lim, 0.0, -1, -1, -1, -1, -1]
    high = [lim, lim, 1.0, 1, 1, 1, 1, 1]
    if not isinstance(task, int | float) and task.config.detector_y:
        low.append(-lim)
        high.append(lim)
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


class PiezoTurntableEnv(gym.Env):
    """
    ## Description

    The piezoelectric stick–slip turntable of Schepers' thesis (U. Twente): a steel half
    sphere rests on three orthogonal piezo tubes and turns by inertial stick–slip steps
    (slow bend: the table sticks and follows; fast flyback: it slips and stays). The
    task is to turn the table about one axis (default B) from a start angle to a target
    angle, reading only what the laser/quadrant-photodiode detector reports, and to do
    it with little electrical energy. The env runs a :class:`~turntable_env.plant.Plant`:
    by default the reduced per-axis model derived from the 3-D model
    (:mod:`turntable_env.reduced`; ``fidelity="translation"`` adds the sphere's translation
    and tilts and the contacts' normal forces, which bring its steps closer to the 3-D model's;
    ``fidelity="full"`` runs the 3-D model itself) with the
    real turntable's parameters (Table D.1) and no effects; ``plant=`` runs any other —
    for example the one a calibration report describes (``plant="cal/report.json"``),
    with the effects it found (creep, hysteresis, drift, vibration, ...) acting at their
    physical stages (:mod:`turntable_env.effects`). ``env.unwrapped.plant`` is the
    plant of the current episode.

    Each step is one **fixed control interval** Δt (``control_interval``, 10 ms: one
    period of the real turntable's 100 Hz nominal drive, §4.1.3). A fixed interval keeps
    time uniform for the controller (rewards per unit time, a time limit in seconds, a
    detector sampled at a constant rate, ``render_fps`` = 1/Δt) while the frequency
    sets how many stick–slip periods fall in it (0.1 at 10 Hz, 20 at 2 kHz). The
    waveform generator is free-running and phase continuous: a new setting takes over
    at the next period start, where every waveform is zero, so a change of action never
    makes the input jump (an idle generator starts at once); periods longer than Δt
    run on over several steps (the phase is observed).

    ## Action Space

    ``Box(-1, 1, (5,), float32)``; finite values outside [-1, 1] are clipped, NaN or
    infinite values raise ValueError.

    | index | name            | physical value                                                 |
    |-------|-----------------|----------------------------------------------------------------|
    | 0     | amplitude       | input amplitude u_A = a·10 V (amplifier ±10 V input, gain 45); |
    |       |                 | sign = direction, 0 = generator idle                           |
    | 1     | frequency       | f = 10 Hz·200^((a+1)/2), 10 Hz … 2 kHz (log scale)             |
    | 2     | ramp_ratio      | a = 0.5 … 0.99, the position of the sawtooth maximum (Fig 3.14)|
    | 3     | slew_adaptation | a ≤ 0: plain sawtooth, flyback ramp over (1 − a)/f;            |
    |       |                 | a > 0: slew-adapted step flyback with overshoot k = a (Fig 4.3)|
    | 4     | scan_offset     | scan level u_0 = a·10 V the sawtooth sits on, ramped linearly  |
    |       |                 | over the interval: the tubes bend, the table sticks and        |
    |       |                 | follows (sub-step "scan" positioning, θ = G·g·u_0/ρ)           |

    The amplifier clips u_0 + sawtooth to its ±10 V input. Scan and stepping combine:
    amplitude 0 with a scan offset bends the tubes without slipping.

    ## Observation Space

    ``Box(low, high, (8,), float32)`` (``(9,)`` with ``detector_y=True``):

    | index | name               | unit | bounds                                         |
    |-------|--------------------|------|------------------------------------------------|
    | 0     | measured_angle_rad | rad  | ±θ_lin = ±½·arctan(0.2 mm/L) = ±5.71e-4 (real) |
    | 1     | target_angle_rad   | rad  | ±θ_lin                                         |
    | 2     | generator_phase    | -    | [0, 1]: position in the running period         |
    | 3–7   | last_<action>      | -    | [-1, 1]: the last action, clipped              |
    | 8     | measured_y_rad     | rad  | ±θ_lin: only with ``detector_y=True`` (9,)     |

    The measured angle is Eq. 4.1 applied to the detector voltage with Gaussian noise
    (``sensor_noise``, 1 mV; angle noise ≈ S·σ/(2L)) and saturation at the ±0.2 mm linear range:
    beyond ±θ_lin the reading sticks at the edge. ``detector_y=True`` adds the quadrant
    photodiode's y channel, read the same way with its own noise: a rotation about the
    watched axis shows on it only through an axis misalignment (θ·sin φ).

    ## Rewards

    r = −|θ* − θ|/θ_lin − w·E/E_ref, with θ the true angle at the end of the interval
    (``reward="log"``: the distance term is −ln(1 + d/tol)/ln(1 + θ_lin/tol) instead;
    ``success_bonus`` is added to it in every interval that ends within ``tolerance``),
    E = C∫|V dV| the energy the amplifier moved through the channel's quadrants
    (capacitance C) during the interval and E_ref = C·(45·10 V)² the energy of one
    full-amplitude period; w = ``energy_weight`` = 0.01. ``info`` holds
    ``reward_distance``, ``reward_energy``, ``distance_rad``, ``energy_J``,
    ``angle_rad`` (true), ``target_rad``, ``detector_V``, ``steps`` (flybacks the
    generator started in the interval, :func:`~turntable_env.drive.generator_flybacks`),
    ``is_success``, ``out_of_workspace`` and ``time_s``.

    ## Starting State

    The table at rest (every friction element stuck, holding the small pendulum torque)
    at a start angle drawn uniformly in ±0.8·θ_lin, target uniformly in ±0.8·θ_lin, the
    generator idle, tubes unbent. ``reset(options={"start_angle": ..., "target_angle":
    ...})`` sets them [rad] (start within ±``angle_limit``, target within ±θ_lin);
    ``move_range`` draws the start as the target less a log-uniform move instead.
    ``options={"reference": r}`` commands a trajectory instead of a fixed target: ``r[k]`` [rad]
    is the target at time k·Δt (the last value held after the end; observation and reward
    use the target of the moment); ``options={"knock": (t, dθ)}`` displaces the table by
    dθ [rad] at the end of the interval ending at t [s] (every contact re-sticks at the new
    angle; a disturbance, :meth:`~turntable_env.plant.PlantStepper.displace`).
    ``retarget_share`` of the episodes draw such a reference themselves: each target held
    for ``retarget_legs`` intervals, the next drawn within ±``target_range``·θ_lin (a
    training distribution with the tracking tasks' target jumps). With
    ``randomize``, the friction coefficients, preload, amplifier slew and sensor noise
    are redrawn each episode (ranges: :data:`~turntable_env.envs.config.DEFAULT_RANDOMIZATION`).

    ## Episode End

    * Termination: |θ* − θ| ≤ ``tolerance`` (1 µrad = 10 nm at the 10 mm table radius)
      at the end of an interval (``info["is_success"]``); with
      ``terminate_on_success=False`` the episode runs on to the time limit (the target
      must be held).
    * Truncation: |θ| > ``angle_limit`` (0.05 rad; the model's small-angle workspace),
      or the registration's time limit, ``max_episode_steps=200`` (2 s).

    ## Arguments

    ```python
    import gymnasium as gym
    env = gym.make("PiezoTurntable-v0", params="real", fidelity="reduced", axis="B",
                   control_interval=0.01, randomize=False, noise=True, sensor_noise=1e-3,
                   tolerance=1e-6, terminate_on_success=True, energy_weight=0.01,
                   render_mode="rgb_array")
    env = gym.make("PiezoTurntable-v0", plant="cal/report.json", randomize=True)
    envs = gym.make_vec("PiezoTurntable-v0", num_envs=64,
                        vectorization_mode="vector_entry_point")  # one compiled call
    ```

    ``plant`` (a :class:`~turntable_env.plant.Plant` or a calibration report) and
    ``params`` are alternatives. With a plant from a report, ``randomize=True`` draws
    each episode's plant from the calibration's posterior (its standard errors). See
    :class:`~turntable_env.envs.config.EnvConfig` for every argument.

    Registered variants (``turntable_env.ENV_VARIANTS``):

    | id                            | plant                                                |
    |-------------------------------|------------------------------------------------------|
    | ``PiezoTurntable-v0``         | real set, reduced model, no effects                  |
    | ``PiezoTurntableFull-v0``     | the same on the full 3-D model                       |
    | ``PiezoTurntableRandomized-v0``| a plant per episode from ``DEFAULT_RANDOMIZATION``  |

    The thesis's scaled set (``params="thesis"``) runs too, but its 4 mrad steps dwarf the
    detector's ±0.57 mrad range, so it has no registered task.

    ## Version History

    * v0: initial version (reduced per-axis model, real parameters). Later additions that
      keep v0's behaviour: ``info["steps"]``, ``terminate_on_success``, ``move_range``,
      ``reward="log"``, ``success_bonus``, ``plant`` (the plant layer: calibrated plants
      with effects), the registered variants, the ``reference`` and ``knock`` reset
      options (tracking and disturbance tasks), and ``retarget_share``/``retarget_legs``
      (0 by default: no episode retargets, and no draw is added).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["human", "rgb_array"],
        "render_fps": 100,
    }

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        self.config = make_config(config)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r}: must be None, 'human' or 'rgb_array'")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.config.control_interval}
        self.task = TurntableTask(self.config, 1)
        self.action_space = action_space()
        self.observation_space = observation_space(self.task)
        self._renderer: Any = None
        self._window: Any = None  # (figure, image) of render_mode="human"
        self._reset_done = False  # step() before the first reset is refused

    @property
    def observation_names(self) -> tuple[str, ...]:
        return self.config.observation_names

    @property
    def plant(self) -> Plant:
        """The plant of the current episode (the configured one, or its randomised draw)."""
        return self.task.plants[0]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:  # gymnasium's own check raises its own error type
            seed = check_int("seed", seed, 0)  # a numpy integer as a Python one
        super().reset(seed=seed)
        self.task.reset_row(0, self.np_random, options)  # refused options change nothing
        self._reset_done = True
        t = self.task
        info = {
            "angle_rad": float(t.angle[0]),
            "target_rad": float(t.target[0]),
            "detector_V": float(t.detector_v[0]),
            "parameter_factors": dict(t.draws[0]),
        }
        if self.render_mode == "human":
            self.render()
        return t.observation()[0], info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self._reset_done:
            raise gym.error.ResetNeeded("PiezoTurntable-v0: call reset() before step()")
        a = check_action(action, (5,))  # ValueError for anything but 5 finite reals
        res = self.task.step(a[None, :], self.np_random)
        info = {k: v[0].item() for k, v in res.info.items()}
        if self.render_mode == "human":
            self.render()
        return (
            res.obs[0],
            float(res.reward[0]),
            bool(res.terminated[0]),
            bool(res.truncated[0]),
            info,
        )

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the frame (H, W, 3) uint8; ``human``: the frame shown in a
        matplotlib window, refreshed at ``render_fps`` (called by ``reset`` and ``step``)."""
        if self.render_mode is None:
            return None
        if self._renderer is None:
            from .render import TurntableRenderer

            self._renderer = TurntableRenderer(self.task)
        frame = self._renderer.draw(0)
        if self.render_mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _show(self, frame: np.ndarray) -> None:
        """The human window: one figure, its image replaced each frame."""
        import matplotlib
        import matplotlib.pyplot as plt

        if self._window is None or not plt.fignum_exists(self._window[0].number):
            fig, ax = plt.subplots(figsize=(frame.shape[1] / 100, frame.shape[0] / 100))
            ax.set_axis_off()
            fig.subplots_adjust(0, 0, 1, 1)
            self._window = (fig, ax.imshow(frame))
            if matplotlib.get_backend().lower() != "agg":
                plt.show(block=False)
        fig, image = self._window
        image.set_data(frame)
        fig.canvas.draw_idle()
        if matplotlib.get_backend().lower() != "agg":  # a headless backend has no window
            plt.pause(1.0 / self.metadata["render_fps"])

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderer"] = None  # matplotlib figures are rebuilt on demand
        state["_window"] = None
        return state

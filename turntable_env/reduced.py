"""Per-axis reduced model: rotation about one axis, derived from the full 3-D model.

Rotation about axis X ∈ {A, B, C} (unit n = d_X) is driven by the two other tubes
k: their contact points lie on the table's equator about n (d_k ⟂ n), so each acts
at lever ρ_k = R_table along e_k = n × d_k — which is one of tube k's two bending
directions (§3.1: the tube axes are orthogonal). The reduced model keeps

* the table: J_n θ̈ = Σ_k ρ_k F_k − k_g θ, with J_n = nᵀJ_O n the inertia about n
  through the sphere centre (App. C, parallel-axis from the CoM) and k_g = m g h_CoM
  (1 − n_z²) the pendulum stiffness of the CoM 3R/8 below the centre;
* each driving tube as one bending degree of freedom at its contact point: the
  full model's 6×6 tube-top spring K, mass M and damping βK condensed (Guyan) onto
  the contact-point displacement along e_k, u_c = aᵀξ with a = (r_c × e_k, e_k):
  K_k = 1/(aᵀK⁻¹a), shape ψ = K⁻¹a K_k, M_k = ψᵀMψ, damping βK_k; the quadrant
  voltages of channel X move it freely by g_k = aᵀK⁻¹B q_X per volt (Eq. 2.11 via
  the tube's rest twist per volt);
* 1-D GMS friction (Eq. 2.24–2.26) between tube contact point and table at the full
  model's static normal force F_N, with the same elements, Stribeck curve, viscous
  term and micro-damping β_t k_i of the sticking elements;
* the channel's amplifier (same gain, τ, slew limit from its load) and the detector.

Nothing is fitted: every number comes from :class:`~turntable_env.model.TurntableModel`.
Integration: :mod:`turntable_env.reduced_kernel` (exact between GMS transitions).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import scipy.linalg

from .detector import Detector
from .drive import DriveSignal, Waveform
from .kernel_types import DriveArrays, ReducedArrays, ReducedRecording, ReducedState
from .model import SimulationError, TurntableModel, axis_index
from .params import ParameterSet, get_parameter_set
from .reduced_kernel import (
    N_REC,
    N_TRANSLATION,
    form_counts,
    run_reduced_batch,
    run_reduced_serial,
)
from .response import SteppingMetrics
from .threads import one_blas_thread
from .validation import check_finite, check_positive

__all__ = [
    "AxisParameters",
    "AxisResponse",
    "ReducedBatch",
    "ReducedModel",
    "simulate_batch",
    "simulate_reduced",
    "waveform_arrays",
]

REDUCED_AXES = ("A", "B", "C")
H_MIN = 62.5e-9  # s, time grid of the reduced integrator (1/16 µs)
SLIP_STEP = 2e-6  # s, largest step while an element slips (linear part exact: see sweep)
RING_FRACTION = 0.25  # of a period of the fastest stick mode: largest step while ringing
# with the translation, the largest step while an element slips is also at most this
# fraction of the fastest mode's period (the tube tops ring at up to 67 kHz, and the
# slipping elements relax at the step's mean sliding velocity; 2 µs moved 1–2 nm steps by
# up to 21 % at half every bound: experiments/reduced_sweep.py --convergence checks it)
MOVED_SLIP_FRACTION = 1.0 / 16.0
QUIET_LENGTH = 0.01  # fraction of the weakest element's breakaway displacement
MAX_RUNG = 18  # largest step h_min·2^18 = 16 ms
_STATE_NAMES = (  # the per-axis form's states
    "table angle",
    "table angular velocity",
    "tube 1 contact displacement",
    "tube 1 contact velocity",
    "tube 2 contact displacement",
    "tube 2 contact velocity",
)


@dataclass(frozen=True)
class AxisParameters:
    """Derived parameters of the reduced model for one axis (SI units).

    Attributes:
        axis: "A", "B" or "C".
        inertia: J_n, table inertia about the axis through the sphere centre [kg·m²].
        gravity_stiffness: k_g, pendulum stiffness of the CoM [N·m/rad].
        lever: ρ_k of the two driving contacts [m].
        tube_mass, tube_stiffness, tube_damping: condensed tube at its contact point
            [kg], [N/m], [N·s/m].
        tube_gain: free contact-point displacement per channel volt [m/V].
        normal_force: F_N of the two contacts [N].
        tubes: names of the two driving tubes.
    """

    axis: str
    inertia: float
    gravity_stiffness: float
    lever: tuple[float, float]
    tube_mass: tuple[float, float]
    tube_stiffness: tuple[float, float]
    tube_damping: tuple[float, float]
    tube_gain: tuple[float, float]
    normal_force: tuple[float, float]
    tubes: tuple[str, str]

    @classmethod
    def from_model(cls, model: TurntableModel, axis: str) -> AxisParameters:
        """Condense the full model onto rotation about ``axis`` (see module docstring)."""
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the reduced model covers {', '.join(REDUCED_AXES)}")
        ar = model.packed
        ps = model.params
        c = axis_index(axis)
        n = model.layout.axis_units[c]
        m = ps.table.mass
        cb = ar["c_body"]
        j_com = np.linalg.inv(ar["jinv"])
        j_o = j_com + m * (cb @ cb * np.eye(3) - np.outer(cb, cb))
        inertia = float(n @ j_o @ n)
        k_g = float(m * model.gravity * ps.table.com_depth * (1.0 - n[2] ** 2))
        beta = ps.tube.damping_coefficient
        r_ball = ps.tube.outer_radius
        fields: dict[str, list[float]] = {k: [] for k in ("lever", "M", "K", "D", "g")}
        tubes = []
        for k in range(3):
            if k == c:
                continue
            d = ar["d_nom"][k]
            e = np.cross(n, d)
            e /= np.linalg.norm(e)
            r_c = ar["r0"][k] - r_ball * d  # tube top → contact point [m]
            a = np.concatenate([np.cross(r_c, e), e])
            kinv_a = np.linalg.solve(ar["ktop"][k], a)
            k_eff = 1.0 / float(a @ kinv_a)
            psi = kinv_a * k_eff
            q = (ar["qchan"][k] == c) * ar["qsign"][k]  # quadrant voltage per channel volt
            gain = float(a @ np.linalg.solve(ar["ktop"][k], ar["bcoup"][k] @ q))
            fields["lever"].append(ps.table.radius)
            fields["M"].append(float(psi @ ar["mtube"][k] @ psi))
            fields["K"].append(k_eff)
            fields["D"].append(beta * k_eff)
            fields["g"].append(gain)
            tubes.append("ABC"[k])
        fn = ps.contact.preload  # type: ignore[union-attr]
        return cls(
            axis=axis,
            inertia=inertia,
            gravity_stiffness=k_g,
            lever=tuple(fields["lever"]),  # type: ignore[arg-type]
            tube_mass=tuple(fields["M"]),  # type: ignore[arg-type]
            tube_stiffness=tuple(fields["K"]),  # type: ignore[arg-type]
            tube_damping=tuple(fields["D"]),  # type: ignore[arg-type]
            tube_gain=tuple(fields["g"]),  # type: ignore[arg-type]
            normal_force=(fn, fn),
            tubes=(tubes[0], tubes[1]),
        )


@dataclass(frozen=True)
class TranslationParameters:
    """The sphere's rigid-body motion beside the turn about the axis (its translation and
    its tilts) and the contacts' normal forces, derived from the full 3-D model (SI units;
    ``ReducedModel(translation=True)``).

    Since stop 93 the kernel keeps the 3-D model's tube tops whole, six coordinates each
    (:meth:`ReducedModel.translation_matrices`), where it condensed each tube at its
    contact point: the kernel takes the table's, the contacts' and the friction's figures
    from here (mass, centre of mass, inertia, g, the Hertz stiffness, the normal damping,
    the stuck stiffness and damping); the condensed tubes' (the axial, side and axis
    tubes', the stroke) are the condensed form that the rigid-body reference's variants
    use (``experiments/sphere_tilt.py``), described below as that form has them.

    The tubes' axes d_1, d_2 (driving) and n (the axis) are orthonormal (§3.1's orthogonal
    tubes). The table's coordinates beside θ are its centre's translation x = x_1 d_1 +
    x_2 d_2 + x_n n and its tilts φ_1, φ_2 about d_1, d_2 (rotation φ = φ_1 d_1 + φ_2 d_2 +
    θ n). Tube k's friction, along e_k = n × d_k = ±d_j, pushes the sphere along the other
    contact's normal, and the translation slides the contact points: slip_k = u_k − ρθ −
    e_k·x (the tilts move a driving contact's point along n alone). Each tube's ball
    moves along the tube's axis d_k with its own coordinate a_k (the tube condensed there:
    its axial mass and stiffness, driven by the stroke s V), and each contact's normal
    force is F_N + k_H(x_k − a_k) + d_c(ẋ_k − ȧ_k) (Eq. 3.21's k_c δ^e + d_c δ̇ linearised
    at F_N; x_n, a_n on the axis); a driving contact's sets its Stribeck level (Eq. 2.13).
    The axis contact never slips: the tube on the axis holds x_1, x_2 and the tilts at
    its contact point ρn (slip b_j − d_j·(x + φ × ρn)), a stuck GMS contact (Σk_i with
    micro-damping β_tΣk_i, Eq. 2.24) in series with the tube's bending there, condensed
    at its contact point as the driving direction is; its normal spring holds x_n. Each
    driving tube holds x_n and the tilts along n at ρd_k (slip w_k − n·(x + φ × ρd_k),
    the tube condensed there too) through its contact's second tangent direction, whose
    GMS elements are the driving direction's: each element is a 2-vector in the contact
    plane under the 2-D law (§3.3.2, :mod:`turntable_env.friction.gms2d`), so the load
    the side tubes' bending puts on it along n takes its share of the element's
    capacity and is given up whenever it slips, as in the 3-D model (stop 93; held
    stuck before, the settled step at +90 V, 100 Hz was 11 % short).

    The table's inertia couples rotation and translation through the centre of mass c,
    3R/8 below the centre (App. C): T = ½m|ẋ + φ̇ × c|² + ½φ̇ᵀJ_cφ̇ (J_c about the centre
    of mass), and gravity's pendulum stiffness on φ is m g (|c| I − c cᵀ/|c|) (Eq. C.16's
    lever).

    Attributes:
        mass: m, the table's mass [kg].
        centre_of_mass: c from the sphere's centre in (d_1, d_2, n) [m].
        centre_inertia: the table's inertia about the sphere's centre in (d_1, d_2, n)
            [kg·m²] (3 × 3).
        gravity: g [m/s²].
        direction: e_k·d_j [-] (row k: driving contact, column j: translation component).
        hertz_stiffness: dF/dδ of the contact's k_c δ^e at F_N, e·F_N/δ_0 [N/m].
        axial_stiffness, axial_mass, axial_damping: each tube condensed at its contact
            point along its axis d_k [N/m], [kg], [N·s/m] (the ball's axial coordinate
            a_k, which the stroke drives and the Hertz spring joins to the table).
        normal_damping: d_c [N·s/m].
        stroke: s, the ball's displacement along d_k per channel volt (the quadrant
            wiring's axial strain, §3.1) [m/V].
        axis_tube_mass, axis_tube_stiffness, axis_tube_damping: the tube on the axis
            condensed at its contact point [kg], [N/m], [N·s/m].
        side_tube_mass, side_tube_stiffness, side_tube_damping, side_tube_gain: each
            driving tube condensed at its contact point along n [kg], [N/m], [N·s/m],
            and its free deflection there per channel volt [m/V].
        stuck_stiffness, stuck_damping: each stuck contact direction (the axis
            contact's two; the driving contacts' along n while every element sticks, as
            at rest) [N/m], [N·s/m].
    """

    mass: float
    centre_of_mass: tuple[float, float, float]
    centre_inertia: tuple[tuple[float, float, float], ...]
    gravity: float
    direction: tuple[tuple[float, float], tuple[float, float]]
    hertz_stiffness: float
    axial_stiffness: float
    axial_mass: float
    axial_damping: float
    normal_damping: float
    stroke: float
    axis_tube_mass: float
    axis_tube_stiffness: float
    axis_tube_damping: float
    side_tube_mass: tuple[float, float]
    side_tube_stiffness: tuple[float, float]
    side_tube_damping: tuple[float, float]
    side_tube_gain: tuple[float, float]
    stuck_stiffness: float
    stuck_damping: float

    @property
    def handedness(self) -> float:
        """σ = (d_1 × d_2)·n = e_1·d_2 = ±1 [-]: cross products in (d_1, d_2, n) carry it."""
        return 1.0 if self.direction[0][1] > 0.0 else -1.0

    @property
    def coupling(self) -> tuple[float, float]:
        """(n × c)·d_j [m]: the rotation's coupling to the translation, m θ̇ (n × c)·ẋ."""
        c, sg = self.centre_of_mass, self.handedness
        return (-sg * c[1], sg * c[0])

    @property
    def normal_stiffness(self) -> float:
        """k_n, the Hertz stiffness in series with the tube's axial stiffness [N/m]."""
        return 1.0 / (1.0 / self.hertz_stiffness + 1.0 / self.axial_stiffness)

    @classmethod
    def from_model(
        cls, model: TurntableModel, axis: str, params: ParameterSet | None = None
    ) -> TranslationParameters:
        """Derive the translation's parameters for ``axis`` (see the class docstring): the
        bodies (table, tubes, drive mode) from ``model``, the contact (preload, Hertz law,
        normal damping) and the friction from ``params`` (default: the model's own; a
        reduced model condensed from a cached 3-D model of other contact values passes its
        own set, as :class:`ReducedModel` does)."""
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the reduced model covers {', '.join(REDUCED_AXES)}")
        ar = model.packed
        ps = params if params is not None else model.params
        contact = ps.contact
        assert contact is not None
        c = axis_index(axis)
        n = model.layout.axis_units[c]
        drv = [k for k in range(3) if k != c]
        d = [ar["d_nom"][k] for k in drv]
        e = [np.cross(n, dk) / np.linalg.norm(np.cross(n, dk)) for dk in d]
        tp = ar["table_p"]
        fn0 = float(contact.preload)
        k_c, e_c = contact.normal_stiffness, contact.normal_exponent
        delta0 = (fn0 / k_c) ** (1.0 / e_c)  # static overlap (F_N/k_c)^(1/e) [m]
        k_hertz = e_c * fn0 / delta0  # dF/dδ of k_c δ^e at F_N [N/m]
        r_ball = ps.tube.outer_radius
        k0 = drv[0]
        r_c = ar["r0"][k0] - r_ball * ar["d_nom"][k0]  # tube top → contact point [m]
        a_d = np.concatenate([np.cross(r_c, d[0]), d[0]])
        kinv = np.linalg.inv(ar["ktop"][k0])
        k_axial = 1.0 / float(a_d @ kinv @ a_d)
        psi_d = kinv @ a_d * k_axial
        q = (ar["qchan"][k0] == c) * ar["qsign"][k0]  # quadrant voltage per channel volt
        stroke = float(a_d @ kinv @ ar["bcoup"][k0] @ q)
        r_cn = ar["r0"][c] - r_ball * ar["d_nom"][c]
        a_n = np.concatenate([np.cross(r_cn, d[0]), d[0]])
        kinv_a = np.linalg.solve(ar["ktop"][c], a_n)
        k_b = 1.0 / float(a_n @ kinv_a)
        psi = kinv_a * k_b
        side: dict[str, list[float]] = {k: [] for k in ("M", "K", "g")}
        for k in drv:  # each driving tube along n, condensed as its driving direction
            r_ck = ar["r0"][k] - r_ball * ar["d_nom"][k]
            a_s = np.concatenate([np.cross(r_ck, n), n])
            kinv_s = np.linalg.solve(ar["ktop"][k], a_s)
            k_s = 1.0 / float(a_s @ kinv_s)
            qk = (ar["qchan"][k] == c) * ar["qsign"][k]
            side["M"].append(float((kinv_s * k_s) @ ar["mtube"][k] @ (kinv_s * k_s)))
            side["K"].append(k_s)
            side["g"].append(float(a_s @ np.linalg.solve(ar["ktop"][k], ar["bcoup"][k] @ qk)))
        fr = ps.friction
        assert fr is not None
        k_sum = float(np.sum(fr.k))
        basis = np.stack([d[0], d[1], n], axis=1)  # columns d_1, d_2, n (world)
        cb = np.asarray(ar["c_body"], float)
        m = float(tp[0])
        j_o = np.linalg.inv(ar["jinv"]) + m * (cb @ cb * np.eye(3) - np.outer(cb, cb))
        beta = ps.tube.damping_coefficient
        return cls(
            mass=m,
            centre_of_mass=tuple(float(v) for v in basis.T @ cb),  # type: ignore[arg-type]
            centre_inertia=tuple(tuple(float(v) for v in row) for row in basis.T @ j_o @ basis),
            gravity=float(model.gravity),
            direction=tuple(tuple(float(ek @ dj) for dj in d) for ek in e),  # type: ignore[arg-type]
            hertz_stiffness=float(k_hertz),
            axial_stiffness=k_axial,
            axial_mass=float(psi_d @ ar["mtube"][k0] @ psi_d),
            axial_damping=beta * k_axial,
            normal_damping=float(contact.normal_damping),
            stroke=stroke,
            axis_tube_mass=float(psi @ ar["mtube"][c] @ psi),
            axis_tube_stiffness=k_b,
            axis_tube_damping=beta * k_b,
            side_tube_mass=tuple(side["M"]),  # type: ignore[arg-type]
            side_tube_stiffness=tuple(side["K"]),  # type: ignore[arg-type]
            side_tube_damping=tuple(beta * k for k in side["K"]),  # type: ignore[arg-type]
            side_tube_gain=tuple(side["g"]),  # type: ignore[arg-type]
            stuck_stiffness=k_sum,
            stuck_damping=fr.stribeck.sigma2 + contact.tangential_damping * k_sum,
        )


@dataclass(frozen=True, eq=False)
class AxisResponse(SteppingMetrics):
    """Time response of the reduced model; time is axis 0 of every array.

    Attributes:
        time: [s]; angle_rad: rotation about the axis [rad]; angular_velocity [rad/s];
        voltage: amplifier output on the channel [V]; tube_displacement (n, 2) contact-point
        deflection of the driving tubes [m]; slip (n, 2) relative displacement tube − table
        at the contacts [m]; friction (n, 2) [N]; n_stick (n, 2) sticking GMS elements.
    """

    time: np.ndarray
    angle_rad: np.ndarray
    angular_velocity: np.ndarray
    voltage: np.ndarray
    tube_displacement: np.ndarray
    slip: np.ndarray
    friction: np.ndarray
    n_stick: np.ndarray
    axis: str
    detector: Detector
    table_radius: float
    period_starts: np.ndarray
    info: dict = field(default_factory=dict)
    effect_row: np.ndarray | None = None  # output-stage effects (SteppingMetrics), or None

    def angle(self, axis: str | None = None) -> np.ndarray:
        """Rotation about the model's axis [rad] (``axis`` must be it or None)."""
        if axis not in (None, self.axis):
            raise ValueError(f"axis={axis!r}: the reduced model only turns about {self.axis}")
        return self.angle_rad

    def signals(self) -> dict[str, np.ndarray]:
        """Every recorded signal by name (unit in the name): angle, angular velocity,
        amplifier output, detector, and each driving tube's deflection, slip, friction and
        sticking elements."""
        cols = {
            "angle_rad": self.angle_rad,
            "angular_velocity_rad_s": self.angular_velocity,
            "voltage_V": self.voltage,
            "detector_V": self.detector_voltage(),
        }
        for k in range(2):
            cols[f"tube{k + 1}_m"] = self.tube_displacement[:, k]
            cols[f"slip{k + 1}_m"] = self.slip[:, k]
            cols[f"friction{k + 1}_N"] = self.friction[:, k]
            cols[f"n_stick{k + 1}"] = self.n_stick[:, k]
        return cols

    def plot(self, axes: Any = None) -> Any:
        """Angle at the table radius, amplifier voltage and sticking elements vs time."""
        import matplotlib.pyplot as plt

        if axes is None:
            _fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 6))
        t_ms = self.time * 1e3
        axes[0].plot(t_ms, self.angle_rad * self.table_radius * 1e6)
        axes[0].set_ylabel(f"rotation about {self.axis}\nat R_table [µm]")
        axes[1].plot(t_ms, self.voltage)
        axes[1].set_ylabel("amplifier output [V]")
        axes[2].plot(t_ms, self.n_stick)
        axes[2].set_ylabel("sticking elements")
        axes[2].set_xlabel("time [ms]")
        return axes


def _ladders(mats: np.ndarray, h: float, n_rungs: int) -> np.ndarray:
    """exp(matᵢ·h·2^r) for every matrix of the stack ``mats`` (k, n, n) and r < n_rungs:
    (k, n_rungs, n, n). One batched expm (scipy's, matrix by matrix, so each equals its
    own expm), then repeated squaring."""
    out = np.empty((mats.shape[0], n_rungs, *mats.shape[1:]))
    e = scipy.linalg.expm(mats * h)
    for r in range(n_rungs):
        out[:, r] = e
        e = e @ e
    return out


class ReducedModel:
    """The reduced per-axis model of one parameter set, ready for the compiled integrator.

    Args:
        params: parameter set (or its name).
        axis: "A", "B" or "C".
        step_scale: scales every step bound (grid, slip step, ringing step); halve it to
            check convergence.
        model: a prebuilt :class:`TurntableModel` (saves the packing); it may belong to another
            parameter set with the same table and tubes (friction, preload and amplifier are
            taken from ``params``: the condensation only needs the bodies).
        analytic: all-stick phases with a linear amplifier take the analytic step (event
            search on the modal solution, :mod:`turntable_env.reduced_kernel`); off by
            default: ``turntable bench`` measures it no faster than the ladder where no
            output is recorded (the env), since sampling the ring near a stuck element's
            capacity costs as much as the ladder steps it replaces.
        resume_rung: a step shortened to land on an output time (the integrator stops
            on each) leaves the step controller's rung where it was, so the next step
            resumes at full length, instead of growing again by one rung a step from the
            shortened one; a breakpoint, where the input's slope changes, still caps the
            rung. About half the steps of a trace recorded at 20 kHz
            (``experiments/landing_accuracy.py``). On by default since stop 84; False
            is the restart rule the independent calibration tables of earlier stops ran
            under (the steps' ends, where transitions are checked, move: sub-nm on a
            20 kHz trace, the same script). The env's golden steps are the same bit for
            bit under both (``experiments/kernel_golden.py --compare``).
    """

    def __init__(
        self,
        params: ParameterSet | Literal["real", "thesis"] = "real",
        axis: str = "B",
        *,
        step_scale: float = 1.0,
        model: TurntableModel | None = None,
        analytic: bool = False,
        translation: bool = False,
        resume_rung: bool = True,
    ) -> None:
        if analytic and translation:
            raise ValueError("analytic=True: the analytic all-stick step has no translation")
        ps = get_parameter_set(params) if isinstance(params, str) else params
        self.params = ps
        if model is not None and (
            model.params.table != ps.table
            or model.params.tube != ps.tube
            or model.params.rig.drive_mode != ps.rig.drive_mode
        ):
            raise ValueError("model: its table, tubes or drive mode differ from those of params")
        self.full = model if model is not None else TurntableModel(ps)
        self.axis = axis
        self.step_scale = check_positive("step_scale", step_scale)
        self.analytic = bool(analytic)
        self.resume_rung = bool(resume_rung)
        fn = ps.contact.preload  # type: ignore[union-attr]
        condensed = AxisParameters.from_model(self.full, axis)
        self.axis_params = replace(condensed, normal_force=(fn, fn))
        self.translation_params = (
            TranslationParameters.from_model(self.full, axis, ps) if translation else None
        )
        self._tops: dict[str, Any] | None = None  # the translation form's bodies
        with one_blas_thread():  # 10×10 expm ladders: a second BLAS thread only waits here
            self._pack()

    @property
    def n_state(self) -> int:
        """Length of the state y: 6 (θ, u1, u2 and their rates), 48 with the translation
        (the 24 coordinates of :meth:`translation_matrices` and their rates)."""
        return 6 if self.translation_params is None else N_TRANSLATION

    @property
    def state_names(self) -> tuple[str, ...]:
        """The name of each entry of the state y (a coordinate, then its rate)."""
        if self.translation_params is None:
            return _STATE_NAMES
        return tuple(f"{c}{r}" for c in self._tube_tops()["names"] for r in ("", " rate"))

    def _tube_tops(self) -> dict[str, Any]:
        """The translation form's bodies in its coordinates p (24, see
        :meth:`translation_matrices`); computed once.

        The 3-D model's coordinates z: the table's centre x and rotation vector φ (world
        frame), then each tube top's twist (θx, θy, θz, ux, uy, uz) with the 3-D model's
        mass, stiffness, damping β K and drive per quadrant volt (``mtube``, ``ktop``,
        ``dtop``, ``bcoup``: the tube tops not condensed, so the tubes' rotational inertia
        and their coupling between directions are the 3-D model's). A contact's slip along
        a tangent t is its ball point's less the table's, (r_c × t, t)·ξ_k − t·(x + φ × R
        d_k), its approach d_k·x − (r_c × d_k, d_k)·ξ_k. p = P z: θ = n·φ, each driving
        tube's contact point along its driving direction e_k, the table's translation and
        tilts in (d_1, d_2, n), then each driving top's twist but the translation that
        its contact point replaces, and the axis tube's top."""
        if self._tops is not None:
            return self._tops
        model, ps = self.full, self.params
        ar = model.packed
        c_ax = axis_index(self.axis)
        n = np.asarray(model.layout.axis_units[c_ax], float)
        drv = [k for k in range(3) if k != c_ax]
        basis = [np.asarray(ar["d_nom"][k], float) for k in drv] + [n]  # d_1, d_2, n
        nz = 24
        mass, kz, cz, bz = (np.zeros((nz, nz)), np.zeros((nz, nz)), np.zeros((nz, nz)),
                            np.zeros(nz))  # fmt: skip
        m = float(ar["table_p"][0])
        cb = np.asarray(ar["c_body"], float)  # the centre of mass from the centre [m]
        skew = np.array([[0.0, -cb[2], cb[1]], [cb[2], 0.0, -cb[0]], [-cb[1], cb[0], 0.0]])
        vmap = np.hstack([np.eye(3), -skew])  # v_com = ẋ + φ̇ × c
        mass[:6, :6] = m * vmap.T @ vmap
        mass[3:6, 3:6] += np.linalg.inv(ar["jinv"])  # J about the centre of mass
        h = float(np.linalg.norm(cb))
        if h > 0.0:  # gravity's pendulum on φ (Eq. C.16), which vanishes with h
            kz[3:6, 3:6] = m * float(model.gravity) * (h * np.eye(3) - np.outer(cb, cb) / h)
        radius = float(ps.table.radius)

        def slip_row(k: int, t: np.ndarray) -> np.ndarray:
            d = np.asarray(ar["d_nom"][k], float)
            r_c = ar["r0"][k] - ps.tube.outer_radius * d  # tube top → contact point [m]
            row = np.zeros(nz)
            row[:3], row[3:6] = -t, -radius * np.cross(d, t)
            row[6 + 6 * k : 12 + 6 * k] = np.concatenate([np.cross(r_c, t), t])
            return row

        for k in range(3):
            sl = slice(6 + 6 * k, 12 + 6 * k)
            mass[sl, sl], kz[sl, sl], cz[sl, sl] = ar["mtube"][k], ar["ktop"][k], ar["dtop"][k]
            bz[sl] = ar["bcoup"][k] @ ((ar["qchan"][k] == c_ax) * ar["qsign"][k])
        e = [np.cross(n, basis[j]) / np.linalg.norm(np.cross(n, basis[j])) for j in range(2)]
        driving = [slip_row(k, e[j]) for j, k in enumerate(drv)]
        side = [slip_row(k, n) for k in drv]
        axis = [slip_row(c_ax, basis[j]) for j in range(2)]
        # d·x less the ball's point along d (d·(φ × R d) = 0)
        approach = [-slip_row(k, np.asarray(ar["d_nom"][k], float)) for k in (*drv, c_ax)]
        rows, names, dropped = [], [], []
        angle = np.zeros(nz)
        angle[3:6] = n
        rows.append(angle)
        names.append("table angle")
        for j, k in enumerate(drv):
            u = driving[j].copy()
            u[:6] = 0.0  # the contact point along e_k
            rows.append(u)
            names.append(f"tube {j + 1} contact displacement")
            dropped.append(6 + 6 * k + 3 + int(np.argmax(np.abs(u[9 + 6 * k : 12 + 6 * k]))))
        for j, label in enumerate(("1", "2", "along the axis")):  # x in (d_1, d_2, n)
            row = np.zeros(nz)
            row[:3] = basis[j]
            rows.append(row)
            names.append(f"sphere translation {label}")
        for j in range(2):  # the tilts about d_1, d_2
            row = np.zeros(nz)
            row[3:6] = basis[j]
            rows.append(row)
            names.append(f"table tilt {j + 1}")
        tube_of = {k: ("1", "2")[j] for j, k in enumerate(drv)} | {c_ax: "on the axis"}
        comp = ("rotation x", "rotation y", "rotation z", "x", "y", "z")
        for k in (*drv, c_ax):
            for i in range(6):
                if 6 + 6 * k + i not in dropped:
                    rows.append(np.eye(nz)[6 + 6 * k + i])
                    names.append(f"tube {tube_of[k]} top {comp[i]}")
        q = np.linalg.inv(np.array(rows))  # z = Q p
        self._tops = {
            "mass": q.T @ mass @ q, "stiffness": q.T @ kz @ q, "damping": q.T @ cz @ q,
            "drive": q.T @ bz, "driving": np.array(driving) @ q, "side": np.array(side) @ q,
            "axis": np.array(axis) @ q, "approach": np.array(approach) @ q,
            "names": tuple(names),
        }  # fmt: skip
        return self._tops

    def _slip_rows(self) -> np.ndarray:
        """(2, 2, n_state): each driving contact's slip (tube point − table point) [m] and
        its rate [m/s] as rows over y: u_k − ρ_kθ; (4, 2, n_state) with the translation
        (:meth:`_tube_tops`), whose rows 2 and 3 are the driving contacts' slips along the
        axis n (:meth:`_side_rows`)."""
        ny = self.n_state
        if self.translation_params is None:
            rows = np.zeros((2, 2, ny))
            for k in range(2):
                for r in range(2):
                    rows[k, r, 2 + 2 * k + r] = 1.0
                    rows[k, r, r] = -self.axis_params.lever[k]
            return rows
        tops = self._tube_tops()
        rows = np.zeros((4, 2, ny))
        for k, row in enumerate((*tops["driving"], *tops["side"])):
            rows[k, 0, 0::2] = row
            rows[k, 1, 1::2] = row
        return rows

    def _side_rows(self) -> np.ndarray:
        """(2, 24): each driving contact's slip along the axis n over p (see
        :meth:`translation_matrices`) [m]: the second tangent direction of its contact
        plane, where its GMS elements are loaded and slip with the driving direction's
        (the 2-D law of §3.3.2, :mod:`turntable_env.friction.gms2d`)."""
        return self._tube_tops()["side"]

    def _stuck_rows(self) -> np.ndarray:
        """(4, 24): the slips over p of the contact directions beside the driving ones
        (tube point − table point): the axis contact along d_1 and d_2, then each driving
        contact along n."""
        tops = self._tube_tops()
        return np.vstack([tops["axis"], tops["side"]])

    def _normal_rows(self) -> np.ndarray:
        """(2, n_state + 2): each driving contact's normal force less F_N [N] as a row over
        (y, V, V̇): k_H(x_k − a_k) + d_c(ẋ_k − ȧ_k), the stroke in a_k (see
        :class:`TranslationParameters`); zero without the translation."""
        ny = self.n_state
        rows = np.zeros((2, ny + 2))
        tr = self.translation_params
        if tr is not None:
            for k, row in enumerate(self._tube_tops()["approach"][:2]):
                rows[k, 0:ny:2] = tr.hertz_stiffness * row
                rows[k, 1:ny:2] = tr.normal_damping * row
        return rows

    def _system_translation(self, s_stuck: tuple[float, float]) -> np.ndarray:
        """Augmented 54×54 matrix of (y, V, V̇, f1, f2, g1, g2) with the translation (y as
        :attr:`n_state`; see :class:`TranslationParameters`): M q̈ = −K q − C q̇ + b_V V +
        b_V̇ V̇ − Σ_k (S_k F_k + N_k G_k) over q of :meth:`translation_matrices` without the
        driving contacts' directions along n, F_k = s_k S_k q + d_k S_k q̇ + f_k the driving
        contacts' friction along their driving directions and G_k = s_k N_k q + d_k N_k q̇
        + g_k along n (Eq. 2.24 in the contact plane, §3.3.2: one stuck stiffness s_k for
        both, the elements sticking or slipping as 2-vectors)."""
        fr = self.params.friction
        assert fr is not None
        beta_t = self.params.contact.tangential_damping  # type: ignore[union-attr]
        mass, kq, cq, b_v, b_vd = self.translation_matrices(side_stuck=False)
        nq = mass.shape[0]
        ny = 2 * nq
        a = np.zeros((ny + 6, ny + 6))
        rows = self._slip_rows()
        acc = np.zeros((nq, ny + 6))  # generalised forces as rows over the augmented state
        acc[:, 0:ny:2] -= kq
        acc[:, 1:ny:2] -= cq
        acc[:, ny] += b_v
        acc[:, ny + 1] += b_vd
        for k in range(4):  # driving directions, then along n: contact k % 2, input column
            sq = rows[k, 0, 0:ny:2]  # slip over q
            d = fr.stribeck.sigma2 + beta_t * s_stuck[k % 2]
            frow = np.zeros(ny + 6)
            frow[:ny] = s_stuck[k % 2] * rows[k, 0] + d * rows[k, 1]
            frow[ny + 2 + k] = 1.0
            acc -= np.outer(sq, frow)
        for i in range(nq):
            a[2 * i, 2 * i + 1] = 1.0
        a[1:ny:2] = np.linalg.solve(mass, acc)
        a[ny, ny + 1] = 1.0
        return a

    def translation_matrices(self, side_stuck: bool = True) -> tuple[np.ndarray, ...]:
        """(M, K, C, b_V, b_V̇) over p [SI] of the model with the translation, without the
        driving contacts' friction (see :meth:`_system_translation`): M p̈ + C ṗ + K p =
        b_V V + b_V̇ V̇ + friction (b_V̇ = 0: the quadrant voltages drive the tube tops).

        p (24): θ, the driving tubes' contact points along their driving directions u_1,
        u_2, the table's translation x_1, x_2, x_n and tilts φ_1, φ_2 in (d_1, d_2, n), then
        the three tube tops' twists (:meth:`_tube_tops`: the 3-D model's table and tube
        tops, linearised at rest). Each contact's normal spring is Hertz's law linearised at
        F_N with the normal damping (Eq. 3.21: k_H on the approach); the axis contact's
        tangent directions are stuck (Σk_i and its damping), and so are the driving
        contacts' directions along n where ``side_stuck`` (every element stuck, as at
        rest), else they are left to the friction."""
        tr = self.translation_params
        if tr is None:
            raise ValueError("translation_matrices: this model has no translation")
        tops = self._tube_tops()
        mass, kq, cq = tops["mass"].copy(), tops["stiffness"].copy(), tops["damping"].copy()
        b_v = tops["drive"].copy()
        for row in tops["approach"]:  # each ball on the table: Hertz's spring
            kq += tr.hertz_stiffness * np.outer(row, row)
            cq += tr.normal_damping * np.outer(row, row)
        stuck = self._stuck_rows()  # the stuck directions' slips
        for row in stuck if side_stuck else stuck[:2]:
            kq += tr.stuck_stiffness * np.outer(row, row)
            cq += tr.stuck_damping * np.outer(row, row)
        return mass, kq, cq, b_v, np.zeros_like(b_v)

    # ------------------------------------------------------------------------------
    def _system(self, s_stuck: tuple[float, float]) -> np.ndarray:
        """Augmented 10×10 matrix of (θ, θ̇, u1, u̇1, u2, u̇2, V, V̇, f1, f2) with the stuck
        stiffness s_stuck[k] on each contact (see module docstring); 34×34 with the
        translation (:meth:`_system_translation`)."""
        if self.translation_params is not None:
            return self._system_translation(s_stuck)
        ap = self.axis_params
        fr = self.params.friction
        assert fr is not None
        sig2 = fr.stribeck.sigma2
        beta_t = self.params.contact.tangential_damping  # type: ignore[union-attr]
        a = np.zeros((10, 10))
        a[0, 1] = 1.0
        a[0 + 1, 0] = -ap.gravity_stiffness / ap.inertia
        a[6, 7] = 1.0
        for k in range(2):
            iu, iv = 2 + 2 * k, 3 + 2 * k
            rho, s = ap.lever[k], s_stuck[k]
            d = sig2 + beta_t * s
            # F_k = s (u − ρθ) + d (u̇ − ρθ̇) + f_k, as a row over the state
            frow = np.zeros(10)
            frow[iu] += s
            frow[0] -= s * rho
            frow[iv] += d
            frow[1] -= d * rho
            frow[8 + k] += 1.0
            a[1] += rho * frow / ap.inertia
            a[iu, iv] = 1.0
            m, kt, dt = ap.tube_mass[k], ap.tube_stiffness[k], ap.tube_damping[k]
            a[iv, iu] -= kt / m
            a[iv, iv] -= dt / m
            a[iv, 6] += kt * ap.tube_gain[k] / m
            a[iv] -= frow / m
        return a

    def stick_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear dynamics with every GMS element stuck: ẏ = A y + b V for the state
        y = (θ, θ̇, u1, u̇1, u2, u̇2) [rad, rad/s, m, m/s, m, m/s] and the channel voltage V
        [V] (amplifier output), element forces at their current offset held constant.
        Returns (A (6, 6), b (6,))."""
        kk = float(np.sum(self.packed["kk"]))
        a = self._system((kk, kk))
        ny = self.n_state
        return a[:ny, :ny].copy(), a[:ny, ny].copy()

    def _pack(self) -> None:
        fr = self.params.friction
        assert fr is not None
        ap = self.axis_params
        kk = np.asarray(fr.k, float)
        nu = np.asarray(fr.nu, float)
        ne = kk.size
        # stuck-stiffness levels of a contact: distinct Σ_{stuck} k_i over the 2^ne masks
        sums = np.array([sum(kk[i] for i in range(ne) if m >> i & 1) for m in range(1 << ne)])
        levels: list[float] = []
        lvl_of = np.empty(1 << ne, dtype=np.int64)
        tol = 1e-12 * float(kk.sum())
        for m, sm in enumerate(sums):
            for j, lv in enumerate(levels):
                if abs(lv - sm) <= tol:
                    lvl_of[m] = j
                    break
            else:
                lvl_of[m] = len(levels)
                levels.append(float(sm))
        nl = len(levels)
        h = H_MIN * self.step_scale
        a_stick = self._system((float(kk.sum()), float(kk.sum())))
        ny = self.n_state
        a6 = a_stick[:ny, :ny]
        lam, vec = np.linalg.eig(a6)
        om = np.abs(lam)
        omega_hi = float(np.max(om))
        ring_frac = RING_FRACTION * self.step_scale
        slip_step = SLIP_STEP
        if self.translation_params is not None:
            slip_step = min(slip_step, MOVED_SLIP_FRACTION * 2.0 * math.pi / omega_hi)
        r_slip = math.floor(math.log2(max(slip_step * self.step_scale / h, 1.0)))
        # quasi-static state per unit input (V, f1, f2) and modal projections (all stick)
        n_in = a_stick.shape[0] - ny  # inputs: V, V̇, the contacts' constant forces
        qs = -np.linalg.solve(a6, a_stick[:ny, [ny, *range(ny + 2, ny + n_in)]])
        srow = self._slip_rows()
        c_rel = np.ascontiguousarray(srow[:2, 0, :])
        # rungs of the configurations with a slipping element: the per-axis form's count in
        # both forms, so that a batch holds either form's arrays (ReducedBatch.set_model)
        r_small = math.floor(math.log2(max(SLIP_STEP * self.step_scale / h, 1.0))) + 1
        systems = np.stack([self._system((levels[i0], levels[i1]))
                            for i0 in range(nl) for i1 in range(nl)])  # fmt: skip
        small = _ladders(systems, h, r_small)  # (nl², r_small, ny + inputs, ny + inputs)
        phi_s = np.ascontiguousarray(small[:, :, :ny, :ny])
        gam_s = np.ascontiguousarray(small[:, :, :ny, ny : ny + n_in])
        e = _ladders(a_stick[None], h, MAX_RUNG + 1)[0]
        amp = self.params.amplifier
        c_load = self.full.output_capacitance(self.axis)
        breakaway = min(
            n_ * fr.stribeck.mu_s * min(ap.normal_force) / k_ for n_, k_ in zip(nu, kk, strict=True)
        )
        s = fr.stribeck
        self.packed = {
            "mech": np.array(
                [
                    ap.inertia,
                    ap.gravity_stiffness,
                    *ap.lever,
                    *ap.tube_mass,
                    *ap.tube_stiffness,
                    *ap.tube_damping,
                    *ap.tube_gain,
                    *ap.normal_force,
                ]
            ),
            "gms": np.array(
                [
                    fr.C,
                    s.mu_s,
                    s.mu_c,
                    s.v_s,
                    s.delta,
                    s.sigma2,
                    self.params.contact.tangential_damping,
                    0.0,  # sliding-direction asymmetry α (friction_asymmetry, set per run)
                ]  # type: ignore[union-attr]
            ),
            "nu": nu,
            "kk": kk,
            "amp": amp.kernel_row(c_load),
            "ctl": np.array([QUIET_LENGTH * breakaway, r_slip, float(self.resume_rung)]),
            "qs": qs,
            "modal_w": np.linalg.inv(vec),
            "modal_c": (c_rel @ vec).astype(complex),
            "modal_om": om,
            "modal_om_max": np.array(omega_hi),
            "q2": np.linalg.solve(a6, qs[:, 0]),
            "modal_v": vec.astype(complex),
            "modal_lam": lam.astype(complex),
            "use_modal": self.analytic,
            "ring_frac": ring_frac,
            "lvl": np.stack([lvl_of, lvl_of]),
            "nlvl": np.array([nl, nl], dtype=np.int64),
            "phi_small": phi_s,
            "gam_small": gam_s,
            "phi_big": e[:, :ny, :ny].copy(),
            "gam_big": e[:, :ny, ny : ny + n_in].copy(),
            "srow": srow,
            "nrow": self._normal_rows(),
            "h": h,
            "omega": (float(np.min(om)), omega_hi),
        }

    @property
    def grid(self) -> float:
        """Time grid of the integrator [s]."""
        return self.packed["h"]

    def initial_state(self, channel_voltage: float = 0.0) -> dict[str, np.ndarray]:
        """Rest state at θ = 0: the tubes bent freely by the channel voltage [V] (u_k = g_k V)
        and the GMS elements unloaded, as the full model's static equilibrium starts."""
        return self.rest_state(0.0, channel_voltage)

    def rest_state(self, angle: float, channel_voltage: float = 0.0) -> dict[str, np.ndarray]:
        """Static equilibrium at table angle θ [rad] with every GMS element stuck.

        The contacts hold the pendulum torque k_gθ (ΣρF_k = k_gθ, F_k ∝ ρ_k), shared by the
        elements in proportion to k_i; each tube is bent by its free deflection g_kV less
        F_k/K_k. With the translation the driving contacts' elements also hold the side
        tubes' deflection along the axis n (their slips there, shared in proportion to
        k_i, an element whose load there would pass its capacity held at it): ``f`` is (4,
        n_e), the driving directions' forces of contacts 1 and 2, then their components
        along n (zero in the per-axis form). Raises ValueError if an element would have to
        exceed its capacity ν_iμ_sF_N along the driving direction.
        """
        th = check_finite("angle", angle)
        v = check_finite("channel_voltage", channel_voltage)
        ap = self.axis_params
        kk = self.packed["kk"]
        nu = self.packed["nu"]
        rho = np.asarray(ap.lever)
        force = ap.gravity_stiffness * th * rho / float(rho @ rho)  # N on the table
        f = np.outer(force, kk / kk.sum())
        mu_s = self.params.friction.stribeck.mu_s  # type: ignore[union-attr]
        y = np.zeros(self.n_state)
        y[0] = th
        y[2:6:2] = np.asarray(ap.tube_gain) * v - force / np.asarray(ap.tube_stiffness)
        if self.translation_params is not None:  # K q = b_V V − Σ S_k F_k, θ given
            _m, kq, _c, b_v, _bd = self.translation_matrices()
            sq = self._slip_rows()[:2, 0, 0::2]
            rhs = b_v * v - sq.T @ force - kq[:, 0] * th
            y[2::2] = np.linalg.solve(kq[1:, 1:], rhs[1:])
        side = np.zeros((2, kk.size))  # the elements' components along n [N]
        if self.translation_params is not None:
            side = np.outer(self._side_rows() @ y[0::2], kk)
        nrow = self._normal_rows()  # the normal forces at rest (F_N without translation)
        fn_rest = np.asarray(ap.normal_force) + nrow[:, : self.n_state] @ y + nrow[:, -2] * v
        cap = nu[None, :] * mu_s * fn_rest[:, None]  # N
        if (np.abs(f) >= cap).any():
            raise ValueError(f"angle={angle!r}: friction cannot hold the table there")
        # an element whose load along n would pass its capacity (a large voltage at rest)
        # holds its share there: it slipped along n as the voltage came on
        room = np.sqrt(np.maximum(cap**2 - f**2, 0.0))
        side = np.clip(side, -room, room)
        a = self.params.amplifier.fast_fraction
        return {
            "y": y, "volt": np.array(v), "f": np.vstack([f, side]),
            "st": np.ones_like(f, dtype=np.int64),
            "vslow": np.array((1.0 - a) * v), "vfast": np.array(a * v),
        }  # fmt: skip


_SCALARS = ("ring_frac", "use_modal")
_STACKED = tuple(f for f in ReducedArrays._fields if f not in _SCALARS)


class ReducedBatch:
    """N reduced turntables and their states, advanced together by one compiled call and
    resumable (the integrator state persists between :meth:`advance` calls).

    Args:
        models: one :class:`ReducedModel` per turntable (same grid and GMS element count).

    Attributes:
        state: the :class:`~turntable_env.kernel_types.ReducedState` (named views:
            :attr:`angle`, :attr:`angular_velocity`, :attr:`tube_displacement`, :attr:`volt`,
            :attr:`stick`).
        counters: (N, 4) accepted steps, rejected steps, status of the last call,
            evaluations of the all-stick analytic solution.
    """

    def __init__(self, models: Sequence[ReducedModel]) -> None:
        if not models:
            raise ValueError("models: need at least one model")
        self.grid = models[0].grid
        ne = models[0].packed["kk"].size
        for i, m in enumerate(models):
            if m.grid != self.grid or m.packed["kk"].size != ne:
                raise ValueError(f"models[{i}]: grid or GMS element count differs from models[0]")
        self.models = list(models)
        nb = len(models)
        stacked: dict[str, np.ndarray] = {}
        for name in _STACKED:
            arrs = [m.packed[name] for m in models]
            shape = np.max([a.shape for a in arrs], axis=0)
            stacked[name] = np.zeros((nb, *shape), dtype=arrs[0].dtype)
            for b, a in enumerate(arrs):
                stacked[name][(b, *tuple(slice(0, s) for s in a.shape))] = a
        for name in _SCALARS:
            if any(m.packed[name] != models[0].packed[name] for m in models):
                raise ValueError(f"models: {name} differs between models")
        self.arrays = ReducedArrays(**stacked, **{k: models[0].packed[k] for k in _SCALARS})
        self._mu = self.arrays.gms[:, 1:3].copy()  # μ_s, μ_c of each model (friction scale 1)
        self._forms = form_counts(self.arrays.nrow)  # (per-axis, translating) turntables
        self.state = ReducedState(
            y=np.zeros((nb, max(m.n_state for m in models))),
            volt=np.zeros(nb),
            f=np.zeros((nb, 4, ne)),
            st=np.ones((nb, 2, ne), dtype=np.int64),
            n=np.zeros(nb, dtype=np.int64),
            vslow=np.zeros(nb),
            vfast=np.zeros(nb),
        )
        self.counters = np.zeros((nb, 4), dtype=np.int64)

    def __len__(self) -> int:
        return len(self.models)

    # named views of the state -----------------------------------------------------------
    @property
    def angle(self) -> np.ndarray:
        """(N,) table angle θ [rad] (a view)."""
        return self.state.y[:, 0]

    @property
    def angular_velocity(self) -> np.ndarray:
        """(N,) θ̇ [rad/s] (a view)."""
        return self.state.y[:, 1]

    @property
    def tube_displacement(self) -> np.ndarray:
        """(N, 2) contact-point displacement of the two driving tubes [m] (a view)."""
        return self.state.y[:, 2:6:2]

    @property
    def volt(self) -> np.ndarray:
        """(N,) amplifier output on the channel [V] (a view)."""
        return self.state.volt

    @property
    def stick(self) -> np.ndarray:
        """(N, 2, n_e) 1 where a GMS element sticks (a view)."""
        return self.state.st

    @property
    def time(self) -> np.ndarray:
        """(N,) simulated time [s]."""
        return self.state.n * self.grid

    # -------------------------------------------------------------------------------------
    def set_model(self, b: int, model: ReducedModel) -> None:
        """Replace turntable b's model (e.g. domain randomisation); arrays must fit."""
        if model.grid != self.grid or model.step_scale != self.models[0].step_scale:
            raise ValueError("model: grid differs from the batch's")
        for name in _STACKED:
            a = np.asarray(model.packed[name])
            dest = getattr(self.arrays, name)
            shape = dest.shape[1:]
            if a.ndim != len(shape) or any(s > d for s, d in zip(a.shape, shape, strict=True)):
                raise ValueError(f"model: array {name!r} {a.shape} does not fit {shape}")
            row = np.zeros(shape, dtype=dest.dtype)
            row[tuple(slice(0, s) for s in a.shape)] = a
            dest[b] = row
        self._mu[b] = self.arrays.gms[b, 1:3]
        self.state.y[b, model.n_state :] = 0.0  # a narrower form's unused states
        self.models[b] = model
        self._forms = form_counts(self.arrays.nrow)

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        """Scale μ_s and μ_c of turntables ``rows`` by ``scale`` [-] from their models' values
        (friction-stage effects, :mod:`turntable_env.effects`); 1 restores them."""
        self.arrays.gms[rows, 1:3] = self._mu[rows] * np.asarray(scale, dtype=float)[..., None]

    def set_friction_asymmetry(self, rows: np.ndarray, alpha: np.ndarray) -> None:
        """μ_s and μ_c of turntables ``rows`` × (1 + ``alpha``) while the table slides
        forward over a tube and × (1 − ``alpha``) backward (the ``friction_asymmetry``
        effect, :mod:`turntable_env.effects`); 0 restores symmetric friction."""
        self.arrays.gms[rows, 7] = np.asarray(alpha, dtype=float)

    def set_state(self, b: int, state: dict[str, np.ndarray], time: float = 0.0) -> None:
        """Set turntable b's state (from :meth:`ReducedModel.rest_state`) at ``time`` [s]."""
        st = self.state
        y = np.asarray(state["y"], dtype=float)
        if y.size != self.models[b].n_state:
            raise ValueError(
                f"state['y']: {y.size} states, turntable {b}'s model has {self.models[b].n_state}"
            )
        st.y[b] = 0.0
        st.y[b, : y.size] = y
        st.volt[b] = float(state["volt"])
        st.f[b] = state["f"]
        st.st[b] = state["st"]
        st.n[b] = round(time / self.grid)
        st.vslow[b] = float(state["vslow"])
        st.vfast[b] = float(state["vfast"])

    def advance(
        self,
        drive: DriveArrays,
        n_end: np.ndarray,
        out_every: np.ndarray,
        rec: np.ndarray,
        n_rec: np.ndarray,
    ) -> None:
        """Integrate every turntable to grid time n_end[b] under its input breakpoints
        (grid units, [V]), recording every out_every[b] grid units into rec (see
        :func:`~turntable_env.reduced_kernel.run_reduced_batch`).

        Raises:
            SimulationError: a state became non-finite (names the state, turntable and time).
        """
        self.counters[:, 2] = 0
        kernel = run_reduced_batch if len(self) > 1 else run_reduced_serial
        kernel(
            self.state, self.arrays, drive, self.grid,
            ReducedRecording(n_end, out_every, rec, n_rec, self.counters), self._forms,
        )  # fmt: skip
        bad_b = np.nonzero(self.counters[:, 2] != 0)[0]
        if bad_b.size:
            b = int(bad_b[0])
            bad = [i for i in range(self.state.y.shape[1]) if not np.isfinite(self.state.y[b, i])]
            name = self.models[b].state_names[bad[0]] if bad else "amplifier voltage"
            raise SimulationError(
                "non-finite",
                float(self.state.n[b] * self.grid),
                f"reduced model {name} (turntable {b})",
            )


def waveform_arrays(waves: Sequence[Waveform], grid: float) -> DriveArrays:
    """Breakpoints of every turntable's input on the grid [s] (rounded), values [V]."""
    nbp = max(max(w.times.size for w in waves), 1)
    wg = np.zeros((len(waves), nbp))  # breakpoints in grid units (integers, as floats)
    wv = np.zeros((len(waves), nbp))
    wn = np.ones(len(waves), dtype=np.int64)
    for b, w in enumerate(waves):
        wg[b, : w.times.size] = np.rint(w.times / grid)
        wv[b, : w.times.size] = w.values
        wn[b] = w.times.size
    return DriveArrays(wg, wv, wn)


def simulate_batch(
    models: Sequence[ReducedModel],
    drives: Sequence[DriveSignal | Waveform],
    duration: float,
    *,
    output_dt: float = 1e-5,
) -> list[AxisResponse]:
    """Run N reduced turntables (own parameters, own drives) together in one compiled call.

    Args:
        models: one :class:`ReducedModel` per turntable (same number of GMS elements and the
            same ``step_scale``).
        drives: one channel input per turntable (DriveSignal or Waveform, starting at 0).
        duration: simulated time [s], the same for all.
        output_dt: sample interval [s], a multiple of the grid (rounded to it).

    Raises:
        ValueError: mismatched lengths or models; SimulationError: a state diverged.
    """
    if len(models) != len(drives) or not models:
        raise ValueError(
            f"models/drives: need equal, non-zero lengths ({len(models)}, {len(drives)})"
        )
    dur = check_positive("duration", duration)
    check_positive("output_dt", output_dt)
    batch = ReducedBatch(models)
    h = batch.grid
    nb = len(models)
    waves = []
    for b, (m, d) in enumerate(zip(models, drives, strict=True)):
        w = m.full.drive_waveforms({m.axis: d})[m.axis]
        waves.append(w)
        amp = m.params.amplifier
        u0 = np.clip(w(0.0)[()], -amp.input_limit, amp.input_limit) * amp.gain
        batch.set_state(b, m.initial_state(u0))
    drive_arrays = waveform_arrays(waves, h)
    out_every = max(round(output_dt / h), 1)
    n_end = round(dur / h)
    n_out = n_end // out_every + 1
    rec = np.zeros((nb, n_out, N_REC))
    n_rec = np.zeros(nb, dtype=np.int64)
    wall0 = _time.perf_counter()
    batch.advance(
        drive_arrays, np.full(nb, n_end, dtype=np.int64), np.full(nb, out_every, dtype=np.int64),
        rec, n_rec,
    )  # fmt: skip
    wall = _time.perf_counter() - wall0
    counters = batch.counters
    out = []
    for b, (m, d) in enumerate(zip(models, drives, strict=True)):
        r = rec[b, : n_rec[b]]
        starts = d.period_starts(r[-1, 0]) if isinstance(d, DriveSignal) else np.empty(0)
        out.append(
            AxisResponse(
                time=r[:, 0].copy(),
                angle_rad=r[:, 1].copy(),
                angular_velocity=r[:, 2].copy(),
                voltage=r[:, 3].copy(),
                tube_displacement=r[:, 4:6].copy(),
                slip=r[:, 6:8].copy(),
                friction=r[:, 8:10].copy(),
                n_stick=r[:, 10:12].astype(np.int64),
                axis=m.axis,
                detector=m.params.detector,
                table_radius=m.params.table.radius,
                period_starts=starts,
                info={
                    "params": m.params.name,
                    "steps": int(counters[b, 0]),
                    "rejected": int(counters[b, 1]),
                    "analytic_evaluations": int(counters[b, 3]),
                    "grid_s": h,
                    "wall_s": wall,
                    "batch": nb,
                },
            )
        )
    return out


def simulate_reduced(
    params: ParameterSet | Literal["real", "thesis"],
    drive: DriveSignal | Waveform,
    duration: float | None = None,
    *,
    axis: str = "B",
    settle: float = 0.0,
    output_dt: float = 1e-5,
    step_scale: float = 1.0,
    model: ReducedModel | None = None,
) -> AxisResponse:
    """Run the reduced model of ``axis`` from rest (see :func:`simulate_batch`)."""
    mdl = model if model is not None else ReducedModel(params, axis, step_scale=step_scale)
    if duration is None:
        end = drive.start + drive.duration if isinstance(drive, DriveSignal) else drive.end
        duration = end + settle
    return simulate_batch([mdl], [drive], duration, output_dt=output_dt)[0]

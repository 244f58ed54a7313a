"""The assembled turntable of chapter 3: table, three tubes, three contacts, drive, detector.

Frames and alignment (§3.1, §3.3.2)
-----------------------------------
World frame: origin at the sphere centre of the unloaded table, z up. Tube k ∈
{A, B, C} lies along the unit vector d_k from the sphere centre through its
contact point, at α = 35.26° below the horizon (Eq. 3.2) and 120° apart, so
d_A, d_B, d_C are orthonormal and right-handed (d_A × d_B = d_C). Along d_k: the
contact at R_table, the ball centre at R_table + R_o, the tube's end face a seat
height further, its base L beyond that.

Each tube frame has z_k = −d_k (base → table). Its quadrants bend the tip along
±x_k, ±y_k with x_k = d_X × d_k, X the next tube (A→B→C→A): the bending
directions are the other two tube axes, i.e. turned 45° from the horizontal
tangent of the contact circle (§3.3.2). Hence (Fig. 3.1):

* rotation about tube axis X (+d_X, right-handed): the quadrant of each other tube
  k that bends along d_X × d_k — channel X drives two quadrants;
* rotation about z (up): the remaining two quadrants of every tube — channel Z
  drives six.

A positive voltage on a channel turns the table positively about its axis.

Bodies (§3.2.1): the table is a rigid body in SE(3) (6 DOF, orientation in full
SO(3), CoM 3R/8 below the sphere centre, App. C.3); each tube top is a rigid
body (6 DOF, App. C mass and inertia lumped at the top, as Table D.1 gives them)
on the variable spatial spring of :mod:`turntable_env.tube`, whose displacement
from its nominal pose is a small twist (µrad, nm): the spring's Eq. 3.8–3.9 is
used in its linearisation about coincident frames, ½ξᵀKξ — exact to the
relative size of the motion (< 1e-4).

Contacts (§3.3): sphere–sphere, normal along the line of centres, overlap from
the rigid shapes (Fig. 3.10), normal force k_c δ^e + d_c δ̇ ≥ 0 (contact loss
when separated), the average tangent plane of Eq. 3.24–3.26, 2-D GMS in it with
the current normal force. Spin friction is neglected as in the thesis (§3.3.2).
The preload spring presses on the table's centre with the constant force that
gives each contact its static normal force F_N; gravity acts at the CoM.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import InitVar, dataclass, field

import numpy as np
import scipy.optimize

from .drive import DriveSignal, Waveform
from .integrator import contact_forces, contact_kinematics, quadrant_voltages, run_full_model
from .interrupt import call_interruptibly
from .kernel_types import DriveArrays, FullArrays, FullRecording, FullState
from .params import ParameterSet
from .validation import check_finite, check_positive

__all__ = [
    "AXES",
    "GRAVITY",
    "SimulationError",
    "TurntableLayout",
    "TurntableModel",
    "layout",
]

AXES = ("A", "B", "C", "Z")
GRAVITY = 9.81  # m/s², standard gravity (the laboratory's; not in the thesis)
TUBES = ("A", "B", "C")
# adaptive step (see TurntableModel._step_control)
QUIET_LENGTH = 0.01  # fraction of the weakest element's breakaway displacement
QUIET_LOAD = 4.0  # coarse steps an element's margin to breakaway must last
QUIET_VOLT = 0.5  # V an amplifier channel may move in one coarse step
HOLD_PERIODS = 5.0  # periods of the highest mode at the fine step after a disturbance


class SimulationError(RuntimeError):
    """The integration stopped: a state became non-finite or diverged.

    Attributes:
        time: simulated time at which it was detected [s].
        variable: name of the offending state variable.
        reason: ``"non-finite"``, ``"diverging"`` or ``"rim"``.
    """

    def __init__(self, reason: str, time: float, variable: str) -> None:
        self.reason = reason
        self.time = time
        self.variable = variable
        what = {
            "non-finite": "became non-finite",
            "diverging": "left its physical bound (diverging)",
            "rim": "reached the rim of the half sphere (table turned too far)",
        }[reason]
        super().__init__(f"simulation stopped at t = {time:.9g} s: {variable} {what}")

    def __reduce__(self) -> tuple[type, tuple[str, float, str]]:
        """Pickled by its fields (a worker process or Ray task raises it in the driver)."""
        return (type(self), (self.reason, self.time, self.variable))


def _variable_name(index: int) -> str:
    """Name of a state variable from the kernel's index (see integrator._first_bad)."""
    xyz = "xyz"
    if index < 0:
        return "unknown state"
    if index < 3:
        return f"table CoM displacement {xyz[index]}"
    if index < 6:
        return f"table velocity {xyz[index - 3]}"
    if index < 9:
        return f"table angular momentum {xyz[index - 6]}"
    if index < 45:
        k, a = divmod(index - 9, 12)
        comp = ["θx", "θy", "θz", "ux", "uy", "uz"][a % 6]
        kind = "displacement" if a < 6 else "velocity"
        return f"tube {TUBES[k]} top {kind} {comp}"
    if index < 48:
        return f"contact {TUBES[index - 45]} GMS element forces"
    if index < 52:
        return f"amplifier channel {AXES[index - 48]} voltage"
    if index < 55:
        return f"contact {TUBES[index - 52]} overlap"
    return f"contact {TUBES[index - 55]} position on the table"


@dataclass(frozen=True)
class TurntableLayout:
    """Directions of the assembled turntable (world frame, see module docstring).

    Attributes:
        d: (3, 3) unit vectors sphere centre → contact of tubes A, B, C.
        tube_frames: (3, 3, 3) rotation tube frame → world; columns x_k, y_k, z_k.
        axis_units: (4, 3) unit vectors of the rotation axes A, B, C, Z.
        quadrant_channel: (3, 4) channel index (0..3 = A, B, C, Z) of each quadrant.
        quadrant_sign: (3, 4) +1 or −1: the quadrant sees that sign times its channel's
            voltage (−1 only in the symmetric drive mode).
        drive_mode: "asymmetric" or "symmetric" (§2.1.2, Fig. 2.5).
    """

    d: np.ndarray
    tube_frames: np.ndarray
    axis_units: np.ndarray
    quadrant_channel: np.ndarray
    quadrant_sign: np.ndarray
    drive_mode: str = "asymmetric"

    def channel_quadrants(self, axis: str) -> list[tuple[str, int]]:
        """(tube, quadrant) pairs driven by channel ``axis``."""
        c = axis_index(axis)
        return [
            (TUBES[k], q) for k in range(3) for q in range(4) if self.quadrant_channel[k, q] == c
        ]


def layout(alpha: float, drive_mode: str = "asymmetric") -> TurntableLayout:
    """Build the :class:`TurntableLayout` for the tube angle α [rad] below the horizon.

    ``drive_mode`` (§2.1.2, Fig. 2.5): ``"asymmetric"`` — channel X drives one quadrant of
    each other tube, the remaining six quadrants are channel Z's (the thesis's wiring);
    ``"symmetric"`` — channel X drives that quadrant at +V and the opposite one at −V,
    which doubles the bending (Eq. 2.11 vs 2.12) and cancels the mean axial strain; every
    quadrant then belongs to A, B or C and channel Z drives none."""
    a = check_finite("alpha", alpha)
    if drive_mode not in ("asymmetric", "symmetric"):
        raise ValueError(f"drive_mode={drive_mode!r}: must be 'asymmetric' or 'symmetric'")
    d = np.empty((3, 3))
    for k in range(3):
        phi = math.pi / 2 + 2 * math.pi * k / 3  # A, B, C counter-clockwise seen from above
        d[k] = [math.cos(a) * math.cos(phi), math.cos(a) * math.sin(phi), -math.sin(a)]
    if np.dot(np.cross(d[0], d[1]), d[2]) < 0.0:  # keep d_A × d_B = d_C
        d[[1, 2]] = d[[2, 1]]
    frames = np.empty((3, 3, 3))
    qchan = np.empty((3, 4), dtype=np.int64)
    qsign = np.ones((3, 4))
    for k in range(3):
        nxt, prv = (k + 1) % 3, (k + 2) % 3
        z = -d[k]
        x = np.cross(d[nxt], d[k])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        frames[k] = np.column_stack([x, y, z])
        # +x bends along d_next × d_k (channel next); −y = d_next... see module docstring
        if drive_mode == "asymmetric":
            qchan[k] = [nxt, 3, 3, prv]
        else:  # quadrants +x, +y, −x, −y: the opposite quadrant at minus the voltage
            qchan[k] = [nxt, prv, nxt, prv]
            qsign[k] = [1.0, -1.0, -1.0, 1.0]
    axis_units = np.vstack([d, [0.0, 0.0, 1.0]])
    return TurntableLayout(
        d=d, tube_frames=frames, axis_units=axis_units, quadrant_channel=qchan,
        quadrant_sign=qsign, drive_mode=drive_mode,
    )  # fmt: skip


def axis_index(axis: str) -> int:
    if axis not in AXES:
        raise ValueError(f"axis={axis!r}: must be one of {', '.join(AXES)}")
    return AXES.index(axis)


def _block_rot(r: np.ndarray) -> np.ndarray:
    b = np.zeros((6, 6))
    b[:3, :3] = r
    b[3:, 3:] = r
    return b


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@dataclass(frozen=True, eq=False)
class TurntableModel:
    """The full 3-D model for one parameter set, packed for the compiled integrator.

    Args:
        params: a complete :class:`~turntable_env.params.ParameterSet` (friction and contact set).
        gravity: g [m/s²].
        size_preload: size the preload spring on the settled geometry (default). False
            builds the bodies only — masses, stiffnesses, wiring and layout, what the
            reduced model's condensation and the channel loads read — without the static
            solves; its 3-D dynamics (:attr:`kernel_arrays`, :meth:`static_equilibrium`,
            :attr:`preload_force`) then refuse with a ValueError.

    Attributes (derived in ``__post_init__``): ``layout``, packed arrays, ``omega_max``
    (highest natural frequency of the linearised model [rad/s]).
    """

    params: ParameterSet
    gravity: float = GRAVITY
    size_preload: InitVar[bool] = True
    packed: dict = field(init=False, repr=False)

    def __post_init__(self, size_preload: bool) -> None:
        ps = self.params
        if ps.friction is None or ps.contact is None:
            raise ValueError(
                f"params={ps.name!r}: the 3-D model needs friction and contact parameters"
            )
        check_positive("gravity", self.gravity)
        object.__setattr__(self, "packed", self._pack())
        self.packed["preload_sized"] = bool(size_preload)
        if size_preload:
            self._size_preload()

    def _sized(self) -> dict:
        """The packed arrays of a model whose preload spring is sized (else ValueError)."""
        if not self.packed["preload_sized"]:
            raise ValueError(
                f"model of {self.params.name!r}: built with size_preload=False (the bodies "
                "only); the 3-D dynamics need TurntableModel(params)"
            )
        return self.packed

    def _size_preload(self) -> None:
        """Size the preload spring on the settled geometry so each contact carries F_N.

        The nominal 3F_N sin α = P + mg ignores that the normals tilt as the table settles
        (1e-4 for the real set, 3 % for Table D.2's 5 cm overlap); a few fixed-point steps
        P ← (P + mg)·F_N/F̄_N − mg remove it.
        """
        ar = self.packed
        fn_target = self.params.contact.preload  # type: ignore[union-attr]
        weight = self.params.table.mass * self.gravity
        for _ in range(6):
            x = self.static_equilibrium()
            fn = float(np.mean(self._normal_forces(x)))
            p_new = (ar["table_p"][2] + weight) * fn_target / fn - weight
            done = abs(p_new - ar["table_p"][2]) < 1e-12 * (p_new + weight)
            ar["table_p"][2] = p_new
            ar["preload"] = p_new
            if done:
                break

    def _contact_geometry(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Contacts at rest at positions ``x`` (see :meth:`static_equilibrium`):
        (cinfo, n, x_c, y_c, tube-top → contact, centre → contact), as the kernel fills them."""
        ar = self.packed
        cinfo = np.zeros((3, 5))
        cn, cx, cy, crc, crt = (np.zeros((3, 3)) for _ in range(5))
        z3 = np.zeros(3)
        contact_kinematics(
            x[3:].reshape(3, 6).copy(), x[:3].copy(), ar["d_nom"], ar["r0"], ar["basis_ref"],
            ar["table_p"], np.zeros((3, 6)), z3, z3, cinfo, cn, cx, cy, crc, crt, np.zeros((16, 3)),
        )  # fmt: skip
        return cinfo, cn, cx, cy, crc, crt

    def _normal_forces(self, x: np.ndarray) -> np.ndarray:
        """Normal forces [N] of the three contacts at rest positions ``x``."""
        tp = self.packed["table_p"]
        cinfo = self._contact_geometry(x)[0]
        return np.array([tp[6] * max(d, 0.0) ** tp[7] for d in cinfo[:, 0]])

    # ------------------------------------------------------------------------------
    @property
    def layout(self) -> TurntableLayout:
        return self.packed["layout"]

    @property
    def preload_force(self) -> float:
        """Force of the preload spring on the table's centre [N] (from F_N per contact)."""
        return self._sized()["preload"]

    @property
    def quadrant_capacitance(self) -> float:
        """Free capacitance of one quadrant (Eq. 2.2) [F]."""
        return self.params.tube.quadrant.capacitance

    def load_capacitance(self, axis: str) -> float:
        """Capacitance channel ``axis`` drives [F]: all its quadrants (the electrical
        energy's load)."""
        return len(self.layout.channel_quadrants(axis)) * self.quadrant_capacitance

    def output_capacitance(self, axis: str) -> float:
        """Capacitance on one amplifier output of channel ``axis`` [F] (its current limit's
        load): all the channel's quadrants in the asymmetric mode; in the symmetric mode
        the +V quadrants, the −V ones hanging on a second, inverting output."""
        c = axis_index(axis)
        lay = self.layout
        n = int(np.sum((lay.quadrant_channel == c) & (lay.quadrant_sign > 0.0)))
        return n * self.quadrant_capacitance

    @property
    def omega_max(self) -> float:
        return self.packed["omega_max"]

    def _pack(self) -> dict:
        ps = self.params
        tube, table, contact, fr = ps.tube, ps.table, ps.contact, ps.friction
        assert contact is not None and fr is not None
        geo = ps.geometry
        lay = layout(geo.alpha, ps.rig.drive_mode)
        R = table.radius
        r_ball = tube.outer_radius
        h_seat = tube.seat_height
        r_nom = R + r_ball
        L = tube.length  # bounds below
        # table
        m = table.mass
        c_depth = table.com_depth
        j_centre = table.inertia
        j_com = np.diag([j_centre - m * c_depth**2, j_centre - m * c_depth**2, j_centre])
        sin_a = math.sin(geo.alpha)
        preload = contact.preload_spring_force(m * self.gravity, sin_a)
        # tubes
        kc_t = tube.spring_stiffness
        g_t = tube.rest_twist_per_volt
        cs_t = tube.blocked_capacitance_matrix
        m_t = np.diag([*tube.inertia, tube.mass, tube.mass, tube.mass])
        beta = tube.damping_coefficient
        r0 = np.empty((3, 3))
        mtube = np.empty((3, 6, 6))
        minv = np.empty((3, 6, 6))
        ktop = np.empty((3, 6, 6))
        dtop = np.empty((3, 6, 6))
        bcoup = np.empty((3, 6, 4))
        cs = np.empty((3, 4, 4))
        for k in range(3):
            rk = lay.tube_frames[k]
            bk = _block_rot(rk)
            z = rk[:, 2]
            r0[k] = h_seat * z  # top → ball centre
            r_tc = -tube.stiffness_centre_offset * z  # top → centre of stiffness
            a_map = np.eye(6)
            a_map[3:, :3] = -_skew(r_tc)  # ξ_centre = A ξ_top
            kw = bk @ kc_t @ bk.T
            ktop[k] = a_map.T @ kw @ a_map
            dtop[k] = beta * ktop[k]
            bcoup[k] = a_map.T @ kw @ (bk @ g_t)
            mtube[k] = bk @ m_t @ bk.T
            minv[k] = np.linalg.inv(mtube[k])
            cs[k] = cs_t
        # GMS
        s = fr.stribeck
        gnu = np.asarray(fr.nu, dtype=float)
        gk = np.asarray(fr.k, dtype=float)
        gms_p = np.array(  # with no sliding-direction asymmetry (α, axis: run's arguments)
            [fr.C, s.mu_s, s.mu_c, s.v_s, s.delta, s.sigma2, contact.tangential_damping,
             0.0, 0.0, 0.0, 0.0]
        )  # fmt: skip
        table_p = np.array(
            [
                m,
                self.gravity,
                preload,
                R,
                r_ball,
                r_nom,
                contact.normal_stiffness,
                contact.normal_exponent,
                contact.normal_damping,
                contact.compressibility_tube,
                contact.compressibility_table,
                0.05 * L + 10.0 * contact.static_overlap,  # bound on translations [m]
                max(0.2 * r_ball, 10.0 * contact.static_overlap),  # bound on the overlap [m]
            ]
        )
        amp = ps.amplifier
        amp_p = np.array(
            [amp.gain, amp.tau, 1.0 if amp.ideal else 0.0, amp.input_limit, amp.fast_fraction,
             amp.fast_time, amp.output_lag]
        )  # fmt: skip
        c_free = tube.quadrant.capacitance
        per_output = (lay.quadrant_sign > 0.0)  # quadrants on each channel's +V output
        amp_rate = np.array(
            [
                amp.rate_limit(c_free * int(np.sum((lay.quadrant_channel == c) & per_output)))
                for c in range(4)
            ]
        )
        # highest natural frequency: each tube top on its spring and contact springs
        kn = contact.static_stiffness
        kt = float(np.sum(gk))
        wmax2 = 0.0
        for k in range(3):
            n = lay.d[k]
            kcont = kn * np.outer(n, n) + kt * (np.eye(3) - np.outer(n, n))
            a_c = np.zeros((3, 6))  # ball velocity from top twist: u̇ + θ̇ × r0
            a_c[:, 3:] = np.eye(3)
            a_c[:, :3] = -_skew(r0[k])
            kk = ktop[k] + a_c.T @ kcont @ a_c
            wmax2 = max(wmax2, float(np.max(np.linalg.eigvals(minv[k] @ kk).real)))
        m_red = 1.0 / (1.0 / m + 1.0 / tube.mass)
        wmax2 = max(wmax2, (kn + kt) / m_red)
        return {
            "layout": lay,
            "preload": preload,
            "table_p": table_p,
            "jinv": np.linalg.inv(j_com),
            "c_body": np.array([0.0, 0.0, -c_depth]),
            "d_nom": lay.d.copy(),
            "r0": r0,
            "basis_ref": lay.tube_frames[:, :, 0].copy(),
            "mtube": mtube,
            "minv": minv,
            "ktop": ktop,
            "dtop": dtop,
            "bcoup": bcoup,
            "cs": cs,
            "qchan": lay.quadrant_channel.copy(),
            "qsign": lay.quadrant_sign.copy(),
            "gnu": gnu,
            "gk": gk,
            "gms_p": gms_p,
            "amp_p": amp_p,
            "amp_rate": amp_rate,
            "omega_max": math.sqrt(wmax2),
        }

    # ------------------------------------------------------------------------------
    def static_equilibrium(self, channel_voltages: np.ndarray | None = None) -> np.ndarray:
        """Positions at rest under preload and gravity with the given channel voltages [V].

        Returns x = (table-centre displacement (3), tube-top twists (3×6)) as a flat array of
        21 numbers [m, rad]; the table orientation is the identity, the GMS elements unloaded.
        """
        ar = self._sized()
        vch = np.zeros(4) if channel_voltages is None else np.asarray(channel_voltages, float)
        vq = np.zeros((3, 4))
        quadrant_voltages(vch, ar["qchan"], ar["qsign"], vq)
        scale = 1e-2 * ar["table_p"][12]  # length scale of the unknowns [m]
        f_scale = self.params.contact.preload  # type: ignore[union-attr]
        ne = ar["gnu"].size
        rot = np.eye(3)

        def residual(y: np.ndarray) -> np.ndarray:
            x = y * scale
            cinfo, cn, cx, cy, crc, crt = self._contact_geometry(x)
            w = np.zeros((3, 6))
            f = np.zeros(3)
            contact_forces(
                x[3:].reshape(3, 6).copy(), np.zeros((3, 6)), vq, ar["ktop"], ar["dtop"],
                ar["bcoup"], cinfo, cn, cx, cy, crc, crt, np.zeros((3, ne, 2)),
                np.ones((3, ne), dtype=np.int64), ar["gk"], ar["table_p"], ar["gms_p"], rot,
                ar["c_body"], w, f, np.zeros(3), np.zeros(3), np.zeros((3, 2)), np.zeros((16, 3)),
            )  # fmt: skip
            return np.concatenate([f, w.reshape(-1)]) / f_scale

        # start: table lowered along z by the static overlap and the tubes' compression
        contact = self.params.contact
        assert contact is not None
        d0 = contact.static_overlap + contact.preload / self.params.tube.K_axial
        y0 = np.zeros(21)
        y0[2] = -d0 * math.sqrt(3.0) / scale
        sol = scipy.optimize.root(residual, y0, method="hybr", tol=1e-14)
        res = np.max(np.abs(residual(sol.x)))
        if not np.isfinite(res) or res > 1e-9:
            raise RuntimeError(
                f"static equilibrium not found (max residual {res:.3g} of F_N): {sol.message}"
            )
        return sol.x * scale

    def _step_control(self, h_fine: float, h_coarse: float) -> np.ndarray:
        """The kernel's step_p: (fine step, coarse step [s], quiet length [m], load fraction,
        volts per coarse step, hold time after a disturbance [s]).

        Quiet length: QUIET_LENGTH × the breakaway displacement ν_i μ_s F_N / k_i of the
        weakest GMS element — a body whose acceleration would move it farther than that in a
        coarse step keeps the fine step. Hold: after anything not quiet, HOLD_PERIODS periods
        of the highest mode pass at the fine step before the coarse one returns.
        """
        fr = self.params.friction
        c = self.params.contact
        assert fr is not None and c is not None
        breakaway = min(
            nu * fr.stribeck.mu_s * c.preload / k for nu, k in zip(fr.nu, fr.k, strict=True)
        )
        hold = HOLD_PERIODS * 2.0 * math.pi / self.omega_max
        return np.array([h_fine, h_coarse, QUIET_LENGTH * breakaway, QUIET_LOAD, QUIET_VOLT, hold])

    def drive_waveforms(self, drive: Mapping[str, DriveSignal | Waveform]) -> dict[str, Waveform]:
        """Channel → input breakpoints (slew-adapted hold time from the channel's load)."""
        out: dict[str, Waveform] = {}
        for axis, sig in drive.items():
            axis_index(axis)
            if isinstance(sig, DriveSignal):
                out[axis] = sig.waveform(self.params.amplifier, self.output_capacitance(axis))
            elif isinstance(sig, Waveform):
                out[axis] = sig
            else:
                raise ValueError(f"drive[{axis!r}]={sig!r}: must be a DriveSignal or a Waveform")
        return out

    def rest_state(
        self, channel_voltages: np.ndarray | None = None, rotation: np.ndarray | None = None
    ) -> FullState:
        """Integrator state at the static equilibrium (every GMS element stuck and unloaded,
        zero velocities) for the channel output voltages [V] (A, B, C, Z).

        ``rotation`` (3×3, default I) turns the table about its centre, the sphere's: the
        contact points stay on the sphere, so the contact geometry is the equilibrium's, and
        the CoM, c below the centre, moves by (R − I)c. The pendulum torque of the turned CoM
        (k_g θ, :class:`~turntable_env.reduced.AxisParameters`) then loads the stuck elements
        in the first microseconds (presliding, of order 1e-6 of θ).
        """
        vch = np.zeros(4) if channel_voltages is None else np.asarray(channel_voltages, float)
        rot = np.eye(3) if rotation is None else np.asarray(rotation, float)
        if rot.shape != (3, 3) or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-9):
            raise ValueError(f"rotation: not a 3×3 rotation matrix: {rotation!r}")
        x = self.static_equilibrium(vch)
        ne = self.packed["gnu"].size
        c_body = self.packed["c_body"]  # CoM from the table centre at R = I [m]
        return FullState(
            pc_disp=x[:3] + rot @ c_body - c_body,  # CoM displacement [m]
            vc=np.zeros(3),
            rot=rot.copy(),
            lam=np.zeros(3),
            xi=x[3:].reshape(3, 6).copy(),
            xid=np.zeros((3, 6)),
            gf=np.zeros((3, ne, 2)),
            gst=np.ones((3, ne), dtype=np.int64),
            vch=vch.copy(),
            acc=np.zeros(5),
            amp_slow=(1.0 - self.params.amplifier.fast_fraction) * vch,
            amp_fast=self.params.amplifier.fast_fraction * vch,
        )

    @property
    def kernel_arrays(self) -> FullArrays:
        """The packed model as :func:`~turntable_env.integrator.run_full_model` reads it."""
        ar = self._sized()
        return FullArrays(**{name: ar[name] for name in FullArrays._fields})

    def run(
        self,
        drive: Mapping[str, DriveSignal | Waveform],
        duration: float,
        *,
        dt_factor: float = 0.05,
        dt_max: float | None = None,
        coarse_factor: float | None = None,
        output_dt: float = 1e-5,
        start: float = 0.0,
        initial_state: FullState | None = None,
        friction_scale: float = 1.0,
        friction_asymmetry: float = 0.0,
        asymmetry_axis: np.ndarray | None = None,
    ) -> dict:
        """Integrate from rest (static equilibrium) for ``duration`` [s]; raw arrays.

        Args:
            drive: channel ("A", "B", "C", "Z") → signal; missing channels stay at 0 V.
            duration: simulated time [s].
            dt_factor: step = dt_factor / ω_max (ω_max the highest natural frequency).
            dt_max: explicit step [s] instead (overrides dt_factor).
            coarse_factor: if given (> dt_factor), the adaptive step of
                :mod:`turntable_env.integrator`: coarse_factor / ω_max while the turntable is
                quiet (every contact sticks well below its capacity, no body accelerates,
                the amplifier is not slewing), the fine step otherwise.
            output_dt: sample interval of the records [s].
            start: initial time [s].
            initial_state: resume from this :class:`~turntable_env.kernel_types.FullState`
                (the ``"final"`` entry of an earlier run; copied, not modified) instead of
                the static equilibrium.
            friction_scale: μ_s and μ_c × this factor for the run (friction-stage effects,
                :mod:`turntable_env.effects`).
            friction_asymmetry: α of the ``friction_asymmetry`` effect: at each contact μ_s
                and μ_c × (1 + α·c), c = −v̂·t̂ the cosine between the tube-minus-table
                sliding velocity and the table's own motion there under a positive turn
                about ``asymmetry_axis`` (unit vector, world frame), weighted by how
                much that contact drives the axis (|t|/ρ): ×(1 + α) where the table
                slides forward over a driving tube, as the per-axis model.

        Raises:
            SimulationError: a state became non-finite or diverged (names time and state).
            KeyboardInterrupt: Ctrl-C in the main thread stops the compiled run within a
                few milliseconds; what it had computed is discarded.
        """
        dur = check_positive("duration", duration)
        t0 = check_finite("start", start)
        odt = check_positive("output_dt", output_dt)
        if dt_max is None:
            h = check_positive("dt_factor", dt_factor) / self.omega_max
        else:
            h = check_positive("dt_max", dt_max)
        h_coarse = h
        if coarse_factor is not None:
            h_coarse = max(h, check_positive("coarse_factor", coarse_factor) / self.omega_max)
        step_p = self._step_control(h, h_coarse)
        waves = self.drive_waveforms(drive)
        nbp = max([w.times.size for w in waves.values()] + [1])
        wt = np.zeros((4, nbp))
        wv = np.zeros((4, nbp))
        wn = np.ones(4, dtype=np.int64)
        for c, axis in enumerate(AXES):
            if axis in waves:
                w = waves[axis]
                wt[c, : w.times.size] = w.times
                wv[c, : w.times.size] = w.values
                wn[c] = w.times.size
            else:
                wt[c, 0] = t0
        amp = self.params.amplifier
        u0 = np.array([waves[a](t0)[()] if a in waves else 0.0 for a in AXES])
        vch = amp.gain * np.clip(u0, -amp.input_limit, amp.input_limit)
        if initial_state is None:
            state = self.rest_state(vch)
        else:
            if not isinstance(initial_state, FullState):
                raise ValueError(f"initial_state: must be a FullState, got {type(initial_state)}")
            ne = self.packed["gnu"].size
            shapes = (
                (3,), (3,), (3, 3), (3,), (3, 6), (3, 6), (3, ne, 2), (3, ne), (4,), (5,), (4,),
                (4,),
            )  # fmt: skip
            for name, shape, v in zip(FullState._fields, shapes, initial_state, strict=True):
                if np.shape(v) != shape:
                    raise ValueError(f"initial_state.{name}: not of shape {shape}")
            state = initial_state.copy()
        arrays = self.kernel_arrays
        alpha = check_finite("friction_asymmetry", friction_asymmetry)
        if not abs(alpha) < 1.0:
            raise ValueError(f"friction_asymmetry={alpha!r}: must be inside (-1, 1)")
        if friction_scale != 1.0 or alpha != 0.0:
            gms_p = arrays.gms_p.copy()
            gms_p[1:3] *= check_positive("friction_scale", friction_scale)
            if alpha != 0.0:
                ax = np.asarray(asymmetry_axis if asymmetry_axis is not None else (), float)
                if ax.shape != (3,) or not np.isclose(np.linalg.norm(ax), 1.0):
                    raise ValueError(f"asymmetry_axis={asymmetry_axis!r}: need a unit 3-vector")
                gms_p[7], gms_p[8:11] = alpha, ax
            arrays = arrays._replace(gms_p=gms_p)
        n_out = math.floor(dur / odt + 1e-9) + 1
        rec = FullRecording(
            t_out=t0 + odt * np.arange(n_out),
            state=np.zeros((n_out, 14)),
            contact=np.zeros((n_out, 3, 6)),
            energy=np.zeros((n_out, 11)),
            xi=np.zeros((n_out, 3, 6)),
        )
        cancel = np.zeros(1, dtype=np.int64)
        status, t_stop, var, n_rec, n_steps, n_coarse = call_interruptibly(
            run_full_model, cancel, state, arrays, DriveArrays(wt, wv, wn), t0, t0 + dur,
            step_p, rec, cancel,
        )  # fmt: skip
        if status != 0:
            raise SimulationError(
                {1: "non-finite", 2: "diverging", 3: "rim"}[int(status)],
                float(t_stop),
                _variable_name(int(var)),
            )
        return {
            "state": rec.state[:n_rec],
            "contact": rec.contact[:n_rec],
            "energy": rec.energy[:n_rec],
            "xi": rec.xi[:n_rec],
            "n_steps": int(n_steps),
            "n_coarse": int(n_coarse),
            "dt": h,
            "dt_coarse": h_coarse,
            "final": state,
            "waveforms": waves,
        }

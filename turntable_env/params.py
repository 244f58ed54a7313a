"""The thesis's two parameter sets (App. D) as immutable objects in SI units.

* ``"real"`` — Table D.1, the real turntable. Everything derivable is derived:
  stiffnesses (App. B), masses and inertias (App. C), geometry (Eq. 3.1–3.3),
  R_bending (Eq. 2.12), quadrant capacitance (Eq. 2.2), E = 1/s₃₃ᴱ.
* ``"thesis"`` — Table D.2, the scaled parameters the thesis simulated. Per App.
  D, values not listed in D.2 are taken from D.1. D.2 gives some quantities
  directly (table and tube masses, tube stiffnesses, R_bending); those are kept
  as *given* and the formula value is printed beside them where one exists.

Thesis inconsistencies, kept visible (``turntable params --json`` prints both sides):

1. R_bending·V = 1.570e4 V·m (Table D.1) needs D = R_o + R_i in Eq. 2.12; 2R_o gives 1.706e4.
2. m_table = 0.0335 kg (Table D.1) is twice Eq. C.1's half sphere (0.01676 kg); the
   default uses Eq. C.1 (``TableParams.mass_convention``).
3. Eq. C.13's parallel-axis shift (7/12·mL²) treats the CoM offset as (L/2, L/2, 0);
   the default reproduces Table D.1, ``parallel_axis="physical"`` gives 1/3·mL².
4. Table D.2's "R_bending = 2 m" is a constant length (the lever of Eq. 3.16,
   πD/(2√2) = 2.04 m for the scaled tube), not the voltage-dependent Eq. 2.12.
5. Table D.2's "R_contact = 2 m" differs from Eq. 3.1 (√(2/3)·3.15 = 2.57 m), which
   orthogonal tubes require; the geometry uses Eq. 3.1, the listed value is printed.

The scaled tube's wall is not in Table D.2: R_i is set so that h/R_o equals the real
tube's (0.16), which reproduces D.2's R_bending lever to 2 % — evidence for reading 4.
"""

from __future__ import annotations

import functools
import json
import math
import numbers
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal

from .amplifier import Amplifier
from .contact import ContactParams, ElasticMaterial, HertzContact
from .detector import Detector
from .friction import GMS, StribeckParams
from .geometry import TurntableGeometry, com_stability
from .quantities import Quantity
from .table import TableParams
from .tube import TubeParams, TubeStiffness
from .validation import check_finite, check_in_open, check_path

__all__ = [
    "AMPLIFIER_FACTORS",
    "FACTORS",
    "PARAMETER_SETS",
    "RIG_CHOICES",
    "RIG_LIMITS",
    "RIG_PRIORS",
    "SET_FACTORS",
    "UNLISTED_FILE",
    "ContactParams",
    "ParameterSet",
    "RigParams",
    "UnlistedRealInputs",
    "get_parameter_set",
    "load_unlisted",
    "real_parameters",
    "thesis_parameters",
]

UNLISTED_FILE = Path(__file__).with_name("data") / "real_unlisted.toml"


@dataclass(frozen=True)
class UnlistedRealInputs:
    """Real-turntable inputs the thesis does not give (``data/real_unlisted.toml``).

    Attributes (SI): table/ball elastic constants [Pa, -], ``normal_force`` F_N per
    contact [N], friction coefficients and Stribeck curve, number of GMS elements,
    contact restitution [-], tube quality factor Q_m [-]; ``sources`` maps each name to
    its source or reasoning.
    """

    table_youngs_modulus: float
    table_poisson: float
    ball_youngs_modulus: float
    ball_poisson: float
    normal_force: float
    mu_static: float
    mu_coulomb: float
    stribeck_velocity: float
    stribeck_exponent: float
    viscous: float
    gms_elements: int
    contact_restitution: float
    tube_quality_factor: float
    sources: Mapping[str, str] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name != "sources":
                check_finite(f.name, getattr(self, f.name))
        check_in_open("contact_restitution", self.contact_restitution, 0.0, 1.0)
        n = self.gms_elements
        if isinstance(n, bool) or int(n) != n or n < 1:
            raise ValueError(f"gms_elements={n!r}: must be a positive integer")
        # the remaining ranges are checked by the objects built from these values

    @property
    def table_material(self) -> ElasticMaterial:
        return ElasticMaterial("steel", self.table_youngs_modulus, self.table_poisson)

    @property
    def ball_material(self) -> ElasticMaterial:
        return ElasticMaterial("alumina", self.ball_youngs_modulus, self.ball_poisson)

    @property
    def stribeck(self) -> StribeckParams:
        return StribeckParams(
            mu_s=self.mu_static,
            mu_c=self.mu_coulomb,
            v_s=self.stribeck_velocity,
            delta=self.stribeck_exponent,
            sigma2=self.viscous,
        )

    @property
    def damping_ratio(self) -> float:
        """ζ of the contact's normal mode from the restitution e: −ln e/√(π² + ln² e)."""
        le = math.log(self.contact_restitution)
        return -le / math.sqrt(math.pi**2 + le**2)


_UNLISTED_UNITS = {
    "table_youngs_modulus": "Pa",
    "table_poisson": "-",
    "ball_youngs_modulus": "Pa",
    "ball_poisson": "-",
    "normal_force": "N",
    "mu_static": "-",
    "mu_coulomb": "-",
    "stribeck_velocity": "m/s",
    "stribeck_exponent": "-",
    "viscous": "N*s/m",
    "gms_elements": "-",
    "contact_restitution": "-",
    "tube_quality_factor": "-",
}


@functools.lru_cache(maxsize=16)
def _parse_toml(path: str, _mtime_ns: int, _size: int) -> dict[str, Any]:
    """A TOML file's contents, parsed once per (path, modification time, size): every
    parameter set rebuilt for a calibration step reads the same file."""
    return tomllib.loads(Path(path).read_text(encoding="utf-8"))


def load_unlisted(
    path: str | Path | None = None, overrides: Mapping[str, float] | None = None
) -> UnlistedRealInputs:
    """Read the unlisted real parameters (TOML: ``[name] value, unit, source``).

    Every name of :class:`UnlistedRealInputs` must be present once with its SI unit;
    ``overrides`` replaces values (for calibration). Raises ValueError naming the file and
    the entry; nothing is returned unless the whole file is valid.
    """
    p = check_path("path", path) if path is not None else UNLISTED_FILE
    try:
        st = p.stat()
        raw = _parse_toml(str(p), st.st_mtime_ns, st.st_size)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{p}: cannot read parameter file: {exc}") from None
    except RecursionError:  # nested arrays beyond the TOML parser's stack
        raise ValueError(f"{p}: cannot read parameter file: nested too deep") from None
    values: dict[str, float] = {}
    sources: dict[str, str] = {}
    for name in raw:
        if name not in _UNLISTED_UNITS:
            raise ValueError(f"{p}: [{name}]: unknown parameter")
    for name, unit in _UNLISTED_UNITS.items():
        entry = raw.get(name)
        if not isinstance(entry, dict):
            raise ValueError(f"{p}: [{name}]: missing")
        v, u, src = entry.get("value"), entry.get("unit"), entry.get("source")
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError(f"{p}: [{name}] value={v!r}: must be a number")
        if u != unit:
            raise ValueError(f"{p}: [{name}] unit={u!r}: must be {unit!r}")
        if not isinstance(src, str) or not src.strip():
            raise ValueError(f"{p}: [{name}] source={src!r}: must name a source or reasoning")
        values[name] = float(v)
        sources[name] = src
    for name, v in (overrides or {}).items():
        if name not in _UNLISTED_UNITS:
            raise ValueError(f"overrides[{name!r}]: unknown parameter")
        values[name] = check_finite(f"overrides[{name!r}]", v)
        sources[name] = "override"
    values["gms_elements"] = (
        int(values["gms_elements"])
        if float(values["gms_elements"]).is_integer()
        else values["gms_elements"]
    )
    try:
        return UnlistedRealInputs(**values, sources=sources)  # type: ignore[arg-type]
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


# The one table of multiplicative factors on a set's uncertain values
# (ParameterSet.with_factors, Plant.factors, the trace calibration's nominal model):
# name → (low, high, what it scales), the bounds physical.
FACTORS: dict[str, tuple[float, float, str]] = {
    "friction": (0.1, 10.0, "μ_s and μ_c together (dry-contact scatter)"),
    "preload": (0.1, 10.0, "normal force F_N of the preload spring (not documented)"),
    "amplifier": (0.1, 10.0, "HVA 900 slew rate per input volt and current limit"),
    # each alone (the trace calibration's nominal model): another unit or make settles
    # slower (a small lab amplifier of ~1 mA is 0.04 of the HVA 900's 25 mA)
    "amplifier_slew": (0.03, 10.0, "amplifier slew rate per input volt alone (τ ÷)"),
    "amplifier_current": (0.03, 10.0, "amplifier current limit alone"),
    "coulomb": (0.1, 10.0, "μ_c alone, on top of friction (μ_c ≤ μ_s)"),
    "stribeck_velocity": (0.01, 100.0, "Stribeck velocity v_S of the contact"),
    "contact_damping": (0.01, 1000.0, "tangential micro-slip damping β_t of the contact"),
    "tube_damping": (0.01, 100.0, "tube loss 1/Q_m"),
}
SET_FACTORS = tuple(FACTORS)
AMPLIFIER_FACTORS = ("amplifier", "amplifier_slew", "amplifier_current")  # no unlisted inputs
RIG_PRIORS: dict[str, tuple[float, float, float, float, str]] = {
    # name: (low, high, prior mean, prior std, source) — continuous rig parameters
    "d31_factor": (
        1.0, 1.4, 1.1, 0.1,
        "large-signal d31 over Table D.1's small-signal value: soft PZT (PIC 151) gains "
        "10-30 % at drive fields of a few hundred V/mm; 90 V over the 0.508 mm wall is "
        "177 V/mm",
    ),
    "length_factor": (
        0.95, 1.05, 1.0, 0.02,
        "tube length over Table D.1's 6.35 mm (1/4 in): commercial tolerance about ±2 %",
    ),
    "detector_gain": (
        0.9, 1.1, 1.0, 0.03,
        "photodiode volts per metre of spot times S (Fig. 4.4's S = 9.9e-5 m/V, quoted to "
        "two digits)",
    ),
    "presliding_factor": (
        0.5, 5.0, 1.0, 0.7,
        "contact presliding distance over Mindlin's smooth-sphere gross-slip displacement: "
        "rough surfaces are more compliant (prior std on the natural log)",
    ),
}  # fmt: skip
# name: (low, high) — the physical range every rig must lie in (wider than the thesis rig's
# priors above: a calibration of another rig's traces may land anywhere in it)
RIG_LIMITS: dict[str, tuple[float, float]] = {
    "d31_factor": (0.3, 3.0),  # soft to hard PZT, also standing in for another rig's lever
    "length_factor": (0.5, 2.0),
    "detector_gain": (0.5, 2.0),
    "presliding_factor": (0.1, 10.0),
    "inertia_factor": (0.5, 3.0),  # the mirror and its mount add to the half sphere
}
RIG_CHOICES: dict[str, tuple[tuple, tuple[float, ...], str]] = {
    # name: (options, prior probabilities, source) — discrete rig parameters
    "drive_mode": (
        ("asymmetric", "symmetric"), (0.8, 0.2),
        "§2.1.2: 'the turntable is used in the asymmetric voltage mode'; symmetric (±V on "
        "opposite quadrants) doubles the bending",
    ),
    "axial_strain_sign": (
        (1, -1), (0.5, 0.5),
        "the quadrants' poling relative to the electrode wiring is not documented",
    ),
    "mirror_tilt": (
        (0.8164965809277261, 1.0), (0.8, 0.2),
        "§4.1.1: 'a mirror sited on top of the turntable' — on the flat face it tilts by "
        "cos 35.26° per rotation about a tube axis; 1 if it faces the axis's perpendicular",
    ),
}  # fmt: skip


@dataclass(frozen=True)
class RigParams:
    """Properties of the laboratory rig that the thesis does not pin down (Table D.1 is the
    design); their priors and sources are :data:`RIG_PRIORS` and :data:`RIG_CHOICES`.

    Attributes:
        d31_factor: large-signal d₃₁ over the small-signal value [-].
        drive_mode: ``"asymmetric"`` (one quadrant per channel and tube, §2.1.2) or
            ``"symmetric"`` (±V on opposite quadrants).
        axial_strain_sign: +1 if the quadrant that bends a tube forward shortens, −1 if it
            lengthens (:class:`~turntable_env.tube.TubeParams`).
        length_factor: tube length over Table D.1's [-].
        mirror_tilt: mirror tilt per table rotation about the watched axis
            (:class:`~turntable_env.detector.Detector`) [-].
        detector_gain: photodiode volts per metre of spot, times S [-].
        presliding_factor: contact presliding distance over Mindlin's value [-].
        inertia_factor: table mass and inertia over the steel half sphere's (Eq. C.1,
            C.8): the mirror and its mount add to both [-].
        tube_inertia: ``"thesis"`` (Eq. C.13 as printed: Table D.1's 7/12·mL²) or
            ``"physical"`` (the parallel-axis shift of a CoM L/2 along the axis: 1/3·mL²).
    """

    d31_factor: float = 1.0
    drive_mode: Literal["asymmetric", "symmetric"] = "asymmetric"
    axial_strain_sign: int = 1
    length_factor: float = 1.0
    mirror_tilt: float = 1.0
    detector_gain: float = 1.0
    presliding_factor: float = 1.0
    tube_inertia: Literal["thesis", "physical"] = "thesis"
    inertia_factor: float = 1.0

    def __post_init__(self) -> None:
        if self.tube_inertia not in ("thesis", "physical"):
            raise ValueError(f"rig.tube_inertia={self.tube_inertia!r}: 'thesis' or 'physical'")
        for name, (lo, hi) in RIG_LIMITS.items():
            v = check_finite(name, getattr(self, name))
            if not lo <= v <= hi:
                raise ValueError(f"rig.{name}={v!r}: outside its physical range {lo:g}…{hi:g}")
        if self.drive_mode not in RIG_CHOICES["drive_mode"][0]:
            raise ValueError(f"rig.drive_mode={self.drive_mode!r}: 'asymmetric' or 'symmetric'")
        s = self.axial_strain_sign  # an int: True and 1.0 equal 1 but are not a sign
        if isinstance(s, bool) or not isinstance(s, int) or s not in (1, -1):
            raise ValueError(f"rig.axial_strain_sign={s!r}: +1 or -1")
        if not 0.5 <= check_finite("mirror_tilt", self.mirror_tilt) <= 1.0:
            raise ValueError(f"rig.mirror_tilt={self.mirror_tilt!r}: must be in [0.5, 1]")

    def describe(self, prefix: str = "rig") -> list[Quantity]:
        out = []
        for name, (lo, hi, mean, std, src) in RIG_PRIORS.items():
            note = f"prior {mean:g} ± {std:g} in [{lo:g}, {hi:g}]: {src}"
            out.append(Quantity(f"{prefix}.{name}", getattr(self, name), "-", "given", note))
        for name, (options, probs, src) in RIG_CHOICES.items():
            opts = ", ".join(f"{o} ({p:.0%})" for o, p in zip(options, probs, strict=True))
            note = f"prior {opts}: {src}"
            out.append(Quantity(f"{prefix}.{name}", getattr(self, name), "-", "given", note))
        note = "Eq. C.13 as printed (thesis) or the physical parallel axis"
        out.append(Quantity(f"{prefix}.tube_inertia", self.tube_inertia, "-", "given", note))
        note = "table mass and inertia over the half sphere's (mirror and mount); prior 1"
        out.append(Quantity(f"{prefix}.inertia_factor", self.inertia_factor, "-", "given", note))
        return out


@dataclass(frozen=True)
class ParameterSet:
    """A complete, immutable parameter set.

    Args:
        name: ``"real"`` or ``"thesis"`` (or a user label).
        table, tube: structural parameters.
        friction: GMS contact friction (2-D, §3.3.2).
        contact: contact parameters (§3.3).
        amplifier, detector: §4.1 hardware.
        ramp_ratio: default position of the sawtooth maximum a (Table D.1: 0.95).
        unlisted: for the real set, the inputs the thesis does not give (printed with
            their sources and the quantities derived from them).
        nominal_frequency: drive frequency of this set's stepping experiments [Hz]
            (real: 100 Hz, §4.1.3; thesis: 2 Hz, see :func:`thesis_parameters`).
        nominal_flyback: ``"step"`` (laboratory, §4.1.2) or ``"ramp"`` (Fig. 3.14 sawtooth).
        notes: how values not in the thesis were obtained (printed).
        rig: properties of the laboratory rig (:class:`RigParams`); the defaults are the
            thesis's design reading. :func:`real_parameters` builds them into the tubes,
            the detector and the contacts; ``TurntableModel`` wires the drive mode.
    """

    name: str
    table: TableParams
    tube: TubeParams
    friction: GMS | None = None
    contact: ContactParams | None = None
    amplifier: Amplifier = field(default_factory=Amplifier)
    detector: Detector = field(default_factory=Detector)
    ramp_ratio: float = 0.95
    unlisted: UnlistedRealInputs | None = None
    nominal_frequency: float = 100.0
    nominal_flyback: Literal["step", "ramp"] = "step"
    notes: tuple[Quantity, ...] = ()
    rig: RigParams = field(default_factory=RigParams)

    def __post_init__(self) -> None:
        check_in_open("ramp_ratio", self.ramp_ratio, 0.0, 1.0)
        check_finite("nominal_frequency", self.nominal_frequency)
        if self.nominal_frequency <= 0.0:
            raise ValueError(f"nominal_frequency={self.nominal_frequency!r}: must be > 0")
        if self.nominal_flyback not in ("step", "ramp"):
            raise ValueError(f"nominal_flyback={self.nominal_flyback!r}: must be 'step' or 'ramp'")
        if self.detector.table_radius != self.table.radius:
            raise ValueError(
                f"detector.table_radius={self.detector.table_radius!r}: must equal "
                f"table.radius={self.table.radius!r}"
            )

    @property
    def geometry(self) -> TurntableGeometry:
        return TurntableGeometry(self.table.radius, self.tube.length)

    def describe(self) -> list[Quantity]:
        """Every given and derived quantity, with unit and source."""
        out: list[Quantity] = []
        out += self.table.describe()
        out += self.tube.describe()
        m = self.tube.material
        out += [
            Quantity("piezo.d31", m.d31, "m/V", "given", "Table D.1"),
            Quantity("piezo.s33E", m.s33E, "m^2/N", "given", "Table D.1"),
            Quantity("piezo.eps11T_rel", m.eps11T_rel, "-", "given", "Table D.1 (2400 eps0)"),
            Quantity("piezo.eps11T", m.eps11T, "F/m", "derived", "2400*eps0"),
            Quantity("piezo.poisson", m.poisson, "-", "given", "App. B.3"),
            Quantity(
                "piezo.E", m.youngs_modulus, "N/m^2", "derived", "1/s33E (Table D.1: 5.263e10)"
            ),
            Quantity("piezo.G", m.shear_modulus, "N/m^2", "derived", "E/(2(1+nu)), App. B.3"),
            Quantity("piezo.k31_squared", m.coupling_k2, "-", "derived", "d31^2/(s33E*eps11T)"),
            Quantity("drive.a", self.ramp_ratio, "-", "given", "Table D.1"),
        ]
        out += self.geometry.describe()
        cs = com_stability(self.table.radius)
        out += [
            Quantity(
                "geometry.com_stable",
                cs.stable,
                "-",
                "derived",
                "§3.1: stable iff R_CoM < R_contact",
            ),
            Quantity(
                "geometry.com_margin",
                cs.margin,
                "m",
                "derived",
                "CoM depth - contact-plane depth (< 0: CoM above the plane)",
            ),
        ]
        if self.unlisted is not None:
            u = self.unlisted
            for f in fields(u):
                if f.name != "sources":
                    out.append(
                        Quantity(
                            f"unlisted.{f.name}",
                            getattr(u, f.name),
                            _UNLISTED_UNITS[f.name],
                            "given",
                            u.sources.get(f.name, ""),
                        )
                    )
            out += _hertz(self.table, self.tube, u).describe(u.normal_force, u.mu_static)
            out.append(
                Quantity(
                    "contact.damping_ratio",
                    u.damping_ratio,
                    "-",
                    "derived",
                    "-ln e/sqrt(pi^2 + ln^2 e) from the restitution e",
                )
            )
        if self.friction is not None:
            out += self.friction.describe()
        if self.contact is not None:
            out += self.contact.describe()
        out += self.amplifier.describe()
        out += self.detector.describe()
        out += self.rig.describe()
        out += list(self.notes)
        names = [q.name for q in out]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise RuntimeError(f"duplicate parameter names: {sorted(dup)}")
        return out

    def with_factors(self, factors: Mapping[str, float]) -> ParameterSet:
        """This set with multiplicative factors on its uncertain values (the one place
        they become parameters: domain randomisation, calibration, plants):

        * ``friction``: μ_s and μ_c; ``coulomb``: μ_c alone (μ_c ≤ μ_s must hold);
          ``stribeck_velocity``: v_S; ``preload``: F_N; ``tube_damping``: the tubes' loss
          1/Q_m — all through the unlisted inputs, so the GMS elements, presliding
          distance and contact damping are re-derived (Hertz–Mindlin,
          :func:`real_parameters`); they need a set with unlisted inputs;
        * ``contact_damping``: the tangential micro-slip damping β_t of the sticking GMS
          elements (the bristle damping σ₁ of LuGre-type models), after the re-derivation;
        * ``amplifier``: slew rate per input volt and current limit (:meth:`Amplifier.scaled`);
          ``amplifier_slew`` and ``amplifier_current`` each alone, on top of it.

        Factors of 1 (or none) return the set unchanged. ValueError for a factor that is
        not a finite number > 0, or an unknown name."""
        if not isinstance(factors, Mapping):
            raise ValueError(f"factors={factors!r}: must be a mapping name → factor")
        for k, v in factors.items():
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (
                    math.isfinite(v) and v > 0.0):  # fmt: skip
                raise ValueError(f"factors[{k!r}]={v!r}: must be a finite number > 0")
        unknown = set(factors) - set(SET_FACTORS)
        if unknown:
            raise ValueError(f"factors: unknown {sorted(unknown)} ({', '.join(SET_FACTORS)})")
        over: dict[str, float] = {}
        u = self.unlisted
        physical = [k for k in factors if k not in AMPLIFIER_FACTORS and factors[k] != 1.0]
        if physical:
            if u is None:
                raise ValueError(
                    f"factors {sorted(physical)} need unlisted inputs; set {self.name!r} "
                    "has none (its friction is given directly)"
                )
            f_mu = factors.get("friction", 1.0)
            if f_mu != 1.0:
                over["mu_static"] = u.mu_static * f_mu
            if f_mu != 1.0 or factors.get("coulomb", 1.0) != 1.0:
                mu_c = u.mu_coulomb * f_mu * factors.get("coulomb", 1.0)
                mu_s = over.get("mu_static", u.mu_static)
                over["mu_coulomb"] = min(mu_c, mu_s)  # μ_c = μ_s up to rounding
                if mu_c > mu_s * (1.0 + 1e-9):
                    raise ValueError(
                        f"factors['coulomb']={factors.get('coulomb', 1.0)!r}: μ_c would exceed "
                        f"μ_s (at most {u.mu_static / u.mu_coulomb:.4g} on set {self.name!r})"
                    )
            if "stribeck_velocity" in factors:
                over["stribeck_velocity"] = u.stribeck_velocity * factors["stribeck_velocity"]
            if "preload" in factors:
                over["normal_force"] = u.normal_force * factors["preload"]
            if "tube_damping" in factors:
                over["tube_quality_factor"] = u.tube_quality_factor / factors["tube_damping"]
        ps = self._rebuilt(over, self.rig) if over else self
        if factors.get("contact_damping", 1.0) != 1.0:
            c = ps.contact
            assert c is not None
            beta_t = c.tangential_damping * factors["contact_damping"]
            ps = replace(ps, contact=replace(c, tangential_damping=beta_t))
        s = factors.get("amplifier", 1.0)
        slew = s * factors.get("amplifier_slew", 1.0)
        current = s * factors.get("amplifier_current", 1.0)
        if slew != 1.0 or current != 1.0:
            ps = replace(ps, amplifier=ps.amplifier.scaled(slew, current))
        return ps

    def with_rig(self, rig: RigParams) -> ParameterSet:
        """This set built for another rig (:class:`RigParams`); needs unlisted inputs."""
        if rig == self.rig:
            return self
        if self.unlisted is None:
            raise ValueError(f"rig: set {self.name!r} has no unlisted inputs to rebuild from")
        return self._rebuilt({}, rig)

    def _rebuilt(self, overrides: Mapping[str, float], rig: RigParams) -> ParameterSet:
        """:func:`real_parameters` from this set's unlisted inputs with ``overrides`` and
        ``rig``, keeping its name and amplifier (the detector follows the rig)."""
        u = self.unlisted
        assert u is not None
        base = {f.name: getattr(u, f.name) for f in fields(u) if f.name != "sources"}
        ps = real_parameters(overrides={**base, **overrides}, rig=rig)
        return replace(ps, name=self.name, amplifier=self.amplifier)

    def to_dict(self) -> dict:
        return {"set": self.name, "parameters": {q.name: q.to_dict() for q in self.describe()}}

    def to_json(self, indent: int = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)


def _hertz(table: TableParams, tube: TubeParams, u: UnlistedRealInputs) -> HertzContact:
    """The ball (Al₂O₃, radius R_o) on the table (steel, radius R_table)."""
    return HertzContact(tube.outer_radius, u.ball_material, table.radius, u.table_material)


def real_parameters(
    overrides: Mapping[str, float] | None = None,
    unlisted_file: str | Path | None = None,
    rig: RigParams | None = None,
) -> ParameterSet:
    """Table D.1, the real turntable, with the unlisted values derived (see module docstring).

    Derivations from ``data/real_unlisted.toml`` (each printed by ``turntable params``):

    * normal contact: Hertz, F = K_H δ^{3/2}, K_H = (4/3)E*√R* (ball R_o on sphere R_table);
    * GMS presliding distance: Mindlin's gross-slip displacement 3μ_sF_N/(16G*a);
    * GMS elements: §4.2.1 rules, ν_i ∝ i, δ_i equally spaced from δ/n to δ (the first
      step of the grid stands for the noise level), k_i = ν_iμ_sF_N/δ_i;
    * GMS attraction C = μ_sF_N·v_S/δ: a slipping element relaxes over the presliding
      distance when sliding at the Stribeck velocity;
    * normal damping d_c = 2ζ√(k_n m_red), ζ from the restitution, k_n = 2E*a at F_N,
      m_red of a tube and the table; tangential micro-damping of the sticking elements
      with the same ζ: β_t = 2ζ/√(Σk_i/m_red);
    * Eq. 3.24 weights: each body's E/(1−ν²);
    * tube damping from Q_m (stiffness-proportional, :attr:`TubeParams.damping_coefficient`).

    The rig (:class:`RigParams`) sets the tubes' large-signal d₃₁, length, axial-strain
    sign and inertia convention, the detector's mirror tilt and gain, the presliding
    distance's factor on Mindlin's value, and (through ``TurntableModel``) the drive mode.

    Args:
        overrides: replace entries of the parameter file (calibration), e.g.
            ``{"normal_force": 2.0}``.
        unlisted_file: another parameter file in the same format.
        rig: the rig's properties (default: the thesis's design reading, every factor 1).
    """
    rig = rig if rig is not None else RigParams()
    u = load_unlisted(unlisted_file, overrides)
    table = TableParams(radius=0.01, density=8.0e3 * rig.inertia_factor)
    design = TubeParams()
    material = design.material
    if rig.d31_factor != 1.0:
        material = replace(material, d31=material.d31 * rig.d31_factor)
    tube = TubeParams(
        quality_factor=u.tube_quality_factor,
        length=design.length * rig.length_factor,
        material=material,
        axial_strain_sign=rig.axial_strain_sign,
        parallel_axis=rig.tube_inertia,
    )
    hz = _hertz(table, tube, u)
    fn = u.normal_force
    delta = hz.slip_displacement(fn, u.mu_static) * rig.presliding_factor
    n = int(u.gms_elements)
    stribeck = u.stribeck
    friction = GMS.from_rules(
        stribeck,
        normal_force=fn,
        n_elements=n,
        presliding_distance=delta,
        noise_level=delta / n,
        C=u.mu_static * fn * u.stribeck_velocity / delta,
    )
    m_red = 1.0 / (1.0 / tube.mass + 1.0 / table.mass)
    k_gms = float(sum(friction.k))
    contact = ContactParams(
        normal_stiffness=hz.hertz_constant,
        normal_exponent=1.5,
        normal_damping=2.0 * u.damping_ratio * math.sqrt(hz.normal_stiffness(fn) * m_red),
        compressibility_tube=u.ball_material.contact_modulus,
        compressibility_table=u.table_material.contact_modulus,
        preload=fn,
        listed_contact_radius=None,
        tangential_damping=2.0 * u.damping_ratio / math.sqrt(k_gms / m_red),
        source="derived: Hertz-Mindlin from data/real_unlisted.toml",
    )
    return ParameterSet(
        name="real",
        table=table,
        tube=tube,
        friction=friction,
        contact=contact,
        detector=Detector(
            table_radius=table.radius, tilt_factor=rig.mirror_tilt, gain=rig.detector_gain
        ),
        unlisted=u,
        rig=rig,
    )


def thesis_parameters() -> ParameterSet:
    """Table D.2: the scaled parameters of the thesis's simulations (D.1 where D.2 is silent).

    Table D.2 cannot be run as printed; four readings make it a working model, each
    printed by ``turntable params --set thesis`` (``thesis.*`` entries):

    1. Tube stiffnesses act at the tube top: D.2 lists K_t, K_o as the quantities
       Table D.1 lists as K_x, K_z, K_φ, which App. B derives for a force at the tip.
    2. K_o,x = K_o,y: the listed 100 N·m/rad, behind the 1.5 m lever from the tube top
       to the contact, leaves the contact point 42 N/m of lateral stiffness, so the 30 N
       static friction would bend the tube by 0.7 m and no contact could slip. The beam
       value that matches the listed K_t, K_o = K_t·L²/3 (the tip's rotational
       stiffness EI/L when K_t = 3EI/L³), is used; K_o,z = 1e5 N·m as listed.
    3. Stroke: with D.1's d₃₁ the scaled tube moves its contact by 0.2 µm at 100 V,
       1e-4 of D.2's presliding distances (ν_iF_st/k_i = 4.5–7.5 mm). The piezo constants
       are scaled by s (d₃₁·s, ε₁₁·s², coupling k² unchanged) with s chosen so that the
       measurement's drive, which §4.2.2 says the simulations used (2 V → 90 V), moves the
       free contact by twice the largest presliding distance; the amplifier is ideal, as
       in the thesis's simulations.
    4. Damping D.2 does not list is taken from the real set (App. D: unlisted values
       come from D.1): tube Q_m and the contact's tangential micro-damping from the
       same restitution.

    Drive: Fig. 3.14's sawtooth (a = 0.95, ramp flyback) at 2 Hz, where the scaled
    model steps regularly: the ramp (0.475 s) is slow against the table's period on its
    contacts (0.16 s), the flyback (25 ms) fast. At Fig. 3.14's 1 Hz the steps are
    irregular (`python experiments/turntable_evidence.py` prints both).
    """
    table = TableParams(radius=3.15, density=None, mass_given=15.0)
    r_tube = 1.0
    length = 2.0
    h_ratio = (3.175e-3 - 2.667e-3) / 3.175e-3  # real tube's h/R_o, see module docstring
    k_t = 1e5  # N/m, Table D.2
    k_o_listed = 100.0  # N*m/rad, Table D.2
    k_o = k_t * length**2 / 3.0  # beam value for the listed K_t (reading 2)
    u = load_unlisted()
    base_tube = TubeParams(
        outer_radius=r_tube,
        inner_radius=r_tube * (1.0 - h_ratio),
        length=length,
        mass_given=0.5,
        stiffness_given=TubeStiffness(translational=(k_t, k_t, k_t), rotational=(k_o, k_o, 1e5)),
        bending_lever_given=2.0,
        axial_coupling=False,
        quality_factor=u.tube_quality_factor,
        source="Table D.2 (R_tube, L); R_i from the real tube's h/R_o; densities from D.1 (unused)",
    )
    friction = GMS(
        stribeck=StribeckParams(mu_s=0.3, mu_c=0.05, v_s=0.8, delta=2.0, sigma2=0.0),
        nu=(0.06, 0.15, 0.21, 0.27, 0.31),
        k=(400.0, 643.0, 1260.0, 1350.0, 1233.0),
        C=200.0,
    )
    f_n = 100.0  # N, Table D.2
    mu_s = friction.stribeck.mu_s
    presliding = max(n * mu_s * f_n / k for n, k in zip(friction.nu, friction.k, strict=True))
    lever = base_tube.stiffness_centre_offset + base_tube.seat_height + base_tube.outer_radius
    travel_per_volt = base_tube.rest_twist_per_volt[1, 0] * lever  # m/V at s = 1
    drive_volts = 2.0 * Amplifier().gain  # V, the §4.1.3 input that §4.2.2 reuses
    stroke = 2.0 * presliding / (travel_per_volt * drive_volts)
    tube = TubeParams(**{**base_tube.__dict__, "stroke_scale": stroke})
    m_red = 1.0 / (1.0 / tube.mass + 1.0 / table.mass)
    contact = ContactParams(
        tangential_damping=2.0 * u.damping_ratio / math.sqrt(sum(friction.k) / m_red)
    )
    d = "derived"
    notes = (
        Quantity("thesis.K_o_xy_listed", k_o_listed, "N*m/rad", "given", "Table D.2"),
        Quantity("thesis.K_o_xy_used", k_o, "N*m/rad", d, "K_t*L^2/3 (reading 2)"),
        Quantity(
            "thesis.contact_lateral_stiffness_listed",
            1.0 / (1.0 / k_t + (base_tube.seat_height + r_tube) ** 2 / k_o_listed),
            "N/m",
            d,
            "with the listed K_o: no contact could slip",
        ),
        Quantity("thesis.presliding_max", presliding, "m", d, "max nu_i*mu_s*F_N/k_i"),
        Quantity("thesis.stroke_scale", stroke, "-", d, "2*presliding/(travel per V*90 V)"),
        Quantity(
            "thesis.contact_travel_at_90V",
            travel_per_volt * stroke * drive_volts,
            "m",
            d,
            "reading 3",
        ),
    )
    return ParameterSet(
        name="thesis",
        table=table,
        tube=tube,
        friction=friction,
        contact=contact,
        amplifier=Amplifier(ideal=True),
        detector=Detector(table_radius=table.radius),
        nominal_frequency=2.0,
        nominal_flyback="ramp",
        notes=notes,
    )


PARAMETER_SETS = ("real", "thesis")  # named sets of this layer; the plant layer adds more


@functools.lru_cache(maxsize=8)
def get_parameter_set(name: Literal["real", "thesis"]) -> ParameterSet:
    """``"real"`` (Table D.1) or ``"thesis"`` (Table D.2); immutable, so cached. Sets
    built from a calibration (``"calibrated"``) are resolved by the plant layer:
    :func:`turntable_env.plant.parameter_set`."""
    if name == "real":
        return real_parameters()
    if name == "thesis":
        return thesis_parameters()
    raise ValueError(
        f"set={name!r}: must be one of {', '.join(PARAMETER_SETS)} (the calibrated set: "
        "turntable_env.plant.parameter_set)"
    )

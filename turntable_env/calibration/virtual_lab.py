"""The virtual lab: measurement files written by the simulator, with any effects on.

A **protocol** is a drive sequence designed so that the catalogue's effects leave
distinguishable signatures. Each is a list of blocks on the watched axis's channel:
``("steps", amplitude V (signed), frequency Hz, periods, a, k)`` (the Fig. 4.3 adapted
flyback for k > 0; for k = 0 the Fig. 3.14 sawtooth, or with a seventh element ``"step"``
the laboratory's unadapted input, a step back to 0 V at a/f, §4.1.2) or
``("hold", seconds)`` or ``("scan", level V, ramp seconds)``:

* ``standard`` (0.81 s): in its first 60 % (a calibrator's fit portion) stepping forward
  and backward at 2 V 100 Hz, 4 V 1 kHz and 2.5 V 1 kHz (asymmetry: forward ≠ backward; amplifier
  dynamics: amplitude and frequency dependence; wear: step size over travel), then scan
  ramps to ±4 V and back with holds (hysteresis: a loop; creep: motion during holds;
  drift, vibration); in the rest other settings — 3 V 100 Hz, a 3 V scan, 5 V 1 kHz —
  so held-out data tests the model at drive settings it was not fitted on;
* ``long`` (about 2.3 s): ``standard``, a variant with other amplitudes and frequencies,
  ``standard`` again — so fit and held-out portions can differ in their drive settings;
* ``thesis``: the §4.1.3 inputs, 5 steps forward and back (two-directional), then 9 steps
  one way at 2 V, 100 Hz, adapted.

Samples: every drive breakpoint (a jump is two samples 1 ns apart) plus detector samples
every ``sample_dt`` (50 µs), so the file holds exactly what the simulator was driven with.
``turntable virtual-lab --effects piezo_creep=0.02,... --protocol standard --out F.csv``
writes one; the effects are recorded nowhere in the file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..drive import StepSetting
from ..params import ParameterSet
from ..plant import Plant, output_capacitance
from ..validation import check_int, check_nonnegative
from .measurement import DRIVE_FREQUENCY_RANGE, INPUT_LIMIT, MAX_SAMPLES, Measurement
from .trace import simulate_trace

__all__ = ["PROTOCOLS", "check_protocol", "protocol_blocks", "protocol_drive", "run_virtual_lab"]

Block = tuple[Any, ...]
_STANDARD: list[Block] = [
    # fit portion (first 60 %): both directions at two settings, scan ramps and holds
    ("hold", 0.01),
    ("steps", 2.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", -2.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", 4.0, 1000.0, 5, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", -4.0, 1000.0, 5, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", 2.5, 1000.0, 8, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", -2.5, 1000.0, 8, 0.9, 1.0),
    ("hold", 0.02),
    ("scan", 4.0, 0.04),
    ("hold", 0.04),
    ("scan", -4.0, 0.06),
    ("hold", 0.04),
    ("scan", 0.0, 0.04),
    ("hold", 0.03),
    # held-out portion: other amplitudes, frequencies and scan levels
    ("steps", 3.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", -3.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.02),
    ("scan", 3.0, 0.04),
    ("hold", 0.04),
    ("scan", 0.0, 0.04),
    ("hold", 0.03),
    ("steps", 5.0, 1000.0, 4, 0.9, 1.0),
    ("hold", 0.02),
    ("steps", -5.0, 1000.0, 4, 0.9, 1.0),
    ("hold", 0.03),
]
_VARIANT: list[Block] = [
    ("steps", 3.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.03),
    ("steps", -3.0, 100.0, 6, 0.9, 1.0),
    ("hold", 0.03),
    ("scan", 3.0, 0.08),
    ("hold", 0.06),
    ("scan", 0.0, 0.08),
    ("hold", 0.04),
    ("steps", 2.0, 1000.0, 8, 0.9, 1.0),
    ("hold", 0.03),
    ("steps", -2.0, 1000.0, 8, 0.9, 1.0),
    ("hold", 0.04),
]
PROTOCOLS: dict[str, list[Block]] = {
    "standard": _STANDARD,
    "long": [*_STANDARD, *_VARIANT, *_STANDARD],
    "thesis": [
        ("hold", 0.01),
        ("steps", 2.0, 100.0, 5, 0.95, 1.0),
        ("steps", -2.0, 100.0, 5, 0.95, 1.0),
        ("hold", 0.02),
        ("steps", 2.0, 100.0, 9, 0.95, 1.0),
        ("hold", 0.02),
    ],
}


MAX_PROTOCOL_S = 100.0  # s, the longest protocol (the thesis's are under 3 s)
SAMPLE_DT_RANGE = (1e-7, 1e-2)  # s, the detector's sample interval
MAX_PROTOCOL_PERIODS = 1_000_000  # stepping periods of one block


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    """A real number in [lo, hi] (bool refused); ValueError naming ``where`` otherwise."""
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise ValueError(f"{where}={v!r}: must be a number")
    if not (np.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{where}={v!r}: must lie in {lo:g}…{hi:g}")
    return float(v)


def check_protocol(protocol: str | Sequence[Block], sample_dt: float = 5e-5) -> list[Block]:
    """The protocol's blocks, each checked (module docstring's forms: amplitudes within the
    amplifier input's ±10 V, 1 Hz–100 kHz, 0.01 ≤ a ≤ 0.999, k in 0…10, whole periods) with
    ``sample_dt`` and the whole length bounded (:data:`MAX_PROTOCOL_S`,
    :data:`SAMPLE_DT_RANGE`), before anything is allocated; ValueError naming the block."""
    if isinstance(protocol, str):
        if protocol not in PROTOCOLS:
            raise ValueError(f"protocol={protocol!r}: choose from {', '.join(PROTOCOLS)}")
        blocks = PROTOCOLS[protocol]
    elif isinstance(protocol, Sequence) and protocol:
        blocks = list(protocol)
    else:
        raise ValueError(f"protocol={protocol!r}: a name or a non-empty list of blocks")
    _number("sample_dt", sample_dt, *SAMPLE_DT_RANGE)
    total = 0.0
    for i, blk in enumerate(blocks):
        w = f"protocol[{i}]"
        if not isinstance(blk, tuple | list) or not blk:
            raise ValueError(f"{w}={blk!r}: a tuple (kind, ...)")
        kind, n_args = blk[0], {"hold": 2, "scan": 3, "steps": 6}.get(blk[0]) if isinstance(
            blk[0], str) else None  # fmt: skip
        if n_args is None or not (len(blk) == n_args or (kind == "steps" and len(blk) == 7)):
            raise ValueError(
                f"{w}={blk!r}: ('hold', s), ('scan', V, s) or ('steps', V, Hz, periods, a, k"
                "[, 'step'])"
            )
        if kind == "hold":
            total += _number(f"{w} seconds", blk[1], 0.0, MAX_PROTOCOL_S)
        elif kind == "scan":
            _number(f"{w} level", blk[1], -INPUT_LIMIT, INPUT_LIMIT)
            total += _number(f"{w} seconds", blk[2], 0.0, MAX_PROTOCOL_S)
        else:
            _number(f"{w} amplitude", blk[1], -INPUT_LIMIT, INPUT_LIMIT)
            f = _number(f"{w} frequency", blk[2], *DRIVE_FREQUENCY_RANGE)
            n = blk[3]
            if isinstance(n, bool) or not isinstance(n, int | np.integer) or not (
                    1 <= n <= MAX_PROTOCOL_PERIODS):  # fmt: skip
                raise ValueError(f"{w} periods={n!r}: an integer in 1…{MAX_PROTOCOL_PERIODS}")
            _number(f"{w} a", blk[4], 0.01, 0.999)
            _number(f"{w} k", blk[5], 0.0, 10.0)
            if len(blk) == 7 and blk[6] != "step":
                raise ValueError(f"{w}: the seventh element is 'step' or absent, got {blk[6]!r}")
            total += int(n) / f
        if total > MAX_PROTOCOL_S:
            raise ValueError(f"protocol: {total:.6g} s up to {w}, more than {MAX_PROTOCOL_S:g} s")
    if total / sample_dt > MAX_SAMPLES:
        raise ValueError(
            f"sample_dt={sample_dt!r}: {total / sample_dt:.3g} samples over {total:.6g} s, more "
            f"than a measurement file holds ({MAX_SAMPLES})"
        )
    return blocks


def _duration(blk: Block) -> float:
    if blk[0] == "steps":
        return blk[3] / blk[2]
    return float(blk[-1])


def protocol_blocks(protocol: str | Sequence[Block]) -> list[tuple[float, float, Block]]:
    """(start [s], end [s], block) of every block of a protocol."""
    blocks = PROTOCOLS[protocol] if isinstance(protocol, str) else list(protocol)
    out, t = [], 0.0
    for blk in blocks:
        out.append((t, t + _duration(blk), blk))
        t += _duration(blk)
    return out


def protocol_drive(
    protocol: str | Sequence[Block], params: ParameterSet, axis: str, sample_dt: float = 5e-5
) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], amplifier input [V]) samples of a protocol (module docstring;
    :func:`check_protocol`)."""
    blocks = check_protocol(protocol, sample_dt)
    amp = params.amplifier
    c_load = None
    tt: list[float] = [0.0]
    uu: list[float] = [0.0]
    level = 0.0
    for blk in blocks:
        kind = blk[0]
        t0 = tt[-1]
        if kind == "hold":
            tt.append(t0 + blk[1])
            uu.append(level)
        elif kind == "scan":
            level = float(blk[1])
            tt.append(t0 + blk[2])
            uu.append(level)
        elif kind == "steps":
            a_v, f, n, a, k = blk[1:6]
            step_back = len(blk) > 6 and blk[6] == "step"
            if k > 0.0 or step_back:
                if c_load is None:
                    c_load = output_capacitance(params, axis)
                setting = StepSetting.adapted(a_v, f, a, k, amp, c_load)
            else:
                setting = StepSetting(a_v, f, a)
            tp, vp = setting.periods(int(n), t0)
            tt.extend(tp[1:].tolist())
            uu.extend((level + vp[1:]).tolist())
        else:
            raise ValueError(f"protocol block {blk!r}: kind must be hold, scan or steps")
    t = np.array(tt)
    u = np.clip(np.array(uu), -amp.input_limit, amp.input_limit)
    # jumps (equal times) → 1 ns apart; add detector samples on a uniform grid
    for i in range(1, t.size):
        if t[i] <= t[i - 1]:
            t[i] = t[i - 1] + 1e-9
    grid = np.arange(0.0, t[-1], sample_dt)
    idx = np.searchsorted(t, grid)
    lo, hi = t[np.clip(idx - 1, 0, t.size - 1)], t[np.clip(idx, 0, t.size - 1)]
    grid = grid[(np.abs(grid - lo) > 2e-9) & (np.abs(grid - hi) > 2e-9)]
    allt = np.concatenate([t, grid])
    order = np.argsort(allt, kind="stable")
    allu = np.concatenate([u, np.interp(grid, t, u)])[order]
    allt = allt[order]
    return allt, allu


def run_virtual_lab(
    protocol: str | Sequence[Block] = "standard",
    effects: Mapping[str, Mapping[str, float]] | None = None,
    *,
    params: ParameterSet | None = None,
    plant: Plant | None = None,
    axis: str = "B",
    noise_std: float = 1e-3,
    seed: int = 0,
    sample_dt: float = 5e-5,
    out: str | Path | None = None,
) -> Measurement:
    """Simulate a protocol on a plant with effects and detector noise; write it if ``out``
    is given.

    Args:
        protocol: a protocol name or its blocks (module docstring).
        effects: catalogue effects added to the plant's, undeclared: the protocol's drive
            (its adapted hold times) is the one the lab would command for ``plant``.
        params: the base parameter set when no ``plant`` is given (default: the real set).
        plant: the plant to run (default: the reduced model of ``params``).
        noise_std: detector noise standard deviation [V] (the plant's ``sensor_noise``).
        seed: of the noise generator.
    """
    check_protocol(protocol, sample_dt)  # before the plant is built
    seed = check_int("seed", seed, 0)
    if plant is not None and not isinstance(plant, Plant):
        raise ValueError(f"plant={type(plant).__name__}: must be a Plant (or None)")
    if effects is not None and not isinstance(effects, Mapping):
        raise ValueError(f"effects={effects!r}: must be a mapping name → parameters")
    base = plant if plant is not None else Plant(params if params is not None else "real")
    p = base.replace(
        effects={**base.effects, **(effects or {})},
        sensor_noise=check_nonnegative("noise_std", noise_std),
    )
    ps = p.params
    # the lab commands its drive for the plant it knows (the undeclared effects aside)
    t, u = protocol_drive(protocol, base.params, axis, sample_dt)
    res = simulate_trace(p, axis, t, u, rng=np.random.default_rng(seed))
    m = Measurement(
        axis=axis,
        amplifier_gain=ps.amplifier.gain,
        detector=ps.detector,
        time=t,
        drives={axis: u},
        detector_v=res.detector_v,
        detector_y_v=res.detector_y_v,
        meta={"protocol": protocol if isinstance(protocol, str) else "custom"},
    )
    if out is not None:
        m.save(out)
    return m

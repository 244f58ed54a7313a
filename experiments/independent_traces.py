"""Write a set of measurement files from the independent plant, plus their truth.

    python experiments/independent_traces.py --out DIR [--only NAME ...]

Each case is one CSV in the project's measurement format (its metadata reveals nothing
of the plant); ``DIR/truth.json`` maps file → effects with their parameters, protocol,
axis, sample rate, noise, drive recording, DAQ bits, seed and the plant parameters.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from turntable_env.testing.independent_plant import (
    DEFAULT_STEP_S,
    AxisMisalignment,
    Creep,
    DetectorNonlinearity,
    Effects,
    FloorVibration,
    FrictionAsymmetry,
    Hysteresis,
    MountResonance,
    PlantParams,
    PreloadRelaxation,
    SensorDrift,
    SlowAmplifier,
    write_trace,
)

__all__ = ["CASES", "Case", "main", "write_all"]


@dataclass(frozen=True)
class Case:
    """One trace: file stem, effects and recording settings."""

    name: str
    effects: Effects = field(default_factory=Effects)
    protocol: str = "standard"
    axis: str = "B"
    sample_rate_Hz: float = 20e3
    noise_std_V: float = 1e-3
    drive_recording: str = "breakpoints"
    daq_bits: int | None = None
    seed: int = 0


CASES: tuple[Case, ...] = (
    Case("clean"),
    Case("creep", Effects(creep=Creep(fraction_per_decade=0.03)), seed=1),
    Case("hysteresis", Effects(hysteresis=Hysteresis()), seed=2),
    Case("vibration", Effects(floor_vibration=FloorVibration()), seed=3),
    Case("friction_asymmetry", Effects(friction_asymmetry=FrictionAsymmetry(0.1)), seed=4),
    Case("slow_amplifier", Effects(slow_amplifier=SlowAmplifier(0.5, 0.5)), seed=5),
    Case("sensor_drift", Effects(sensor_drift=SensorDrift(4e-3, 6e-3)), seed=6),
    Case("detector_nonlinearity", Effects(detector_nonlinearity=DetectorNonlinearity(0.1)), seed=7),
    Case("axis_misalignment", Effects(axis_misalignment=AxisMisalignment(0.05)), seed=8),
    Case("preload_relaxation", Effects(preload_relaxation=PreloadRelaxation(0.35, 0.5)), seed=9),
    Case("mount_resonance", Effects(mount_resonance=MountResonance(380.0, 0.03, 0.5)), seed=10),
    Case("stepping_only", protocol="stepping_only", seed=11),
    Case("long", protocol="long", seed=12),
    Case("axis_C", axis="C", seed=13),
    Case("rate_10kHz", sample_rate_Hz=10e3, seed=14),
    Case("noise_5mV", noise_std_V=5e-3, seed=15),
    Case("noise_0p5mV", noise_std_V=0.5e-3, seed=16),
    Case("sampled_12bit", drive_recording="sampled", daq_bits=12, seed=17),
)


def write_all(
    out: Path, cases: tuple[Case, ...] = CASES, params: PlantParams | None = None
) -> dict:
    """Write every case into ``out`` and ``out/truth.json``; returns the truth."""
    p = PlantParams() if params is None else params
    out.mkdir(parents=True, exist_ok=True)
    truth: dict[str, object] = {
        "plant": p.to_dict(),
        "integration_step_s": DEFAULT_STEP_S,
        "notes": (
            "axis only labels the file (same plant for every axis); adapted flybacks are "
            "timed with the nominal amplifier; daq_bits quantises the recorded drive only"
        ),
        "files": {},
    }
    files: dict[str, object] = truth["files"]  # type: ignore[assignment]
    for c in cases:
        fname = f"{c.name}.csv"
        t0 = time.perf_counter()
        write_trace(
            out / fname,
            p,
            c.protocol,
            effects=c.effects,
            axis=c.axis,
            sample_rate_Hz=c.sample_rate_Hz,
            noise_std=c.noise_std_V,
            drive_recording=c.drive_recording,  # type: ignore[arg-type]
            daq_bits=c.daq_bits,
            seed=c.seed,
        )
        files[fname] = {
            "effects": c.effects.to_dict(),
            "protocol": c.protocol,
            "axis": c.axis,
            "sample_rate_Hz": c.sample_rate_Hz,
            "noise_std_V": c.noise_std_V,
            "drive_recording": c.drive_recording,
            "daq_bits": c.daq_bits,
            "seed": c.seed,
        }
        effs = ", ".join(c.effects.active()) or "none"
        print(
            f"{out / fname}: protocol={c.protocol} axis={c.axis} fs={c.sample_rate_Hz:g} Hz "
            f"noise={c.noise_std_V:g} V drive={c.drive_recording} effects={effs} "
            f"({time.perf_counter() - t0:.1f} s)"
        )
    (out / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    print(f"{out / 'truth.json'}: {len(cases)} files")
    return truth


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    ap.add_argument("--only", nargs="*", default=None, help="case names to write (default: all)")
    args = ap.parse_args(argv)
    cases = CASES
    if args.only:
        known = {c.name for c in CASES}
        bad = [n for n in args.only if n not in known]
        if bad:
            ap.error(f"unknown case(s) {bad}; known: {sorted(known)}")
        cases = tuple(c for c in CASES if c.name in args.only)
    write_all(args.out, cases)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Measurement files from the second independent plant, with the truth beside them.

Writes one CSV per case (see :data:`CASES`) into ``--out`` and ``truth.json``:
``{"plant": {...}, "plant_derived": {...}, "notes": ..., "files": {"<name>.csv":
{"effects": {...}, "protocol": ..., "axis": ..., "sample_rate_Hz": ..., "noise_std_V": ...,
"drive_recording": ..., "seed": ...}}}``. The files themselves hold only what a laboratory
records (the measurement format's required metadata); everything about the plant and the
injected effects is in ``truth.json`` only.

Usage: ``python experiments/second_plant_traces.py --out DIR [--only NAME ...]``
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from turntable_env.testing.second_plant import (
    EFFECT_NAMES,
    PROTOCOLS,
    AxisMisalignment,
    ContactWear,
    Creep,
    DetectorNonlinearity,
    Effects,
    FloorVibration,
    FrictionAsymmetry,
    Hysteresis,
    MainsPickup,
    MirrorPlay,
    PlantParams,
    SensorDrift,
    SlowAmplifier,
    params_truth,
    write_trace,
)


@dataclass(frozen=True)
class Case:
    """One file to write."""

    effects: Effects = field(default_factory=Effects)
    protocol: str = "scan_and_bursts"
    axis: str = "B"
    sample_rate_Hz: float = 20e3
    noise_std_V: float = 1e-3
    drive_recording: str = "breakpoints"
    seed: int = 0


# one case per effect, each at a strength the data shows clearly
_EFFECT_DEFAULTS = {
    "creep": Creep(fraction_per_decade=0.07),
    "hysteresis": Hysteresis(loop_width_fraction=0.13, reference_V=360.0),
    "floor_vibration": FloorVibration(amplitude_m=30e-9, frequency_Hz=147.0),
    "friction_asymmetry": FrictionAsymmetry(fraction=0.3),
    "slow_amplifier": SlowAmplifier(slew_limit_V_per_s=0.6e6, bandwidth_factor=0.4),
    "sensor_drift": SensorDrift(rate_V_per_s=8e-3),
    "detector_nonlinearity": DetectorNonlinearity(edge_gain_loss=0.2),
    "axis_misalignment": AxisMisalignment(angle_deg=4.0),
    "mains_pickup": MainsPickup(amplitude_V=0.15, frequency_Hz=50.0),
    "contact_wear": ContactWear(friction_loss=0.35, distance_m=8e-6),
    "mirror_play": MirrorPlay(play_rad=1.5e-5),
}

CASES: dict[str, Case] = {
    "clean": Case(seed=1),
    **{
        name: Case(effects=Effects(**{name: _EFFECT_DEFAULTS[name]}), seed=10 + k)
        for k, name in enumerate(EFFECT_NAMES)
    },
    "axis_A_10kHz": Case(axis="A", sample_rate_Hz=10e3, seed=30),
    "axis_C_20kHz": Case(axis="C", sample_rate_Hz=20e3, protocol="scan_holds", seed=31),
    "noise_5mV": Case(noise_std_V=5e-3, seed=32),
    "bursts_only": Case(protocol="stepping_bursts", seed=33),
    "sampled": Case(drive_recording="sampled", seed=34),
}

NOTES = (
    "Second independent plant (turntable_env/testing/second_plant.py): single rotation axis, "
    "elasto-plastic (Dupont) friction at the driven contacts, tube tips as masses on the "
    "tube bending stiffness, table rotation mode on the contact compliance (~2.5 kHz) and a "
    "mirror-mount rocking mode (9.5 kHz), HVA amplifier with 2nd-order small-signal response "
    "and slew limit. 'effects' lists the injected effects with their parameters (an empty "
    "dict: none). drive_recording 'breakpoints': rows at the sample times and at every drive "
    "breakpoint, so the recorded drive linearly interpolated is the applied one; 'sampled': "
    "rows at the sample times only (drive corners between samples are missing from the "
    "file). mains_pickup is added at the amplifier input and is not in the recorded drive. "
    "Angles: detector V = L*tan(2*phi)/S (Eq. 4.1), clipped at +-linear_range/S."
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path, help="output directory")
    ap.add_argument("--only", nargs="+", metavar="NAME", help=f"cases: {', '.join(CASES)}")
    args = ap.parse_args(argv)
    names = args.only or list(CASES)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; known: {', '.join(CASES)}")
    args.out.mkdir(parents=True, exist_ok=True)
    params = PlantParams()
    truth_path = args.out / "truth.json"
    files: dict[str, dict] = {}
    if args.only and truth_path.exists():
        files = json.loads(truth_path.read_text()).get("files", {})
    for name in names:
        case = CASES[name]
        t0 = time.perf_counter()
        path = write_trace(
            args.out / f"{name}.csv",
            params,
            PROTOCOLS[case.protocol],
            effects=case.effects,
            axis=case.axis,
            sample_rate_Hz=case.sample_rate_Hz,
            noise_std_V=case.noise_std_V,
            seed=case.seed,
            drive_recording=case.drive_recording,
        )
        files[path.name] = {
            "effects": case.effects.truth(),
            "protocol": case.protocol,
            "axis": case.axis,
            "sample_rate_Hz": case.sample_rate_Hz,
            "noise_std_V": case.noise_std_V,
            "drive_recording": case.drive_recording,
            "seed": case.seed,
        }
        print(f"{path.name:28s} {time.perf_counter() - t0:6.2f} s", flush=True)
    truth = {
        "plant": params_truth(params),
        "plant_derived": params.derived(),
        "notes": NOTES,
        "files": files,
    }
    truth_path.write_text(json.dumps(truth, indent=2, sort_keys=False) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

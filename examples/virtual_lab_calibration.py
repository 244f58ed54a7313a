"""Closing the loop on data with an undeclared effect: virtual lab → calibration.

    python examples/virtual_lab_calibration.py [--effect piezo_creep=0.02] [--global-points 16]
        [--candidates piezo_creep,sensor_drift] [--hops N]

The virtual lab runs the standard protocol on the real turntable with an effect the
calibrator is not told about and writes a measurement file. The calibrator fits the
nominal model, searches the effect catalogue on held-out data and prints the error before
and after and what it selected.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path


def _count(text: str) -> int:
    """An integer ≥ 0 (argparse refuses anything else with exit 2, before any work)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: must be an integer ≥ 0") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be an integer ≥ 0")
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effect", default="piezo_creep=0.02")
    ap.add_argument("--global-points", type=_count, default=16, help="Sobol points")
    ap.add_argument("--candidates", default=None, help="comma-separated effects to try")
    ap.add_argument("--hops", type=_count, default=None,
                    help="basin hops from the best fit (0: none, a quick look; default: the "
                         "calibrator's)")  # fmt: skip
    args = ap.parse_args()
    # the package after the arguments: a refusal comes at once, before the kernels load
    from turntable_env.calibration.calibrate import calibrate
    from turntable_env.calibration.virtual_lab import run_virtual_lab
    from turntable_env.effects import parse_effects

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "lab.csv"
        run_virtual_lab("standard", parse_effects(args.effect), out=path)
        cands = args.candidates.split(",") if args.candidates else None
        budget = {} if args.hops is None else {"hops": args.hops}
        res = calibrate([path], global_points=args.global_points, candidates=cands,
                        workers=1, progress=None, **budget)  # fmt: skip
    selected = ", ".join(res.selected_effects) or "none"
    print(f"injected {args.effect}; selected {selected}; held-out error "
          f"{res.error_before:.3g} → {res.error_after:.3g} {res.error_unit}")  # fmt: skip


if __name__ == "__main__":
    main()

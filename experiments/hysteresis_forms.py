"""How closely the catalogue's hysteresis form can follow the first independent plant's
(issue 31: the first plant's hysteresis row misses its target by a few per cent).

The plant writes Bouc–Wen hysteresis on the quadrant voltage (``Hysteresis`` in
``turntable_env/testing/independent_plant.py``: ḣ = α·V̇ − β·|V̇|·h − γ·V̇·|h|, strain
∝ V − h); the catalogue's ``piezo_hysteresis`` is a Prandtl–Ishlinskii operator, (1 − h)·u
+ h·mean of 8 plays with thresholds up to ``width`` (``effects.input_stage_nb``). This
script drives both with the trace's own recorded drive, breakpoint by breakpoint (the
amplifier taken as its gain alone) and fits to the plant's V − h, in input volts:

* the catalogue's form, h and width within their catalogue ranges, and a gain;
* the best a Prandtl–Ishlinskii operator can do: 24 plays up to 3 V with free weights
  (linear least squares), an upper bound for any re-weighting of the catalogue's plays;
* no hysteresis (a gain alone).

    python experiments/hysteresis_forms.py [--traces DIR]

prints the RMS misfit of each [mV of input] (the input stage only: no mechanics).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from turntable_env.effects import CATALOGUE, apply_input

ROOT = Path(__file__).resolve().parent / "results" / "independent_traces"
DV_MAX = 0.5  # V of quadrant voltage per Bouc–Wen update (explicit Euler, substeps)


def bouc_wen(v: np.ndarray, alpha: float, beta: float, gamma: float) -> np.ndarray:
    """The plant's hysteresis state h [V] along the quadrant voltage v [V] (its update, in
    substeps of at most :data:`DV_MAX`: a flyback drops hundreds of volts between two
    breakpoints, which the plant's amplifier spreads over microseconds)."""
    h = np.zeros_like(v)
    hb = 0.0
    for i in range(1, v.size):
        n = max(1, int(np.ceil(abs(v[i] - v[i - 1]) / DV_MAX)))
        dv = (v[i] - v[i - 1]) / n
        for _ in range(n):
            hb += alpha * dv - beta * abs(dv) * hb - gamma * dv * abs(hb)
        h[i] = hb
    return h


def plays(u: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """(len(u), len(thresholds)) play-operator outputs from rest at 0 [V]."""
    out = np.empty((u.size, thresholds.size))
    p = np.zeros(thresholds.size)
    for i, x in enumerate(u):
        p = np.minimum(np.maximum(p, x - thresholds), x + thresholds)
        out[i] = p
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--traces", type=Path, default=ROOT)
    args = ap.parse_args(argv)
    truth = json.loads((args.traces / "truth.json").read_text())
    spec = truth["files"]["hysteresis.csv"]["effects"]["hysteresis"]
    gain = truth["plant"]["amplifier_gain"]
    d = pd.read_csv(args.traces / "hysteresis.csv", comment="#")
    drive = d.filter(like="drive_").iloc[:, 0].to_numpy()
    tf = d["t_s"].to_numpy()  # the drive's breakpoints (both operators are rate-independent)
    u = drive
    v = gain * u
    y = (v - bouc_wen(v, spec["alpha"], spec["beta_per_V"], spec["gamma_per_V"])) / gain

    p = {q.name: q for q in CATALOGUE["piezo_hysteresis"].parameters}

    def catalogue(x: np.ndarray) -> np.ndarray:
        eff = {"piezo_hysteresis": {"h": x[0], "width": x[1]}}
        to, vo = apply_input(tf, u, eff)
        return x[2] * np.interp(tf, to, vo) - y

    fit = least_squares(catalogue, [p["h"].typical, p["width"].typical, 1.0],
                        bounds=([p["h"].low, p["width"].low, 0.5],
                                [p["h"].high, p["width"].high, 1.5]))  # fmt: skip
    thr = 3.0 * np.arange(1, 25) / 24
    a = np.column_stack([u, plays(u, thr)])
    w, *_ = np.linalg.lstsq(a, y, rcond=None)
    gain_only = least_squares(lambda c: c[0] * u - y, [1.0])

    def rms(r: np.ndarray) -> float:
        return 1e3 * float(np.sqrt(np.mean(r**2)))

    print(f"plant: Bouc–Wen alpha {spec['alpha']}, beta {spec['beta_per_V']} /V, gamma "
          f"{spec['gamma_per_V']} /V on the quadrant voltage (gain {gain:g})")  # fmt: skip
    print(f"no hysteresis (a gain):                      {rms(gain_only.fun):6.1f} mV")
    print(f"catalogue Prandtl–Ishlinskii (h {fit.x[0]:.3f}, width {fit.x[1]:.2f} V): "
          f"{rms(fit.fun):6.1f} mV")  # fmt: skip
    print(f"Prandtl–Ishlinskii, 24 free weights to 3 V:  {rms(a @ w - y):6.1f} mV")


if __name__ == "__main__":
    main()

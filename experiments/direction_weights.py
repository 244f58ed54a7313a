"""The direction pairs' two weightings on five pairs, one with a tenth of the others'
noise (issue 31, stop 62; the case of ``tests/test_signatures.py -k alike``).

    python experiments/direction_weights.py

Prints, for a constant asymmetry that explains all five pairs alike and one fitted to the
quiet pair only, the gain in nats and the least gain with one pair left out: with the
misfit as a factor on each pair's noise variance (before stop 62) and as a variance common
to the pairs (``signatures.group_scores`` now).
"""

from __future__ import annotations

import numpy as np

from turntable_env.calibration.identify import leave_one_out
from turntable_env.calibration.signatures import Features, group_scores


def factor_nats(d: Features, a: Features, b: Features, n_free: int = 1) -> float:
    """The gain with the misfit as a factor on the noise variance (the F-test scale)."""
    za, zb = (d.value - a.value) / d.noise, (d.value - b.value) / d.noise
    ra, rb = float(za @ za), float(zb @ zb)
    s2 = max(1.0, rb / (d.value.size - n_free))
    return 0.5 * (ra - rb) / s2


def main() -> None:
    names = tuple(f"pair {k}" for k in range(5))
    sd = np.array([1e-4, 1e-3, 1e-3, 1e-3, 1e-3])
    data = Features(names, ("direction",) * 5, np.array([-0.02, -0.03, -0.04, -0.05, -0.062]), sd)
    current = data._replace(value=np.zeros(5))
    for label, alpha in (("explains all five", -0.040), ("fits the quiet pair", -0.0201)):
        cand = data._replace(value=np.full(5, alpha))
        loo_f = min(factor_nats(data.subset(k != np.arange(5)), current.subset(k != np.arange(5)),
                                cand.subset(k != np.arange(5))) for k in range(5))  # fmt: skip
        whole = group_scores(data, current, cand)["direction"]["nats"]
        loo, _ = leave_one_out(data, current, cand, ("direction",))
        print(f"{label:<20} factor: {factor_nats(data, current, cand):5.1f} nats "
              f"({loo_f:.1f} with one left out)   common variance: {whole:5.1f} nats "
              f"({loo:.1f})")  # fmt: skip


if __name__ == "__main__":
    main()

"""The compiled kernels give the numbers they gave before their split into named phases
(issue 33): short standard runs of the 3-D model (fixed and adaptive step), the reduced
model (ladder and analytic step, a batch of two, under the restart rule and the resumed
rung) and the env on both fidelities, against tests/data/kernel_golden.json, recorded with
the kernels of commit e52b118, the resumed rung's runs at stop 84
(experiments/kernel_golden.py). On the machine that recorded it the match is bit for bit
(``python experiments/kernel_golden.py --compare``); elsewhere another CPU's fused
multiply-adds may move the last bits, so the test allows 1e-9 of each run's scale — a
change of the physics moves them by far more."""

from __future__ import annotations

from conftest import experiment


def test_kernels_reproduce_the_recorded_runs():
    mod = experiment("kernel_golden")
    diffs = mod.compare(mod.record())
    assert len(diffs) == 8
    assert {name: rel for name, rel in diffs.items() if not rel <= 1e-9} == {}

"""The slow tier's schedule (``.ci/run``: ``-n 2 --dist loadgroup``): tests that share one
``xdist_group`` run on one worker, so a calibration or a module fixture they share is
computed once per run. pytest 9.2's structured node ids silently undo that grouping
(pytest-dev/pytest-xdist#1386), hence pyproject's ``pytest<9.2``: this test fails on it."""

import re

import pytest

pytest_plugins = ["pytester"]


@pytest.mark.slow  # a contract of the slow tier's schedule, checked where it runs
def test_tests_of_one_group_run_on_one_worker(pytester):
    pytester.makepyfile(
        test_grouped="""
        import pytest

        @pytest.mark.xdist_group("shared")
        @pytest.mark.parametrize("i", range(4))
        def test_member(i):
            pass

        @pytest.mark.parametrize("i", range(4))
        def test_free(i):
            pass
        """
    )
    res = pytester.runpytest_subprocess("-n", "2", "--dist", "loadgroup", "-v",
                                        "-p", "no:cacheprovider")  # fmt: skip
    res.assert_outcomes(passed=8)
    runs = re.findall(r"\[(gw\d)\][^\n]*PASSED test_grouped\.py::test_member\[\d\](\S*)",
                      res.stdout.str())  # fmt: skip
    assert len(runs) == 4
    assert {suffix for _, suffix in runs} == {"@shared"}  # the group reached the scheduler
    assert len({worker for worker, _ in runs}) == 1

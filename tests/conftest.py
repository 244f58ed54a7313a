"""Shared fixtures."""

import pytest

from turntable_env.params import real_parameters, thesis_parameters


@pytest.fixture(scope="session")
def real():
    return real_parameters()


@pytest.fixture(scope="session")
def thesis():
    return thesis_parameters()

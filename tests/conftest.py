"""Shared fixtures: a seeded ``rng`` whose seed is printed in the header (``--seed``)."""

from __future__ import annotations

import numpy as np
import pytest

DEFAULT_SEED = 20261122


def pytest_addoption(parser):
    parser.addoption("--seed", type=int, default=DEFAULT_SEED,
                     help="seed for the rng fixture (default %(default)s)")


def pytest_report_header(config):
    return f"tactilab rng seed: {config.getoption('--seed')} (rerun with --seed N)"


@pytest.fixture
def seed(request) -> int:
    return request.config.getoption("--seed")


@pytest.fixture
def rng(seed) -> np.random.Generator:
    return np.random.default_rng(seed)

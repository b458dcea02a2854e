"""Shared fixtures: a seeded ``rng`` whose seed is printed in the header (``--seed``)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import settings

# CI runs are reproducible: hypothesis draws the same examples each run (derandomize);
# locally it explores new ones. Select with HYPOTHESIS_PROFILE=ci|dev.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))

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


def pytest_configure(config):
    # No tqdm monitor thread in the test process: the fork-based reliability tests need one thread.
    import tqdm

    tqdm.tqdm.monitor_interval = 0


def pytest_collection_modifyitems(session, config, items):
    """Run the tests that start a Dask client last.

    A Dask client leaves its IO-loop thread running in this process after it closes, and the
    kill -9 reliability tests fork, which needs a single-threaded process.
    """
    items.sort(key=lambda item: item.nodeid.startswith("tests/test_batch"))


@pytest.fixture(params=["compiled", "numpy"])
def kernel_path(request, monkeypatch) -> str:
    """Runs a test on both paths of tactilab.core.jit: the compiled kernels and their NumPy twins."""
    monkeypatch.setenv("TACTILAB_JIT", "1" if request.param == "compiled" else "0")
    return request.param

"""Shared fixtures: paths to the independent simulator's recordings and common objects."""

from __future__ import annotations

import json
import os
from pathlib import Path

import jax
import pytest
from threadpoolctl import threadpool_limits

import rattlefit as rf
from rattlefit.testing.shared import recordings_dir

# pytest-xdist already runs one worker per core: keep each worker on one JAX device (starting
# JAX here fixes that, so the CLI's use_cpu_cores() is a no-op under test), and its BLAS on one
# thread (two workers each spinning two BLAS threads on two cores run numpy's matrix products
# several times slower). numpy is loaded before this file, so the environment variable would
# come too late: threadpoolctl sets the loaded library.
rf.configure(cpu_cores=1)
jax.devices()
threadpool_limits(limits=1, user_api="blas")
# the CLI keeps compiled programs in a cache under the home directory; tests leave it alone
os.environ.setdefault("RATTLEFIT_CACHE_DIR", "off")

ROOT = Path(__file__).resolve().parents[1]
#: The independent simulator's recordings (../shared/recordings, else the repository's copy).
SHARED = recordings_dir(ROOT)

#: A skip whose reason starts with this names something the environment should provide (the
#: independent recordings, a headless browser): under ``CI`` (set, and not "0" or "false") it
#: is a failure, because in CI what it needs must be there.
NEEDS = "needs "
CI_ENV = "CI"

#: Tests marked ``@pytest.mark.slow`` are identifications too long for the CI time budget:
#: skipped unless ``--run-slow`` is given or this variable is set (to anything but 0).
SLOW_ENV = "RATTLEFIT_SLOW"
SLOW_REASON = f"slow: run with --run-slow (or {SLOW_ENV}=1)"


def pytest_addoption(parser):
    parser.addoption(
        "--run-slow",
        action="store_true",
        default=False,
        help=f"also run the tests marked slow (long identifications; or set {SLOW_ENV}=1)",
    )


def in_ci() -> bool:
    return os.environ.get(CI_ENV, "").strip().lower() not in ("", "0", "false")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.skipped and in_ci() and isinstance(report.longrepr, tuple):
        reason = str(report.longrepr[2]).removeprefix("Skipped: ")
        if reason.startswith(NEEDS):
            report.outcome = "failed"
            report.longrepr = f"in CI nothing may be missing: {reason}"


def pytest_collection_modifyitems(config, items):
    if config.getoption("--run-slow") or os.environ.get(SLOW_ENV, "") not in ("", "0"):
        return
    skip = pytest.mark.skip(reason=SLOW_REASON)
    for item in items:
        if item.get_closest_marker("slow") is not None:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def shared_recordings() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"{NEEDS}the independent simulator's recordings, not at {SHARED}")
    return SHARED


@pytest.fixture(scope="session")
def shared_truth(shared_recordings) -> dict:
    return json.loads((shared_recordings / "truth.json").read_text())


@pytest.fixture(scope="session")
def pair2():
    return rf.table2_pair("II", center_distance_mm=65.6)

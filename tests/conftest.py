"""Shared fixtures: paths to the independent simulator's recordings and common objects."""

from __future__ import annotations

import atexit
import json
import os
import shutil
import tempfile
from pathlib import Path

from rattlefit.reproducibility import cap_numpy_simd

# numpy's kernels below AVX-512, as XLA's are (rattlefit.reproducibility), in the workers,
# notebook kernels, CLI and dask processes the run starts: numpy reads the setting at import
cap_numpy_simd()

import pytest  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import rattlefit as rf  # noqa: E402
from rattlefit.compile_cache import CACHE_ENV  # noqa: E402
from rattlefit.testing.shared import recordings_dir  # noqa: E402
from xla_threads import start_jax_on_one_thread  # noqa: E402

# pytest-xdist already runs one worker per core: keep each worker on one JAX device (starting
# JAX here fixes that, so the CLI's use_cpu_cores() is a no-op under test) served by one thread
# of XLA's CPU pool (tests/xla_threads.py), and its BLAS on one thread (two workers each
# spinning two BLAS threads on two cores run numpy's matrix products several times slower).
# numpy is loaded before this file, so the environment variable would come too late:
# threadpoolctl sets the loaded library.
# One compilation cache for the whole test run, in a temporary directory that the main process
# makes before the workers start (they, and every CLI, notebook and campaign process a test
# starts, inherit it) and removes at its exit: the same programs are compiled once, not once
# per process, and the user's cache under the home directory is left alone. A cache entry is
# the program a fresh compilation gives, so no result depends on it (tests/test_compile_cache.py).
if CACHE_ENV not in os.environ:
    os.environ[CACHE_ENV] = tempfile.mkdtemp(prefix="rattlefit-test-cache-")
    atexit.register(shutil.rmtree, os.environ[CACHE_ENV], ignore_errors=True)
start_jax_on_one_thread()  # rattlefit configured on one device
rf.use_compilation_cache()  # $RATTLEFIT_CACHE_DIR, or none when it is "off"
threadpool_limits(limits=1, user_api="blas")

ROOT = Path(__file__).resolve().parents[1]
#: The independent simulator's recordings (../shared/recordings, else the repository's copy).
SHARED = recordings_dir(ROOT)

#: A skip whose reason starts with this names something the environment should provide (the
#: independent recordings, a headless browser): under ``CI`` (set, and not "0" or "false") it
#: is a failure, because in CI what it needs must be there.
NEEDS = "needs "
CI_ENV = "CI"

#: Tests marked ``@pytest.mark.slow`` are the statistical suite, identifications too long for
#: the CI time budget: not collected (deselected, not skipped) unless ``--run-slow`` is given or
#: this variable is set (to anything but 0).
SLOW_ENV = "RATTLEFIT_SLOW"


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
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item.get_closest_marker("slow") is None]


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

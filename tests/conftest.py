"""Shared fixtures: paths to the independent simulator's recordings and common objects."""

from __future__ import annotations

import json
import os
from pathlib import Path

import jax
import pytest

import rattlefit as rf

# pytest-xdist already runs one worker per core: keep each worker on one JAX device (starting
# JAX here fixes that, so the CLI's use_cpu_cores() is a no-op under test).
jax.devices()
# the CLI keeps compiled programs in a cache under the home directory; tests leave it alone
os.environ.setdefault("RATTLEFIT_CACHE_DIR", "off")

SHARED = Path(__file__).resolve().parents[2] / "shared" / "recordings"


@pytest.fixture(scope="session")
def shared_recordings() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"the independent simulator's recordings are not at {SHARED}")
    return SHARED


@pytest.fixture(scope="session")
def shared_truth(shared_recordings) -> dict:
    return json.loads((shared_recordings / "truth.json").read_text())


@pytest.fixture(scope="session")
def pair2():
    return rf.table2_pair("II", center_distance_mm=65.6)

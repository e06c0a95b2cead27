"""The test processes' XLA pool (tests/xla_threads.py): one thread, and every core kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from xla_threads import pool_threads

SCRIPT = """
import json, os
from pathlib import Path
before = sorted(os.sched_getaffinity(0))
from xla_threads import pool_threads, start_jax_on_one_thread
start_jax_on_one_thread()
def affinity(task):
    try:
        return sorted(os.sched_getaffinity(int(task.name)))
    except ProcessLookupError:  # the thread ended after it was listed
        return None
found = [affinity(t) for t in Path("/proc/self/task").iterdir()]
print(json.dumps({"before": before, "pool": pool_threads(),
                  "threads": [a for a in found if a is not None]}))
"""


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="Linux only")
def test_jax_starts_on_one_pool_thread_and_every_thread_keeps_every_core():
    paths = (str(Path(__file__).parent), os.environ.get("PYTHONPATH", ""))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in paths if p)}
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen["pool"] == 1
    assert len(seen["threads"]) > 1 and all(t == seen["before"] for t in seen["threads"])
    assert pool_threads() == 1  # this worker's, started by tests/conftest.py

"""``import rattlefit`` changes nothing; ``rattlefit.configure()`` sets JAX up, and a
simulation refuses to run in single precision."""

import json
import os
import subprocess
import sys

import pytest

import rattlefit as rf

IMPORT_ONLY = """
import json, os
import jax
before = [jax.config.read("jax_enable_x64"), os.environ.get("XLA_FLAGS")]
import rattlefit, rattlefit.cli, rattlefit.diagnosis, rattlefit.likelihood, rattlefit.report
from jax._src import xla_bridge
after = [jax.config.read("jax_enable_x64"), os.environ.get("XLA_FLAGS")]
started = xla_bridge.backends_are_initialized()
try:
    rattlefit.RattleModel.from_geometry(rattlefit.table2_pair("II"))
    refused = ""
except rattlefit.RattlefitError as exc:
    refused = str(exc)
config = rattlefit.configure(cpu_cores=2)
import jax.numpy as jnp
print(json.dumps({"before": before, "after": after, "started": started,
                  "refused": refused, "devices": config.devices, "isa": config.cpu_isa,
                  "dtype": str(jnp.ones(1).dtype), "n_cpu": len(jax.devices("cpu"))}))
"""


def run_fresh(script: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "RATTLEFIT_CPU_ISA")}
    out = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_leaves_jax_alone_and_configure_sets_it_up():
    got = run_fresh(IMPORT_ONLY)
    assert got["before"] == got["after"] == [False, None]
    assert not got["started"]  # importing does not start JAX: configure can still choose
    assert "configure()" in got["refused"]  # a simulation without 64-bit mode is refused
    assert got["devices"] == got["n_cpu"] == 2
    assert got["dtype"] == "float64"
    assert got["isa"] in ("AVX2", "native")  # native on CPUs that are not x86-64


def test_configure_again_with_what_is_in_effect_is_silent(recwarn):
    # the test process configured JAX already (conftest): the CLI configures again
    config = rf.configure(cpu_cores=1)
    assert config.devices == 1
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_configure_cannot_change_a_started_device_count():
    with pytest.warns(RuntimeWarning, match="already started"):
        config = rf.configure(cpu_cores=3)
    assert config.devices == 1

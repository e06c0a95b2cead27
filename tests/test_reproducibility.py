"""A seeded result must not depend on the CPU that computed it (rattlefit.reproducibility)."""

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from rattlefit import reproducibility as rp

X86 = platform.machine().lower() in ("x86_64", "amd64")
BUNDLED = "pairII_boundary_65.6_20pct_16Hz.h5"  # a recording in data/
MILD_RECORDING_SEED = 11  # the mild boundary recording of pair II (as in test_fit)

# A 1 s synthetic recording of the mild rattle: long enough for the chaos to grow a last-bit
# difference into another recording (on an AVX-512 CPU the uncapped default and the AVX2 cap
# give different counts; over 0.3 s they still agree), so equal hashes mean equal arithmetic.
SCRIPT = (
    f"MILD_RECORDING_SEED = {MILD_RECORDING_SEED}\n"
    + """
import hashlib, json, os
import numpy as np
import rattlefit as rf
rf.configure()
from rattlefit.io.recording import OperatingPoint
from rattlefit.simulation.synthetic import synthesize
g = rf.table2_pair("II", center_distance_mm=65.0)
op = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
rec, _ = synthesize(g, op, p, seed=MILD_RECORDING_SEED, duration=1.0, burn_in=0.5)
counts = np.asarray(rec.secondary)
print(json.dumps({"hash": hashlib.sha1(counts.tobytes()).hexdigest(),
                  "platform": rf.platform_info()}))
"""
)


def _run(env_changes):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", rp.ISA_ENV)}
    env.update(env_changes)
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not X86, reason="the cap applies to x86-64 CPUs only")
def test_configure_caps_the_isa_before_jax_starts():
    # the default configuration must give exactly what an explicit XLA cap gives: if the cap
    # were set too late (after JAX started its backend) or not at all, an AVX-512 machine
    # would compute the native realisation instead
    default = _run({})
    explicit = _run({rp.ISA_ENV: "native", "XLA_FLAGS": f"--xla_cpu_max_isa={rp.DEFAULT_CPU_ISA}"})
    assert default["hash"] == explicit["hash"]
    assert default["platform"]["cpu_isa"] == rp.DEFAULT_CPU_ISA
    assert default["platform"]["devices"] >= 1 and default["platform"]["jax"]


def test_a_cap_the_user_set_wins(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1 --xla_cpu_max_isa=SSE4_2")
    monkeypatch.setenv(rp.ISA_ENV, "AVX512")
    assert rp.pin_cpu_isa() == "SSE4_2"
    assert os.environ["XLA_FLAGS"] == "--xla_foo=1 --xla_cpu_max_isa=SSE4_2"


def test_native_leaves_xla_alone(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1")
    monkeypatch.setenv(rp.ISA_ENV, "native")
    assert rp.pin_cpu_isa() == "native"
    assert os.environ["XLA_FLAGS"] == "--xla_foo=1"
    assert rp.cpu_isa() == "native"


@pytest.mark.skipif(not X86, reason="the cap applies to x86-64 CPUs only")
def test_too_late_a_cap_warns_and_changes_nothing(monkeypatch):
    # the test process has started JAX (conftest): a cap set now could not take effect
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1")
    monkeypatch.delenv(rp.ISA_ENV, raising=False)
    with pytest.warns(RuntimeWarning, match="not capped"):
        assert rp.pin_cpu_isa() == "native"
    assert os.environ["XLA_FLAGS"] == "--xla_foo=1"


def test_platform_info_names_the_cpu_model():
    # a seeded result can depend on the CPU model even under the cap (another CPU of the same
    # instruction set can compute another realisation), so the outputs say which CPU computed
    # them
    text = (
        "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 1\n"
        "model name\t: AMD EPYC\nflags\t\t: fpu avx2\n\n"
        "processor\t: 1\nvendor_id\t: GenuineIntel\ncpu family\t: 6\nmodel\t\t: 85\n"
        "model name\t: Intel Xeon\n"
    )
    assert rp.cpu_model(text) == "AMD EPYC (AuthenticAMD family 25 model 1)"
    arm = "processor\t: 0\nBogoMIPS\t: 108.00\n\nprocessor\t: 1\n\nHardware\t: BCM2835\n"
    assert rp.cpu_model(arm) == "BCM2835"  # some ARM kernels, after every processor's block
    info = rp.platform_info()
    assert info["cpu"] == rp.cpu_model() and isinstance(info["cpu"], str)
    from importlib.metadata import version

    assert info["rattlefit"] == version("rattlefit")  # the installed distribution's
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as f:
            vendor = next((ln.split(":")[1].strip() for ln in f if ln.startswith("vendor_id")), "")
        assert vendor in info["cpu"]


# A command line started without numpy: `rattlefit info`, then what numpy's kernels use.
CLI_SCRIPT = """
import sys
from rattlefit.cli import main
from rattlefit.reproducibility import numpy_simd
try:
    main(["info", sys.argv[1]])
except SystemExit:
    pass
print(numpy_simd())
"""


def _numpy_simd_of(script, *args, env_changes=()):
    env = {k: v for k, v in os.environ.items() if k not in (rp.NUMPY_FEATURES_ENV, rp.ISA_ENV)}
    env.update(dict(env_changes))
    out = subprocess.run(
        [sys.executable, "-c", script, *args], env=env, capture_output=True, text=True, check=True
    )
    return out.stdout.strip().splitlines()[-1]


@pytest.mark.skipif(not X86, reason="the cap applies to x86-64 CPUs only")
def test_the_command_line_keeps_numpy_below_avx512():
    # numpy rounds its exp, log and sin differently with AVX-512: the command line must name
    # the AVX-512 levels before numpy is imported, or an AVX-512 CPU computes another
    # realisation than an AVX2 one (this can fail only on a CPU with AVX-512)
    recording = str(Path(__file__).resolve().parents[1] / "data" / BUNDLED)
    used = _numpy_simd_of(CLI_SCRIPT, recording)
    assert used and not any(level in used.split() for level in rp.NUMPY_ABOVE_AVX2), used
    # the workers of this test run inherit the cap from tests/conftest.py
    assert not any(level in rp.numpy_simd().split() for level in rp.NUMPY_ABOVE_AVX2)


def test_numpy_is_left_alone_when_asked(monkeypatch):
    monkeypatch.delenv(rp.NUMPY_FEATURES_ENV, raising=False)
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1")
    monkeypatch.setenv(rp.ISA_ENV, "native")
    rp.cap_numpy_simd()
    assert rp.NUMPY_FEATURES_ENV not in os.environ
    rp.cap_numpy_simd("AVX512")
    assert rp.NUMPY_FEATURES_ENV not in os.environ
    monkeypatch.setenv(rp.NUMPY_FEATURES_ENV, "AVX512_SPR")  # the user's own choice wins
    rp.cap_numpy_simd("AVX2")
    assert os.environ[rp.NUMPY_FEATURES_ENV] == "AVX512_SPR"
    monkeypatch.delenv(rp.NUMPY_FEATURES_ENV)
    rp.cap_numpy_simd("AVX2")
    assert os.environ[rp.NUMPY_FEATURES_ENV].split() == list(rp.NUMPY_ABOVE_AVX2) or not X86


@pytest.mark.skipif(not X86, reason="the cap applies to x86-64 CPUs only")
def test_a_cap_in_xla_flags_wins_for_numpy_too(monkeypatch):
    monkeypatch.delenv(rp.NUMPY_FEATURES_ENV, raising=False)
    monkeypatch.setenv(rp.ISA_ENV, "AVX2")
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_max_isa=AVX512")
    assert rp.requested_cap("SSE4_2") == "AVX512"
    rp.cap_numpy_simd("AVX2")  # XLA runs with AVX-512, so numpy may too
    assert rp.NUMPY_FEATURES_ENV not in os.environ
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1 --xla_cpu_max_isa=SSE4_2")
    rp.cap_numpy_simd("native")
    assert os.environ[rp.NUMPY_FEATURES_ENV].split() == list(rp.NUMPY_ABOVE_AVX2)
    monkeypatch.setenv("XLA_FLAGS", "--xla_foo=1")
    assert rp.requested_cap() == "AVX2" and rp.requested_cap("native") == "native"

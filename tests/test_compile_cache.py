"""The persistent compilation cache: used by a second process, and results unchanged."""

import os
import subprocess
import sys
import warnings
from pathlib import Path

from rattlefit.compile_cache import CACHE_ENV, use_compilation_cache

DATA = Path(__file__).resolve().parents[1] / "data"
RECORDING = "pairII_boundary_65.6_20pct_16Hz.h5"

# a fresh process evaluates the fit's features (the program every identification spends its
# time in) at one point, with the cache in argv[1], and prints them exactly
EVALUATE = """
import sys
import numpy as np
import rattlefit as rf
rf.configure(compilation_cache=sys.argv[1])
from rattlefit.problem.forward import evaluate
from rattlefit.problem.problem import build_problem
rec = rf.read_recording(sys.argv[2])
problem, _ = build_problem([rec], rf.FitOptions(), np.random.default_rng(0))
features = evaluate(problem, np.zeros((1, len(problem.specs))))
print(features.tobytes().hex())
"""


def _evaluate_in_a_fresh_process(cache):
    proc = subprocess.run(
        [sys.executable, "-c", EVALUATE, str(cache), str(DATA / RECORDING)],
        env={**os.environ, CACHE_ENV: "off"},  # the argument, not the environment, decides
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


def test_a_second_process_reuses_the_cache_and_gets_the_same_features(tmp_path):
    cache = tmp_path / "cache"
    first = _evaluate_in_a_fresh_process(cache)
    written = sorted(p.name for p in cache.iterdir())
    # the batched evaluation of the fit was kept (programs compiled in < 0.5 s are not)
    assert any(name.startswith("jit_features_chunk") for name in written), written
    second = _evaluate_in_a_fresh_process(cache)
    # a program read back from the cache is the one compiled before: the chaotic motion, and
    # so the features, are the same to the last bit; and nothing was compiled afresh
    assert second == first
    assert sorted(p.name for p in cache.iterdir()) == written


def test_the_cache_can_be_turned_off_and_an_unusable_directory_only_warns(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, "off")
    assert use_compilation_cache() is None
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert use_compilation_cache(blocker / "cache") is None
    assert any("compilation cache" in str(w.message) for w in caught)

"""What the learned likelihood costs: `identify --likelihood learned` cold and reusing its
stored likelihood, and `sample` on it, against the synthetic likelihood's `identify` of the same
file in the same run (the baseline).

    python benchmarks/learned_time.py [FILE] [--json benchmarks/results/learned_time.json]

Each command runs in a fresh process with the compilation cache off (wall time of the process,
Python and JAX starting included), and the reuse once more with the cache warm (as the command
line keeps it by default). The aims: cold, learning included, under 3 min; reusing
what was learned, under 20 s; the posterior's ESS ≥ 400 per parameter in under 60 s after
learning. Writes the result file with the commit, date, platform and command.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rattlefit as rf
from rattlefit.testing.results import tree_state

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "data" / "pairII_boundary_65.6_20pct_16Hz.h5"


def timed(args: list[str], cache: str = "off") -> float:
    """Wall time (s) of ``rattlefit ARGS`` in a fresh process, with the compilation cache
    in ``cache`` (``off``: none)."""
    env = {**os.environ, "RATTLEFIT_CACHE_DIR": cache}
    exe = Path(sys.executable).with_name("rattlefit")
    t0 = time.perf_counter()
    subprocess.run([str(exe), *args, "-q"], check=True, env=env, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(DEFAULT))
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "learned_time.json"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "fit.json"
        base = timed(["identify", args.file, "-o", str(Path(tmp) / "base.json")])
        cold = timed(["identify", args.file, "--likelihood", "learned", "-o", str(out)])
        stored = out.with_suffix(".likelihood.h5")
        reuse = timed(
            [
                "identify",
                args.file,
                "--reuse-likelihood",
                str(stored),
                "-o",
                str(Path(tmp) / "again.json"),
            ]
        )
        again = ["identify", args.file, "--reuse-likelihood", str(stored), "-o"]
        timed([*again, str(Path(tmp) / "warming.json")], cache=str(Path(tmp) / "jax"))
        reuse_warm = timed([*again, str(Path(tmp) / "warm.json")], cache=str(Path(tmp) / "jax"))
        post = Path(tmp) / "post.json"
        sample = timed(
            [
                "sample",
                args.file,
                "--reuse-likelihood",
                str(stored),
                "--steps",
                "1500",
                "--walkers",
                "32",
                "-o",
                str(post),
            ]
        )
        fit = json.loads(out.read_text())
        chain = json.loads(post.read_text())["sampler"]
    ess = min(chain["ess"].values())
    learn_s = sum(r["simulate_s"] + r["train_s"] for r in fit["fit"]["likelihood"]["rounds"])
    rates = [r["simulations_per_s_per_core"] for r in fit["fit"]["likelihood"]["rounds"]]
    verdict = (
        "met"
        if cold < 180 and reuse < 20 and ess >= 400 and chain["wall_time_s"] < 60
        else "missed"
    )
    doc = {
        "order": 4.5,
        "headline": True,
        "what": "the learned likelihood's cost: `identify --likelihood learned` cold and reusing "
        "its stored likelihood, and `sample` on it, against the synthetic `identify` of the same "
        "file in the same run",
        "summary": f"cold {cold:.0f} s (learning {learn_s:.0f} s), reused {reuse:.0f} s "
        f"({reuse_warm:.0f} s with the compilation cache warm), "
        f"posterior ESS ≥ {ess:.0f} in {chain['wall_time_s']:.0f} s; the synthetic identify "
        f"{base:.0f} s (cold learned ×{cold / base:.1f})",
        "aim": "cold < 3 min, reused < 20 s, ESS ≥ 400 in < 60 s",
        "verdict": verdict,
        "measured": "wall time of each `rattlefit` process (compilation cache off) on "
        f"{Path(args.file).name}: identify (the baseline), identify --likelihood learned, "
        "identify --reuse-likelihood (also with a warm compilation cache), "
        "sample --reuse-likelihood --steps 1500 --walkers 32 "
        "(its identify included; the chain's own time is the sampler's wall_time_s)",
        "command": "python benchmarks/learned_time.py " + Path(args.file).name,
        "results": {
            "synthetic_identify_s": base,
            "learned_identify_cold_s": cold,
            "learning_s": learn_s,
            "simulations_per_recording": fit["fit"]["likelihood"]["simulations_per_recording"],
            "simulations_per_s_per_core": rates,
            "learned_identify_reused_s": reuse,
            "learned_identify_reused_warm_cache_s": reuse_warm,
            "sample_process_s": sample,
            "chain_s": chain["wall_time_s"],
            "ess_min": ess,
            "ratio_cold_over_synthetic": cold / base,
        },
        "platform": rf.platform_info(),
        "date": time.strftime("%Y-%m-%d"),
        **tree_state(),
    }
    path = Path(args.json)
    tmp_path = path.with_name(f".{path.name}.tmp")
    tmp_path.write_text(json.dumps(doc, indent=1))
    os.replace(tmp_path, path)
    print(doc["summary"])


if __name__ == "__main__":
    main()

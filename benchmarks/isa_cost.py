"""What the AVX2 cap (rattlefit.reproducibility) costs in speed, and whether it matters.

rattlefit.configure() caps XLA's CPU instruction set at AVX2 so that a seeded result does not
depend on the extensions a CPU offers beyond it; on a CPU with wider vectors the cap gives them
up. This measures the price as a ratio in one run: the same synthetic recording (pair II at 65.0 mm,
10 % at 8 Hz, 3 s + 0.5 s burn-in, one simulation at rtol 1e-7 by ``synthesize``) is made in
fresh processes under each cap, alternating caps between repetitions so that both see the
same machine load; the first call in each process compiles, the second is timed. The fit's
workload is timed too: 16 members in one lockstep ``simulate_batch`` (rtol 1e-6). It also
reports whether the caps give the same recording (they differ where the CPU offers more than
the narrower cap).

    python benchmarks/isa_cost.py                 # native vs AVX2, 3 repetitions, ~1 min
    python benchmarks/isa_cost.py --caps native,AVX2,SSE4_2 --repeat 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = """
import hashlib, json, time
import numpy as np
import rattlefit as rf
rf.configure()
from rattlefit.io.recording import OperatingPoint
from rattlefit.simulation.synthetic import synthesize
g = rf.table2_pair("II", center_distance_mm=65.0)
op = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
t0 = time.perf_counter()
synthesize(g, op, p, seed=11)
first = time.perf_counter() - t0
t0 = time.perf_counter()
rec, _ = synthesize(g, op, p, seed=11)
steady = time.perf_counter() - t0
counts = np.asarray(rec.secondary)
# the fit's workload: 16 members in one lockstep batch (rtol 1e-6, as the fit simulates)
import jax.numpy as jnp
from rattlefit import rig
from rattlefit.simulation.solve import broadcast_params, simulate_batch
s = rig.setup(rec)
c = s.geometry.backlash / 2
y0 = jnp.stack([jnp.linspace(-0.9, 0.9, 16) * c, jnp.zeros(16)], axis=1)
opts = dict(duration=3.0, sample_rate=s.sample_rate, burn_in=0.5, rtol=1e-6, atol=1e-9)
run = lambda: simulate_batch(s.model, broadcast_params(p, 16), s.drive, y0=y0,
                             batch="lockstep", **opts).relative_motion.block_until_ready()
run()
t0 = time.perf_counter()
run()
batch = time.perf_counter() - t0
print(json.dumps({"first": first, "steady": steady, "batch": batch,
                  "cpu_isa": rf.platform_info()["cpu_isa"],
                  "hash": hashlib.sha1(counts.tobytes()).hexdigest()[:12]}))
"""


def run_once(cap: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env["RATTLEFIT_CPU_ISA"] = cap
    out = subprocess.run(
        [sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--caps", default="native,AVX2", help="comma-separated; the first is 1.0")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    caps = args.caps.split(",")
    runs: dict[str, list[dict]] = {c: [] for c in caps}
    for r in range(args.repeat):
        for cap in caps if r % 2 == 0 else caps[::-1]:  # alternate the order
            res = run_once(cap)
            runs[cap].append(res)
            print(
                f"[{r + 1}/{args.repeat}] {cap:8s} first {res['first']:6.1f} s, "
                f"steady {res['steady']:6.2f} s, batch {res['batch']:6.2f} s, "
                f"recording {res['hash']}",
                file=sys.stderr,
                flush=True,
            )
    keys = ("steady", "batch", "first")
    base = {k: statistics.median(x[k] for x in runs[caps[0]]) for k in keys}
    print(f"median over {args.repeat} repetitions; ratio: time / time under {caps[0]}")
    print(f"{'cap':8s}" + "".join(f"  {k + ' s':>9s}  {'ratio':>5s}" for k in keys) + "  recording")
    for cap in caps:
        med = {k: statistics.median(x[k] for x in runs[cap]) for k in keys}
        cells = "".join(f"  {med[k]:9.2f}  {med[k] / base[k]:5.2f}" for k in keys)
        print(f"{cap:8s}{cells}  {','.join(sorted({x['hash'] for x in runs[cap]}))}")


if __name__ == "__main__":
    main()

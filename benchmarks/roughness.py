"""Is the profile roughness near the optimum noise, or structure of the cost?

`identify`'s roughness allowance (`FitOptions.profile_roughness`) takes the rms Δcost of the
points 1–2 % (in z) from the optimum as the noise of a profile's Δcost, and widens the profile
threshold by 1.645 × that rms. This script fits a recording as `identify` does up to the
optimum (spread, starts, Levenberg–Marquardt), then costs the optimum and those jitter points
four times, each time with the noise model re-estimated at the optimum from that set's own
realisations, as the profile stage does:

* A: the release states `identify` would draw (the same seeded stream);
* B: other release states;
* C: A's release states with dither offsets and encoder count phases drawn afresh (the
  realisation settings the Levenberg–Marquardt stage shares with the profile stage; drawn
  afresh, not permuted, since a permutation keeps the parameter values the realisations
  sample, and so most of their noise);
* D: B's release states with C's dither and phases.

If the jitter Δcosts were Monte Carlo noise they would differ from set to set by about their
rms; if they are structure of the cost in the parameters (a slope where the optimum stopped
short of the minimum, a kink where a regime's share changes) they repeat. It prints each set's
Δcosts, then their mean and spread over the four sets.

    python benchmarks/roughness.py [--recording pairII_boundary_65.0_10pct_8Hz] [--seed 0]
    python benchmarks/roughness.py --sweep     # the joint fit of the 65.0 + 65.4 mm sweep

A few minutes on 2 cores with a warm compilation cache; benchmarks/README.md ("The roughness
allowance measures structure, not noise") discusses the outcome.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import rattlefit

rattlefit.use_cpu_cores()  # before JAX starts

import equinox as eqx  # noqa: E402
import numpy as np  # noqa: E402

from rattlefit.inference.forward import evaluate  # noqa: E402
from rattlefit.inference.least_squares import refine_starts  # noqa: E402
from rattlefit.inference.noise import band_sigma, noise_model  # noqa: E402
from rattlefit.inference.options import FitOptions  # noqa: E402
from rattlefit.inference.parameters import Z_END  # noqa: E402
from rattlefit.inference.problem import build_problem, redrawn, release_states  # noqa: E402
from rattlefit.inference.profile import PROFILE_JITTER  # noqa: E402
from rattlefit.inference.starts import starting_points  # noqa: E402
from rattlefit.io.recording import read_recording  # noqa: E402

RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "recordings"


def jitter_dcosts(problem, options, z, near, y0, dof_rec) -> np.ndarray:
    """Δcost of ``near[1:]`` above ``near[0]`` (= ``z``), the noise model re-estimated at
    ``z`` from the realisations released at ``y0``, as identify's profile stage does."""
    per = evaluate(problem, near, y0)
    sigma = band_sigma(problem, options, per[0])
    prob = eqx.tree_at(lambda q: q.sigma, problem, sigma)
    data = np.asarray(prob.data)
    r0 = ((data - np.asarray(prob.mean_of(per[0]))) / np.asarray(sigma)).reshape(-1)
    noise = noise_model(prob, per[0], r0, dof_rec)

    def cost_of(features, zk):
        sig = np.asarray(band_sigma(prob, options, features))
        r = ((data - np.asarray(prob.mean_of(features))) / sig).reshape(-1)
        prior = prob.prior_rows(np.asarray(zk))
        return float(noise.quadratic(r) + 2 * np.sum(np.log(sig)) + np.sum(prior**2))

    costs = np.array([cost_of(per[k], near[k]) for k in range(len(near))])
    return costs[1:] - costs[0]


def sweep() -> list:
    """The two recordings of tests/test_fit.py's joint-sweep test (65.0 and 65.4 mm)."""
    from rattlefit.simulation.synthetic import backlash_sweep

    return [rec for rec, _ in backlash_sweep((65.0, 65.4), (21, 22))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recording", default="pairII_boundary_65.0_10pct_8Hz")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--sweep",
        action="store_true",
        help="instead, the synthetic backlash sweep of the joint-fit test (pair II, boundary, "
        "10 %% at 8 Hz, 65.0 and 65.4 mm), fitted jointly",
    )
    args = ap.parse_args()
    recs = sweep() if args.sweep else [read_recording(RECORDINGS / f"{args.recording}.h5")]
    options = FitOptions(seed=args.seed)
    t0 = time.perf_counter()

    def say(msg):
        print(f"{time.perf_counter() - t0:6.1f} s  {msg}", flush=True)

    rng = np.random.default_rng(options.seed)
    problem, _ = build_problem(recs, options, rng)
    starts = starting_points(
        problem, options.n_starts, rng, nuisance_starts=options.nuisance_starts
    )
    refined = refine_starts(problem, starts, options, rng, say)
    problem, z = refined.problem, refined.optimum
    p = len(problem.specs)
    free = [i for i, s in enumerate(problem.specs) if s.log_sd is None]
    jitter = [z + h * np.eye(p)[i] for i in free for h in PROFILE_JITTER]
    near = np.clip(np.stack([z, *jitter]), -Z_END, Z_END)
    n_rec, n_band = np.asarray(problem.data).shape
    dof_rec = max(n_rec * n_band - len(free), 1) / n_rec
    n = options.n_covariance_realisations
    y0_a = release_states(problem, z, n, rng)  # as identify draws them
    y0_b = release_states(problem, z, n, np.random.default_rng(args.seed + 12345))
    # fresh dither offsets, not A's permuted: a permutation keeps the set of offsets, that is
    # which neighbouring parameter values the realisations sample, and that is most of the noise
    reshuffled = redrawn(problem, options, np.random.default_rng(args.seed + 777))
    labels = [
        f"{specs.name} {h:+.2f}"
        for specs in (problem.specs[i] for i in free)
        for h in PROFILE_JITTER
    ]
    sets = {"A": (problem, y0_a), "B": (problem, y0_b), "C": (reshuffled, y0_a)}
    sets["D"] = (reshuffled, y0_b)
    rows = []
    for name, (prob, y0) in sets.items():
        d = jitter_dcosts(prob, options, z, near, y0, dof_rec)
        rows.append(d)
        say(f"{name}: Δcost {np.round(d, 1)}, rms {np.sqrt(np.mean(d**2)):.1f}")
    rows = np.array(rows)
    mean, sd = rows.mean(axis=0), rows.std(axis=0, ddof=1)
    print("\njitter point        mean Δcost   sd over the 4 sets")
    for label, m, s in zip(labels, mean, sd, strict=True):
        print(f"{label:18s} {m:11.1f} {s:11.1f}")
    print(
        f"rms of the mean {np.sqrt(np.mean(mean**2)):.1f} (structure), "
        f"rms of the spread {np.sqrt(np.mean(sd**2)):.1f} (Monte Carlo noise)"
    )


if __name__ == "__main__":
    main()

"""Which learned density: a Gaussian, a flow, or a Gaussian whitening followed by a flow,
compared on held-out simulations of rattlefit's simulator.

At one operating point (by default the violent boundary point, where the run-to-run spread
changes most with the parameters) a scrambled Sobol' design over the prior box is simulated,
one simulation per point, and a held-out set of points drawn uniformly from the same box. Each
candidate is trained on the first N design points for each N of ``--sizes``:

* ``gaussian``: the whitening stage alone (mean, log scale and a shared correlation factor);
* ``flow``: the spline flow alone (``DensityOptions(whitening=False)``);
* ``whitening+flow``: both stages (what ``rattlefit.likelihood`` uses).

    python studies/density_choice.py [--point boundary] [--sizes 1024,8192] [--held-out 512]
                                     [--cases 100] [--seed 0]
                                     [--json studies/results/density_choice.json]

Reports per candidate and size: the held-out mean log density per simulation (nats; higher is
closer to the simulator's distribution, the difference between two candidates estimating the
difference of their KL divergences from it) with its standard error, the held-out residuals'
mean square (1 where calibrated) and the share beyond χ²_F's 99 % quantile, and the training
time. At the largest size, ``--cases`` held-out simulations are each treated as a recording:
the posterior over the prior box by adaptive importance sampling, and the coverage of the
truth by the 50 % and 95 % central intervals of every parameter.
"""

from __future__ import annotations

import argparse
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from common import tree_state, write_result
from sbc import POINTS, problem_at
from scipy import stats

import rattlefit as rf
from rattlefit.likelihood import DensityOptions, fit_density
from rattlefit.likelihood.density import make_flow
from rattlefit.likelihood.design import prior_box, simulate_design, sobol_design

CANDIDATES = ("gaussian", "flow", "whitening+flow")
#: Importance-sampling draws per posterior, and the proposal's refinements.
DRAWS, REFINE = 8192, 3


def trained(name: str, u, y, seed):
    """A candidate density trained on design points ``u`` and features ``y``."""
    options = DensityOptions(whitening=name != "flow")
    density, _ = fit_density(u, y, tuple(range(u.shape[1])), options, seed)
    if name == "gaussian":  # the flow reset to the identity
        identity = make_flow(u.shape[1], y.shape[1], options, jax.random.key(0))
        density = eqx.tree_at(lambda d: d.flow, density, identity)
    return density


def held_out(density, uh, yh) -> dict:
    """Held-out log density and residual calibration."""
    lp = np.asarray(jax.vmap(density.log_prob)(jnp.asarray(yh), jnp.asarray(uh)))
    r = np.asarray(jax.vmap(density.residual)(jnp.asarray(yh), jnp.asarray(uh)))
    q = np.sum(r**2, axis=1)
    f = r.shape[1]
    return {
        "log_density": float(np.mean(lp)),
        "log_density_se": float(np.std(lp) / np.sqrt(len(lp))),
        "residual_mean_square": float(np.mean(q) / f),
        "beyond_chi2_99": float(np.mean(q > stats.chi2(f).ppf(0.99))),
    }


def posterior_cdf(density, y, truth, lo, hi, rng) -> np.ndarray:
    """The posterior CDF (P,) of each parameter at its truth, for features ``y`` under a
    uniform prior on the box [lo, hi]: importance sampling from the prior, then from a
    widened Gaussian fitted to the weighted draws, :data:`REFINE` times."""
    log_like = jax.jit(jax.vmap(density.log_prob, in_axes=(None, 0)))
    p = len(lo)
    draws = lo + (hi - lo) * rng.uniform(size=(DRAWS, p))
    log_w = np.asarray(log_like(jnp.asarray(y), jnp.asarray(draws)))
    for _ in range(REFINE):
        w = np.exp(log_w - log_w.max())
        w /= w.sum()
        mean, cov = w @ draws, 2 * np.cov(draws.T, aweights=w) + 1e-12 * np.eye(p)
        draws = rng.multivariate_normal(mean, cov, size=DRAWS)
        inside = np.all((draws >= lo) & (draws <= hi), axis=1)
        lq = stats.multivariate_normal(mean, cov).logpdf(draws)
        ll = np.asarray(log_like(jnp.asarray(y), jnp.asarray(np.clip(draws, lo, hi))))
        log_w = np.where(inside, ll - lq, -np.inf)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    return np.array([np.sum(w * (draws[:, j] < truth[j])) for j in range(p)])


def coverage(density, uh, yh, lo, hi, cases: int, seed) -> dict:
    """Coverage of the 50 % and 95 % central intervals over ``cases`` held-out simulations."""
    rng = np.random.default_rng(seed)
    cdf = np.array([posterior_cdf(density, yh[k], uh[k], lo, hi, rng) for k in range(cases)])
    return {
        "coverage_50": np.mean((cdf > 0.25) & (cdf < 0.75), axis=0).tolist(),
        "coverage_95": np.mean((cdf > 0.025) & (cdf < 0.975), axis=0).tolist(),
        "uniformity_p": [float(stats.kstest(c, "uniform").pvalue) for c in cdf.T],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--point", default="boundary", choices=sorted(POINTS))
    ap.add_argument("--sizes", default="1024,8192")
    ap.add_argument("--held-out", type=int, default=512)
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default="studies/results/density_choice.json")
    args = ap.parse_args()
    devices = rf.configure().devices
    sizes = sorted(int(s) for s in args.sizes.split(","))
    s_problem, s_design, s_held, s_sim, s_train, s_cases = np.random.SeedSequence(args.seed).spawn(
        6
    )
    problem = problem_at(args.point, int(s_problem.generate_state(1)[0]))
    lo, hi = prior_box(problem)
    u = sobol_design(sizes[-1], lo, hi, s_design)
    uh = lo + (hi - lo) * np.random.default_rng(s_held).uniform(size=(args.held_out, len(lo)))
    t0 = time.perf_counter()
    y_all = simulate_design(problem, np.concatenate([u, uh]), 0, s_sim)
    print(f"{len(y_all)} simulations in {time.perf_counter() - t0:.0f} s", flush=True)
    y, yh = y_all[: len(u)], y_all[len(u) :]
    rows = []
    for n in sizes:
        for name in CANDIDATES:
            t1 = time.perf_counter()
            density = trained(name, u[:n], y[:n], s_train)
            row = {"candidate": name, "simulations": n, "train_s": time.perf_counter() - t1}
            row.update(held_out(density, uh, yh))
            if n == sizes[-1] and args.cases:
                row.update(coverage(density, uh, yh, lo, hi, args.cases, s_cases))
            rows.append(row)
            print(
                f"{name:15s} N {n:5d}: held-out log density {row['log_density']:.2f} "
                f"± {row['log_density_se']:.2f}; residual mean square "
                f"{row['residual_mean_square']:.2f}; trained in {row['train_s']:.0f} s"
                + (
                    f"; 95 % coverage {np.round(row['coverage_95'], 2)}"
                    if "coverage_95" in row
                    else ""
                ),
                flush=True,
            )
    write_result(
        args.json,
        {
            "what": "learned density candidates on held-out simulations of rattlefit's simulator",
            "command": f"python studies/density_choice.py --point {args.point} --sizes "
            f"{args.sizes} --held-out {args.held_out} --cases {args.cases} --seed {args.seed}",
            **tree_state(),
            "date": time.strftime("%Y-%m-%d"),
            "platform": rf.platform_info(),
            "devices": devices,
            "parameters": [s.name for s in problem.specs],
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()

"""Simulation-based calibration (SBC) of the learned likelihood.

At each operating point the likelihood is learned once over the priors (amortised: a
space-filling design, no posterior rounds). Each case then draws parameters from the priors,
simulates one recording's features at them with rattlefit's simulator (encoders included),
and samples the posterior on the learned likelihood (emcee, started at the learned optimum).
Where the likelihood is calibrated, the rank of the truth among posterior draws is uniform,
and the central intervals cover the truth at their level (Talts et al. 2018).

    python studies/sbc.py [--cases 70] [--points boundary,oil_jet,dry] [--initial 8192]
                          [--seed 0] [--json studies/results/sbc.json]
                          [--figure studies/results/sbc.png]

Reports per parameter (``a``, ``drag_torque``, ``viscosity_scale``, ``stiffness_scale``,
``min_film``, ``backlash[0]`` and the derived ``squeeze_momentum``): the rank histogram and
its χ² uniformity p-value, the coverage of the 50/90/95 % central intervals, and the mean
log-bias of the posterior median. Cases are seeded from ``--seed``; every case is
reproducible.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from common import tree_state, write_result
from scipy import stats

import rattlefit as rf
from rattlefit.inference.posterior import LogPosterior, run_chain
from rattlefit.inference.smooth import fit_learned
from rattlefit.io.recording import OperatingPoint
from rattlefit.likelihood import LearningOptions, learn_likelihood
from rattlefit.likelihood.design import EDGE, simulate_design, unit_of_z, z_of_unit
from rattlefit.likelihood.learn import best_points
from rattlefit.likelihood.store import Learned, read_learned, test_point_key, write_learned
from rattlefit.physics.model import squeeze_momentum
from rattlefit.physics.oil import dynamic_viscosity
from rattlefit.problem.options import FitOptions
from rattlefit.problem.problem import Problem, problem_from
from rattlefit.simulation.synthetic import synthesize

#: The operating points: (pair, lubrication, centre distance mm, fluctuation %, frequency Hz,
#: oil temperature °C). The violent headline boundary point, a mild oil-jet point and a dry
#: point.
POINTS = {
    "boundary": ("II", "boundary", 65.6, 20, 16.0, 20.0),
    "oil_jet": ("II", "oil_jet", 65.0, 20, 4.0, 25.0),
    "dry": ("I", "dry", 65.4, 10, 16.0, 20.0),
}
LEVELS = (0.5, 0.9, 0.95)
#: Posterior draws per case, for the rank statistic (ranks 0…DRAWS).
DRAWS = 99
BINS = 10


def problem_at(point: str, seed: int) -> Problem:
    """The fit's problem at an operating point (a recording made there gives its rig; its own
    features are replaced case by case)."""
    pair, lub, cd, pct, f, temp = POINTS[point]
    g = rf.table2_pair(pair, center_distance_mm=cd)
    op = OperatingPoint(lub, temp, 52.36, 52.36 * pct / 100, f)
    mu = dynamic_viscosity(temp, 156.5, 15.7, 890.0)
    rec, _ = synthesize(g, op, rf.RattleParams(1e-4, 0.025, mu, g.backlash), seed=seed)
    problem, _, _ = problem_from([rec], FitOptions(seed=seed))
    return problem


def prior_draw(problem: Problem, rng) -> np.ndarray:
    """Parameters (z) drawn from the fit's priors: log-uniform over the range, or log-normal
    truncated to it."""
    u = []
    for s in problem.specs:
        if s.log_sd is None:
            u.append(rng.uniform(EDGE, 1 - EDGE))
            continue
        while True:
            logv = np.log(s.center) + s.log_sd * rng.normal()
            x = (logv - np.log(s.lower)) / s.log_range
            if EDGE < x < 1 - EDGE:
                u.append(x)
                break
    return z_of_unit(np.asarray(u))


def momentum(problem: Problem, z) -> np.ndarray:
    """The squeeze momentum (N s) at points ``z`` (K, P)."""
    z = np.atleast_2d(z)
    v = {s.name: np.asarray(s.value(z[:, i])) for i, s in enumerate(problem.specs)}
    return np.asarray(
        squeeze_momentum(
            v["film_half_length"],
            v["viscosity_scale"] * float(problem.viscosities[0]),
            v["min_film"],
            float(problem.models.curvature_radius[0]),
            float(problem.models.axial_width[0]),
        )
    )


def log_values(problem: Problem, z) -> dict[str, np.ndarray]:
    """Each parameter's log value, and the squeeze momentum's, at points ``z`` (K, P)."""
    z = np.atleast_2d(z)
    out = {s.name: np.log(np.asarray(s.value(z[:, i]))) for i, s in enumerate(problem.specs)}
    out["squeeze_momentum"] = np.log(momentum(problem, z))
    return out


def one_case(problem, like, z_true, seed: np.random.SeedSequence, steps: int) -> dict:
    """One SBC case: the truth's rank, interval coverage and the median's log-bias."""
    s_sim, s_chain = seed.spawn(2)
    data = simulate_design(problem, unit_of_z(z_true)[None], 0, s_sim)
    like_k = like.replace_data(data)
    fit = fit_learned(like_k, best_points(like_k, DESIGN_U, 8), [])
    target = LogPosterior(problem.specs, Learned(like_k))
    chain_seed = int(np.random.default_rng(s_chain).integers(2**31))
    sampler = run_chain(
        target, fit.optimum.z, fit.covariance_z, n_walkers=32, n_steps=steps, seed=chain_seed
    )
    kept = sampler.get_chain(discard=steps // 3, flat=True)
    pick = np.linspace(0, len(kept) - 1, DRAWS).astype(int)
    draws = log_values(problem, kept[pick])
    truth = log_values(problem, z_true)
    row = {"chi2": fit.chi2, "dof": fit.dof}
    for name, d in draws.items():
        t = float(truth[name][0])
        entry = {"truth": t, "rank": int(np.sum(d < t)), "median": float(np.median(d))}
        for level in LEVELS:
            q = 50 * (1 - level)
            lo, hi = np.percentile(d, [q, 100 - q])
            entry[f"covered_{round(100 * level)}"] = bool(lo <= t <= hi)
        row[name] = entry
    return row


DESIGN_U = None  # the current point's design, whose best points start each case's search


def summarise(rows: list[dict], names: list[str]) -> dict:
    """Per parameter: rank histogram, its uniformity p, coverage per level, mean log-bias."""
    out = {}
    for name in names:
        ranks = np.array([r[name]["rank"] for r in rows])
        hist = np.histogram(ranks, bins=BINS, range=(0, DRAWS + 1))[0]
        p = float(stats.chisquare(hist).pvalue) if len(rows) >= BINS else float("nan")
        bias = np.array([r[name]["median"] - r[name]["truth"] for r in rows])
        out[name] = {
            "rank_histogram": hist.tolist(),
            "uniformity_p": p,
            **{
                f"coverage_{round(100 * lv)}": float(
                    np.mean([r[name][f"covered_{round(100 * lv)}"] for r in rows])
                )
                for lv in LEVELS
            },
            "mean_log_bias": float(np.mean(bias)),
        }
    return out


def figure(summary: dict, path: Path, title: str) -> None:
    """Rank histograms, one panel per parameter, with the uniform expectation's 99 % band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(summary)
    fig, axes = plt.subplots(1, len(names), figsize=(2.4 * len(names), 2.6), sharey=True)
    n = sum(summary[names[0]]["rank_histogram"])
    lo, hi = stats.binom.ppf([0.005, 0.995], n, 1 / BINS)
    for ax, name in zip(axes, names, strict=True):
        s = summary[name]
        ax.bar(range(BINS), s["rank_histogram"], width=0.9, color="C0")
        ax.axhspan(lo, hi, color="0.85", zorder=0)
        ax.set_title(f"{name}\np={s['uniformity_p']:.2g}, 95%: {s['coverage_95']:.0%}", fontsize=8)
        ax.set_xticks([])
    axes[0].set_ylabel("cases per rank decile")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=150)
    os.replace(tmp, path)


def learned_at(problem, point: str, learning, seed, args):
    """The point's learned likelihood, its design and the simulation rate (per s per core):
    read from ``args.cache`` when kept there for this seed and budget, else learned (and kept
    there)."""
    path = None
    if args.cache:
        Path(args.cache).mkdir(parents=True, exist_ok=True)
        path = Path(args.cache) / f"{point}_{args.seed}_{args.initial}.likelihood.h5"
        if path.exists():
            stored = read_learned(path, problem)
            return stored.likelihood, stored.design, float("nan")
    like, design, rounds = learn_likelihood(problem, learning, seed=seed, progress=print)
    if path is not None:
        kept = Learned(like, design, test_point_key(problem), args.seed, learning.density)
        write_learned(path, kept)
    return like, design, rounds[0].per_second_per_core


def main() -> None:
    global DESIGN_U
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=70, help="cases per operating point")
    ap.add_argument("--points", default="boundary,oil_jet,dry")
    ap.add_argument("--initial", type=int, default=8192, help="simulations learned per point")
    ap.add_argument("--steps", type=int, default=1200, help="chain steps per case")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default="studies/results/sbc.json")
    ap.add_argument("--figure", default="studies/results/sbc.png")
    ap.add_argument(
        "--cache",
        help="a directory that keeps each point's learned likelihood (POINT.likelihood.h5) and "
        "reuses it when the budget and seed match",
    )
    args = ap.parse_args()
    devices = rf.configure().devices
    root = np.random.SeedSequence(args.seed)
    points = args.points.split(",")
    all_rows, per_point = [], {}
    t_start = time.perf_counter()
    learning = LearningOptions(initial=args.initial, rounds=0)
    for point, s_point in zip(points, root.spawn(len(points)), strict=True):
        s_problem, s_learn, s_cases = s_point.spawn(3)
        problem = problem_at(point, int(s_problem.generate_state(1)[0]))
        t0 = time.perf_counter()
        like, design, rate = learned_at(problem, point, learning, s_learn, args)
        DESIGN_U = design.u
        learn_s = time.perf_counter() - t0
        rng = np.random.default_rng(s_cases)
        rows = []
        for k, s_case in enumerate(s_cases.spawn(args.cases)):
            z_true = prior_draw(problem, rng)
            t1 = time.perf_counter()
            row = one_case(problem, like, z_true, s_case, args.steps)
            row["point"] = point
            rows.append(row)
            print(
                f"[{point} {k + 1}/{args.cases}] {time.perf_counter() - t1:.1f} s; χ² "
                f"{row['chi2']:.1f}/{row['dof']}; ranks "
                + " ".join(f"{n}:{row[n]['rank']}" for n in ("film_half_length", "drag_torque")),
                flush=True,
            )
        names = [n for n in rows[0] if isinstance(rows[0][n], dict)]
        per_point[point] = {
            "operating_point": dict(
                zip(
                    (
                        "pair",
                        "lubrication",
                        "center_distance_mm",
                        "fluctuation_pct",
                        "frequency_hz",
                        "oil_temperature_c",
                    ),
                    POINTS[point],
                    strict=True,
                )
            ),
            "learn_s": learn_s,
            "simulations": int(design.u.shape[0]),
            "simulations_per_s_per_core": rate,
            "summary": summarise(rows, names),
        }
        all_rows += rows
        write(args, per_point, all_rows, devices, time.perf_counter() - t_start, points)


def table_fields(summary: dict, cases: int) -> dict:
    """The result table's ``summary``, ``aim`` and ``verdict`` of the per-parameter
    ``summary`` (:func:`summarise`) over ``cases`` cases."""
    cover = {n: s["coverage_95"] for n, s in summary.items()}
    worst = min(cover, key=cover.get)
    uniform = [n for n, s in summary.items() if s["uniformity_p"] > 0.01]
    bias = {n: summary[n]["mean_log_bias"] for n in ("drag_torque", "squeeze_momentum")}
    met = (
        cases >= 200
        and all(0.90 <= c <= 0.99 for c in cover.values())
        and len(uniform) == len(summary)
        and all(abs(b) <= 0.1 for b in bias.values())
    )
    return {
        "summary": f"95 % coverage {min(cover.values()):.0%}–{max(cover.values()):.0%} over "
        f"{cases} cases (lowest: {worst}); ranks uniform (p > 0.01) for "
        f"{len(uniform)}/{len(summary)} parameters; mean log-bias of T_b "
        f"{bias['drag_torque']:+.2f}, of the squeeze momentum {bias['squeeze_momentum']:+.2f}",
        "aim": "95 % coverage 90–99 % and uniform ranks for every parameter over ≥ 200 cases; "
        "|mean log-bias| ≤ 0.1 for T_b and the squeeze momentum",
        "verdict": "met" if met else "not met",
        "headline": True,
    }


def write(args, per_point: dict, all_rows: list, devices: int, wall: float, points) -> None:
    """Write the result file (atomically) and the figure from the cases so far."""
    names = [n for n in all_rows[0] if isinstance(all_rows[0][n], dict)]
    summary = summarise(all_rows, names)
    doc = {
        "what": "simulation-based calibration of the learned likelihood (amortised over the "
        "priors at each operating point)",
        "command": "python studies/sbc.py "
        + " ".join(f"--{k} {v}" for k, v in vars(args).items() if k not in ("json", "figure")),
        **tree_state(),
        "date": time.strftime("%Y-%m-%d"),
        "platform": rf.platform_info(),
        "devices": devices,
        "seed": args.seed,
        "cases": len(all_rows),
        "wall_s": wall,
        **table_fields(summary, len(all_rows)),
        "parameters": summary,
        "points": per_point,
        "rows": all_rows,
    }
    write_result(args.json, doc)
    figure(summary, Path(args.figure), f"SBC, {len(all_rows)} cases at {', '.join(points)}")
    for name, s in summary.items():
        print(
            f"{name:18s} uniform p {s['uniformity_p']:.3f}; coverage 50/90/95 "
            f"{s['coverage_50']:.2f}/{s['coverage_90']:.2f}/{s['coverage_95']:.2f}; "
            f"mean log-bias {s['mean_log_bias']:+.3f}"
        )


if __name__ == "__main__":
    main()

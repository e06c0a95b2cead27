"""Coverage study of `identify` on synthetic recordings over the paper's operating grid.

For a seeded sample of (pair, lubrication, centre distance, fluctuation, frequency), this
simulates a recording with known truth (`rattlefit.simulation.synthetic.synthesize`),
identifies it with the default `FitOptions`, and reports whether each 95 % interval holds the
truth and whether the fit called `a` identified. The check: truth inside the interval in
≥ 90 % of cases, and `a` within 20 % where reported identified.

    python studies/coverage.py [--cases 10] [--seed 0] [--json out.json] [--only K ...]
                               [--result studies/results/coverage.json]
                                  [--rtol R] [--dither D] [--set FIELD=JSON ...] [--quiet]
                                  [--prior NAME=CENTER:LOG_SD ...] [--companion LUB]

`--rtol` and `--dither` replace those `FitOptions` fields (the defaults otherwise), to measure
what a cheaper tolerance or another dither does to coverage; `--set` replaces any other field
(`--set profile_roughness=true`), its value read as JSON; `--prior min_film=2e-6:0.1` replaces
a nuisance's prior (what a rig that knows h_min would give). `--companion oil_jet` fits each
case jointly with an oil-jet recording of the same pair and operating point (one `a` per
lubrication, the oil, `T_b` and `h_min` shared); `a` in the table is then the case's own
lubrication's, and the companion's `a` is reported beside it.

Each case costs one identification (minutes on 2 cores), so the default sample of 10 takes
about half an hour or more. Seeds are printed; every case is reproducible.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from common import add_set_argument, provenance, set_overrides, write_result

import rattlefit as rf
from rattlefit.inference.identify import identify
from rattlefit.io.recording import OperatingPoint
from rattlefit.physics.oil import dynamic_viscosity
from rattlefit.problem.options import FitOptions
from rattlefit.problem.parameters import film_names, parse_prior
from rattlefit.simulation.synthetic import synthesize

LUBRICATION = {"dry": (0.0, 20.0), "boundary": (0.085e-3, 20.0), "oil_jet": (1.0e-3, 25.0)}
DRAG = {"I": 0.03, "II": 0.025}
GRID = list(
    itertools.product(
        ("I", "II"), LUBRICATION, (65.0, 65.4, 66.0), ((10, 8.0), (20, 16.0), (20, 4.0))
    )
)


def parse_args() -> tuple[argparse.Namespace, dict]:
    """The command line, and the ``FitOptions`` overrides it asks for."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write every case's row here")
    ap.add_argument(
        "--result",
        help="write the result table's file here (studies/results/coverage.json), with the "
        "summary, aim, verdict and provenance",
    )
    ap.add_argument(
        "--only",
        type=int,
        nargs="+",
        metavar="K",
        help="run only these cases of the seeded sample (1-based, as printed)",
    )
    ap.add_argument(
        "--companion",
        choices=sorted(LUBRICATION),
        help="fit each case jointly with a recording of the same pair and operating point under "
        "this lubrication (seed: the case's + 1); cases already under it are skipped",
    )
    ap.add_argument(
        "--quiet", action="store_true", help="print each case's result, not identify's progress"
    )
    ap.add_argument("--rtol", type=float, help="FitOptions.rtol (default: FitOptions')")
    ap.add_argument("--dither", type=float, help="FitOptions.dither (default: FitOptions')")
    add_set_argument(ap)
    ap.add_argument(
        "--prior",
        action="append",
        default=[],
        metavar="NAME=CENTER:LOG_SD",
        help="replace a nuisance's prior (rattlefit.problem.parameters.parse_prior), e.g. "
        "min_film=2e-6:0.1",
    )
    args = ap.parse_args()
    overrides = {k: getattr(args, k) for k in ("rtol", "dither") if getattr(args, k) is not None}
    if args.prior:
        try:
            overrides["priors"] = dict(parse_prior(text) for text in args.prior)
        except rf.RattlefitError as exc:
            ap.error(f"--prior: {exc}")
    overrides.update(set_overrides(ap, args.set))
    return args, overrides


def companion_recording(g, op, pair: str, lubrication: str, seed: int):
    """A recording of the same pair and operating point under ``lubrication`` (its truth a
    and oil temperature), and that truth's ``a``."""
    a_c, temp_c = LUBRICATION[lubrication]
    mu_c = dynamic_viscosity(temp_c, 156.5, 15.7, 890.0)
    op_c = dataclasses.replace(op, lubrication=lubrication, oil_temperature_c=temp_c)
    params_c = rf.RattleParams(a_c, DRAG[pair], mu_c, g.backlash)
    return synthesize(g, op_c, params_c, seed=seed)[0], a_c


def interval_row(p, truth: float) -> dict:
    """One parameter's interval against its truth."""
    return {
        "truth": truth,
        "lower": p.lower,
        "upper": p.upper,
        "estimate": p.estimate,
        "identified": p.identified,
        "bound": p.bound,
        "covered": bool(p.lower <= truth <= p.upper),
    }


NAMES = ("film_half_length", "drag_torque", "viscosity")
#: Each reported parameter's profile (the viscosity is profiled as its factor).
PROFILED = {"viscosity": "viscosity_scale"}


def crossing(points, threshold: float, direction: int):
    """Where the profile ``points`` ((value, Δcost) pairs) first rises above ``threshold``
    walking from its optimum (Δ = 0) in ``direction`` (±1), linear in the log value; its last
    point's value where it never does."""
    pts = sorted(points)
    k = min(range(len(pts)), key=lambda i: abs(pts[i][1]))
    walk = pts[k::direction]
    for (v0, d0), (v1, d1) in itertools.pairwise(walk):
        if d1 > threshold:
            t = (threshold - d0) / (d1 - d0) if d1 != d0 else 1.0
            return float(np.exp(np.log(v0) + t * (np.log(v1) - np.log(v0))))
    return walk[-1][0]


def chi2_1_row(res, name: str, truth: float) -> dict | None:
    """The interval χ²₁'s 3.84 would cut from ``name``'s profile of a fit whose intervals are
    cut at critical values by simulation (None for other fits), and whether it holds
    ``truth``."""
    profile = res.estimates.profile
    if "calibration" not in profile:
        return None
    points = res.estimates.profiles[PROFILED.get(name, name)]
    scale = res.estimates.parameters[name].estimate / min(points, key=lambda p: abs(p[1]))[0]
    lower, upper = (scale * crossing(points, profile["threshold"], d) for d in (-1, 1))
    return {"lower": lower, "upper": upper, "covered": bool(lower <= truth <= upper)}


def result_document(rows: list[dict], seed: int, overrides: dict) -> dict:
    """The result table's file of one seeded sample's ``rows`` (without provenance)."""
    covered = sum(r[k]["covered"] for r in rows for k in NAMES)
    total = 3 * len(rows)
    missed = [f"{r['case']}: {k}" for r in rows for k in NAMES if not r[k]["covered"]]
    within = [r["a_within_20pct"] for r in rows if r["a_within_20pct"] is not None]
    chi2_1 = [r[k]["chi2_1"]["covered"] for r in rows for k in NAMES if "chi2_1" in r[k]]
    compared = (
        f"; cut at χ²₁'s 3.84 instead of the critical values: {sum(chi2_1)}/{len(chi2_1)}"
        if chi2_1
        else ""
    )
    return {
        "headline": not overrides,
        "order": 7,
        "what": "`identify` coverage"
        + (f" with {overrides}" if overrides else "")
        + ": truth inside the 95 % intervals of `a`, `T_b` and μ",
        "summary": f"{covered}/{total} = {covered / total:.0%} over a seeded sample of "
        f"{len(rows)} cases (seed {seed}); `a` identified in {len(within)}, within 20 % in "
        f"{sum(within)}; missed: {', '.join(missed) or 'none'}{compared}",
        "aim": "≥ 90 %, and `a` within 20 % where identified",
        "verdict": "met" if covered >= 0.9 * total and all(within) else "not met",
        "measured": "studies/coverage.py: a seeded sample of the paper's operating grid (both "
        "pairs; dry, boundary and oil-jet lubrication; 65.0–66.0 mm; 10 % at 8 Hz, 20 % at 16 "
        "Hz and 4 Hz), each case simulated with known truth and identified with the default "
        "FitOptions" + (f" and {overrides}" if overrides else "") + "; counts the intervals of "
        "a, T_b and μ that hold the truth.",
        "results": {
            "seed": seed,
            "covered": covered,
            "intervals": total,
            "chi2_1_covered": sum(chi2_1) if chi2_1 else None,
            "cases": rows,
        },
    }


def print_summary(rows: list[dict]) -> None:
    """Coverage over every case, how often ``a`` was identified and within 20 %, and the
    coverage of the cases not flagged as a poor fit."""
    total = sum(3 for _ in rows)
    covered = sum(
        r[k]["covered"] for r in rows for k in ("film_half_length", "drag_torque", "viscosity")
    )
    print(f"coverage: {covered}/{total} = {covered / total:.0%} (aim ≥ 90 %)")
    within = [r["a_within_20pct"] for r in rows if r["a_within_20pct"] is not None]
    print(f"a identified in {len(within)}/{len(rows)} cases; within 20 % in {sum(within)}")
    flagged = [r for r in rows if r["poor_fit"]]
    unflagged = [r for r in rows if not r["poor_fit"]]
    hit = sum(
        r[k]["covered"] for r in unflagged for k in ("film_half_length", "drag_torque", "viscosity")
    )
    print(
        f"{len(flagged)} case(s) flagged as a poor fit; coverage of the others: "
        f"{hit}/{3 * len(unflagged)}"
    )


def case_row(n: int, k: int, seed: int, overrides: dict, companion, quiet: bool) -> dict | None:
    """Case ``n`` (grid point ``k``, recording seed ``seed``) simulated and identified: its
    row, or None when it is the companion's own lubrication."""
    rf.configure()
    pair, lub, cd, (pct, f) = GRID[k]
    a, temp = LUBRICATION[lub]
    g = rf.table2_pair(pair, center_distance_mm=cd)
    mu = dynamic_viscosity(temp, 156.5, 15.7, 890.0)
    op = OperatingPoint(lub, temp, 52.36, 52.36 * pct / 100, f)
    params = rf.RattleParams(a, DRAG[pair], mu, g.backlash)
    recs = [synthesize(g, op, params, seed=seed)[0]]
    film = "film_half_length"
    if companion:
        if lub == companion:
            return None
        rec_c, a_c = companion_recording(g, op, pair, companion, seed + 1)
        recs.append(rec_c)
        film, film_c = film_names([lub, companion])
    t0 = time.perf_counter()
    res = identify(
        recs,
        FitOptions(seed=seed, **overrides),
        progress=None if quiet else lambda msg: print(f"  [{n + 1}] {msg}", flush=True),
    )
    truth = {"film_half_length": a, "drag_torque": DRAG[pair], "viscosity": mu}
    row = {
        "case": f"pair {pair}, {lub}, {cd} mm, {pct} %, {f:g} Hz",
        "seed": seed,
        "wall_s": time.perf_counter() - t0,
        "chi2": res.statistics.chi2,
        "dof": res.statistics.dof,
        "poor_fit": res.statistics.poor_fit,
    }
    for name, value in truth.items():
        reported = film if name == "film_half_length" else name
        row[name] = interval_row(res.estimates.parameters[reported], value)
        chi2_1 = chi2_1_row(res, reported, value)
        if chi2_1 is not None:
            row[name]["chi2_1"] = chi2_1
    if companion:
        c = interval_row(res.estimates.parameters[film_c], a_c)
        row["a_companion"] = {k: c[k] for k in ("truth", "lower", "upper", "covered")}
    a_est = row["film_half_length"]
    row["a_within_20pct"] = (
        None if not a_est["identified"] or a == 0 else abs(a_est["estimate"] / a - 1) <= 0.2
    )
    row["success"] = res.statistics.success
    return row


def print_row(row: dict, n: int, cases: int, companion) -> None:
    """One case's line: each interval in or out, `a` identified, χ² and time."""
    cov = " ".join(f"{k}:{'IN' if row[k]['covered'] else 'OUT'}" for k in NAMES)
    ident = "a identified" if row["film_half_length"]["identified"] else "a not identified"
    if companion:
        ident += f"; companion a:{'IN' if row['a_companion']['covered'] else 'OUT'}"
    poor = " (flagged poor fit)" if row["poor_fit"] else ""
    print(
        f"[{n + 1}/{cases}] {row['case']} (seed {row['seed']}): {cov}; {ident}; "
        f"χ²={row['chi2']:.0f}/{row['dof']}{poor}; {row['wall_s']:.0f} s",
        flush=True,
    )


def main() -> None:
    args, overrides = parse_args()
    print(
        f"{rf.configure().devices} JAX device(s); seed {args.seed}; "
        f"FitOptions overrides {overrides}",
        flush=True,
    )
    rng = np.random.default_rng(args.seed)
    picks = rng.choice(len(GRID), size=min(args.cases, len(GRID)), replace=False)
    rows = []
    # each case in a fresh process: one process that compiles fit after fit runs out of
    # memory maps for its compiled code
    fresh = multiprocessing.get_context("spawn")
    for n, k in enumerate(picks):
        seed = int(rng.integers(1 << 30))
        if args.only and n + 1 not in args.only:
            continue
        with ProcessPoolExecutor(1, mp_context=fresh) as pool:
            job = pool.submit(case_row, n, int(k), seed, overrides, args.companion, args.quiet)
            row = job.result()
        if row is None:
            print(f"[{n + 1}/{len(picks)}] skipped (the companion's lubrication)")
            continue
        rows.append(row)
        print_row(row, n, len(picks), args.companion)
    print_summary(rows)
    if args.json:
        doc = {"options": overrides, "seed": args.seed, "companion": args.companion, "cases": rows}
        write_result(args.json, doc, default=dataclasses.asdict)  # the priors' specs
    if args.result:
        doc = {**result_document(rows, args.seed, overrides), **provenance()}
        write_result(args.result, doc, default=dataclasses.asdict)


if __name__ == "__main__":
    main()

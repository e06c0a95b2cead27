"""Where a simulation's steps go: free flight inside the backlash, the squeeze film ahead of a
flank, or mesh contact.

A simulation's cost is its number of solver steps times the cost of one
(``benchmarks/step_anatomy.py``). This script counts the steps of one simulation per
operating point of the forward comparison (the first seven independent recordings, at their
truth, released at rest on the drive flank as :func:`rattlefit.simulate` does), with the
solver and controller of :func:`rattlefit.simulate` and the absolute tolerances of a fit
(:func:`rattlefit.simulation.solve.absolute_tolerances`), at the fit's relative tolerance and
at 1e-4 (where the forward comparison's features match the sharp reference), and sorts
each accepted step by the state at its start:

* ``contact``: the nearer flank's gap is closed (the mesh force acts);
* ``film``: the gap is open, but the flank forces (mesh and squeeze film) exceed
  :data:`FORCE_SHARE` of the forcing that drives the rattle (the drag ``T_b/r2`` plus the
  inertial ``m r1 max|θ̈1|``);
* ``flight``: neither, the gear flies freely under the drive and the drag.

It reports the steps per simulated second, each regime's share and median step, the impacts
(entries into contact) per second and the steps each impact costs, and the ceiling on the gain
of any scheme that crosses free flight at no cost: all steps over the contact and film steps.
At the first tolerance it also counts the steps (accepted and rejected) of other diffrax
solvers on the same simulations (:data:`SOLVERS`): a higher and a lower order, and implicit
ones, which would take fewer steps if the film's damping made the equations stiff.
Nothing asserts a count.

    python benchmarks/step_regimes.py [--rtol 1e-5 1e-4] [--json FILE]
"""

from __future__ import annotations

import argparse
import sys

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import rattlefit as rf
from rattlefit.simulation.lockstep import FIRST_STEP
from rattlefit.simulation.solve import absolute_tolerances, initial_state, step_controller
from rattlefit.testing.results import provenance, write_result
from rattlefit.testing.shared import operating_points, truth_params
from run import FORWARD_POINTS as POINTS  # the forward comparison's operating points

DURATION, BURN_IN = 3.0, 0.5
#: A step is in the film regime when the flank forces exceed this share of the rattle's forcing.
FORCE_SHARE = 0.01
REGIMES = ("flight", "film", "contact")


def accepted_steps(setup, params, rtol: float, solver=None):
    """The accepted steps' start times (n,) and states (n, 2) of one simulation with
    ``solver`` (default Tsit5, :func:`rattlefit.simulate`'s), and its accepted and rejected
    step counts."""
    solver = solver or diffrax.Tsit5()
    lub = (setup.recording.operating.lubrication,)
    atol = setup.model.state_atol(absolute_tolerances(rtol, lub))
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(setup.model.vector_field),
        solver,
        t0=-BURN_IN,
        t1=DURATION,
        dt0=FIRST_STEP,
        y0=setup.model.full_state(initial_state(setup.model, params)),
        args=(params, setup.drive),
        saveat=diffrax.SaveAt(t0=True, steps=True),
        stepsize_controller=step_controller(rtol, atol),
        max_steps=400_000,
        throw=False,
    )
    if sol.result != diffrax.RESULTS.successful:
        raise RuntimeError(f"{type(solver).__name__} failed: {sol.result}")
    ts, ys = np.asarray(sol.ts), np.asarray(sol.ys)
    keep = np.isfinite(ts)
    accepted = int(sol.stats["num_accepted_steps"])
    rejected = int(sol.stats["num_rejected_steps"])
    return ts[keep], ys[keep], accepted, rejected


def regimes(setup, params, ts, ys) -> np.ndarray:
    """Each step's regime (index into :data:`REGIMES`) from the state at its start."""
    model, drive = setup.model, setup.drive
    f_mesh, f_squeeze = jax.vmap(lambda t, y: model.forces(t, y[0], y[1], params, drive))(
        jnp.asarray(ts), jnp.asarray(ys)
    )
    half = 0.5 * float(params.backlash)
    gap = half - np.abs(ys[:, 0])
    forcing = (
        float(params.drag_torque) / float(model.r2)
        + float(model.mass) * float(model.r1) * drive.max_acceleration()
    )
    flank = np.abs(np.asarray(f_mesh)) + np.abs(np.asarray(f_squeeze))
    out = np.zeros(len(ts), dtype=int)
    out[flank > FORCE_SHARE * forcing] = 1
    out[gap < 0] = 2
    return out


def point_row(name, setup, known, rtol: float) -> dict:
    """The step census of one operating point's simulation (burn-in excluded)."""
    params = truth_params(setup, known)
    ts, ys, accepted, rejected = accepted_steps(setup, params, rtol)
    kind = regimes(setup, params, ts, ys)
    recorded = ts[:-1] >= 0.0
    dt, kind = np.diff(ts)[recorded], kind[:-1][recorded]
    impacts = int(np.sum((kind[1:] == 2) & (kind[:-1] != 2)))
    steps = len(dt)
    share = {r: float(np.mean(kind == i)) for i, r in enumerate(REGIMES)}
    median_dt = {r: float(np.median(dt[kind == i])) if np.any(kind == i) else None
                 for i, r in enumerate(REGIMES)}  # fmt: skip
    near = int(np.sum(kind > 0))
    return {
        "steps_per_s": steps / DURATION,
        "rejected_share": rejected / max(accepted + rejected, 1),
        "share": share,
        "median_step_us": {r: (v * 1e6 if v is not None else None) for r, v in median_dt.items()},
        "impacts_per_s": impacts / DURATION,
        "near_flank_steps_per_impact": near / impacts if impacts else None,
        "gain_ceiling_without_flight": steps / near if near else None,
        "all_steps_per_s": (accepted + rejected) / (DURATION + BURN_IN),
    }


#: Other diffrax solvers whose step counts are compared with Tsit5's: a higher order, a lower
#: order, and implicit ones (which would pay off if the film's damping made the steps stiff).
SOLVERS = {
    "Tsit5": diffrax.Tsit5,
    "Dopri8": diffrax.Dopri8,
    "Bosh3": diffrax.Bosh3,
    "Kvaerno3": diffrax.Kvaerno3,
    "Kvaerno5": diffrax.Kvaerno5,
}


def solver_steps(rtol: float, points, tsit5: dict) -> dict:
    """Steps (accepted + rejected, burn-in included) per simulated second of each of
    :data:`SOLVERS` at each operating point, at ``rtol``; Tsit5's are taken from its census
    at that tolerance (``tsit5``: :func:`census`), not solved again."""
    out = {}
    for name, setup, known in points:
        params = truth_params(setup, known)
        out[name] = {"Tsit5": tsit5[name]["all_steps_per_s"]}
        for label, solver in list(SOLVERS.items())[1:]:
            _, _, accepted, rejected = accepted_steps(setup, params, rtol, solver())
            out[name][label] = (accepted + rejected) / (DURATION + BURN_IN)
        print(f"solvers {name}: {out[name]}", file=sys.stderr)
    return out


def solver_summary(steps: dict) -> str:
    """The range over the operating points of each solver's steps relative to Tsit5's."""
    parts = []
    for label in list(SOLVERS)[1:]:
        ratio = [row[label] / row["Tsit5"] for row in steps.values()]
        parts.append(f"{label} {min(ratio):.1f}–{max(ratio):.1f}×")
    return "steps against Tsit5's: " + ", ".join(parts)


def summary(rows: dict) -> str:
    """One line on the spread of the regimes' shares and the ceiling."""
    flight = [r["share"]["flight"] for r in rows.values()]
    ceiling = [v for r in rows.values() if (v := r["gain_ceiling_without_flight"])]
    per_impact = [v for r in rows.values() if (v := r["near_flank_steps_per_impact"])]
    return (
        f"free flight takes {min(flight):.0%}–{max(flight):.0%} of the steps over "
        f"{len(rows)} operating points; crossing it at no cost gains at most "
        f"{min(ceiling):.1f}–{max(ceiling):.1f}×; an impact with its film costs "
        f"{min(per_impact):.0f}–{max(per_impact):.0f} steps"
    )


def census(rtol: float, points) -> dict:
    """:func:`point_row` of each operating point at ``rtol``, each printed as it is done."""
    rows = {}
    for name, setup, known in points:
        rows[name] = r = point_row(name, setup, known, rtol)
        print(
            f"rtol {rtol:g} {name}: {r['steps_per_s']:.0f} steps/s; flight "
            f"{r['share']['flight']:.0%}, film {r['share']['film']:.0%}, contact "
            f"{r['share']['contact']:.0%}; {r['impacts_per_s']:.0f} impacts/s",
            file=sys.stderr,
        )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--rtol",
        type=float,
        nargs="+",
        default=[rf.FitOptions().rtol, 1e-4],
        help="relative tolerances; the first is the summary's (default: the fit's, then 1e-4)",
    )
    parser.add_argument("--json", help="write the result file here")
    args = parser.parse_args(argv)
    rf.configure(cpu_cores=1)
    points = operating_points(POINTS)
    by_rtol = {f"{rtol:g}": census(rtol, points) for rtol in args.rtol}
    first = f"{args.rtol[0]:g}"
    solvers = solver_steps(args.rtol[0], points, by_rtol[first])
    doc = {
        "order": 2.6,
        "what": "where a simulation's steps go: free flight, the squeeze film ahead of a "
        "flank, mesh contact",
        "summary": f"at rtol {first}: " + summary(by_rtol[first]) + "; " + solver_summary(solvers),
        "aim": "—",
        "verdict": "—",
        "measured": "one simulation per operating point at its truth (3 s after 0.5 s of "
        "burn-in, released at rest on the drive flank), Tsit5 with simulate()'s PID "
        f"controller at rtol {', '.join(by_rtol)} and the fit's absolute tolerances; each "
        "accepted step sorted by the state at its start (film: flank forces above "
        f"{FORCE_SHARE:g} of T_b/r2 + m r1 max|θ̈1|)",
        "results": {
            "rtol": {k: {"summary": summary(v), "points": v} for k, v in by_rtol.items()},
            "solvers": {"rtol": args.rtol[0], "steps_per_s": solvers},
        },
        **provenance(),
    }
    if args.json:
        write_result(args.json, doc)
    print(doc["summary"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

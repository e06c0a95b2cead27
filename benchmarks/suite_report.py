"""The analysis and report of ``benchmarks/run.py``'s results (numpy only, in the parent
process)."""

from __future__ import annotations

import math
import statistics

from suite_steps import (
    AIM_DIAGNOSE,
    AIM_FORWARD,
    AIM_IDENTIFY,
    AIM_POSTERIOR_ESS,
    AIM_POSTERIOR_S,
    BATCH_MODES,
    BATCH_SIZES,
    BURN_IN,
    DIAGNOSE_RECORDING,
    DURATION,
    FD_LOG_STEP,
    FIT_RTOL,
    IDENTIFY_RECORDING,
    P_FD,
    REF_LOOSE_TOL,
    REF_TOL,
    RTOLS,
    TARGET_FORWARD,
    Z_FLOOR,
    Z_MATCH,
    M,
    median,
)

# -- analysis and report (parent process: numpy only) ----------------------------------------


def rms_z(f_a, f_b) -> float:
    """rms over bands of the ensemble-mean difference in units of its standard error, which
    is floored at :data:`Z_FLOOR` (where rattle locks into a periodic orbit the realisations
    agree to 1e-3 and the bare standard error would call any smoothing artefact a mismatch)."""
    import numpy as np

    a, b = np.asarray(f_a), np.asarray(f_b)
    se = np.sqrt((a.var(0, ddof=1) + b.var(0, ddof=1)) / a.shape[0] + Z_FLOOR**2)
    return float(np.sqrt(np.mean(((a.mean(0) - b.mean(0)) / se) ** 2)))


def match(ref_pt, fwd_pt) -> dict:
    """z of each rtol against the reference, and the loosest rtol that matches."""
    z = {r: rms_z(fwd_pt[str(r)]["features"], ref_pt["tight"]["features"]) for r in RTOLS}
    ok = {r: not any(fwd_pt[str(r)]["result"]) for r in RTOLS}  # every solve succeeded
    passing = [r for r in RTOLS if z[r] < Z_MATCH and ok[r]]  # RTOLS runs loose → tight
    matched = passing[0] if passing else min(RTOLS, key=lambda r: z[r])
    return {
        "z": {str(r): v for r, v in z.items()},
        "z_ref_loose": rms_z(ref_pt["loose"]["features"], ref_pt["tight"]["features"]),
        "rtol": matched,
        "matched": bool(passing),
        "failed_solves": [r for r in RTOLS if not ok[r]],
    }


def paired_ratio(res: dict, name: str) -> float:
    """Reference / rattlefit wall time at the matched rtol, from the interleaved step."""
    e = res["paired"]["points"][name]
    return median(e["reference_s"]) / median(e["rattlefit_s"])


def verdict(value: float, aim: float, higher_is_better: bool = True) -> str:
    ok = value >= aim if higher_is_better else value < aim
    factor = value / aim if higher_is_better else aim / value
    if ok:
        return f"PASS (by {factor:.2f}×)"
    return f"MISS (short by {1 / factor:.2f}×)"


def table(headers, rows) -> str:
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]

    def line(r):
        return "  ".join(
            c.ljust(w) if i == 0 else c.rjust(w)
            for i, (c, w) in enumerate(zip(r, widths, strict=True))
        )

    return "\n".join(
        [line(cells[0]), line(["-" * w for w in widths])] + [line(r) for r in cells[1:]]
    )


def short(name: str) -> str:
    return (
        name.replace("_20pct_16Hz", "/16Hz")
        .replace("_10pct_8Hz", "/8Hz")
        .replace("_20pct_8Hz", "/8Hz/20%")
    )


def report_header(res: dict) -> list[str]:
    """The run's title, machine and simulation settings."""
    out = []
    m = res["machine"]
    out.append("rattlefit benchmarks" + (" (--quick)" if res["quick"] else ""))
    out.append(
        f"machine: {m['cpu_count']} CPU(s) ({m['cpu_model']}), jax {m['jax']} on "
        f"{m['jax_backend']} ({res.get('devices', 1)} JAX device(s): "
        "rattlefit.configure), "
        f"diffrax {m['diffrax']}, scipy {m['scipy']}, "
        f"python {m['python']}; load average {res['load_before'][0]:.2f} before, "
        f"{res['load_after'][0]:.2f} after the run (anything > 0 means shared CPUs)"
    )
    out.append(
        f"each run: {DURATION:g} s recorded + {BURN_IN:g} s burn-in = "
        f"{DURATION + BURN_IN:g} s simulated at 10 kHz output, truth parameters from truth.json; "
        f"ensembles of M={M} releases at s·c, s ∈ linspace(-0.9, 0.9, {M})"
    )
    out.append("")
    return out


def report_accuracy(res: dict) -> list[str]:
    """1a. Accuracy: each point's rms z against the sharp reference per rtol."""
    out = []
    out.append(
        f"1a. Accuracy: rms z of ensemble-mean log band PSDs vs the sharp reference "
        f"(rtol={REF_TOL[0]:g}, atol={REF_TOL[1]:g}); matched = loosest rtol with z < {Z_MATCH:g}"
    )
    rows = []
    for name in res["names"]:
        mt = res["match"][name]
        rows.append(
            [short(name)]
            + [f"{mt['z'][str(r)]:.2f}" for r in RTOLS]
            + [f"{mt['z_ref_loose']:.2f}", f"{mt['rtol']:g}" + ("" if mt["matched"] else " (!)")]
        )
    out.append(
        table(
            ["operating point"]
            + [f"z rf {r:g}" for r in RTOLS]
            + [f"z ref {REF_LOOSE_TOL[0]:g}", "matched rtol"],
            rows,
        )
    )
    out.append("")
    return out


def report_forward(res: dict) -> list[str]:
    """1b. Forward speed: reference and rattlefit wall times and their ratios."""
    import numpy as np

    out = []
    out.append(
        "1b. Forward speed: median wall time of one 3.5-s simulation, same release states for "
        "both solvers. ratio = reference / rattlefit single steady state at the matched rtol: "
        "'paired' alternates the two in one process (the headline), 'sep.' uses the separate "
        f"step processes; 'vs ref {REF_LOOSE_TOL[0]:g}' = the reference at rtol "
        f"{REF_LOOSE_TOL[0]:g}, atol {REF_LOOSE_TOL[1]:g} instead (sep.)"
    )
    rows = []
    for name in res["names"]:
        ref = res["reference"]["points"][name]
        fwd = res["forward"]["points"][name]
        mt = res["match"][name]
        t_ref = median(ref["tight"]["times_s"])
        t_loose = median(ref["loose"]["times_s"])
        times = {r: median(fwd[str(r)]["times_s"]) for r in RTOLS}
        rt = mt["rtol"]
        rows.append(
            [
                short(name),
                f"{t_ref:.2f}",
                f"{int(np.median(ref['tight']['n_rhs'])):,}",
                f"{int(np.median(ref['tight']['n_events']))}",
            ]
            + [f"{times[r] * 1e3:.0f}" for r in RTOLS]
            + [
                f"{int(np.median(fwd[str(rt)]['num_steps'])):,}",
                f"{paired_ratio(res, name):.1f}×",
                f"{t_ref / times[rt]:.1f}×",
                f"{t_loose / times[rt]:.1f}×",
            ]
        )
    out.append(
        table(
            ["operating point", "ref s", "ref RHS", "events"]
            + [f"rf ms {r:g}" for r in RTOLS]
            + ["rf steps", "paired", "sep.", f"vs ref {REF_LOOSE_TOL[0]:g}"],
            rows,
        )
    )
    comp = res["forward"]["compile_s"]
    out.append(
        "rattlefit single compile time (first call − steady run): "
        + ", ".join(f"rtol {float(k):g}: {v:.2f} s" for k, v in comp.items())
    )
    out.append("")
    return out


def report_batch(res: dict) -> list[str]:
    """1c. Batched forward: time per member of each batch mode and size."""
    out = []
    out.append(
        "1c. Batched forward at the matched rtol: wall time per member (ms); "
        "single = one simulate() in the same process; 'map' splits the batch over the JAX "
        "devices (one per core), so 'ref/best member' compares 2 cores with the reference's 1"
    )
    rows = []
    compile_rows = {}
    for name in res["names"]:
        b = res["batch"]["points"][name]
        t_ref = median(res["reference"]["points"][name]["tight"]["times_s"])
        row = [short(name), f"{b['rtol']:g}", f"{b['single_s'] * 1e3:.0f}"]
        for size in BATCH_SIZES:
            for mode in BATCH_MODES:
                e = b[f"{mode}{size}"]
                row.append(f"{e['per_member_s'] * 1e3:.0f}" + ("" if e["all_success"] else "!"))
                if e["compile_s"] is not None:
                    compile_rows.setdefault(f"{mode} B={size}", []).append(e["compile_s"])
        best = min(
            b[f"{mode}{size}"]["per_member_s"] for size in BATCH_SIZES for mode in BATCH_MODES
        )
        row.append(f"{t_ref / best:.1f}×")
        rows.append(row)
    out.append(
        table(
            ["operating point", "rtol", "single"]
            + [f"{mode} B={size}" for size in BATCH_SIZES for mode in BATCH_MODES]
            + ["ref/best member"],
            rows,
        )
    )
    out.append(
        "batch compile time (first call − steady run): "
        + ", ".join(f"{k}: {median(v):.2f} s" for k, v in compile_rows.items())
    )
    out.append("")
    return out


def report_jacobian(res: dict) -> list[str]:
    """2. Jacobian cost: jacfwd and the fit's FD Jacobian against one forward run."""
    out = []
    jac = res["jacobian"]
    out.append(
        f"2. Jacobian cost at rtol={FIT_RTOL:g} (simulate's default), relative to one forward "
        "simulation "
        f"(simulate() + features, release at -0.9c) in the same process; "
        f"|J| in d log10 PSD / d log p"
    )
    rows = []
    for name in res["names"]:
        e = jac["points"][name]
        mag = f"{e['jacfwd_max_abs']:.1e}" if e["jacfwd_finite"] else "non-finite"
        rows.append(
            [
                short(name),
                f"{e['forward_s'] * 1e3:.0f}",
                f"{e['forward_in_jit_s'] * 1e3:.0f}",
                f"{e['jacfwd_s'] * 1e3:.0f}",
                f"{e['jacfwd_ratio']:.1f}×",
                mag,
                f"{e['fd_s']:.2f}",
                f"{e['fd_ratio']:.1f}×",
                f"{e['fd_max_abs']:.2f}",
            ]
        )
    out.append(
        table(
            [
                "operating point",
                "fwd ms",
                "fwd in jit ms",
                "jacfwd ms",
                "jacfwd/fwd",
                "max|J| jacfwd",
                f"FD {(2 * P_FD + 1) * M} sims s",
                "FD/fwd",
                "max|J| FD",
            ],
            rows,
        )
    )
    out.append(
        "compile: "
        + ", ".join(f"{k} {v:.2f} s" for k, v in jac["compile_s"].items())
        + f"; FD = (2P+1)·M = (2·{P_FD}+1)·{M} simulations in one simulate_batch(batch='lockstep') "
        f"call, central differences at ±{FD_LOG_STEP:g} in log p; jacfwd = "
        "jax.jit(jax.jacfwd(features ∘ simulate)) over 6 parameters; 'fwd in jit' = the same "
        "forward function under that outer jax.jit (model, drive, y0 traced)"
    )
    out.append("")
    return out


def report_identify(res: dict) -> list[str]:
    """3. One identify() run: wall time, fit quality, estimates."""
    out = []
    out.append(f"3. identify([{IDENTIFY_RECORDING}], FitOptions()), compile included")
    idf = res.get("identify")
    if idf is None:
        out.append("   not run (pass --identify)")
    elif not idf["ok"]:
        out.append(f"   ERROR: {idf['error']}")
    else:
        out.append(
            f"   wall {idf['wall_s']:.1f} s; success={idf['success']} "
            f"({idf.get('outcome') or idf.get('message')}); "
            f"χ²={idf['chi2']:.1f} on {idf['dof']} dof"
        )
        for k, v in idf["parameters"].items():
            est = f"{v['estimate']:.4g}" + ("" if v.get("identified") else " (not identified)")
            out.append(f"   {k:>16s} = {est} [{v['lower']:.3g}, {v['upper']:.3g}] {v['unit']}")
    out.append("")
    return out


def report_posterior(res: dict) -> list[str]:
    """3b. identify() then sample(): wall times, ESS and τ per parameter."""
    out = []
    post = res.get("posterior")
    out.append(
        f"3b. posterior: identify() then sample() of {IDENTIFY_RECORDING} (emcee, synthetic "
        "likelihood), compile included"
    )
    if post is None:
        out.append("   not run (pass --posterior [STEPS])")
    elif not post["ok"]:
        out.append(f"   ERROR: {post['error']}")
    else:
        sims = post["evaluations"] * post["realisations"]
        out.append(
            f"   fit {post['fit_s']:.0f} s + chain {post['sample_s']:.0f} s: {post['walkers']} "
            f"walkers × {post['steps']} steps (burn-in {post['burn_in']}), "
            f"{post['evaluations']} points = {sims} simulations "
            f"({post['sample_s'] / max(sims, 1) * 1e3:.0f} ms each on all cores), acceptance "
            f"{post['acceptance']:.2f}{'' if post['reliable'] else ' (chain < 50 τ: τ, ESS rough)'}"
        )
        rows = []
        for k, ess in post["ess"].items():
            med, lo, hi = post["intervals"][k]
            rows.append(
                [
                    k,
                    f"{med:.4g} [{lo:.3g}, {hi:.3g}]",
                    f"{post['tau'][k]:.1f}",
                    f"{ess:.0f}",
                    f"{ess / post['sample_s']:.3f}",
                ]
            )
        out.append(table(["parameter", "median [95 %]", "τ steps", "ESS", "ESS/s"], rows))
    out.append("")
    return out


def report_diagnose(res: dict) -> list[str]:
    """3c. diagnose() with every effect: wall time and each effect's χ² change."""
    out = []
    diag = res.get("diagnose")
    out.append(f"3c. diagnose of {DIAGNOSE_RECORDING}: identify, then every effect")
    if diag is None:
        out.append("   not run (pass --diagnose)")
    elif not diag["ok"]:
        out.append(f"   ERROR: {diag['error']}")
    else:
        out.append(
            f"   wall {diag['wall_s']:.0f} s (identify {diag['identify_s']:.0f} s); χ² without "
            f"effects {diag['chi2']:.1f} on {diag['dof']} dof; verdict: {diag['verdict']}"
        )
        out.append(f"   {diag.get('sentence', '')}")
        rows = [
            [
                e["name"],
                f"{e['chi2_without']:.1f} → {e['chi2_with']:.1f}",
                f"{e['p_value']:.2g}",
                "yes" if e["supported"] else "no",
                f"{e['wall_s']:.0f}",
            ]
            for e in diag["effects"]
        ]
        out.append(table(["effect", "χ² without → with", "p", "supported", "s"], rows))
    out.append("")
    return out


def report_memory(res: dict) -> list[str]:
    """4. Peak memory of each step's process against the baseline."""
    out = []
    out.append("4. Peak memory (ru_maxrss of a fresh spawned process per step)")
    base = res["memory"]["baseline"]
    rows = [["baseline (import rattlefit)", f"{base:.0f}", "—"]]
    for step, peak in res["memory"].items():
        if step != "baseline":
            rows.append([step, f"{peak:.0f}", f"+{peak - base:.0f}"])
    out.append(table(["step", "peak MiB", "over baseline MiB"], rows))
    out.append("")
    return out


def report_aims(res: dict) -> list[str]:
    """The aims, each with its measured value and verdict."""
    out = []
    idf, post, diag = res.get("identify"), res.get("posterior"), res.get("diagnose")
    out.append("Aims")
    ratios = {n: paired_ratio(res, n) for n in res["names"]}
    worst = min(ratios, key=ratios.get)
    geo = math.exp(statistics.fmean(math.log(v) for v in ratios.values()))
    unmatched = [short(n) for n in res["names"] if not res["match"][n]["matched"]]
    rows = [
        [
            f"forward ≥ {AIM_FORWARD:g}× reference, matched accuracy (worst point)",
            f"{ratios[worst]:.1f}× ({short(worst)})",
            verdict(ratios[worst], AIM_FORWARD),
        ],
        [
            f"forward ≥ {AIM_FORWARD:g}× (geometric mean over points)",
            f"{geo:.1f}×",
            verdict(geo, AIM_FORWARD),
        ],
        [
            f"forward target {TARGET_FORWARD:g}× (geometric mean)",
            f"{geo:.1f}×",
            verdict(geo, TARGET_FORWARD),
        ],
    ]
    if idf is None:
        rows.append([f"identify < {AIM_IDENTIFY:g} s", "not run", "—"])
    elif not idf["ok"]:
        rows.append([f"identify < {AIM_IDENTIFY:g} s", "error", "MISS (identify failed)"])
    else:
        rows.append(
            [
                f"identify < {AIM_IDENTIFY:g} s",
                f"{idf['wall_s']:.1f} s",
                verdict(idf["wall_s"], AIM_IDENTIFY, higher_is_better=False),
            ]
        )
    if post is None:
        rows.append(
            [f"posterior ESS ≥ {AIM_POSTERIOR_ESS:g} < {AIM_POSTERIOR_S:g} s", "not run", "—"]
        )
    elif not post["ok"]:
        rows.append(["posterior", "error", "MISS (posterior failed)"])
    else:
        rate = min(post["ess"].values()) / post["sample_s"]  # the slowest parameter
        needed = post["fit_s"] + AIM_POSTERIOR_ESS / max(rate, 1e-12)
        rows.append(
            [
                f"posterior ESS ≥ {AIM_POSTERIOR_ESS:g} per parameter < {AIM_POSTERIOR_S:g} s",
                f"{needed:.0f} s projected (fit + {AIM_POSTERIOR_ESS:g} / min ESS/s)",
                verdict(needed, AIM_POSTERIOR_S, higher_is_better=False),
            ]
        )
    if diag is None:
        rows.append([f"diagnose < {AIM_DIAGNOSE:g} s", "not run", "—"])
    elif not diag["ok"]:
        rows.append(["diagnose", "error", "MISS (diagnose failed)"])
    else:
        rows.append(
            [
                f"diagnose < {AIM_DIAGNOSE:g} s",
                f"{diag['wall_s']:.0f} s",
                verdict(diag["wall_s"], AIM_DIAGNOSE, higher_is_better=False),
            ]
        )
    out.append(table(["aim", "measured", "verdict"], rows))
    if unmatched:
        out.append(
            f"(!) no rtol in {RTOLS} reached z < {Z_MATCH:g} at: {', '.join(unmatched)}; "
            "the ratio there is at the rtol with the lowest z"
        )
    out.append(f"total benchmark wall time: {res['wall_s']:.0f} s")
    return out


def report(res: dict) -> str:
    """The plain-text report of a run's results (``main``'s ``res``)."""
    sections = (
        report_header,
        report_accuracy,
        report_forward,
        report_batch,
        report_jacobian,
        report_identify,
        report_posterior,
        report_diagnose,
        report_memory,
        report_aims,
    )
    return "\n".join(line for section in sections for line in section(res))


#: What the forward result measures: a change there makes it stale (benchmarks/readme_table.py).


def forward_result(res: dict) -> dict:
    """The result file ``forward.json`` of a run's sections 1a–1b: the paired speed ratio per
    point at its matched rtol, their geometric mean, and the aim's verdict (without the
    provenance, which the caller adds)."""
    import numpy as np

    per_point = []
    for name in res["names"]:
        ref, fwd, mt = (
            res["reference"]["points"][name],
            res["forward"]["points"][name],
            res["match"][name],
        )
        rt = mt["rtol"]
        per_point.append({
            "point": short(name),
            "matched_rtol": rt,
            "matched": mt["matched"],
            "reference_s": round(median(ref["tight"]["times_s"]), 2),
            "contact_events": int(np.median(ref["tight"]["n_events"])),
            "rattlefit_ms": round(1e3 * median(fwd[str(rt)]["times_s"])),
            "steps": int(np.median(fwd[str(rt)]["num_steps"])),
            "paired_ratio": round(paired_ratio(res, name), 1),
        })  # fmt: skip
    ratios = [p["paired_ratio"] for p in per_point]
    geo = math.exp(statistics.fmean(math.log(r) for r in ratios))
    worst = min(per_point, key=lambda p: p["paired_ratio"])
    ms = [p["rattlefit_ms"] for p in per_point]
    met = geo >= AIM_FORWARD
    return {
        "headline": True,
        "order": 1,
        "what": "forward simulation vs the sharp `solve_ivp` reference, matched feature accuracy",
        "summary": f"{geo:.0f}× faster (geometric mean of {len(ratios)} operating points; "
        f"{min(ratios):.0f}–{max(ratios):.0f}×, slowest {worst['point']}); one "
        f"{DURATION + BURN_IN:g} s simulation {min(ms)}–{max(ms)} ms",
        "aim": f"≥ {AIM_FORWARD:g}× (target {TARGET_FORWARD:g}×)",
        "verdict": ("met" if met else "missed") + f" on the geometric mean; "
        f"{sum(r >= AIM_FORWARD for r in ratios)}/{len(ratios)} points at ≥ {AIM_FORWARD:g}×",
        "measured": "benchmarks/run.py, sections 1a–1b: at each operating point, "
        f"{M} releases across the gap; rattlefit's smoothed model (diffrax Tsit5) at rtol "
        f"{max(RTOLS):g}…{min(RTOLS):g} against the sharp-switching scipy reference (rtol "
        f"{REF_TOL[0]:g}). The matched rtol is the loosest whose ensemble-mean log band PSDs "
        f"lie within rms z < {Z_MATCH:g} of the reference's; the ratio is the reference's wall "
        "time over rattlefit's at that rtol, the two alternated in one process.",
        "devices": res.get("devices"),
        "results": {
            "paired_ratio_geometric_mean": round(geo, 1),
            "per_point": per_point,
            "compile_s": res["forward"]["compile_s"],
        },
    }

"""The measured steps of ``benchmarks/run.py``: each runs in a fresh spawned process
(:func:`run_step`), so that its peak resident memory is its own."""

from __future__ import annotations

import functools
import multiprocessing as mp
import os
import platform
import resource
import statistics
import sys
import time
import traceback
from pathlib import Path

from rattlefit.report import verdict_sentence
from rattlefit.testing.shared import operating_points, recordings_dir, truth_params

QUICK_RECORDING = "pairII_boundary_65.0_10pct_8Hz"
IDENTIFY_RECORDING = "pairII_boundary_65.0_10pct_8Hz.h5"

DURATION = 3.0  # recorded time, s
BURN_IN = 0.5  # simulated before the first sample, s
M = 4  # realisations per ensemble, released at s·c for s in linspace(-0.9, 0.9, M)
RTOLS = (1e-4, 1e-5, 1e-6, 1e-7)  # rattlefit tolerances tried; atol = ATOL_PER_RTOL · rtol
ATOL_PER_RTOL = 1e-3  # 1e-6 → 1e-9 (simulate's default), 1e-7 → 1e-10 (test_convergence)
REF_TOL = (1e-8, 1e-11)  # the reference's own defaults: the ground truth of the comparison
REF_LOOSE_TOL = (1e-6, 1e-9)  # the reference at rattlefit's default tolerances (for context)
Z_MATCH = 2.0  # rms z below which two ensembles' mean features agree
# log10 floor of that standard error: FitOptions.sigma_floor, the smallest band spread the fit
# resolves. Without it the periodic orbit of the mild point (pairII_boundary_65.0, h_min 2 µm)
# has z ≈ 20–30 at every rtol, from the contact smoothing (0.07 in the 8 Hz band; 0.03 at a
# tenth of the contact width, 0.01 at 3 %), not from the solver tolerance.
Z_FLOOR = 0.03
BATCH_SIZES = (8, 32)
BATCH_MODES = ("map", "vmap", "lockstep")
FIT_RTOL = 1e-6  # simulate()'s default rtol, at which the Jacobians are costed
P_FD = 6  # fitted parameters (a, T_b, μ, backlash, h_min, stiffness scale)
FD_LOG_STEP = 0.15  # ParameterSpec.fd_log_step
AIM_FORWARD, TARGET_FORWARD = 50.0, 100.0  # × faster than the reference at matched accuracy
AIM_IDENTIFY = 60.0  # s, one 3-s recording, compile included
AIM_POSTERIOR_ESS, AIM_POSTERIOR_S = 400.0, 600.0  # ESS per parameter within this wall time
POSTERIOR_STEPS = 150  # default chain length of the posterior step (16 walkers)
AIM_DIAGNOSE = 900.0  # s, identify + every effect of rattlefit.physics.effects, compile included
# the shared file whose truth lists an unmodelled effect (run-out) and that has rattle
DIAGNOSE_RECORDING = "pairII_boundary_65.4_20pct_16Hz_runout.h5"

PARAM_NAMES = ("film_half_length", "T_b", "mu", "backlash", "h_min", "k_scale")


# -- helpers used in the child processes ---------------------------------------------------


def say(msg: str) -> None:
    print(f"  [{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def median(xs) -> float:
    return float(statistics.median(xs))


def atol(rtol: float) -> float:
    return rtol * ATOL_PER_RTOL


def release_fractions(m: int):
    import numpy as np

    return np.linspace(-0.9, 0.9, m)


def timed(fn, *args, **kwargs):
    """(wall time of fn(*args, **kwargs) until its outputs are ready, outputs)."""
    import jax

    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    jax.block_until_ready(out)
    return time.perf_counter() - t0, out


# -- the steps (each runs in a fresh spawned process) ----------------------------------------


def step_baseline(_args):
    import rattlefit  # noqa: F401

    peak = peak_mib()  # before anything initialises the JAX backend
    import diffrax
    import jax
    import numpy as np
    import scipy

    return {
        "peak_mib": peak,
        "machine": {
            "cpu_count": os.cpu_count(),
            "cpu_model": cpu_model(),
            "platform": platform.platform(),
            "python": platform.python_version(),
            "jax_backend": jax.default_backend(),
            "jax": jax.__version__,
            "diffrax": diffrax.__version__,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
        },
    }


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def step_reference(args):
    """The sharp scipy reference: M realisations at its default and at loose tolerances."""
    import numpy as np

    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.reference import simulate_reference

    out = {}
    for name, s, truth in operating_points(args["names"]):
        c = s.geometry.backlash / 2
        res = {}
        for label, (rtol, atol) in (("tight", REF_TOL), ("loose", REF_LOOSE_TOL)):
            times, rhs, events, motion = [], [], [], []
            for frac in release_fractions(M):
                t0 = time.perf_counter()
                ref = simulate_reference(
                    s.geometry,
                    s.drive,
                    film_half_length=truth["a_mm"] * 1e-3,
                    drag_torque=truth["drag_torque_Nm"],
                    viscosity=truth["viscosity_Pa_s"],
                    backlash=s.geometry.backlash,
                    initial_state=(frac * c, 0.0),
                    duration=DURATION,
                    sample_rate=s.sample_rate,
                    burn_in=BURN_IN,
                    rtol=rtol,
                    atol=atol,
                )
                times.append(time.perf_counter() - t0)
                rhs.append(ref.n_rhs)
                events.append(ref.n_events)
                motion.append(ref.relative_motion)
            feats = spectral_features(np.stack(motion), s.bands, noise_floor=s.noise_floor)
            res[label] = {
                "rtol": rtol,
                "atol": atol,
                "times_s": times,
                "n_rhs": rhs,
                "n_events": events,
                "features": np.asarray(feats).tolist(),
            }
            say(f"reference {label:5s} {name}: median {median(times):.2f} s")
        out[name] = res
    return {"points": out}


def step_forward(args):
    """rattlefit single simulations at each rtol, same M release states as the reference."""
    import jax.numpy as jnp
    import numpy as np

    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate

    reps = args["reps"]
    compile_s = {}
    out = {}
    for name, s, truth in operating_points(args["names"]):
        params = truth_params(s, truth)
        c = s.geometry.backlash / 2
        res = {}
        for rtol in RTOLS:
            opts = sim_options(s, rtol)
            y0s = [jnp.asarray([frac * c, 0.0]) for frac in release_fractions(M)]
            first = None
            if str(rtol) not in compile_s:  # first call at this rtol: compile + one run
                first, _ = timed(simulate, s.model, params, s.drive, y0=y0s[0], **opts)
            times, steps, codes, motion = [], [], [], []
            for rep in range(reps):
                for i, y0 in enumerate(y0s):
                    dt, sol = timed(simulate, s.model, params, s.drive, y0=y0, **opts)
                    times.append(dt)
                    if rep == 0:
                        steps.append(int(sol.num_steps))
                        codes.append(int(sol.result))
                        motion.append(np.asarray(sol.relative_motion))
                    if i == 0 and first is not None and rep == 0:
                        compile_s[str(rtol)] = first - dt
            feats = spectral_features(np.stack(motion), s.bands, noise_floor=s.noise_floor)
            res[str(rtol)] = {
                "rtol": rtol,
                "atol": atol(rtol),
                "times_s": times,
                "num_steps": steps,
                "result": codes,
                "features": np.asarray(feats).tolist(),
            }
            say(f"rattlefit rtol={rtol:g} {name}: median {median(times) * 1e3:.0f} ms")
        out[name] = res
    return {"points": out, "compile_s": compile_s}


def sim_options(s, rtol):
    """simulate() options of every timed run: the recording's rate, matched tolerances."""
    return dict(
        duration=DURATION, sample_rate=s.sample_rate, burn_in=BURN_IN, rtol=rtol, atol=atol(rtol)
    )


def step_paired(args):
    """Reference and rattlefit (matched rtol) alternately in one process, same release states.

    The headline speed ratio comes from here: alternating the two solvers exposes both to the
    same machine load, which separate processes minutes apart do not guarantee.
    """
    from rattlefit.simulation.reference import simulate_reference
    from rattlefit.simulation.solve import simulate

    compiled = set()
    out = {}
    for name, s, truth in operating_points(args["names"]):
        rtol = args["rtol"][name]
        opts = sim_options(s, rtol)
        params = truth_params(s, truth)
        c = s.geometry.backlash / 2
        t_ref, t_rf = [], []
        for frac in release_fractions(M)[: args["pairs"]]:
            y0 = (float(frac * c), 0.0)
            if rtol not in compiled:
                timed(simulate, s.model, params, s.drive, y0=y0, **opts)
                compiled.add(rtol)
            t0 = time.perf_counter()
            simulate_reference(
                s.geometry,
                s.drive,
                film_half_length=truth["a_mm"] * 1e-3,
                drag_torque=truth["drag_torque_Nm"],
                viscosity=truth["viscosity_Pa_s"],
                backlash=s.geometry.backlash,
                initial_state=y0,
                duration=DURATION,
                sample_rate=s.sample_rate,
                burn_in=BURN_IN,
                rtol=REF_TOL[0],
                atol=REF_TOL[1],
            )
            t_ref.append(time.perf_counter() - t0)
            for _ in range(3):
                t_rf.append(timed(simulate, s.model, params, s.drive, y0=y0, **opts)[0])
        out[name] = {"rtol": rtol, "reference_s": t_ref, "rattlefit_s": t_rf}
        ratio = median(t_ref) / median(t_rf)
        say(f"paired {name}: reference / rattlefit(rtol={rtol:g}) = {ratio:.1f}×")
    return {"points": out}


def step_batch(args):
    """simulate_batch with B members (release states across the gap): time per member."""
    import jax.numpy as jnp
    import numpy as np

    from rattlefit.simulation.solve import broadcast_params, simulate, simulate_batch

    compiled = set()
    out = {}
    for name, s, truth in operating_points(args["names"]):
        rtol = args["rtol"][name]
        opts = sim_options(s, rtol)
        params = truth_params(s, truth)
        c = s.geometry.backlash / 2
        # the single simulation in this same process, as the yardstick of the batched ones
        y_single = jnp.asarray([-0.9 * c, 0.0])
        single = (simulate, s.model, params, s.drive)
        if ("single", rtol) not in compiled:
            timed(*single, y0=y_single, **opts)
            compiled.add(("single", rtol))
        t_single = [timed(*single, y0=y_single, **opts)[0] for _ in range(3)]
        res = {"rtol": rtol, "single_s": median(t_single)}
        for b in BATCH_SIZES:
            pb = broadcast_params(params, b)
            y0 = jnp.stack([jnp.asarray(release_fractions(b)) * c, jnp.zeros(b)], axis=1)
            for mode in BATCH_MODES:
                run = (simulate_batch, s.model, pb, s.drive)
                key = (b, mode, rtol)
                first = None
                if key not in compiled:
                    first, _ = timed(*run, y0=y0, batch=mode, **opts)
                    compiled.add(key)
                times = []
                for _ in range(args["reps"]):
                    dt, sol = timed(*run, y0=y0, batch=mode, **opts)
                    times.append(dt)
                total = median(times)
                res[f"{mode}{b}"] = {
                    "B": b,
                    "mode": mode,
                    "total_s": total,
                    "per_member_s": total / b,
                    "compile_s": None if first is None else first - total,
                    "all_success": bool(np.all(np.asarray(sol.success))),
                    "num_steps_total": int(np.sum(np.asarray(sol.num_steps))),
                }
                say(f"batch {mode} B={b} {name}: {total / b * 1e3:.0f} ms per member")
        out[name] = res
    return {"points": out}


def params_from(v):
    """RattleParams from the vector (a, T_b, μ, backlash, h_min, stiffness scale)."""
    from rattlefit.physics.model import RattleParams

    return RattleParams(v[0], v[1], v[2], v[3], min_film=v[4], stiffness_scale=v[5])


def forward_features(s, params, y0, opts):
    """One forward simulation as a user runs it: simulate(), then the features."""
    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate

    sol = simulate(s.model, params, s.drive, y0=y0, sample_rate=s.sample_rate, **opts)
    return spectral_features(sol.relative_motion, s.bands, noise_floor=s.noise_floor)


def fd_features(s, params, y0, opts):
    """Features of a batch of members (one simulate_batch call, batch='lockstep', as the fit
    simulates), and the batch."""
    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate_batch

    sol = simulate_batch(
        s.model, params, s.drive, y0=y0, batch="lockstep", sample_rate=s.sample_rate, **opts
    )
    return spectral_features(sol.relative_motion, s.bands, noise_floor=s.noise_floor), sol


def jacobian_functions():
    """Jitted features(scale) and its jacfwd, built once so every point reuses the compile."""
    import jax

    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate

    def feats(scale, base, model, drive, y0, noise_floor, bands):
        # features as a function of multiplicative factors on the six parameters: the
        # Jacobian at ones is d features / d log p (dimensionless)
        sol = simulate(
            model,
            params_from(base * scale),
            drive,
            y0=y0,
            duration=DURATION,
            sample_rate=bands.sample_rate,
            burn_in=BURN_IN,
            rtol=FIT_RTOL,
            atol=atol(FIT_RTOL),
        )
        return spectral_features(sol.relative_motion, bands, noise_floor=noise_floor)

    forward = jax.jit(feats, static_argnames="bands")
    jac = jax.jit(jax.jacfwd(feats), static_argnames="bands")
    return forward, jac


def step_jacobian(args):
    """jax.jacfwd through simulate vs one forward simulation, and the fit's FD Jacobian."""
    import jax.numpy as jnp
    import numpy as np

    reps = args["reps"]
    opts = dict(duration=DURATION, burn_in=BURN_IN, rtol=FIT_RTOL, atol=atol(FIT_RTOL))
    forward_fn, jac_fn = jacobian_functions()
    out = {}
    compile_s = {}
    for name, s, truth in operating_points(args["names"]):
        base = jnp.asarray(
            [
                truth["a_mm"] * 1e-3,
                truth["drag_torque_Nm"],
                truth["viscosity_Pa_s"],
                s.geometry.backlash,
                10e-6,
                1.0,
            ]
        )

        y_single = jnp.asarray([-0.9 * s.geometry.backlash / 2, 0.0])
        fixed = (base, s.model, s.drive, y_single, s.noise_floor)
        one = jnp.ones(P_FD)
        warm = not compile_s  # the first point compiles; the others reuse the executables
        # the yardstick: one forward simulation as a user runs it, simulate() + features
        direct = (forward_features, s, params_from(base), y_single, opts)
        first_f = timed(*direct)[0] if warm else None
        t_fwd = median([timed(*direct)[0] for _ in range(max(reps, 3))])
        # the same inside an outer jax.jit with everything traced (as jacfwd runs it)
        first_fj = timed(forward_fn, one, *fixed, bands=s.bands)[0] if warm else None
        t_fwd_jit = median(
            [timed(forward_fn, one, *fixed, bands=s.bands)[0] for _ in range(max(reps, 3))]
        )
        first_j = timed(jac_fn, one, *fixed, bands=s.bands)[0] if warm else None
        t_jac_all = []
        for _ in range(reps):
            dt, j = timed(jac_fn, one, *fixed, bands=s.bands)
            t_jac_all.append(dt)
        t_jac = median(t_jac_all)
        j = np.asarray(j)

        # the fit's finite-difference ensemble Jacobian: (2P+1)·M members in one call
        steps = np.zeros((2 * P_FD + 1, P_FD))
        for i in range(P_FD):
            steps[1 + 2 * i, i], steps[2 + 2 * i, i] = FD_LOG_STEP, -FD_LOG_STEP
        values = np.asarray(base)[None] * np.exp(steps)  # (2P+1, P)
        rows = np.repeat(values, M, axis=0)  # (2P+1)·M members
        fracs = np.tile(release_fractions(M), 2 * P_FD + 1)
        y0 = np.stack([fracs * rows[:, 3] / 2, np.zeros(len(fracs))], axis=1)
        pb = params_from(jnp.asarray(rows.T))
        fd = (fd_features, s, pb, jnp.asarray(y0), opts)
        first_fd = timed(*fd)[0] if warm else None
        t_fd, (f_fd, sol) = timed(*fd)  # (2P+1)·M simulations: one run suffices
        if warm:
            compile_s.update(
                forward=first_f - t_fwd,
                forward_in_jit=first_fj - t_fwd_jit,
                jacfwd=first_j - t_jac,
                fd_batch=first_fd - t_fd,
            )
        mean = np.asarray(f_fd).reshape(2 * P_FD + 1, M, -1).mean(axis=1)
        j_fd = (mean[1::2] - mean[2::2]) / (2 * FD_LOG_STEP)  # (P, B)
        out[name] = {
            "rtol": FIT_RTOL,
            "forward_s": t_fwd,
            "forward_in_jit_s": t_fwd_jit,
            "jacfwd_s": t_jac,
            "jacfwd_ratio": t_jac / t_fwd,
            "jacfwd_max_abs": float(np.max(np.abs(j))) if np.all(np.isfinite(j)) else None,
            "jacfwd_finite": bool(np.all(np.isfinite(j))),
            "jacfwd_max_abs_per_param": {
                n: float(np.nanmax(np.abs(j[:, i]))) for i, n in enumerate(PARAM_NAMES)
            },
            "fd_members": int(rows.shape[0]),
            "fd_s": t_fd,
            "fd_ratio": t_fd / t_fwd,
            "fd_all_success": bool(np.all(np.asarray(sol.success))),
            "fd_max_abs": float(np.max(np.abs(j_fd))),
            "fd_max_abs_per_param": {
                n: float(np.max(np.abs(j_fd[i]))) for i, n in enumerate(PARAM_NAMES)
            },
        }
        say(
            f"jacobian {name}: jacfwd {t_jac / t_fwd:.1f}× forward (max|J| "
            f"{out[name]['jacfwd_max_abs']}), FD {t_fd / t_fwd:.1f}× forward"
        )
    return {"points": out, "compile_s": compile_s}


def guarded(step):
    """A step that returns ``{"ok": False, "error", "traceback"}`` instead of raising, so
    that one failing end-to-end step does not lose the rest of the run."""

    @functools.wraps(step)
    def run(args):
        try:
            return {"ok": True, **step(args)}
        except Exception as exc:
            return {
                "ok": False,
                "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(limit=4),
            }

    return run


def timed_identify(file: str):
    """(recording, identify([recording], FitOptions()) result, wall time with compilation)."""
    from rattlefit.inference.identify import identify
    from rattlefit.io.recording import read_recording
    from rattlefit.problem.options import FitOptions

    rec = read_recording(recordings_dir() / file)
    t0 = time.perf_counter()
    result = identify([rec], FitOptions(), progress=lambda msg: say(f"identify: {msg}"))
    return rec, result, time.perf_counter() - t0


@guarded
def step_identify(args):
    """One identification of a 3-s recording, compile included (guarded: a failure is
    reported in the results, not raised)."""
    _, result, wall = timed_identify(args["file"])
    params = {}
    for k, v in result.estimates.parameters.items():
        params[k] = {
            "estimate": v.estimate,
            "lower": v.lower,
            "upper": v.upper,
            "unit": v.unit,
            "identified": v.identified,
        }
    return {
        "wall_s": wall,
        "success": bool(result.statistics.success),
        "outcome": result.statistics.search.outcome.value,
        "chi2": float(result.statistics.chi2),
        "dof": int(result.statistics.dof),
        "parameters": params,
    }


@guarded
def step_posterior(args):
    """identify() then sample() of the same 3-s recording: wall times, ESS, ESS per second."""
    from rattlefit.inference.posterior import SampleOptions, sample
    from rattlefit.problem.options import FitOptions

    rec, fit, t_fit = timed_identify(args["file"])
    t0 = time.perf_counter()
    post = sample(
        [rec],
        fit,
        SampleOptions(n_steps=args["steps"], seed=0),
        progress=lambda msg: say(f"sample: {msg}"),
    )
    t_sample = time.perf_counter() - t0
    return {
        "fit_s": t_fit,
        "sample_s": t_sample,
        "walkers": int(post.chain.shape[1]),
        "steps": int(post.chain.shape[0]),
        "burn_in": post.burn_in,
        "evaluations": post.n_evaluations,
        "realisations": FitOptions().n_realisations,
        "acceptance": float(post.acceptance.mean()),
        "reliable": post.reliable,
        "ess": dict(zip(post.names, map(float, post.ess), strict=True)),
        "tau": dict(zip(post.names, map(float, post.autocorr_time), strict=True)),
        "intervals": post.intervals(),
    }


@guarded
def step_diagnose(args):
    """diagnose() of a 3-s recording fitting every effect of the catalogue (``every_effect``:
    the worst case, also the effects its findings rule out): wall time, identify included."""
    from rattlefit.diagnosis.diagnose import DiagnoseOptions, diagnose
    from rattlefit.io.recording import read_recording

    rec = read_recording(recordings_dir() / args["file"])
    t0 = time.perf_counter()
    options = DiagnoseOptions(every_effect=True)
    diag = diagnose([rec], options, progress=lambda msg: say(f"diagnose: {msg}"))
    wall = time.perf_counter() - t0
    return {
        "wall_s": wall,
        "identify_s": diag.baseline.provenance.wall_time,
        "chi2": diag.baseline.statistics.chi2,
        "dof": diag.baseline.statistics.dof,
        "gap_chi2": diag.gap_chi2[0],
        "verdict": diag.verdict.label,
        "sentence": verdict_sentence(diag),
        "effects": [
            {
                "name": o.name,
                "chi2_without": o.chi2_without,
                "chi2_with": o.chi2_with,
                "p_value": o.p_value,
                "supported": o.supported,
                "wall_s": o.wall_time,
            }
            for o in diag.outcomes
        ],
    }


STEPS = {
    "baseline": step_baseline,
    "reference": step_reference,
    "forward": step_forward,
    "paired": step_paired,
    "batch": step_batch,
    "jacobian": step_jacobian,
    "identify": step_identify,
    "posterior": step_posterior,
    "diagnose": step_diagnose,
}


def child(step: str, args: dict) -> dict:
    import rattlefit

    # one JAX device per core (as the CLI does): batches and identify use every core
    devices = rattlefit.configure().devices
    t0 = time.perf_counter()
    result = STEPS[step](args)
    result.setdefault("devices", devices)
    result.setdefault("peak_mib", peak_mib())
    result["step_wall_s"] = time.perf_counter() - t0
    return result


def run_step(step: str, args: dict) -> dict:
    """Run one step in a fresh spawned process; its result carries its own peak RSS."""
    print(f"→ {step} …", file=sys.stderr, flush=True)
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        return pool.apply(child, (step, args))

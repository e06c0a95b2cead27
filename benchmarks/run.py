"""Benchmarks of rattlefit against the sharp scipy reference, at the shared recordings.

Run ``python benchmarks/run.py [--quick] [--identify] [--posterior [STEPS]] [--diagnose]
[--json out.json]``.

Every measured step runs in its own fresh ``multiprocessing`` "spawn" process, so that its peak
resident memory (``ru_maxrss``) is its own; a baseline process that only imports rattlefit gives
the reference level. Steps run one after another (never two at once), and speed is reported only
as ratios of wall times measured in the same run: nothing here asserts a time.

Rattle is chaotic: two solvers' trajectories part after ~20 ms, so accuracy is judged on the
ensemble-mean spectral features (log10 band PSDs) of ``M`` realisations released across the
gap, in units of their chaotic standard error (as ``tests/test_convergence.py`` does).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import multiprocessing as mp
import os
import platform
import resource
import statistics
import sys
import time
import traceback
from pathlib import Path

RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "recordings"
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

PARAM_NAMES = ("a", "T_b", "mu", "backlash", "h_min", "k_scale")


# -- helpers used in the child processes ---------------------------------------------------


def _say(msg: str) -> None:
    print(f"  [{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def _median(xs) -> float:
    return float(statistics.median(xs))


def _atol(rtol: float) -> float:
    return rtol * ATOL_PER_RTOL


def operating_points(names):
    """(name, RigSetup, truth dict) of each recording, in the order given."""
    from rattlefit.inference import rig
    from rattlefit.io.recording import read_recording

    truth = json.loads((RECORDINGS / "truth.json").read_text())
    return [(n, rig.setup(read_recording(RECORDINGS / f"{n}.h5")), truth[n]) for n in names]


def truth_params(setup, truth):
    """The RattleParams of a recording's truth (``truth.json``) on its rig ``setup``."""
    from rattlefit.physics.model import RattleParams

    return RattleParams(
        truth["a_mm"] * 1e-3,
        truth["drag_torque_Nm"],
        truth["viscosity_Pa_s"],
        setup.geometry.backlash,
    )


def _release_fractions(m: int):
    import numpy as np

    return np.linspace(-0.9, 0.9, m)


def _timed(fn, *args, **kwargs):
    """(wall time of fn(*args, **kwargs) until its outputs are ready, outputs)."""
    import jax

    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    jax.block_until_ready(out)
    return time.perf_counter() - t0, out


# -- the steps (each runs in a fresh spawned process) ----------------------------------------


def step_baseline(_args):
    import rattlefit  # noqa: F401

    peak = _peak_mib()  # before anything initialises the JAX backend
    import diffrax
    import jax
    import numpy as np
    import scipy

    return {
        "peak_mib": peak,
        "machine": {
            "cpu_count": os.cpu_count(),
            "cpu_model": _cpu_model(),
            "platform": platform.platform(),
            "python": platform.python_version(),
            "jax_backend": jax.default_backend(),
            "jax": jax.__version__,
            "diffrax": diffrax.__version__,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
        },
    }


def _cpu_model() -> str:
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
            for frac in _release_fractions(M):
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
            _say(f"reference {label:5s} {name}: median {_median(times):.2f} s")
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
            opts = _sim_options(s, rtol)
            y0s = [jnp.asarray([frac * c, 0.0]) for frac in _release_fractions(M)]
            first = None
            if str(rtol) not in compile_s:  # first call at this rtol: compile + one run
                first, _ = _timed(simulate, s.model, params, s.drive, y0=y0s[0], **opts)
            times, steps, codes, motion = [], [], [], []
            for rep in range(reps):
                for i, y0 in enumerate(y0s):
                    dt, sol = _timed(simulate, s.model, params, s.drive, y0=y0, **opts)
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
                "atol": _atol(rtol),
                "times_s": times,
                "num_steps": steps,
                "result": codes,
                "features": np.asarray(feats).tolist(),
            }
            _say(f"rattlefit rtol={rtol:g} {name}: median {_median(times) * 1e3:.0f} ms")
        out[name] = res
    return {"points": out, "compile_s": compile_s}


def _sim_options(s, rtol):
    """simulate() options of every timed run: the recording's rate, matched tolerances."""
    return dict(
        duration=DURATION, sample_rate=s.sample_rate, burn_in=BURN_IN, rtol=rtol, atol=_atol(rtol)
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
        opts = _sim_options(s, rtol)
        params = truth_params(s, truth)
        c = s.geometry.backlash / 2
        t_ref, t_rf = [], []
        for frac in _release_fractions(M)[: args["pairs"]]:
            y0 = (float(frac * c), 0.0)
            if rtol not in compiled:
                _timed(simulate, s.model, params, s.drive, y0=y0, **opts)
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
                t_rf.append(_timed(simulate, s.model, params, s.drive, y0=y0, **opts)[0])
        out[name] = {"rtol": rtol, "reference_s": t_ref, "rattlefit_s": t_rf}
        ratio = _median(t_ref) / _median(t_rf)
        _say(f"paired {name}: reference / rattlefit(rtol={rtol:g}) = {ratio:.1f}×")
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
        opts = _sim_options(s, rtol)
        params = truth_params(s, truth)
        c = s.geometry.backlash / 2
        # the single simulation in this same process, as the yardstick of the batched ones
        y_single = jnp.asarray([-0.9 * c, 0.0])
        single = (simulate, s.model, params, s.drive)
        if ("single", rtol) not in compiled:
            _timed(*single, y0=y_single, **opts)
            compiled.add(("single", rtol))
        t_single = [_timed(*single, y0=y_single, **opts)[0] for _ in range(3)]
        res = {"rtol": rtol, "single_s": _median(t_single)}
        for b in BATCH_SIZES:
            pb = broadcast_params(params, b)
            y0 = jnp.stack([jnp.asarray(_release_fractions(b)) * c, jnp.zeros(b)], axis=1)
            for mode in BATCH_MODES:
                run = (simulate_batch, s.model, pb, s.drive)
                key = (b, mode, rtol)
                first = None
                if key not in compiled:
                    first, _ = _timed(*run, y0=y0, batch=mode, **opts)
                    compiled.add(key)
                times = []
                for _ in range(args["reps"]):
                    dt, sol = _timed(*run, y0=y0, batch=mode, **opts)
                    times.append(dt)
                total = _median(times)
                res[f"{mode}{b}"] = {
                    "B": b,
                    "mode": mode,
                    "total_s": total,
                    "per_member_s": total / b,
                    "compile_s": None if first is None else first - total,
                    "all_success": bool(np.all(np.asarray(sol.success))),
                    "num_steps_total": int(np.sum(np.asarray(sol.num_steps))),
                }
                _say(f"batch {mode} B={b} {name}: {total / b * 1e3:.0f} ms per member")
        out[name] = res
    return {"points": out}


def _params_from(v):
    """RattleParams from the vector (a, T_b, μ, backlash, h_min, stiffness scale)."""
    from rattlefit.physics.model import RattleParams

    return RattleParams(v[0], v[1], v[2], v[3], min_film=v[4], stiffness_scale=v[5])


def _forward_features(s, params, y0, opts):
    """One forward simulation as a user runs it: simulate(), then the features."""
    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate

    sol = simulate(s.model, params, s.drive, y0=y0, sample_rate=s.sample_rate, **opts)
    return spectral_features(sol.relative_motion, s.bands, noise_floor=s.noise_floor)


def _fd_features(s, params, y0, opts):
    """Features of a batch of members (one simulate_batch call, batch='lockstep', as the fit
    simulates), and the batch."""
    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate_batch

    sol = simulate_batch(
        s.model, params, s.drive, y0=y0, batch="lockstep", sample_rate=s.sample_rate, **opts
    )
    return spectral_features(sol.relative_motion, s.bands, noise_floor=s.noise_floor), sol


def _jacobian_functions():
    """Jitted features(scale) and its jacfwd, built once so every point reuses the compile."""
    import jax

    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import simulate

    def feats(scale, base, model, drive, y0, noise_floor, bands):
        # features as a function of multiplicative factors on the six parameters: the
        # Jacobian at ones is d features / d log p (dimensionless)
        sol = simulate(
            model,
            _params_from(base * scale),
            drive,
            y0=y0,
            duration=DURATION,
            sample_rate=bands.sample_rate,
            burn_in=BURN_IN,
            rtol=FIT_RTOL,
            atol=_atol(FIT_RTOL),
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
    opts = dict(duration=DURATION, burn_in=BURN_IN, rtol=FIT_RTOL, atol=_atol(FIT_RTOL))
    forward_fn, jac_fn = _jacobian_functions()
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
        direct = (_forward_features, s, _params_from(base), y_single, opts)
        first_f = _timed(*direct)[0] if warm else None
        t_fwd = _median([_timed(*direct)[0] for _ in range(max(reps, 3))])
        # the same inside an outer jax.jit with everything traced (as jacfwd runs it)
        first_fj = _timed(forward_fn, one, *fixed, bands=s.bands)[0] if warm else None
        t_fwd_jit = _median(
            [_timed(forward_fn, one, *fixed, bands=s.bands)[0] for _ in range(max(reps, 3))]
        )
        first_j = _timed(jac_fn, one, *fixed, bands=s.bands)[0] if warm else None
        t_jac_all = []
        for _ in range(reps):
            dt, j = _timed(jac_fn, one, *fixed, bands=s.bands)
            t_jac_all.append(dt)
        t_jac = _median(t_jac_all)
        j = np.asarray(j)

        # the fit's finite-difference ensemble Jacobian: (2P+1)·M members in one call
        steps = np.zeros((2 * P_FD + 1, P_FD))
        for i in range(P_FD):
            steps[1 + 2 * i, i], steps[2 + 2 * i, i] = FD_LOG_STEP, -FD_LOG_STEP
        values = np.asarray(base)[None] * np.exp(steps)  # (2P+1, P)
        rows = np.repeat(values, M, axis=0)  # (2P+1)·M members
        fracs = np.tile(_release_fractions(M), 2 * P_FD + 1)
        y0 = np.stack([fracs * rows[:, 3] / 2, np.zeros(len(fracs))], axis=1)
        pb = _params_from(jnp.asarray(rows.T))
        fd = (_fd_features, s, pb, jnp.asarray(y0), opts)
        first_fd = _timed(*fd)[0] if warm else None
        t_fd, (f_fd, sol) = _timed(*fd)  # (2P+1)·M simulations: one run suffices
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
        _say(
            f"jacobian {name}: jacfwd {t_jac / t_fwd:.1f}× forward (max|J| "
            f"{out[name]['jacfwd_max_abs']}), FD {t_fd / t_fwd:.1f}× forward"
        )
    return {"points": out, "compile_s": compile_s}


def _guarded(step):
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


def _timed_identify(file: str):
    """(recording, identify([recording], FitOptions()) result, wall time with compilation)."""
    from rattlefit.inference.identify import identify
    from rattlefit.inference.options import FitOptions
    from rattlefit.io.recording import read_recording

    rec = read_recording(RECORDINGS / file)
    t0 = time.perf_counter()
    result = identify([rec], FitOptions(), progress=lambda msg: _say(f"identify: {msg}"))
    return rec, result, time.perf_counter() - t0


@_guarded
def step_identify(args):
    """One identification of a 3-s recording, compile included (guarded: a failure is
    reported in the results, not raised)."""
    _, result, wall = _timed_identify(args["file"])
    params = {}
    for k, v in result.parameters.items():
        params[k] = {
            "estimate": v.estimate,
            "lower": v.lower,
            "upper": v.upper,
            "unit": v.unit,
            "identified": v.identified,
        }
    return {
        "wall_s": wall,
        "success": bool(result.success),
        "message": str(result.message),
        "chi2": float(result.chi2),
        "dof": int(result.dof),
        "parameters": params,
    }


@_guarded
def step_posterior(args):
    """identify() then sample() of the same 3-s recording: wall times, ESS, ESS per second."""
    from rattlefit.inference.options import FitOptions
    from rattlefit.inference.posterior import SampleOptions, sample

    rec, fit, t_fit = _timed_identify(args["file"])
    t0 = time.perf_counter()
    post = sample(
        [rec],
        fit,
        SampleOptions(n_steps=args["steps"], seed=0),
        progress=lambda msg: _say(f"sample: {msg}"),
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


@_guarded
def step_diagnose(args):
    """diagnose() of a 3-s recording fitting every effect of the catalogue (``every_effect``:
    the worst case, also the effects its findings rule out): wall time, identify included."""
    from rattlefit.diagnosis.diagnose import DiagnoseOptions, diagnose
    from rattlefit.io.recording import read_recording

    rec = read_recording(RECORDINGS / args["file"])
    t0 = time.perf_counter()
    options = DiagnoseOptions(every_effect=True)
    diag = diagnose([rec], options, progress=lambda msg: _say(f"diagnose: {msg}"))
    wall = time.perf_counter() - t0
    return {
        "wall_s": wall,
        "identify_s": diag.baseline.wall_time,
        "chi2": diag.baseline.chi2,
        "dof": diag.baseline.dof,
        "gap_chi2": diag.gap_chi2[0],
        "verdict": diag.verdict.label,
        "sentence": diag.verdict.sentence,
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


def _child(step: str, args: dict) -> dict:
    import rattlefit

    # one JAX device per core (as the CLI does): batches and identify use every core
    devices = rattlefit.use_cpu_cores()
    t0 = time.perf_counter()
    result = STEPS[step](args)
    result.setdefault("devices", devices)
    result.setdefault("peak_mib", _peak_mib())
    result["step_wall_s"] = time.perf_counter() - t0
    return result


def run_step(step: str, args: dict) -> dict:
    """Run one step in a fresh spawned process; its result carries its own peak RSS."""
    print(f"→ {step} …", file=sys.stderr, flush=True)
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        return pool.apply(_child, (step, args))


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
    return _median(e["reference_s"]) / _median(e["rattlefit_s"])


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
        "rattlefit.use_cpu_cores), "
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
        t_ref = _median(ref["tight"]["times_s"])
        t_loose = _median(ref["loose"]["times_s"])
        times = {r: _median(fwd[str(r)]["times_s"]) for r in RTOLS}
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
        t_ref = _median(res["reference"]["points"][name]["tight"]["times_s"])
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
        + ", ".join(f"{k}: {_median(v):.2f} s" for k, v in compile_rows.items())
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
            f"   wall {idf['wall_s']:.1f} s; success={idf['success']} ({idf['message']}); "
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one operating point, fewer repetitions")
    ap.add_argument("--identify", action="store_true", help="also time one identify() run")
    ap.add_argument(
        "--posterior",
        nargs="?",
        type=int,
        const=POSTERIOR_STEPS,
        default=None,
        metavar="STEPS",
        help=f"also time a posterior (identify + a chain of STEPS, default {POSTERIOR_STEPS})",
    )
    ap.add_argument(
        "--diagnose",
        action="store_true",
        help=f"also time one diagnose() of {DIAGNOSE_RECORDING} (identify + every effect)",
    )
    ap.add_argument("--json", type=Path, help="write all results to this JSON file")
    args = ap.parse_args(argv)

    if not RECORDINGS.is_dir():
        print(f"the shared recordings are not at {RECORDINGS}", file=sys.stderr)
        return 2
    if args.quick:
        names = [QUICK_RECORDING]
    else:
        names = sorted(p.stem for p in RECORDINGS.glob("*.h5"))
    reps = 1 if args.quick else 3

    t0 = time.perf_counter()
    res: dict = {"quick": args.quick, "names": names, "memory": {}}
    res["load_before"] = os.getloadavg()
    base = run_step("baseline", {})
    res["machine"] = base["machine"]
    res["devices"] = base["devices"]
    res["memory"]["baseline"] = base["peak_mib"]

    for step, step_args in (
        ("reference", {"names": names}),
        ("forward", {"names": names, "reps": reps}),
    ):
        res[step] = run_step(step, step_args)
        res["memory"][step] = res[step]["peak_mib"]
    res["match"] = {
        n: match(res["reference"]["points"][n], res["forward"]["points"][n]) for n in names
    }
    rtol = {n: res["match"][n]["rtol"] for n in names}
    res["paired"] = run_step(
        "paired", {"names": names, "rtol": rtol, "pairs": 2 if args.quick else M}
    )
    res["memory"]["paired"] = res["paired"]["peak_mib"]
    res["batch"] = run_step("batch", {"names": names, "rtol": rtol, "reps": 1})
    res["memory"]["batch"] = res["batch"]["peak_mib"]
    res["jacobian"] = run_step("jacobian", {"names": names, "reps": 2 if args.quick else 3})
    res["memory"]["jacobian"] = res["jacobian"]["peak_mib"]
    if args.identify:
        res["identify"] = run_step("identify", {"file": IDENTIFY_RECORDING})
        res["memory"]["identify"] = res["identify"]["peak_mib"]
    if args.posterior:
        res["posterior"] = run_step(
            "posterior", {"file": IDENTIFY_RECORDING, "steps": args.posterior}
        )
        res["memory"]["posterior"] = res["posterior"]["peak_mib"]
    if args.diagnose:
        res["diagnose"] = run_step("diagnose", {"file": DIAGNOSE_RECORDING})
        res["memory"]["diagnose"] = res["diagnose"]["peak_mib"]
    res["wall_s"] = time.perf_counter() - t0
    res["load_after"] = os.getloadavg()

    text = report(res)
    print(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=1, default=float))
        print(f"results written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

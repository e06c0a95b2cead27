"""Solve the rattle model with diffrax and sample it like the rig's encoders.

``simulate(model, params, drive, *, duration, ...)`` integrates the smoothed one-dof model with
an adaptive explicit Runge–Kutta method (Tsit5, PID step-size control) and returns the relative
motion Δθ* at the encoder rate. Failures never pass silently: the :class:`Solution` carries the
solver's result code, and :func:`raise_if_failed` turns a failure into a
:class:`~rattlefit.errors.SolverError`. Differentiation is forward mode by default
(``diffrax.ForwardMode``), which suits Jacobians with few parameters (Levenberg–Marquardt).
"""

from __future__ import annotations

import functools
import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ..config import require_x64
from ..errors import SolverError
from ..physics.drive import Drive
from ..physics.model import (
    RattleModel,
    RattleParams,
    share_stiffness_tables,
    with_stiffness_tables,
)
from .lockstep import FIRST_STEP, ICOEFF, PCOEFF, solve_lockstep
from .parallel import map_blocks, map_rows


class Solution(eqx.Module):
    """A simulated recording (arrays may carry leading batch axes of the parameters).

    Attributes
    ----------
    time : sample times, s (0 … duration − 1/sample_rate).
    q : relative pitch-circle displacement r2θ2 − r1θ1, m.
    velocity : its rate, m/s.
    relative_motion : Δθ* = −q/r1 of eq. (6), rad.
    theta1 : primary-shaft angle θ1 at the samples, rad.
    result : diffrax result code (0 = success).
    num_steps : accepted + rejected solver steps.
    """

    time: Float[Array, " N"]
    q: Float[Array, "*batch N"]
    velocity: Float[Array, "*batch N"]
    relative_motion: Float[Array, "*batch N"]
    theta1: Float[Array, " N"]
    result: Int[Array, "*batch"]
    num_steps: Int[Array, "*batch"]

    @property
    def success(self) -> Array:
        """True where the solve succeeded."""
        return self.result == 0


@functools.cache
def _adjoint(kind: str):
    if kind == "forward":
        return diffrax.ForwardMode()
    if kind == "reverse":
        return diffrax.RecursiveCheckpointAdjoint()
    raise ValueError(f"unknown sensitivity {kind!r}: use 'forward' or 'reverse'")


def step_controller(rtol: float, atol: float | tuple[float, ...]) -> diffrax.PIDController:
    """The PI step-size controller of :func:`simulate` at ``rtol`` and ``atol`` (one number,
    or one per state component of the model's full state)."""
    atol = atol if isinstance(atol, float) else jnp.asarray(atol)
    return diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=PCOEFF, icoeff=ICOEFF)


def _solve(
    model: RattleModel,
    params: RattleParams,
    drive: Drive,
    y0: Float[Array, " 2"],
    *,
    n_samples: int,
    sample_rate: float,
    burn_in: float,
    rtol: float,
    atol: float | tuple[float, float],
    max_steps: int,
    sensitivity: str,
):
    ts = jnp.arange(n_samples) / sample_rate
    atol = model.state_atol(atol)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(model.vector_field),
        diffrax.Tsit5(),
        t0=-burn_in,
        t1=ts[-1],
        dt0=FIRST_STEP,
        y0=model.full_state(y0),
        args=(params, drive),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=step_controller(rtol, atol),
        max_steps=max_steps,
        adjoint=_adjoint(sensitivity),
        throw=False,
    )
    ok = sol.result == diffrax.RESULTS.successful
    # After a failure diffrax leaves non-finite fill values: replace them by zeros so that no
    # NaN leaks into features or gradients; the result code says the solve is invalid.
    ys = jnp.where(ok, jnp.nan_to_num(sol.ys, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
    theta1 = jax.vmap(drive.angle)(ts)
    code = jnp.where(ok, 0, 1 + jnp.asarray(sol.result._value, dtype=int))
    return Solution(
        ts, ys[:, 0], ys[:, 1], -ys[:, 0] / model.r1, theta1, code, sol.stats["num_steps"]
    )


_solve_one = eqx.filter_jit(_solve)


def solve_rows(
    models: RattleModel,
    params: RattleParams,
    drives: Drive,
    y0: Float[Array, "B 2"],
    *,
    n_samples: int,
    sample_rate: float,
    burn_in: float,
    rtol: float,
    atol: float | tuple[float, float],
    max_steps: int,
    sensitivity: str = "forward",
    stiffness_tables: Float[Array, "T 2 n"] | None = None,
) -> Solution:
    """B solves stepped together by :func:`~rattlefit.simulation.lockstep.solve_lockstep`
    (traceable).

    Every array leaf of ``models``, ``params`` and ``drives`` has the leading axis B: each
    row may be another gear pair, parameter set and drive. With ``stiffness_tables`` the
    rows' models come from :func:`~rattlefit.physics.model.share_stiffness_tables`: each reads its
    stiffness table out of that shared stack (much faster than a copy per row). The
    :class:`Solution` has the axis B on every field (``time`` and ``theta1`` included).
    Forward-mode differentiable only.
    """
    if sensitivity != "forward":
        raise ValueError("the lockstep batch is forward-mode differentiable only")

    def field(t, y, row):
        model, p, drive = row
        return with_stiffness_tables(model, stiffness_tables).vector_field(t, y, (p, drive))

    ys, steps, result = solve_lockstep(
        field,
        models.full_state(y0),
        (models, params, drives),
        t0=-burn_in,
        n_samples=n_samples,
        sample_rate=sample_rate,
        rtol=rtol,
        atol=models.state_atol(atol),
        max_steps=max_steps,
    )
    ts = jnp.arange(n_samples) / sample_rate
    # the harmonics by recurrence (two transcendentals a sample, not two per harmonic)
    theta1 = jax.vmap(lambda d: jax.vmap(lambda t: d.angle_and_acceleration(t)[0])(ts))(drives)
    q, v = ys[..., 0], ys[..., 1]
    return Solution(
        jnp.broadcast_to(ts, q.shape), q, v, -q / models.r1[:, None], theta1, result, steps
    )


@eqx.filter_jit
def _solve_many(model, params, drive, y0, *, batch: str, **static):
    if batch == "lockstep":
        size = y0.shape[0]
        repeat = lambda x: jnp.broadcast_to(x, (size, *jnp.shape(x)))  # noqa: E731
        # one stiffness table for all rows, read through table_row 0 (not a copy per row)
        untabled, tables = share_stiffness_tables(jax.tree_util.tree_map(lambda x: x[None], model))
        untabled = jax.tree_util.tree_map(lambda x: x[0], untabled)
        shared = jax.tree_util.tree_map(repeat, (untabled, drive))
        rows = (shared[0], params, shared[1], y0)
        return map_blocks(lambda r: solve_rows(*r, stiffness_tables=tables, **static), rows)
    one = lambda p, y: _solve(model, p, drive, y, **static)  # noqa: E731
    if batch == "vmap":
        return jax.vmap(one)(params, y0)
    return map_rows(lambda py: one(*py), (params, y0))


def initial_state(model: RattleModel, params: RattleParams) -> Float[Array, " 2"]:
    """At rest on the drive flank (where the drag torque pushes the driven gear), m and m/s."""
    return jnp.stack([-0.5 * params.backlash, jnp.zeros_like(params.backlash)])


def simulate(
    model: RattleModel,
    params: RattleParams,
    drive: Drive,
    *,
    duration: float = 3.0,
    sample_rate: float = 10_000.0,
    burn_in: float = 0.5,
    rtol: float = 1e-6,
    atol: float | tuple[float, float] = 1e-9,
    max_steps: int | None = None,
    sensitivity: str = "forward",
    y0: Float[Array, " 2"] | None = None,
) -> Solution:
    """Simulate Δθ*(t) of one parameter set, sampled like the rig.

    Parameters
    ----------
    model : the gear pair's model (:meth:`RattleModel.from_geometry`).
    params : physical parameters (scalars; use :func:`simulate_batch` for a batch).
    drive : primary-shaft motion.
    duration : recorded time, s; samples at k / sample_rate for k < duration·sample_rate.
    sample_rate : encoder trigger rate, Hz.
    burn_in : simulated time before the first sample, s, so that the start-up transient
        (released at rest on the drive flank) has decayed.
    rtol, atol : tolerances of the PID step-size controller; ``atol`` applies to q (m) and
        v (m/s) alike, or is a pair (q, v) (:func:`absolute_tolerances` gives the fit's).
    max_steps : solver step budget; exceeding it is a failure reported in ``result``.
        Default :func:`step_budget` (200,000 up to 3.5 s simulated, proportionally more
        beyond).
    sensitivity : ``"forward"`` (forward-mode derivatives, for Jacobians) or ``"reverse"``.
    y0 : initial (q, v) at ``-burn_in`` (effects with a state of their own start it at zero),
        or the full state; default at rest on the drive flank.

    Raises :class:`~rattlefit.RattlefitError` when JAX's 64-bit mode is off
    (:func:`rattlefit.configure`).
    """
    require_x64("simulate")
    n = round(duration * sample_rate)
    if n < 2:
        raise ValueError(f"duration {duration} s gives fewer than two samples")
    if y0 is None:
        y0 = initial_state(model, params)
    return _solve_one(
        model,
        params,
        drive,
        jnp.asarray(y0, dtype=float),
        **static_options(duration, sample_rate, burn_in, rtol, atol, max_steps, sensitivity),
    )


#: Characteristic sizes of the state, (q in m, v in m/s), where the flanks have an oil film: the
#: fit's absolute tolerances are its ``rtol`` times these (:func:`absolute_tolerances`). 1 mm is
#: a few backlashes; 30 mm/s is the rattle's impact velocity (the median |v| of a mild-rattle
#: step in flight is 15–20 mm/s). A tighter velocity scale makes the controller resolve
#: fluctuations of a gear resting on its film that move no feature; a looser one moves the band
#: features (``benchmarks/state_tolerance.py`` measures both against a tight reference).
STATE_SCALES = (1e-3, 3e-2)
#: The same for dry flanks: the velocity held as tightly as the position. Without a film to
#: rest on, a dry pair's steps are set by its impacts, so a looser velocity tolerance saves no
#: steps, and what a dry recording is fitted and diagnosed on is the impact itself, where the
#: velocity reverses under the mesh force and flank friction acts: a looser velocity tolerance
#: blurs exactly that (the withheld-friction diagnosis of ``tests/test_diagnose.py`` then names
#: run-out instead of friction).
DRY_STATE_SCALES = (1e-3, 1e-3)


def absolute_tolerances(rtol: float, lubrications=()) -> tuple[float, float]:
    """(atol of q in m, atol of v in m/s) for the relative tolerance ``rtol``: ``rtol`` times
    :data:`STATE_SCALES`, or :data:`DRY_STATE_SCALES` if any of ``lubrications`` (the
    recordings' ``operating.lubrication``) is ``"dry"``."""
    scales = DRY_STATE_SCALES if "dry" in tuple(lubrications) else STATE_SCALES
    return tuple(float(rtol) * s for s in scales)


def _atol_option(atol) -> float | tuple[float, ...]:
    """``atol`` as a static option: one float, or a tuple of one per state component."""
    if np.ndim(atol) == 0:
        return float(atol)
    atol = tuple(float(x) for x in np.asarray(atol).ravel())
    if len(atol) != 2:
        raise ValueError(f"atol must be one number or two (q in m, v in m/s), got {atol}")
    return atol


#: Solver steps allowed per 3.5 s simulated (a 3 s recording and its burn-in); longer
#: simulations get a proportionally larger budget (:func:`step_budget`).
STEPS_PER_3_5_S = 200_000


def step_budget(duration: float, burn_in: float) -> int:
    """The default step budget of a simulation of ``duration`` s after ``burn_in`` s:
    :data:`STEPS_PER_3_5_S`, scaled up with the simulated time beyond 3.5 s, so that a 30 s
    recording is not refused for the steps a 3 s one may take."""
    return math.ceil(STEPS_PER_3_5_S * max(1.0, (duration + burn_in) / 3.5))


def static_options(duration, sample_rate, burn_in, rtol, atol, max_steps, sensitivity):
    """The solver options of :func:`simulate` as the hashable keyword arguments of its compiled
    core: ``n_samples = round(duration · sample_rate)`` and the rest as Python floats/ints
    (``atol`` one float or a (q, v) pair). Raises ``ValueError`` for fewer than two samples or
    an ``atol`` of another length."""
    n = round(duration * sample_rate)
    if n < 2:
        raise ValueError(f"duration {duration} s gives fewer than two samples")
    return dict(
        n_samples=n,
        sample_rate=float(sample_rate),
        burn_in=float(burn_in),
        rtol=float(rtol),
        atol=_atol_option(atol),
        max_steps=int(step_budget(duration, burn_in) if max_steps is None else max_steps),
        sensitivity=sensitivity,
    )


def simulate_batch(
    model: RattleModel,
    params: RattleParams,
    drive: Drive,
    *,
    y0: Float[Array, "B 2"] | None = None,
    batch: str = "map",
    duration: float = 3.0,
    sample_rate: float = 10_000.0,
    burn_in: float = 0.5,
    rtol: float = 1e-6,
    atol: float | tuple[float, float] = 1e-9,
    max_steps: int | None = None,
    sensitivity: str = "forward",
) -> Solution:
    """:func:`simulate` for B parameter sets at once (one compiled call).

    Every leaf of ``params`` must have a leading axis of size B (see :func:`broadcast_params`);
    ``y0`` (B, 2) gives each member its own initial state (default: at rest on the drive
    flank). ``batch="map"`` runs the members one after another inside one compiled loop
    (``jax.lax.map``) on each local device, the batch split evenly over the devices (see
    :func:`rattlefit.use_cpu_cores` to give JAX one device per CPU core). That measures 3×
    faster than ``"vmap"`` on a CPU because a vmapped adaptive solve steps every member until
    the slowest has finished; on a GPU ``"vmap"`` is the natural choice. ``"lockstep"``
    steps the members together with rattlefit's own Tsit5 (:mod:`rattlefit.simulation.lockstep`),
    vectorised over each device's share: 2–5× faster per member than ``"map"`` on a CPU,
    forward-mode differentiable only, and the integrator every fit uses; a member's
    trajectory does not depend on its batch while each device's share is a multiple of 4
    members (other sizes compile to code that rounds differently, and chaos makes that
    another realisation). Outputs have shape (B, N); ``time`` and ``theta1`` are shared.
    """
    require_x64("simulate_batch")
    if batch not in ("map", "vmap", "lockstep"):
        raise ValueError(f"batch must be 'map', 'vmap' or 'lockstep', got {batch!r}")
    if y0 is None:
        y0 = jax.vmap(lambda p: initial_state(model, p))(params)
    sols = _solve_many(
        model,
        params,
        drive,
        jnp.asarray(y0, dtype=float),
        batch=batch,
        **static_options(duration, sample_rate, burn_in, rtol, atol, max_steps, sensitivity),
    )
    return eqx.tree_at(lambda s: (s.time, s.theta1), sols, (sols.time[0], sols.theta1[0]))


def broadcast_params(params: RattleParams, size: int) -> RattleParams:
    """Give every leaf of ``params`` a leading axis of ``size`` (scalar leaves are repeated)."""

    def grow(x):
        x = jnp.asarray(x)
        return x if (x.ndim and x.shape[0] == size) else jnp.broadcast_to(x, (size, *x.shape))

    return jax.tree_util.tree_map(grow, params)


def raise_if_failed(solution: Solution) -> Solution:
    """Return ``solution`` or raise :class:`SolverError` if any solve in it failed."""
    code = np.asarray(solution.result)
    if np.any(code != 0):
        bad = int(np.sum(code != 0))
        raise SolverError(
            f"{bad} of {code.size} simulation(s) failed (diffrax result code "
            f"{sorted(set((code[code != 0] - 1).tolist()))}); try a larger max_steps or looser rtol"
        )
    return solution


def _encoder_readings(q, theta1, model: RattleModel, counts_per_rev, phase):
    """Both encoders' count readings ``floor(θ·N/2π + phase)`` (float arrays, counts).

    θ2 = (q + r1·θ1) / r2; ``phase`` (..., 2) is each encoder's count phase (fraction of a
    count at zero angle), one pair per batch member of ``q``. Pure jnp, so that it traces
    inside the fit's compiled feature map.
    """
    phase = jnp.asarray(phase, dtype=float)
    theta2 = (q + model.r1 * theta1) / model.r2
    scale = counts_per_rev / (2.0 * jnp.pi)
    return (
        jnp.floor(theta1 * scale + phase[..., 0, None]),
        jnp.floor(theta2 * scale + phase[..., 1, None]),
    )


def encoder_counts(
    solution: Solution, model: RattleModel, *, counts_per_rev: int = 40_000
) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative counts (primary, secondary) a rig would latch for this solution (int64).

    θ2 = (q + r1·θ1) / r2; each angle is quantised by ``floor(θ·counts_per_rev / 2π)``, as an
    incremental encoder with quadrature decoding does.
    """
    primary, secondary = _encoder_readings(
        jnp.asarray(solution.q, dtype=float),
        jnp.asarray(solution.theta1, dtype=float),
        model,
        counts_per_rev,
        np.zeros(2),
    )
    return np.asarray(primary).astype(np.int64), np.asarray(secondary).astype(np.int64)


def quantised_relative_motion(
    solution: Solution,
    model: RattleModel,
    *,
    counts_per_rev: int = 40_000,
    phase: Float[Array, "*batch 2"] | None = None,
) -> Array:
    """Δθ* as the rig measures it: from the two quantised encoders, eq. (6), rad.

    θ1 and θ2 are quantised as :func:`encoder_counts` does (each encoder offset by ``phase``
    (..., 2), a fraction of a count, default 0) and combined as ``θ1 − θ2·r2/r1``, relative
    to the first sample. The error has the standard deviation of eq. (8) but is not white:
    while the count rate beats with the sample rate (33⅓ counts per sample at 500 rpm and
    10 kHz) it concentrates in lines; ``FitOptions(quantisation="encoders")`` reads the fit's
    simulations this way instead of adding eq. (8)'s white floor. Traceable (jnp);
    ``solution`` may carry batch axes.
    """
    primary, secondary = _encoder_readings(
        solution.q,
        solution.theta1,
        model,
        counts_per_rev,
        np.zeros(2) if phase is None else phase,
    )
    step = 2.0 * jnp.pi / counts_per_rev
    ratio = model.r2 / model.r1
    return step * (primary - primary[..., :1]) - step * ratio * (secondary - secondary[..., :1])

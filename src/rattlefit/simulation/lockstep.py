"""A batch of adaptive Tsit5 solves stepped together, sampled by dense output.

diffrax solves one trajectory at a time here: a batch either runs its members one after
another (``jax.lax.map``) or, vmapped, drags diffrax's per-step bookkeeping (saving into a
time grid, the controller's state) through every member. On a CPU that bookkeeping, not the
vector field, dominates a step of this small model. :func:`solve_lockstep` is a lean
integrator for the batches the fit needs (many realisations and parameter points at once):

* the Tsit5 tableau (taken from :class:`diffrax.Tsit5`, so the method is the same, FSAL
  included) with diffrax's PI step-size control (``pcoeff``, ``icoeff``, error order 5, the
  scaled error ``|err| / (atol + rtol·max(|y0|, |y1|))`` in the RMS norm);
* every member keeps its own time and step size; one loop iteration advances every member
  that has not finished by one attempted step, so the iteration count is the longest
  member's step count, and all the arithmetic is vectorised over the batch;
* the samples at ``k / sample_rate`` inside an accepted step are filled by Tsit5's own
  fourth-order interpolant (the one diffrax uses for ``SaveAt(ts=...)``); a step never spans
  more than ``samples_per_step`` sample intervals.

Its samples agree with diffrax's Tsit5 to within the tolerances (the band features within
their chaotic spread), at a fraction of the time per member. It is forward-mode
differentiable (``jax.lax.while_loop``) but not reverse-mode:
:func:`rattlefit.simulation.solve.simulate` (diffrax) is the differentiable path.
"""

from __future__ import annotations

from collections.abc import Callable

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

_TABLEAU = diffrax.Tsit5.tableau
_C = tuple(float(c) for c in _TABLEAU.c)
_A = tuple(tuple(float(x) for x in row) for row in _TABLEAU.a_lower)
_B_SOL = tuple(float(x) for x in _TABLEAU.b_sol)
_B_ERR = tuple(float(x) for x in _TABLEAU.b_error)

#: Result codes of :func:`solve_lockstep`.
SUCCESS, STEP_LIMIT = 0, 1
#: The step-size control of every simulation (this module's and diffrax's in
#: :func:`~rattlefit.simulation.solve.simulate`): the first step tried, s, and the PI
#: controller's proportional and integral coefficients.
FIRST_STEP = 1e-5
PCOEFF, ICOEFF = 0.3, 0.4


def _dense_monomials() -> tuple[tuple[float, ...], ...]:
    """Tsit5's free interpolant (Tsitouras 2011; the polynomials of diffrax's ``Tsit5``
    interpolation, in their factored form) expanded in powers of the step fraction s:
    ``b_i(s) = Σ_p M[p][i] s^(p+1)``, p = 0 … 3, i = 1 … 7 (every b_i vanishes at s = 0)."""
    s2 = [0.0, 0.0, 1.0]
    factored = [
        ([-1.0530884977290216], [0.0, 1.0], [-1.3299890189751412, 1.0],
         [0.7139816917074209, -1.4364028541716351, 1.0]),
        ([0.1017], s2, [1.2949852507374631, -2.1966568338249754, 1.0]),
        ([2.490627285651252793], s2, [1.57803468208092486, -2.38535645472061657, 1.0]),
        ([-16.54810288924490272], [-1.21712927295533244, 1.0], [-0.61620406037800089, 1.0], s2),
        ([47.37952196281928122], [-1.203071208372362603, 1.0], [-0.658047292653547382, 1.0], s2),
        ([-34.87065786149660974], [-1.2, 1.0], [-0.666666666666666667, 1.0], s2),
        ([2.5], [-1.0, 1.0], [-0.6, 1.0], s2),
    ]  # fmt: skip
    columns = []
    for factors in factored:
        coeffs = np.array([1.0])
        for factor in factors:
            coeffs = np.polynomial.polynomial.polymul(coeffs, factor)
        columns.append(np.pad(coeffs, (0, 5 - coeffs.size))[1:])
    return tuple(tuple(float(x) for x in row) for row in np.array(columns).T)


_DENSE = _dense_monomials()


def dense_output(y, kh, s):
    """Tsit5's fourth-order dense output ``y + Σ_i b_i(s) h k_i`` at step fractions ``s``
    (B, S), from the step's start ``y`` (B, D) and its stages times the step ``kh`` (7 of
    (B, D)): (B, S, D).

    The stage sums are taken once a step (the coefficient of each power of s) and the
    polynomial evaluated by Horner's rule, all elementwise: written as a contraction of
    (B, S, 7) weights with the stages, XLA on a CPU would make it a batched matrix product
    through a slow library call.
    """
    powers = [_combine(row, kh)[:, None] for row in _DENSE]  # coefficients of s, …, s⁴
    s = s[..., None]
    acc = powers[3]
    for c in powers[2::-1]:
        acc = acc * s + c
    return y[:, None] + acc * s


def _combine(coeffs, ks):
    """``Σ_i coeffs[i] · ks[i]`` over the non-zero coefficients."""
    return sum(c * k for c, k in zip(coeffs, ks, strict=False) if c != 0.0)


def _tsit5_attempt(f, args, t, y, k1, h):
    """One attempted Tsit5 step of every member from ``(t, y)`` (B,), (B, D) with first stage
    ``k1`` (B, D) and step ``h`` (B,): the proposed ``y1`` (B, D), the seven stages (the last
    one is ``f(t + h, y1)``, the next step's first by FSAL) and the error estimate (B, D)."""
    hc = h[:, None]
    ks = [k1]
    for i in range(5):
        ks.append(f(t + _C[i] * h, y + hc * _combine(_A[i], ks), args))
    y1 = y + hc * _combine(_B_SOL, ks)
    ks.append(f(t + h, y1, args))
    err = hc * _combine(_B_ERR, ks)
    return y1, ks, err


def solve_lockstep(
    vector_field: Callable,
    y0: Float[Array, "B D"],
    args,
    *,
    t0: float,
    n_samples: int,
    sample_rate: float,
    rtol: float,
    atol: float | tuple[float, ...],
    dt0: float = FIRST_STEP,
    max_steps: int = 200_000,
    pcoeff: float = PCOEFF,
    icoeff: float = ICOEFF,
    samples_per_step: int = 8,
) -> tuple[Float[Array, "B N D"], Int[Array, " B"], Int[Array, " B"]]:
    """Integrate B initial-value problems from ``t0`` and sample each at ``k / sample_rate``.

    Parameters
    ----------
    vector_field : ``f(t, y, args_b) -> dy/dt`` for one member (``y`` of shape (D,)).
    y0 : initial states at ``t0``, one row per member.
    args : a pytree whose array leaves all have the leading batch axis B (member b gets
        ``args[b]``).
    t0 : start time, s (≤ 0; the first sample is at t = 0).
    n_samples : samples per member, at ``k / sample_rate``, k < n_samples.
    rtol, atol : tolerances of the PI step-size controller. ``atol`` is one number for every
        state component or one per component (D of them), in that component's units.
    dt0 : first step tried, s.
    max_steps : attempted steps per member; a member that has not reached the last sample
        by then (or whose state became non-finite, which rejects every step) fails.
    samples_per_step : the longest step, in sample intervals.

    Returns
    -------
    ``(ys, num_steps, result)``: the samples (B, N, D), attempted steps per member and a
    result code per member (:data:`SUCCESS` or :data:`STEP_LIMIT`). A failed member's samples
    after the failure are zeros.
    """
    # one trace of the vector field serves its seven calls a step (tracing each call anew
    # would dominate the cost of a first fit)
    f = jax.jit(jax.vmap(vector_field))
    y0 = jnp.asarray(y0, dtype=float)
    batch = y0.shape[0]
    atol_d = jnp.broadcast_to(jnp.asarray(atol, dtype=float), y0.shape[1:])
    order = 5.0  # Tsit5's error order as diffrax's PIDController counts it
    c_now, c_prev = (pcoeff + icoeff) / order, -pcoeff / order
    dt_max = samples_per_step / sample_rate
    t_last = (n_samples - 1) / sample_rate
    slots = jnp.arange(samples_per_step + 1)
    members = jnp.arange(batch)[:, None]
    t = jnp.full((batch,), float(t0))
    out = jnp.zeros((batch, n_samples + samples_per_step + 1, y0.shape[1]))
    init = (
        t,
        y0,
        f(t, y0, args),
        jnp.full((batch,), float(dt0)),
        jnp.ones((batch,)),  # the previous step's inverse scaled error (PI control)
        jnp.zeros((batch,), dtype=int),  # attempted steps
        jnp.zeros((batch,), dtype=int),  # next sample to fill
        out,
    )

    def running(steps, next_sample):
        return (next_sample < n_samples) & (steps < max_steps)

    def cond(carry):
        return jnp.any(running(carry[5], carry[6]))

    def step(carry):
        t, y, k1, dt, prev_inv, steps, next_sample, out = carry
        active = running(steps, next_sample)
        h = jnp.minimum(jnp.minimum(dt, dt_max), t_last - t + 1e-9)
        h = jnp.where(active, jnp.maximum(h, 1e-14), 1e-9)
        hc = h[:, None]
        y1, ks, err = _tsit5_attempt(f, args, t, y, k1, h)
        k7 = ks[6]
        scale = atol_d + rtol * jnp.maximum(jnp.abs(y), jnp.abs(y1))
        e = jnp.sqrt(jnp.mean((err / scale) ** 2, axis=-1))
        e = jnp.where(jnp.isfinite(e) & jnp.all(jnp.isfinite(y1), axis=-1), e, 1e10)
        accept = active & (e < 1.0)
        inv = 1.0 / jnp.maximum(e, 1e-10)
        factor = jnp.clip(0.9 * inv**c_now * prev_inv**c_prev, 0.2, 10.0)
        factor = jnp.where(e < 1.0, factor, jnp.minimum(factor, 0.9))
        t1 = t + h
        # dense output: the samples in (t, t1] of the accepted members
        index = next_sample[:, None] + slots[None, :]
        t_k = index / sample_rate
        inside = accept[:, None] & (t_k <= t1[:, None]) & (index < n_samples)
        s = jnp.clip((t_k - t[:, None]) / hc, 0.0, 1.0)
        y_k = dense_output(y, [hc * k for k in ks], s)  # (B, S, D)
        out = out.at[members, index].set(jnp.where(inside[..., None], y_k, out[members, index]))
        keep = accept[:, None]
        return (
            jnp.where(accept, t1, t),
            jnp.where(keep, y1, y),
            jnp.where(keep, k7, k1),
            jnp.where(active, h * factor, dt),
            jnp.where(accept, inv, prev_inv),
            steps + active,
            next_sample + jnp.sum(inside, axis=1),
            out,
        )

    final = jax.lax.while_loop(cond, step, init)
    steps, next_sample, out = final[5], final[6], final[7]
    result = jnp.where(next_sample >= n_samples, SUCCESS, STEP_LIMIT)
    return out[:, :n_samples], steps, result

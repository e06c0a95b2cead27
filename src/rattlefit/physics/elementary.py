"""Sine, cosine and arctangent as polynomials that XLA vectorises on a CPU.

XLA compiles ``jnp.sin``, ``jnp.cos`` and ``jnp.arctan`` on a CPU to one library call per
element, while sums and products of a batch run as vector instructions, several times
faster. The vector field calls the drive's sine and cosine and the squeeze film's arctangent
six times a Tsit5 step for every row of a batch, so these library calls would be a large share
of a lockstep step (``benchmarks/elementwise_cost.py`` times both forms).

Both are accurate to a few units in the last place over their whole range (tests against
numpy); they round differently from the library calls, which chaos turns into another
realisation of every seeded simulation, not into another model.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

# Taylor coefficients of sin r / r and cos r in r², for |r| ≤ π/4: the first omitted terms,
# r¹⁷/17! and r¹⁸/18!, are below 3e-16 there
_SIN = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(8))
_COS = tuple((-1) ** k / math.factorial(2 * k) for k in range(9))

# Cephes' atan (S. L. Moshier): a rational function of x² on |x| ≤ 0.66, after reducing
# x > tan(3π/8) to π/2 + atan(−1/x) and 0.66 < x ≤ tan(3π/8) to π/4 + atan((x − 1)/(x + 1));
# relative error about 1e-16
_ATAN_P = (
    -8.750608600031904122785e-1,
    -1.615753718733365076637e1,
    -7.500855792314704667340e1,
    -1.228866684490136173410e2,
    -6.485021904942025371773e1,
)
_ATAN_Q = (
    2.485846490142306297962e1,
    1.650270098316988542046e2,
    4.328810604912902668951e2,
    4.853903996359136964868e2,
    1.945506571482613964425e2,
)
_TAN_3PI_8 = 2.41421356237309504880
_MOREBITS = 6.123233995736765886130e-17  # π/2 − fl(π/2)


def _horner(coeffs, x):
    acc = coeffs[-1]
    for c in coeffs[-2::-1]:
        acc = acc * x + c
    return acc


def sin_cos_cycles(u: Float[ArrayLike, "*shape"]) -> tuple[Array, Array]:
    """``(sin 2πu, cos 2πu)`` of an angle ``u`` in cycles (turns).

    The angle is reduced to the nearest quarter turn exactly (u − n/4 is exact in binary
    floating point for |u| < 2⁵⁰), then r = 2π(u − n/4) ∈ [−π/4, π/4] goes into the Taylor
    polynomials. In cycles, a drive's phase f·t needs no reduction by an inexact 2π.
    """
    u = jnp.asarray(u, dtype=float)
    n = jnp.round(4.0 * u)
    r = (u - 0.25 * n) * (2.0 * math.pi)
    r2 = r * r
    s = r * _horner(_SIN, r2)
    c = _horner(_COS, r2)
    quadrant = n - 4.0 * jnp.floor(0.25 * n)  # n mod 4, in {0, 1, 2, 3}
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sin = jnp.where(odd, c, s)
    cos = jnp.where(odd, s, c)
    sin = jnp.where(quadrant >= 2.0, -sin, sin)
    cos = jnp.where((quadrant == 1.0) | (quadrant == 2.0), -cos, cos)
    return sin, cos


def arctan(x: Float[ArrayLike, "*shape"]) -> Array:
    """arctan x, rad, for any real x (odd: computed on |x|)."""
    x = jnp.asarray(x, dtype=float)
    ax = jnp.abs(x)
    big = ax > _TAN_3PI_8
    mid = ~big & (ax > 0.66)
    # keep every branch finite (where() differentiates both): 1/ax only where ax is large
    safe = jnp.where(big, ax, 1.0)
    reduced = jnp.where(big, -1.0 / safe, jnp.where(mid, (ax - 1.0) / (ax + 1.0), ax))
    offset = jnp.where(big, 0.5 * math.pi, jnp.where(mid, 0.25 * math.pi, 0.0))
    extra = jnp.where(big, _MOREBITS, jnp.where(mid, 0.5 * _MOREBITS, 0.0))
    z = reduced * reduced
    p = z * _horner(_ATAN_P[::-1], z) / _horner((*_ATAN_Q[::-1], 1.0), z)
    result = offset + (reduced * p + extra + reduced)
    return jnp.where(x < 0, -result, result)

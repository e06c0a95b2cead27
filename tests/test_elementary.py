"""The vectorising sine, cosine and arctangent against numpy's (correctly rounded to ~1 ulp)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from rattlefit.physics.elementary import arctan, sin_cos_cycles

EPS = np.finfo(float).eps


def test_sin_cos_cycles_match_numpy_over_many_turns():
    rng = np.random.default_rng(3)
    # random phases, the quarter-turn boundaries where the reduction switches, and just off them
    quarters = np.arange(-400, 401) / 4.0
    u = np.concatenate([rng.uniform(-50, 50, 200_000), quarters, quarters + 1e-9, quarters - 1e-9])
    s, c = jax.jit(sin_cos_cycles)(jnp.asarray(u))
    # reference on the exact fractional turn (u − round(u) is exact), so numpy's own argument
    # rounding (2π·u carries |u|·1e-16 rad) does not enter
    frac = u - np.round(u)
    assert np.max(np.abs(np.asarray(s) - np.sin(2 * np.pi * frac))) < 4 * EPS
    assert np.max(np.abs(np.asarray(c) - np.cos(2 * np.pi * frac))) < 4 * EPS
    # exact where the answer is 0 or ±1
    s_q, c_q = sin_cos_cycles(jnp.asarray([0.0, 0.25, 0.5, 0.75, -0.25]))
    np.testing.assert_array_equal(np.asarray(s_q), [0.0, 1.0, 0.0, -1.0, -1.0])
    np.testing.assert_array_equal(np.abs(np.asarray(c_q)), [1.0, 0.0, 1.0, 0.0, 0.0])


def test_arctan_matches_numpy_to_an_ulp_or_two_and_is_differentiable():
    x = np.concatenate(
        [
            np.linspace(-60, 60, 240_001),
            np.logspace(-300, 300, 20_001),
            -np.logspace(-300, 300, 2_001),
            [0.0, 0.66, np.nextafter(0.66, 1), 2.414213562373095, 2.4142135623730954, 1e308],
        ]
    )
    got = np.asarray(jax.jit(arctan)(jnp.asarray(x)))
    ref = np.arctan(x)
    assert np.max(np.abs(got - ref) / np.maximum(np.abs(ref), 1e-300)) < 3 * EPS
    # its derivative is 1 / (1 + x²) on every branch of the reduction, and finite at 0
    for x0 in (0.0, 0.3, 1.0, 5.0, -40.0):
        np.testing.assert_allclose(float(jax.grad(arctan)(x0)), 1 / (1 + x0**2), rtol=1e-14)

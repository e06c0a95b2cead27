"""Field declarations shared by the effect plug-ins."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = ["Scalar", "parameter_field"]

#: A 0-d float array: one parameter of an effect.
Scalar = Float[Array, ""]


def parameter_field(default: float = 0.0):
    """An effect parameter: an array field, converted to a float array on construction.

    ``default`` is its value (SI units) when the effect is built without it.
    """
    return eqx.field(default=default, converter=lambda x: jnp.asarray(x, dtype=float))

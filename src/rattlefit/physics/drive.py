"""The imposed motion of the driving (primary) shaft, θ1(t).

The seed paper drives the primary shaft with the speed law of eq. (9),
ω(t) = Ω_m + ΔΩ sin(2π f t). A real motor follows its command only approximately, so by
default rattlefit drives the model with a smooth fit to the primary encoder: a Fourier series in
the harmonics of the fluctuation frequency on top of a constant speed,

    θ1(t) = θ0 + Ω t + Σ_k [A_k cos(2π k f t) + B_k sin(2π k f t)],

which has analytic speed and acceleration (the forcing term I2·(r1/r2)·θ̈1 of eq. 2).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ..errors import ParameterError
from ..util import concrete
from .elementary import sin_cos_cycles


class Drive(eqx.Module):
    """Primary-shaft motion as a constant speed plus harmonics of the fluctuation frequency.

    Attributes
    ----------
    mean_speed : Ω, rad/s.
    frequency : fundamental frequency f of the fluctuation, Hz.
    cos_coeffs, sin_coeffs : A_k and B_k, rad, for k = 1 … K.
    offset : θ0, rad.
    """

    mean_speed: Float[Array, ""]
    frequency: Float[Array, ""]
    cos_coeffs: Float[Array, " K"]
    sin_coeffs: Float[Array, " K"]
    offset: Float[Array, ""]

    def __init__(self, mean_speed, frequency, cos_coeffs, sin_coeffs, offset=0.0):
        self.mean_speed = jnp.asarray(mean_speed, dtype=float)
        self.frequency = jnp.asarray(frequency, dtype=float)
        self.cos_coeffs = jnp.atleast_1d(jnp.asarray(cos_coeffs, dtype=float))
        self.sin_coeffs = jnp.atleast_1d(jnp.asarray(sin_coeffs, dtype=float))
        self.offset = jnp.asarray(offset, dtype=float)
        if self.cos_coeffs.shape != self.sin_coeffs.shape:
            raise ParameterError("drive: cos_coeffs and sin_coeffs must have the same length")
        f, w = concrete(self.frequency), concrete(self.mean_speed)
        if f is None or w is None:  # traced inside a transformation: checked by the caller
            return
        if not np.all((f > 0) & np.isfinite(f)):
            raise ParameterError(f"drive: frequency must be positive, got {f} Hz")
        if not np.all(np.isfinite(w)):
            raise ParameterError(f"drive: mean speed must be finite, got {w} rad/s")

    @classmethod
    def commanded(cls, mean_speed: float, amplitude: float, frequency: float) -> Drive:
        """The paper's eq. (9): ω(t) = Ω_m + ΔΩ sin(2π f t), θ1(0) = 0."""
        w = 2 * math.pi * frequency
        return cls(mean_speed, frequency, [-amplitude / w], [0.0], offset=amplitude / w)

    @classmethod
    def fit(
        cls,
        time: ArrayLike,
        angle: ArrayLike,
        frequency: float,
        *,
        n_harmonics: int = 6,
    ) -> Drive:
        """Least-squares fit of the Fourier drive to a measured angle history (rad vs s).

        The encoder quantisation (±½ count) is white and is averaged away by the fit; impacts
        felt by a real primary shaft are short and broadband, and leave the low harmonics alone.
        """
        t = np.asarray(time, dtype=float)
        y = np.asarray(angle, dtype=float)
        k = np.arange(1, n_harmonics + 1)
        phase = 2 * np.pi * frequency * np.outer(t, k)
        design = np.column_stack([np.ones_like(t), t, np.cos(phase), np.sin(phase)])
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        return cls(
            coef[1],
            frequency,
            coef[2 : 2 + n_harmonics],
            coef[2 + n_harmonics :],
            offset=coef[0],
        )

    def _phases(self, t):
        k = jnp.arange(1, self.cos_coeffs.shape[-1] + 1)
        omega_k = 2 * jnp.pi * self.frequency * k
        return omega_k, omega_k * t

    def angle(self, t: ArrayLike) -> Array:
        """θ1(t), rad (scalar t)."""
        _, ph = self._phases(t)
        return (
            self.offset
            + self.mean_speed * t
            + jnp.sum(self.cos_coeffs * jnp.cos(ph) + self.sin_coeffs * jnp.sin(ph))
        )

    def speed(self, t: ArrayLike) -> Array:
        """θ̇1(t), rad/s (scalar t)."""
        w, ph = self._phases(t)
        return self.mean_speed + jnp.sum(
            w * (-self.cos_coeffs * jnp.sin(ph) + self.sin_coeffs * jnp.cos(ph))
        )

    def acceleration(self, t: ArrayLike) -> Array:
        """θ̈1(t), rad/s² (scalar t)."""
        w, ph = self._phases(t)
        return -jnp.sum(w**2 * (self.cos_coeffs * jnp.cos(ph) + self.sin_coeffs * jnp.sin(ph)))

    def angle_and_acceleration(self, t: ArrayLike) -> tuple[Array, Array]:
        """θ1(t) (rad) and θ̈1(t) (rad/s²) together (scalar t), as the vector field needs them.

        The same series as :meth:`angle` and :meth:`acceleration`, with the harmonics'
        cosines and sines from one cosine and sine by the angle-addition recurrence, and
        those two from the phase f·t in cycles by
        :func:`~rattlefit.physics.elementary.sin_cos_cycles` (polynomials that vectorise, where
        ``jnp.sin`` and ``jnp.cos`` are a library call a value on a CPU).
        """
        w = 2 * jnp.pi * self.frequency
        sin1, cos1 = sin_cos_cycles(self.frequency * t)
        cos_k, sin_k = cos1, sin1
        angle = self.offset + self.mean_speed * t
        acc = jnp.zeros_like(angle)
        for k in range(1, self.cos_coeffs.shape[-1] + 1):
            term = self.cos_coeffs[..., k - 1] * cos_k + self.sin_coeffs[..., k - 1] * sin_k
            angle = angle + term
            acc = acc - (w * k) ** 2 * term
            cos_k, sin_k = cos_k * cos1 - sin_k * sin1, sin_k * cos1 + cos_k * sin1
        return angle, acc

    def max_acceleration(self) -> float:
        """max |θ̈1| over one period, rad/s² (sampled finely; concrete drives only)."""
        t = np.linspace(0.0, 1.0 / float(self.frequency), 2049)
        return float(jnp.max(jnp.abs(jax.vmap(self.acceleration)(jnp.asarray(t)))))

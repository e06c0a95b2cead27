"""Statistics of Δθ* folded over the drive cycle: where in the speed fluctuation the gear sits
and which flank it rests on.

The band spectrum says how much the gear rattles, not when. The drag torque and the squeeze
film act at different moments of the cycle: the drag decides when the gear leaves the
driving flank as the primary decelerates, the film how long it takes to settle on a flank
after an impact. Folding Δθ* over the drive cycle keeps that. Each sample gets its phase in
the cycle, ``φ = frac(f t − φ0)`` (φ0 the phase of the speed's maximum, so that phase 0 is
the fastest point), and per phase bin the statistics are

* the mean position, ``u = 2 (Δθ* − lo)/(hi − lo) − 1``, with ``lo`` and ``hi`` the signal's
  robust extremes (its 0.1 and 99.9 percentiles), so that −1 and +1 are the two flanks
  whatever the encoders' zero and the backlash;
* the share of the samples within :data:`~rattlefit.features.orders.CONTACT_BAND` of the
  play from the upper flank (``u > 1 − 2·band``), and from the lower flank.

All work on numpy and JAX arrays alike, batched over leading axes.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float

from ..util import array_namespace
from .orders import CONTACT_BAND

#: Phase bins of the drive cycle.
PHASE_BINS = 16
#: Percentiles that stand for the two flanks (robust extremes of Δθ*).
FLANK_PERCENTILES = (0.1, 99.9)
#: The statistics per phase bin, in the order :func:`folded_statistics` returns them.
STATISTICS = ("position", "upper_flank", "lower_flank")


def drive_phase(n: int, sample_rate: float, frequency, phase0=0.0):
    """Phase in the drive cycle (cycles, in [0, 1)) of ``n`` samples from t = 0:
    ``frac(f t − phase0)``."""
    xp = array_namespace(frequency, phase0)
    t = xp.arange(n) / sample_rate
    return xp.mod(frequency * t - phase0, 1.0)


def speed_maximum_phase(cos_coeff, sin_coeff):
    """Phase (cycles) of the maximum of the speed fluctuation of a drive angle
    ``c cos(ωt) + s sin(ωt)`` (its first harmonic): the speed is ``ω (s cos ωt − c sin ωt)``,
    largest at ``ωt = atan2(−c, s)``."""
    xp = array_namespace(cos_coeff, sin_coeff)
    return xp.mod(xp.arctan2(-cos_coeff, sin_coeff) / (2.0 * math.pi), 1.0)


def cycle_phase(drive, n: int, sample_rate: float):
    """Drive phase (:func:`drive_phase`) of ``n`` samples from t = 0 of a
    :class:`~rattlefit.physics.drive.Drive`, zero at its speed's maximum."""
    phase0 = speed_maximum_phase(drive.cos_coeffs[0], drive.sin_coeffs[0])
    return drive_phase(n, sample_rate, drive.frequency, phase0)


def phase_means(values, phase, bins: int = PHASE_BINS):
    """Mean of ``values`` (*batch, N) over the samples of each phase bin: (*batch, bins);
    ``phase`` (N,) in cycles, in [0, 1). A bin without samples gives 0."""
    xp = array_namespace(values, phase)
    k = xp.minimum(xp.floor(xp.asarray(phase) * bins).astype(int), bins - 1)
    if xp is np:
        onehot = (k[:, None] == np.arange(bins)[None, :]).astype(float)
        return (np.asarray(values) @ onehot) / np.maximum(onehot.sum(axis=0), 1.0)
    count = jax.ops.segment_sum(jnp.ones_like(phase), k, num_segments=bins)

    def per_signal(v):
        return jax.ops.segment_sum(v, k, num_segments=bins) / jnp.maximum(count, 1.0)

    flat = jnp.reshape(values, (-1, values.shape[-1]))
    return jnp.reshape(jax.vmap(per_signal)(flat), (*values.shape[:-1], bins))


def folded_statistics(
    x: Float[ArrayLike, "*batch N"],
    phase: Float[ArrayLike, " N"],
    *,
    bins: int = PHASE_BINS,
    band: float = CONTACT_BAND,
) -> Float[ArrayLike, "*batch S"]:
    """The folded statistics of Δθ* signals ``x`` (rad) whose samples are at drive phases
    ``phase`` (:func:`drive_phase`): for each of ``bins`` phase bins, the mean normalised
    position, the upper flank's share and the lower flank's, concatenated in that order
    (S = 3 · bins, see :data:`STATISTICS`)."""
    xp = array_namespace(x, phase)
    x = xp.asarray(x)
    lo = xp.percentile(x, FLANK_PERCENTILES[0], axis=-1)[..., None]
    hi = xp.percentile(x, FLANK_PERCENTILES[1], axis=-1)[..., None]
    u = 2.0 * (x - lo) / xp.maximum(hi - lo, 1e-30) - 1.0
    edge = 1.0 - 2.0 * band
    stacked = xp.stack([u, xp.where(u > edge, 1.0, 0.0), xp.where(u < -edge, 1.0, 0.0)], axis=-2)
    means = phase_means(stacked, phase, bins)  # (*batch, 3, bins)
    return xp.reshape(means, (*means.shape[:-2], 3 * bins))

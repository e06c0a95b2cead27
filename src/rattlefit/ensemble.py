"""Statistics of an ensemble of chaotic realisations: their mean, spread and correlation.

The fit compares one recording's spectral features with ``n`` simulated realisations of the
same parameters, released from different positions in the gap. Rattle is chaotic, and its
realisations do not scatter like a Gaussian: a few of them settle into a different regime (a
periodic orbit, or in dry conditions, where the model has no dissipation at all, a different
invariant set) whose features sit far from the others in every band at once. Measured at the
truth of synthetic recordings (24 realisations, ``d²`` of :func:`regime_weights`): pair I dry
65.0 mm 10 % at 8 Hz 15–42 for 3 of 24; pair II boundary 65.0 mm 10 % at 8 Hz 10–24 for 4;
pair I oil jet 66.0 mm 8–14 for 2; the rest below 5.

One such realisation moves the mean of six by a third of its excursion and inflates the spread
of every band, so the fit then matches data that belong to the common regime with a wrong
parameter (on the pair I dry coverage cases, a film half-length of 10–40 µm whose damping
suppresses the rare regime). :func:`regime_weights` therefore sets realisations far from the
ensemble median aside, and :func:`ensemble_mean` and :func:`chaotic_part` describe the regime
that most realisations share. All functions take features shaped (..., n, B): realisations on
the second-last axis, bands on the last.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._util import array_namespace

#: Robust scale of the median absolute deviation of a Gaussian.
MAD_TO_SD = 1.4826
#: Fewest realisations for which regimes are told apart (the median and MAD of fewer are
#: too rough).
MIN_FOR_REGIMES = 5


def regime_weights(features, threshold: float | None, *, scale_floor: float = 0.03):
    """1 for the realisations of the common regime, 0 for those set aside: (..., n).

    A realisation is set aside when its mean squared deviation from the ensemble median over
    the bands, each in units of the band's robust spread (``1.4826 · MAD``, at least
    ``scale_floor``, log10 units), exceeds ``threshold``; a Gaussian realisation has about 1.
    Never more than half are set aside (the median's breakdown point), and nothing is with
    fewer than :data:`MIN_FOR_REGIMES` realisations or with ``threshold=None``. Traces inside
    the fit's residual; on concrete features it computes in numpy (see
    :func:`~rattlefit._util.array_namespace`).
    """
    xp = array_namespace(features)
    f = xp.asarray(features)
    n = f.shape[-2]
    if threshold is None or n < MIN_FOR_REGIMES:
        return xp.ones(f.shape[:-1], dtype=f.dtype)
    med = xp.median(f, axis=-2, keepdims=True)
    mad = MAD_TO_SD * xp.median(xp.abs(f - med), axis=-2, keepdims=True)
    d2 = xp.mean(((f - med) / xp.maximum(mad, scale_floor)) ** 2, axis=-1)
    keep = d2 <= threshold
    enough = 2 * xp.sum(keep, axis=-1, keepdims=True) >= n
    return xp.where(enough, keep, True).astype(f.dtype)


def ensemble_mean(features, threshold: float | None):
    """Mean features of the common regime (see :func:`regime_weights`): (..., B); numpy for
    concrete features, like :func:`regime_weights`."""
    f = array_namespace(features).asarray(features)
    return _weighted_mean(f, regime_weights(f, threshold))


def _weighted_mean(f, w):
    return (w[..., None] * f).sum(axis=-2) / w.sum(axis=-1)[..., None]


def dither_design(n: int, offsets: np.ndarray | None) -> np.ndarray:
    """Regressors of :func:`chaotic_part` for n realisations: a constant, and the offsets
    when at least three degrees of freedom remain."""
    x = np.ones((n, 1))
    if offsets is not None and offsets.shape[1] and n - 1 - offsets.shape[1] >= 3:
        x = np.column_stack([x, offsets])
    return x


def chaotic_part(
    ens: np.ndarray, offsets: np.ndarray | None, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The run-to-run (chaotic) deviations of ``ens`` (R, n, B) and their degrees of freedom
    (R,).

    Each realisation runs at the fit's point moved by its own fixed dither ``offsets`` (n, q)
    (see ``FitOptions.dither``). Their centred mean is zero, so to first order the dither does
    not move the mean features, but it does spread the realisations, the more where the
    features depend strongly on the parameters. Left in, that spread inflates σ, makes bands
    look correlated that only share a parameter, and (through the synthetic likelihood's
    log-determinant) rewards regions where the features are insensitive. So the features are
    regressed on the known offsets and the residuals kept, with n − 1 − q degrees of
    freedom. Without offsets (or with too few realisations for the regression to leave at
    least three) the deviations from the mean are returned, with n − 1.

    ``weights`` (R, n) of :func:`regime_weights` restrict each recording's regression to the
    realisations it keeps; the others get zero deviations and count no degree of freedom.
    """
    ens = np.asarray(ens)
    n_rec, n = ens.shape[:2]
    w = np.ones((n_rec, n), bool) if weights is None else np.asarray(weights) > 0
    dev = np.zeros_like(ens)
    dof = np.zeros(n_rec, dtype=int)
    for r in range(n_rec):
        kept = np.flatnonzero(w[r])
        x = dither_design(kept.size, None if offsets is None else np.asarray(offsets)[kept])
        hat = x @ np.linalg.pinv(x)  # projection onto the regressors
        dev[r, kept] = ens[r, kept] - hat @ ens[r, kept]
        dof[r] = x.shape[0] - x.shape[1]
    return dev, dof


def band_sigma(
    ens: np.ndarray,
    m: int,
    floor: float,
    noise_floor: np.ndarray,
    floor_sd: float,
    discrepancy: float = 0.0,
    offsets: np.ndarray | None = None,
    threshold: float | None = None,
) -> jnp.ndarray:
    """Per-band σ of the residual (data − mean of m), floored: ``s_run² (1 + 1/m)`` plus
    ``(floor_sd · φ)²``, φ the share of the quantisation floor in the band's mean PSD, plus
    the model discrepancy ``discrepancy²``: (R, B).

    ``ens`` (R, n, B) are log10 features of n realisations per recording and ``noise_floor``
    (R,) the white quantisation PSD added to them. The second term is the uncertainty of that
    white floor: a real encoder's quantisation error is not white when the count rate beats
    with the sample rate, so in floor-dominated bands the measured level departs from eq. (8).
    ``offsets`` (n, q) are the realisations' dither offsets: the run-to-run spread s_run is
    then that of :func:`chaotic_part`, without the dither's share; with ``threshold`` it is
    the spread of the common regime (:func:`regime_weights`).
    """
    ens = np.asarray(ens)
    weights = np.asarray(regime_weights(ens, threshold))
    dev, dof = chaotic_part(ens, offsets, weights)
    var = np.sum(dev**2, axis=1) / dof[:, None] * (1.0 + 1.0 / m)
    mean = _weighted_mean(ens, weights)
    share = np.asarray(noise_floor)[:, None] / 10.0**mean
    var = var + (floor_sd * np.clip(share, 0.0, 1.0)) ** 2 + discrepancy**2
    return jnp.asarray(np.sqrt(np.maximum(var, floor**2)))


def shrunk_correlation(samples: np.ndarray) -> np.ndarray:
    """Correlation matrix of ``samples`` (n, p) shrunk towards the identity.

    Schäfer & Strimmer (2005), target D: the optimal shrinkage intensity
    λ = Σ_{i≠j} Var(r_ij) / Σ_{i≠j} r_ij², clipped to [0, 1]. With fewer samples than bands
    the sample correlation is singular; the shrunk one is positive definite.
    """
    n = samples.shape[0]
    x = samples - samples.mean(axis=0)
    sd = x.std(axis=0, ddof=1)
    x = x / np.where(sd > 0, sd, 1.0)
    w = x[:, :, None] * x[:, None, :]  # (n, p, p)
    r = w.mean(axis=0) * n / (n - 1)
    var_r = n / (n - 1) ** 3 * np.sum((w - w.mean(axis=0)) ** 2, axis=0)
    off = ~np.eye(r.shape[0], dtype=bool)
    denom = np.sum(r[off] ** 2)
    lam = 1.0 if denom == 0 else float(np.clip(np.sum(var_r[off]) / denom, 0.0, 1.0))
    out = (1 - lam) * r
    np.fill_diagonal(out, 1.0)
    return out

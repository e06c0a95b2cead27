"""Statistics of an ensemble of chaotic realisations: their mean, spread and correlation.

The fit compares one recording's spectral features with ``n`` simulated realisations of the
same parameters, released from different positions in the gap. Rattle is chaotic, and its
realisations do not scatter like a Gaussian: a few of them settle into a different regime (a
periodic orbit, or in dry conditions, where the model has no dissipation at all, a different
invariant set) whose features sit far from the others in every band at once: at the truth
of a synthetic recording, typically up to a few of 24 realisations lie at ``d²`` 10–40 (of
:func:`regime_weights`), the rest below 5.

One such realisation moves the mean of six by a third of its excursion and inflates the spread
of every band, so the fit then matches data that belong to the common regime with a wrong
parameter (on the pair I dry coverage cases, a film half-length of 10–40 µm whose damping
suppresses the rare regime). :func:`regime_weights` therefore sets realisations far from the
ensemble median aside, and :func:`ensemble_mean` and :func:`chaotic_part` describe the regime
that most realisations share, unless the recording itself is in another one that enough of
them reach: then that regime (``target``, ``FitOptions.regime``). All functions
take features shaped (..., n, B): realisations on the second-last axis, bands on the last.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..util import array_namespace

#: Robust scale of the median absolute deviation of a Gaussian.
MAD_TO_SD = 1.4826
#: Fewest realisations for which regimes are told apart (the median and MAD of fewer are
#: too rough).
MIN_FOR_REGIMES = 5


def regime_weights(features, threshold: float | None, *, scale_floor: float = 0.03, target=None):
    """1 for the realisations of the regime kept, 0 for those set aside: (..., n).

    A realisation is set aside when its mean squared deviation from the ensemble median over
    the bands, each in units of the band's robust spread (``1.4826 · MAD``, at least
    ``scale_floor``, log10 units), exceeds ``threshold``; a Gaussian realisation has about 1.
    Never more than half are set aside (the median's breakdown point), and nothing is with
    fewer than :data:`MIN_FOR_REGIMES` realisations or with ``threshold=None``: this is the
    *common* regime.

    With ``target`` (..., B), the features of a recording, the regime kept is the one the
    recording is in (:func:`_target_regime`): the common regime when the realisation
    nearest the target belongs to it, else the realisations that cluster with that nearest
    one (at least :data:`MIN_IN_REGIME`, and :data:`MIN_REGIME_SHARE` of all). Traces inside
    the fit's residual; on concrete features it computes in numpy (see
    :func:`~rattlefit.util.array_namespace`).
    """
    xp = array_namespace(features, target)
    f = xp.asarray(features)
    n = f.shape[-2]
    if threshold is None or n < MIN_FOR_REGIMES:
        return xp.ones(f.shape[:-1], dtype=f.dtype)
    med = xp.median(f, axis=-2, keepdims=True)
    scale = xp.maximum(MAD_TO_SD * xp.median(xp.abs(f - med), axis=-2, keepdims=True), scale_floor)
    d2 = xp.mean(((f - med) / scale) ** 2, axis=-1)
    keep = d2 <= threshold
    enough = 2 * xp.sum(keep, axis=-1, keepdims=True) >= n
    common = xp.where(enough, keep, True)
    if target is not None:
        common = _target_regime(f, med, scale, common, xp.asarray(target), xp)
    return common.astype(f.dtype)


#: Fewest realisations that make a regime other than the common one the recording's: two
#: give its mean and a spread, …
MIN_IN_REGIME = 2
#: … and at least this share of them. A regime that fewer releases reach is too improbable to
#: be the recording's, however near it lies: a fit that may pick the nearest of many rare
#: orbits fits noise, while a sixth still admits a genuine rarer regime of the recording.
MIN_REGIME_SHARE = 1 / 6


def _target_regime(f, med, scale, common, target, xp):
    """The regime of ``target`` among realisations ``f`` (..., n, B): ``common`` (..., n)
    when the realisation nearest the target (in the robust ``scale``) is in it; else the
    realisations nearer to that nearest one than to the ensemble median ``med`` (one step of
    two-centre clustering), when there are at least :data:`MIN_IN_REGIME` of them and at
    least :data:`MIN_REGIME_SHARE` of all.

    Rattle has coexisting attractors: at one parameter point some releases settle into one
    regime and the rest into another, and a recording is in one of them, whichever its
    history chose. Matched against the common regime's mean, a recording of the rarer one
    is explained only by other (wrong) parameters.
    """

    def dist2(x, centre):
        return xp.mean(((x - centre) / scale) ** 2, axis=-1)

    nearest = xp.argmin(dist2(f, target[..., None, :]), axis=-1)[..., None]
    f_near = xp.take_along_axis(f, nearest[..., None], axis=-2)  # (..., 1, B)
    near = dist2(f, f_near) < dist2(f, med)
    in_common = xp.take_along_axis(common, nearest, axis=-1)  # (..., 1)
    least = max(MIN_IN_REGIME, math.ceil(MIN_REGIME_SHARE * f.shape[-2] - 1e-9))
    other = ~in_common & (xp.sum(near, axis=-1, keepdims=True) >= least)
    return xp.where(other, near, common)


def ensemble_mean(features, threshold: float | None, target=None):
    """Mean features of the regime kept (see :func:`regime_weights`; with ``target``, the
    recording's): (..., B); numpy for concrete features, like :func:`regime_weights`."""
    f = array_namespace(features, target).asarray(features)
    return weighted_mean(f, regime_weights(f, threshold, target=target))


def weighted_mean(f, w):
    """Mean of features ``f`` (..., n, F) over the realisations, weighted by ``w`` (..., n)."""
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
    target: np.ndarray | None = None,
    n_bands: int | None = None,
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
    the spread of the common regime (:func:`regime_weights`), or with ``target`` (R, B) of
    the recordings' own regimes. ``n_bands`` (default all) says how many leading features
    are log band PSDs: the regimes are told apart by those, and only those get the
    quantisation floor's term; the others (e.g. drive-cycle-folded statistics) get the
    rest alike.
    """
    ens = np.asarray(ens)
    nb = ens.shape[-1] if n_bands is None else n_bands
    bands_target = None if target is None else np.asarray(target)[..., :nb]
    weights = np.asarray(regime_weights(ens[..., :nb], threshold, target=bands_target))
    dev, dof = chaotic_part(ens, offsets, weights)
    var = np.sum(dev**2, axis=1) / dof[:, None] * (1.0 + 1.0 / m)
    mean = weighted_mean(ens, weights)
    share = np.zeros_like(mean)
    share[:, :nb] = np.asarray(noise_floor)[:, None] / 10.0 ** mean[:, :nb]
    var = var + (floor_sd * np.clip(share, 0.0, 1.0)) ** 2 + discrepancy**2
    return jnp.asarray(np.sqrt(np.maximum(var, floor**2)))


def shrunk_correlation(samples: np.ndarray) -> np.ndarray:
    """Correlation matrix of ``samples`` (n, p) shrunk towards the identity.

    Schäfer & Strimmer (2005), target D: the optimal shrinkage intensity
    λ = Σ_{i≠j} Var(r_ij) / Σ_{i≠j} r_ij², clipped to [0, 1]. With fewer samples than bands
    the sample correlation is singular; the shrunk one is positive definite. From fewer than
    three samples (e.g. the two realisations of a rare regime) every sample correlation is
    ±1 and its variance estimate zero, so nothing is learnt: the identity.
    """
    n = samples.shape[0]
    if n < 3:
        return np.eye(samples.shape[1])
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

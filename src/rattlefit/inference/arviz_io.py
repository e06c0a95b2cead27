"""The posterior in ArviZ's format: an ``arviz.InferenceData`` and its netCDF file.

Groups of :func:`inference_data`:

* ``posterior``: each parameter under its name (``a``, ``drag_torque``, ``viscosity``, the
  nuisances), dims ``(chain, draw)``: the walkers as chains and the draws kept after the
  chain's ``discard`` steps (draw 0 is step ``discard``); SI values, the unit in each
  variable's ``units`` attribute.
* ``sample_stats``: ``lp``, the log posterior density of each kept draw (in the fit's
  unconstrained coordinates, up to a constant), dims ``(chain, draw)``.
* given the recordings, ``observed_data``: ``log10_psd``, the measured features (log10 of the
  band-mean PSD of the relative motion, rad²/Hz), dims ``(recording, band)``;
  ``posterior_predictive``: ``log10_psd``, the mean simulated features at ``n_draws`` seeded
  draws of the kept chain, dims ``(chain, draw, recording, band)`` with one chain, the walker
  and step each draw was taken from as the coordinates ``walker`` and ``step`` along ``draw``;
  ``constant_data``: ``band_center``, the bands' centre frequencies (Hz), dim ``band``.
  The coordinate ``band`` is the centre frequency in Hz and ``recording`` the index of the
  recording in the attribute ``recordings``.

Every group carries the attributes ``seed`` (the chain's), ``discard``, ``recordings`` (a
JSON list of the recordings' paths, ``"<memory>"`` for one never read from a file),
``rattlefit_version`` and ``platform`` (a JSON object: what seeded results depend on);
``posterior_predictive`` also ``predictive_seed`` and ``predictive_draws``. The file holds
only numbers, strings and these attributes, so ``arviz.from_netcdf`` reopens it without
rattlefit.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import RattlefitError
from ..io.recording import Recording
from ..io.schema import MEMORY
from ..util import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    import arviz

    from .posterior import Posterior

#: Unit of the features in ``observed_data`` and ``posterior_predictive``.
FEATURE_UNITS = "log10(rad^2/Hz)"


def predictive_pick(n_kept: int, n_draws: int, seed: int) -> np.ndarray:
    """Indices of ``n_draws`` distinct draws among ``n_kept`` kept ones (steps × walkers,
    step-major), drawn with ``numpy.random.default_rng(seed)``. Raises
    :class:`~rattlefit.errors.RattlefitError` when ``n_draws`` is not in [1, n_kept]."""
    if not 1 <= n_draws <= n_kept:
        raise RattlefitError(
            f"posterior predictive: n_draws must lie in [1, {n_kept}] (the kept draws), "
            f"got {n_draws}"
        )
    return np.random.default_rng(seed).choice(n_kept, size=n_draws, replace=False)


def _attrs(post: Posterior, recordings: Sequence[Recording] | None) -> dict:
    from ..version import __version__

    paths = (
        list(post.recordings)
        if recordings is None
        else [str(r.path) if r.path else MEMORY for r in recordings]
    )
    return {
        "seed": int(post.seed),
        "discard": int(post.discard),
        "recordings": json.dumps(paths),
        "rattlefit_version": __version__,
        "platform": json.dumps(post.platform, sort_keys=True),
    }


def _predictive(post: Posterior, recordings: Sequence[Recording], n_draws: int, seed: int):
    """(groups, coords, dims, (walker, step) of each draw) of the recordings' data."""
    n_steps, n_walkers = post.chain.shape[:2]
    pick = predictive_pick((n_steps - post.discard) * n_walkers, n_draws, seed)
    draws, data, centres = post.predictive_features(recordings, n_draws=n_draws, seed=seed)
    groups = {
        "observed_data": {"log10_psd": np.asarray(data, dtype=float)},
        "posterior_predictive": {"log10_psd": np.asarray(draws, dtype=float)[None]},
        "constant_data": {"band_center": np.asarray(centres, dtype=float)},
    }
    coords = {"band": np.asarray(centres, dtype=float), "recording": np.arange(len(data))}
    dims = {"log10_psd": ["recording", "band"], "band_center": ["band"]}
    return groups, coords, dims, (pick % n_walkers, post.discard + pick // n_walkers)


def inference_data(
    post: Posterior,
    recordings: Sequence[Recording] | None = None,
    *,
    n_draws: int = 8,
    seed: int = 0,
) -> arviz.InferenceData:
    """``post`` as an ``arviz.InferenceData`` with the groups of this module's description.

    Without ``recordings`` it has only ``posterior`` and ``sample_stats``. With them (the
    chain's own recordings) it also has ``observed_data``, ``constant_data`` and a
    ``posterior_predictive`` of ``n_draws`` draws of the kept chain chosen with ``seed``
    (:meth:`Posterior.predictive_features`, which simulates them). Raises
    :class:`~rattlefit.errors.RattlefitError` for recordings given to a posterior without its
    chain in fit coordinates, or ``n_draws`` outside [1, kept draws].
    """
    import arviz as az

    kept = np.swapaxes(post.chain[post.discard :], 0, 1)  # (walker, draw, P)
    lp = np.swapaxes(post.log_prob[post.discard :], 0, 1)
    groups, coords, dims, origin = {}, {}, {}, None
    if recordings is not None:
        groups, coords, dims, origin = _predictive(post, recordings, n_draws, seed)
    attrs = _attrs(post, recordings)
    idata = az.from_dict(
        posterior={n: kept[..., i] for i, n in enumerate(post.names)},
        sample_stats={"lp": lp},
        coords=coords or None,
        dims=dims or None,
        **groups,
    )
    for group in idata.groups():
        idata[group].attrs.update(attrs)
    for name, unit in zip(post.names, post.units, strict=True):
        idata.posterior[name].attrs["units"] = unit
    if origin is not None:
        walker, step = origin
        pp = idata.posterior_predictive.assign_coords(
            walker=("draw", walker.astype(np.int64)), step=("draw", step.astype(np.int64))
        )
        pp.attrs.update(predictive_seed=int(seed), predictive_draws=int(n_draws))
        idata.posterior_predictive = pp
        for group in ("observed_data", "posterior_predictive"):
            idata[group]["log10_psd"].attrs["units"] = FEATURE_UNITS
        idata.constant_data["band_center"].attrs["units"] = "Hz"
    return idata


def save_netcdf(
    post: Posterior,
    path: str | Path,
    recordings: Sequence[Recording] | None = None,
    **kw,
) -> Path:
    """Write :func:`inference_data` (``recordings`` and ``kw`` passed on) to the netCDF file
    ``path`` atomically (a temporary file beside it, then renamed), so an interrupted write
    leaves any earlier file whole; returns ``path``. ``arviz.from_netcdf(path)`` reopens it."""
    idata = inference_data(post, recordings, **kw)
    return atomic_write(path, lambda tmp: idata.to_netcdf(str(tmp)))

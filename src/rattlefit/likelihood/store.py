"""Storing a learned likelihood, so that a re-fit, the posterior and other recordings of the
same test point reuse it instead of learning it again.

A file (HDF5, group ``/learned_likelihood``) holds the feature densities' weights, the design they
were trained on (the design points and every simulation's features), the seed, and the
**test-point key**: a hash of everything that defines the simulator's feature distribution
(each recording's gear pair, operating point, drive, lubrication and encoders, the
parameters' ranges and priors, and the simulator options), but not the measured features.
A stored likelihood is reused only where the key matches. Files are written to a temporary
file and renamed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import ClassVar

import equinox as eqx
import h5py
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import RattlefitError
from ..problem.problem import Problem
from .density import DensityOptions, FeatureDensity, Whitening, make_flow
from .information import SMOOTH_STEP, moment_information
from .learn import Design
from .model import LearnedLikelihood, batch_chi2_terms
from .noise import NoiseModel

#: Format tag and version of a stored learned likelihood.
FORMAT, VERSION = "rattlefit-learned-likelihood", 2
GROUP = "learned_likelihood"


def test_point_key(problem: Problem) -> str:
    """A hash of what defines the simulator's feature distribution for ``problem``: the
    stacked models and drives, the parameters' specs, the feature bands and the simulator's
    static options (not the measured features, the realisations or the band spread)."""
    h = hashlib.sha256()
    for leaf in jax.tree_util.tree_leaves((problem.models, problem.drives)):
        h.update(np.ascontiguousarray(np.asarray(leaf, dtype=float)).tobytes())
    for x in (problem.counts_per_rev, problem.floors, problem.viscosities):
        h.update(np.asarray(x, dtype=float).tobytes())
    specs = [dataclasses.asdict(s) for s in problem.specs]
    meta = [specs, repr(problem.static), problem.quantise, problem.statistics, problem.films]
    h.update(json.dumps(meta, default=str, sort_keys=True).encode())
    h.update(np.asarray(problem.bands.centers, dtype=float).tobytes())
    return h.hexdigest()[:24]


#: The flow's shape options kept with its weights.
SHAPE = ("whitening_width", "whitening_depth", "layers", "width", "knots", "interval")


def skeleton(n_in: int, n_out: int, columns, options: DensityOptions) -> FeatureDensity:
    """A density of the stored shape, to read the weights into."""
    key = jax.random.key(0)
    width, depth = options.whitening_width, options.whitening_depth
    return FeatureDensity(
        Whitening(n_in, n_out, width, depth, key),
        make_flow(n_in, n_out, options, key),
        jnp.zeros(n_in),
        jnp.ones(n_in),
        jnp.zeros(n_out),
        jnp.ones(n_out),
        jnp.zeros(n_out),
        tuple(columns),
    )


def write_group(
    g: h5py.Group,
    like: LearnedLikelihood,
    design: Design,
    *,
    key: str,
    seed: int,
    options: DensityOptions,
) -> None:
    """Write ``like`` with its ``design``, test-point ``key`` and ``seed`` into group ``g``."""
    g.attrs.update(format=FORMAT, version=VERSION, key=key, seed=seed)
    g.attrs.update({name: getattr(options, name) for name in SHAPE})
    g.create_dataset("design_u", data=design.u)
    g.create_dataset("design_features", data=design.features)
    for r, density in enumerate(like.densities):
        buffer = io.BytesIO()
        eqx.tree_serialise_leaves(buffer, density)
        d = g.create_dataset(f"density_{r}", data=np.frombuffer(buffer.getvalue(), np.uint8))
        d.attrs["columns"] = np.asarray(density.columns)


def write_learned(path: str | os.PathLike, learned: Learned) -> Path:
    """Write ``learned`` (:meth:`Learned.save`) to the file ``path``, atomically; returns
    it."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with h5py.File(tmp, "w") as f:
        learned.save(f.create_group(GROUP))
    os.replace(tmp, path)
    return path


@dataclasses.dataclass(frozen=True)
class Learned:
    """A learned likelihood (a :class:`~rattlefit.likelihood.protocol.Likelihood`): the
    likelihood on the problem it was read for, its design (None: not stored with it, and it
    cannot be saved), test-point key, seed and flow options, and the noise model at a fit's
    optimum (:func:`learned_noise`; None before)."""

    kind: ClassVar[str] = "learned"
    likelihood: LearnedLikelihood
    design: Design | None = None
    key: str = ""
    seed: int = 0
    options: DensityOptions = dataclasses.field(default_factory=DensityOptions)
    noise: NoiseModel | None = dataclasses.field(default=None, repr=False, compare=False)

    def bind(self, problem: Problem) -> Learned:
        """This likelihood with ``problem``'s measured features as its data."""
        return dataclasses.replace(self, likelihood=self.likelihood.replace_data(problem.data))

    def log_density(self, zs) -> np.ndarray:
        """log p(d | z) up to a constant at each point of ``zs`` (K, P): each recording's
        learned density, ``−½ (|r|² + log-volume term)``, summed: (K,)."""
        zs = jnp.atleast_2d(jnp.asarray(zs, dtype=float))
        chi2, logdet = (np.asarray(x) for x in batch_chi2_terms(self.likelihood, zs))
        return -0.5 * np.sum(chi2 + logdet, axis=1)

    def information(self, z, names: Sequence[str], *, rng=None) -> np.ndarray:
        """The recordings' Fisher information (P, P) about ``names`` at ``z``, per unit log,
        from the learned mean and covariance
        (:func:`~rattlefit.likelihood.information.moment_information`); ``rng`` is unused."""
        return moment_information(
            lambda x: self.likelihood.moments(jnp.asarray(x)),
            self.likelihood.specs,
            z,
            names,
            step=SMOOTH_STEP,
        )

    def save(self, g: h5py.Group) -> None:
        """Write the likelihood (:func:`write_group`) and any noise model into group ``g``.
        Raises :class:`~rattlefit.errors.RattlefitError` for a likelihood without its
        design."""
        if self.design is None:
            raise RattlefitError(f"{g.name}: a learned likelihood without its design")
        write_group(
            g, self.likelihood, self.design, key=self.key, seed=self.seed, options=self.options
        )
        if self.noise is not None:
            self.noise.save(g.create_group("noise"))

    @classmethod
    def load(cls, g: h5py.Group, problem: Problem, where: str) -> Learned:
        """The likelihood :meth:`save` wrote into ``g``, for ``problem``
        (:func:`read_group`)."""
        learned = read_group(g, problem, where)
        if "noise" in g:
            learned = dataclasses.replace(learned, noise=NoiseModel.load(g["noise"], where))
        return learned


def learned_noise(total, n_realisations: int, chi2_recordings, simulations: int) -> NoiseModel:
    """The noise model of a fit on the learned likelihood, from the learned density's feature
    covariance ``total`` (R, F, F) at the optimum: each feature's spread and the features'
    correlation (the whitening block-diagonal, since recordings are independent), each spread
    widened by the Monte Carlo error of a mean of ``n_realisations`` realisations, as the
    synthetic likelihood's is. No Birge inflation (``row_scale`` one): the learned density's
    spread is checked against fresh simulations instead (:mod:`rattlefit.likelihood.check`).
    ``chi2_recordings`` (R,) are each recording's χ² there, ``simulations`` what it was
    learned from per recording (its ``sigma_dof``)."""
    cov = np.asarray(total)
    n_rec, n_feat = cov.shape[:2]
    sigma = np.sqrt(np.diagonal(cov, axis1=1, axis2=2) * (1.0 + 1.0 / n_realisations))
    whiten = np.zeros((n_rec * n_feat, n_rec * n_feat))
    for k in range(n_rec):
        sd = np.sqrt(np.diag(cov[k]))
        corr = cov[k] / np.outer(sd, sd) + 1e-9 * np.eye(n_feat)
        sl = slice(k * n_feat, (k + 1) * n_feat)
        whiten[sl, sl] = np.linalg.inv(np.linalg.cholesky(corr))
    return NoiseModel(
        sigma, whiten, np.ones(n_rec * n_feat), np.asarray(chi2_recordings, float), int(simulations)
    )


def read_group(g: h5py.Group, problem: Problem, where: str) -> Learned:
    """The learned likelihood in group ``g`` for ``problem``'s recordings (their measured
    features become its data); ``where`` names the file and group in errors. Raises
    :class:`~rattlefit.errors.RattlefitError` for another format version or test point."""
    if g.attrs.get("format") != FORMAT or int(g.attrs.get("version", -1)) != VERSION:
        raise RattlefitError(
            f"{where}@format: expected {FORMAT} version {VERSION}, got "
            f"{g.attrs.get('format')} {g.attrs.get('version')}"
        )
    key = str(g.attrs["key"])
    if key != test_point_key(problem):
        raise RattlefitError(
            f"{where}@key: learned for another test point (gear pair, operating point, "
            "drive, priors or simulator options differ); learn anew"
        )
    default = DensityOptions()
    options = DensityOptions(**{n: type(getattr(default, n))(g.attrs[n]) for n in SHAPE})
    design = Design(np.asarray(g["design_u"]), np.asarray(g["design_features"]))
    densities = []
    for r in range(problem.n_rec):
        d = g[f"density_{r}"]
        columns = tuple(int(c) for c in d.attrs["columns"])
        shape = skeleton(len(columns), problem.data.shape[-1], columns, options)
        densities.append(eqx.tree_deserialise_leaves(io.BytesIO(d[()].tobytes()), shape))
    like = LearnedLikelihood(tuple(densities), jnp.asarray(problem.data), problem.specs)
    return Learned(like, design, key, int(g.attrs["seed"]), options)


def read_learned(path: str | os.PathLike, problem: Problem) -> Learned:
    """The learned likelihood stored in the file ``path`` (:func:`read_group`). Raises
    :class:`~rattlefit.errors.RattlefitError` naming the file and the field when it is not
    a stored likelihood, has another format version, or was learned for another test
    point."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            if GROUP not in f:
                raise RattlefitError(f"{path}: /{GROUP}: missing; not a learned likelihood")
            return Learned.load(f[GROUP], problem, f"{path}: /{GROUP}")
    except RattlefitError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise RattlefitError(f"{path}: /{GROUP}: unreadable learned likelihood ({exc})") from exc

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
from pathlib import Path

import equinox as eqx
import h5py
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import RattlefitError
from ..problem.problem import Problem
from .density import DensityOptions, FeatureDensity, Whitening, make_flow
from .learn import Design
from .model import LearnedLikelihood

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


def write_learned(
    path: str | os.PathLike,
    like: LearnedLikelihood,
    design: Design,
    *,
    key: str,
    seed: int,
    options: DensityOptions,
) -> Path:
    """Write ``like`` (see :func:`write_group`) to the file ``path``, atomically; returns it."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with h5py.File(tmp, "w") as f:
        write_group(f.create_group(GROUP), like, design, key=key, seed=seed, options=options)
    os.replace(tmp, path)
    return path


@dataclasses.dataclass(frozen=True)
class Learned:
    """A stored learned likelihood: the likelihood (on the problem it was read for), its
    design, key, seed and flow options."""

    likelihood: LearnedLikelihood
    design: Design
    key: str
    seed: int
    options: DensityOptions


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
            return read_group(f[GROUP], problem, f"{path}: /{GROUP}")
    except RattlefitError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise RattlefitError(f"{path}: /{GROUP}: unreadable learned likelihood ({exc})") from exc

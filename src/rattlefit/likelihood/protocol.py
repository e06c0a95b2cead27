"""The likelihood contract: how a fit's recordings are scored, whatever the kind.

``identify`` makes one :class:`Likelihood`; the fit's
:class:`~rattlefit.inference.result.FittedState` holds it, and the posterior, the diagnosis and
the test planning use only this contract. Two kinds exist: the synthetic likelihood
(:class:`~rattlefit.likelihood.synthetic.SyntheticLikelihood`, simulated ensembles) and the
learned one (:class:`~rattlefit.likelihood.store.Learned`, feature densities learned from
simulations). A new kind implements the protocol and registers its ``load`` in
:data:`KINDS`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, Protocol, runtime_checkable

import h5py
import numpy as np

from ..errors import RattlefitError
from ..problem.problem import Problem
from .noise import NoiseModel
from .store import Learned
from .synthetic import SyntheticLikelihood


@runtime_checkable
class Likelihood(Protocol):
    """p(d | z) of a problem's recordings ``d`` at the fit's coordinates ``z``.

    kind : the kind's name, stored with it (``"synthetic"``, ``"learned"``).
    noise : the :class:`~rattlefit.likelihood.noise.NoiseModel` at the fit's optimum: how the
        data rows are weighted where a residual is scored by simulation (the diagnosis).
    """

    kind: ClassVar[str]
    noise: NoiseModel

    def bind(self, problem: Problem) -> Likelihood:
        """This likelihood of ``problem``'s recordings (their measured features its data)."""
        ...

    def log_density(self, zs) -> np.ndarray:
        """log p(d | z) up to a constant at each point of ``zs`` (K, P): (K,), ``-inf`` or
        NaN where it cannot be evaluated."""
        ...

    def information(self, z, names: Sequence[str], *, rng: np.random.Generator) -> np.ndarray:
        """The recordings' Fisher information (P, P) about the parameters ``names`` at ``z``,
        per unit log of each."""
        ...

    def save(self, g: h5py.Group) -> None:
        """Write what :func:`load_likelihood` needs into the HDF5 group ``g``."""
        ...


#: Each kind's ``load(group, problem, where)``.
KINDS = {"synthetic": SyntheticLikelihood.load, "learned": Learned.load}


def save_likelihood(g: h5py.Group, likelihood: Likelihood) -> None:
    """Write ``likelihood`` and its kind into the HDF5 group ``g``."""
    g.attrs["kind"] = likelihood.kind
    likelihood.save(g)


def load_likelihood(g: h5py.Group, problem: Problem, where: str) -> Likelihood:
    """The likelihood :func:`save_likelihood` wrote into ``g``, bound to ``problem``;
    ``where`` names the file and group in the :class:`~rattlefit.errors.RattlefitError`
    raised for an unknown kind or a malformed group."""
    kind = g.attrs.get("kind")
    if kind not in KINDS:
        raise RattlefitError(
            f"{where}@kind: unknown likelihood kind {kind!r}; known: {', '.join(KINDS)}"
        )
    return KINDS[str(kind)](g, problem, where)

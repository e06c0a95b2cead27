"""How a fit's search ended, as a value: the wording is the report's
(:func:`rattlefit.report.wording.search_sentence`)."""

from __future__ import annotations

import dataclasses
import enum


class SearchOutcome(enum.StrEnum):
    """How the optimiser's runs of a fit ended.

    ``CONVERGED``: every run met its tolerance. ``STALLED``: every run ended by its own
    criterion, at least one because its last trial steps were all rejected (the cost's noise
    floor of a synthetic likelihood). ``STEP_LIMIT``: a run stopped at its step limit, and the
    estimate is its last iterate. The value is the JSON spelling.
    """

    CONVERGED = "converged"
    STALLED = "stalled"
    STEP_LIMIT = "step_limit"

    @property
    def success(self) -> bool:
        """True unless a run stopped at its step limit."""
        return self is not SearchOutcome.STEP_LIMIT


@dataclasses.dataclass(frozen=True)
class SearchEnd:
    """A fit's search: its outcome, how many optimiser runs it made, how many of those
    stalled and how many times the fit was re-centred on its profiles' minimum."""

    outcome: SearchOutcome = SearchOutcome.CONVERGED
    runs: int = 1
    stalled_runs: int = 0
    recentred: int = 0

    def to_dict(self) -> dict:
        """The JSON fields: ``outcome`` (a :class:`SearchOutcome` value), ``runs``,
        ``stalled_runs``, ``recentred``."""
        return {**dataclasses.asdict(self), "outcome": self.outcome.value}

    @classmethod
    def from_dict(cls, doc: dict) -> SearchEnd:
        """The inverse of :meth:`to_dict`; raises ``ValueError`` for an unknown outcome."""
        return cls(
            SearchOutcome(doc["outcome"]),
            int(doc.get("runs", 1)),
            int(doc.get("stalled_runs", 0)),
            int(doc.get("recentred", 0)),
        )


def search_end(converged: bool, stalled: tuple[bool, ...], recentred: int = 0) -> SearchEnd:
    """The :class:`SearchEnd` of runs that all ended by their criterion (``converged``) or
    not, ``stalled`` saying which of them stalled."""
    if not converged:
        outcome = SearchOutcome.STEP_LIMIT
    elif any(stalled):
        outcome = SearchOutcome.STALLED
    else:
        outcome = SearchOutcome.CONVERGED
    return SearchEnd(outcome, max(len(stalled), 1), sum(stalled), recentred)

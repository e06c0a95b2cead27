"""The JSON documents rattlefit writes, each tagged with its format and version.

``identify -o`` writes a fit (:data:`FIT`), ``sample -o`` a posterior (:data:`POSTERIOR`),
``diagnose -o`` a diagnosis (:data:`DIAGNOSIS`). Every document opens with ``format`` and
``version``; every reader refuses another format or version with one error naming the document,
the field and the command that writes a current one. A version is raised when a field changes
meaning.
"""

from __future__ import annotations

import dataclasses

from .errors import RattlefitError


@dataclasses.dataclass(frozen=True)
class DocumentFormat:
    """A document's ``format`` tag, its current ``version`` and the command that writes it."""

    tag: str
    version: int
    writer: str

    def header(self) -> dict:
        """The fields a document of this format opens with."""
        return {"format": self.tag, "version": self.version}

    def check(self, doc: dict, where: str) -> None:
        """Raise :class:`~rattlefit.errors.RattlefitError` naming ``where`` unless ``doc``
        carries this format's tag and version."""
        got = (doc.get("format"), doc.get("version"))
        if got != (self.tag, self.version):
            raise RattlefitError(
                f"{where}: format: expected {self.tag!r} version {self.version}, got "
                f"{got[0]!r} version {got[1]!r} ({self.writer} again with this rattlefit)"
            )


FIT = DocumentFormat("rattlefit.fit", 2, "identify")
POSTERIOR = DocumentFormat("rattlefit.posterior", 1, "sample")
DIAGNOSIS = DocumentFormat("rattlefit.diagnosis", 3, "diagnose")

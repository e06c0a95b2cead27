"""The independent simulator's recordings (``truth.json`` beside them) as references.

They are found at ``$RATTLEFIT_SHARED_RECORDINGS``, else at ``../shared/recordings`` from the
working directory (the repository's root, where tests, benchmarks and studies run), else in the
repository's copy, ``tests/data/independent``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

#: The environment variable that points at the recordings' directory.
RECORDINGS_ENV = "RATTLEFIT_SHARED_RECORDINGS"


#: The repository's copy, from its root.
COPY = Path("tests") / "data" / "independent"


def recordings_dir(root: str | os.PathLike | None = None) -> Path:
    """The directory of the independent recordings (which may not exist): the environment
    variable's, else the first of ``root/../shared/recordings`` and ``root/``:data:`COPY`
    that exists (``root``: the repository's root, default the working directory)."""
    env = os.environ.get(RECORDINGS_ENV)
    if env:
        return Path(env)
    root = Path(root or Path.cwd()).resolve()
    beside = root.parent / "shared" / "recordings"
    return beside if beside.is_dir() or not (root / COPY).is_dir() else root / COPY


def truth() -> dict:
    """``truth.json``: per recording name (the file's stem), its true parameters."""
    return json.loads((recordings_dir() / "truth.json").read_text())


def operating_points(names) -> list:
    """(name, RigSetup, truth dict) of each named recording, in the order given."""
    from .. import rig
    from ..io.recording import read_recording

    known = truth()
    root = recordings_dir()
    return [(n, rig.setup(read_recording(root / f"{n}.h5")), known[n]) for n in names]


def truth_params(setup, known: dict):
    """The :class:`~rattlefit.RattleParams` of a recording's truth (a ``truth.json`` entry) on
    its rig ``setup``."""
    from ..physics.model import RattleParams

    return RattleParams(
        known["a_mm"] * 1e-3,
        known["drag_torque_Nm"],
        known["viscosity_Pa_s"],
        setup.geometry.backlash,
    )

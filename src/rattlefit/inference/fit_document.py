"""The fit's JSON document (``identify -o``) read back, validated, with its state.

The document is ``FitResult.to_json()`` (:mod:`rattlefit.inference.result`): ``format``
(:data:`rattlefit.documents.FIT`), ``version``, ``parameters``, ``fit``, ``spectra`` and
``state``, the
:class:`~rattlefit.inference.result.FittedState` that sampling and diagnosis start from (the
optimum ``z`` and its Laplace covariance in the fit's coordinates, the noise model fixed at the
optimum, each recording's features and MAP parameters, and the recordings' counts' SHA-256).
Floats are written by their ``repr``, so a fit read back (:func:`read_fit`) holds the same
state to the last bit, and a diagnosis started from it is the one started from the fit in
memory.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..documents import FIT
from ..errors import RattlefitError
from ..io.recording import Recording, counts_sha256
from ..likelihood.noise import NoiseModel
from ..likelihood.store import read_learned
from ..likelihood.synthetic import SyntheticLikelihood
from ..problem.options import FitOptions
from .outcome import SearchEnd
from .result import (
    NOISE_ARRAYS,
    Estimates,
    FitResult,
    FittedState,
    ParameterEstimate,
    Provenance,
    Spectra,
    Statistics,
)


def read_fit(path: str | os.PathLike, recordings: Sequence[Recording] | None = None) -> FitResult:
    """The fit that ``identify -o`` wrote to ``path``, with the state sampling and diagnosis
    start from. With ``recordings``, they must be the fitted ones, in order (matched by their
    counts, :func:`~rattlefit.io.recording.counts_sha256`, wherever the files now lie), and
    the fit is re-pointed at their paths. Raises :class:`~rattlefit.errors.RattlefitError`
    naming the file and the field for a file that is not such a document, of another format or
    version, one written without its state (identify again), or recordings it was not fitted
    to."""
    file = os.fspath(path)
    try:
        doc = json.loads(Path(file).read_text(encoding="utf-8"))
    except OSError as exc:
        raise RattlefitError(f"{file}: cannot read the fit ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise RattlefitError(f"{file}: not JSON ({exc})") from None
    fit = fit_of(doc, file)
    return fit if recordings is None else fitted_to(fit, recordings, file)


def fitted_to(fit: FitResult, recordings: Sequence[Recording], file: str) -> FitResult:
    """``fit`` re-pointed at ``recordings``' paths, after checking that they are the ones it
    was fitted to, in order (raises naming ``file`` and the first that is not)."""
    known = fit.provenance.recordings_sha256
    given = [counts_sha256(r) for r in recordings]
    if len(given) != len(known):
        raise RattlefitError(
            f"{file}: fit/recordings: the fit is of {len(known)} recording(s), {len(given)} given"
        )
    for k, (a, b) in enumerate(zip(known, given, strict=True)):
        if a != b:
            name = recordings[k].path or f"recording {k + 1}"
            raise RattlefitError(
                f"{file}: fit/recordings/{k}: {name} is not the recording fitted there "
                f"({fit.provenance.recordings[k]}): its counts differ"
            )
    paths = [str(r.path) for r in recordings]
    fit = dataclasses.replace(fit, provenance=dataclasses.replace(fit.provenance, recordings=paths))
    return with_stored_likelihood(fit, recordings, file)


def stored_likelihood_file(fit: FitResult, file: str) -> Path | None:
    """The learned likelihood file ``identify -o`` stored beside the fit's document ``file``
    (its ``fit.likelihood.file``, else ``X.likelihood.h5`` beside ``X.json``); None for a
    fit on the synthetic likelihood or when the file is not there."""
    if fit.provenance.likelihood.get("method") != "learned":
        return None
    named = fit.provenance.likelihood.get("file")
    for path in (Path(named) if named else None, Path(file).with_suffix(".likelihood.h5")):
        if path is not None and path.is_file():
            return path
    return None


def with_stored_likelihood(fit: FitResult, recordings: Sequence[Recording], file: str):
    """``fit`` holding its learned likelihood (:func:`stored_likelihood_file`), with the
    document's noise model, when the file is there; else ``fit`` as read."""
    path = stored_likelihood_file(fit, file)
    if path is None:
        return fit
    problem = fit.problem_for(recordings)
    learned = dataclasses.replace(read_learned(path, problem), noise=fit.state.likelihood.noise)
    state = dataclasses.replace(fit.state, likelihood=learned, problem=problem)
    return dataclasses.replace(fit, state=state)


def fit_of(doc, file: str = "<fit>") -> FitResult:
    """:func:`read_fit` of a document already parsed, ``file`` naming it in errors."""
    if not isinstance(doc, dict):
        raise RattlefitError(f"{file}: expected a JSON object written by rattlefit identify -o")
    FIT.check(doc, file)
    for key in ("parameters", "fit", "spectra", "state"):
        if not isinstance(doc.get(key), dict):
            problem = "missing" if key not in doc else "not an object"
            hint = "; the fit had no noise model to keep" if key == "state" else ""
            raise RattlefitError(f"{file}: {key}: {problem}{hint}")
    try:
        return FitResult(
            estimates_of_document(doc),
            statistics_of_document(doc["fit"]),
            spectra_of_document(doc),
            provenance_of_document(doc),
            fitted_state_of_document(doc),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise RattlefitError(f"{file}: a field is missing or malformed ({exc!r})") from None


def estimates_of_document(doc: dict) -> Estimates:
    fit, state = doc["fit"], doc["state"]
    return Estimates(
        parameters={k: ParameterEstimate(**p) for k, p in doc["parameters"].items()},
        names=list(fit["correlation"]["names"]),
        correlation=np.asarray(fit["correlation"]["matrix"], dtype=float),
        map_params=[dict(p) for p in state["map_params"]],
        profile=dict(fit.get("profile") or {}),
        profiles={k: [tuple(p) for p in v] for k, v in (fit.get("profiles") or {}).items()},
    )


def statistics_of_document(fit: dict) -> Statistics:
    return Statistics(
        chi2=float(fit["chi2"]),
        dof=int(fit["dof"]),
        chi2_recordings=[float(c) for c in fit.get("chi2_per_recording") or []],
        regime_share=[float(s) for s in fit.get("regime_share_per_recording") or []],
        n_iterations=int(fit.get("iterations", 0)),
        search=SearchEnd.from_dict(fit["search"]),
    )


def spectra_of_document(doc: dict) -> Spectra:
    state = doc["state"]
    return Spectra(
        measured=[np.asarray(f, dtype=float) for f in state["features"]],
        fitted=[np.asarray(f, dtype=float) for f in state["fitted_features"]],
        sigma=[np.asarray(f, dtype=float) for f in state["sigma_features"]],
        band_centers=np.asarray(doc["spectra"]["band_centers_hz"], dtype=float),
    )


def provenance_of_document(doc: dict) -> Provenance:
    fit = doc["fit"]
    return Provenance(
        recordings=[str(p) for p in fit["recordings"]],
        seed=int(fit["seed"]),
        wall_time=float(fit.get("wall_time_s", 0.0)),
        platform=dict(fit.get("platform") or {}),
        likelihood=dict(fit.get("likelihood") or {}),
        recordings_sha256=list(doc["state"]["recordings_sha256"]),
    )


def fitted_state_of_document(doc: dict) -> FittedState:
    state, noise = doc["state"], doc["state"]["noise"]
    share = noise.get("regime_share")
    model = NoiseModel(
        *(np.asarray(noise[k], dtype=float) for k in NOISE_ARRAYS),
        int(noise["sigma_dof"]),
        None if share is None else np.asarray(share, dtype=float),
    )
    options = FitOptions.from_dict(doc["fit"]["options"])
    return FittedState(
        options,
        np.asarray(state["z"], dtype=float),
        np.asarray(state["covariance_z"], dtype=float),
        likelihood=SyntheticLikelihood.of_fit(model, None, options),
    )

"""The HTML report's inputs checked: the JSON documents of identify, sample and diagnose, the
recordings a fit names, and an ArviZ posterior given as a file or an object. Every problem is a
:class:`~rattlefit.errors.RattlefitError` naming the document (or file), the field and what is
wrong."""

from __future__ import annotations

import json
from pathlib import Path

from ..documents import DIAGNOSIS, FIT, POSTERIOR
from ..errors import RattlefitError
from ..io.recording import Recording, read_recording
from ..io.schema import MEMORY
from ..quantities import FILM, base_name

#: Fields each document must hold, as paths of keys: what the report reads.
REQUIRED = {
    "fit": (
        ("parameters",),
        ("fit", "chi2"),
        ("fit", "dof"),
        ("fit", "p_value"),
        ("fit", "recordings"),
        ("spectra", "band_centers_hz"),
        ("spectra", "measured"),
        ("spectra", "fitted"),
        ("spectra", "sigma"),
    ),
    "posterior": (("parameters",), ("sampler", "ess"), ("sampler", "reliable")),
    "diagnosis": (
        ("verdict",),
        ("baseline", "chi2"),
        ("effects",),
        ("missed_bands",),
        ("residuals",),
        ("band_centers_hz",),
    ),
}
#: The format each kind of document must carry.
FORMATS = {"fit": FIT, "posterior": POSTERIOR, "diagnosis": DIAGNOSIS}
#: Fields of each entry of a fit's ``parameters``.
PARAMETER_FIELDS = ("unit", "lower", "upper", "identified", "bound")


def check(doc, kind: str, source: str | None = None) -> dict:
    """``doc`` if it is a ``kind`` document (``"fit"``, ``"posterior"`` or ``"diagnosis"``:
    what identify, sample and diagnose write with ``-o``); raises naming ``source`` (default:
    ``kind``), the first missing field and the command that writes such a document."""
    where = source or kind
    writer = {"fit": "identify", "posterior": "sample", "diagnosis": "diagnose"}[kind]
    if not isinstance(doc, dict):
        raise RattlefitError(
            f"{where}: expected a JSON object written by rattlefit {writer} -o, "
            f"got {type(doc).__name__}"
        )
    for keys in REQUIRED[kind]:
        node = doc
        for depth, key in enumerate(keys):
            if not isinstance(node, dict) or key not in node:
                field = "/".join(keys[: depth + 1])
                raise RattlefitError(
                    f"{where}: {field}: missing; not the output of rattlefit {writer} -o"
                )
            node = node[key]
    FORMATS[kind].check(doc, where)
    renamed(doc)
    if kind == "fit":
        for name, p in doc["parameters"].items():
            missing = [f for f in PARAMETER_FIELDS if not isinstance(p, dict) or f not in p]
            if missing:
                raise RattlefitError(f"{where}: parameters/{name}/{missing[0]}: missing")
    return doc


#: Parameter names of earlier versions, read as today's: ``a`` was the film half-length.
OLD_NAMES = {"a": FILM}


def new_name(name: str) -> str:
    """Today's name of parameter ``name`` (``a[oil_jet]`` → ``film_half_length[oil_jet]``)."""
    base = base_name(name)
    return OLD_NAMES.get(base, base) + name[len(base) :]


def renamed(doc: dict) -> None:
    """Rename, in place, the parameter keys of a document written before the film
    half-length was named ``film_half_length`` (``parameters`` and ``fit/profiles``)."""
    tables = [doc.get("parameters"), doc.get("fit", {}).get("profiles")]
    for table in tables:
        if isinstance(table, dict) and any(new_name(k) != k for k in table):
            items = list(table.items())  # renamed in place, in their order
            table.clear()
            table.update((new_name(k), v) for k, v in items)


def load_json(path: str | Path, kind: str) -> dict:
    """The ``kind`` document in the JSON file ``path`` (:func:`check`); raises naming the file
    when it is absent, unreadable, not JSON or not such a document."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise RattlefitError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RattlefitError(f"{path}: unreadable ({exc})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RattlefitError(
            f"{path}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None
    return check(doc, kind, str(path))


def recordings_of(fit: dict, recordings: list[Recording] | None) -> list[Recording]:
    """The fit's recordings: ``recordings`` when given (as many as the fit has), else read from
    the paths in ``fit["fit"]["recordings"]``; raises naming a file that is missing."""
    paths = list(fit["fit"]["recordings"])
    if recordings is not None:
        if len(recordings) != len(paths):
            raise RattlefitError(
                f"recordings: {len(recordings)} given, but the fit was made on {len(paths)} "
                f"({', '.join(paths)})"
            )
        return list(recordings)
    out = []
    for p in paths:
        if p == MEMORY or not Path(p).is_file():
            raise RattlefitError(
                f"{p}: recording named in the fit's fit/recordings not found; give the "
                "recordings explicitly (recordings=…, or --recording FILE)"
            )
        out.append(read_recording(p))
    return out


def same_recordings(doc_paths, fit_paths, where: str) -> None:
    """Raise naming ``where`` when a document was made on other recordings than the fit
    (compared by file name; recordings never read from a file are not compared)."""
    a = [Path(p).name for p in doc_paths]
    b = [Path(p).name for p in fit_paths]
    if MEMORY in doc_paths or MEMORY in fit_paths:
        return
    if a != b:
        raise RattlefitError(
            f"{where}: made on {', '.join(a)}, but the fit on {', '.join(b)}; give documents "
            "of the same recordings"
        )


def load_inference_data(source):
    """An ``arviz.InferenceData`` from ``source`` (one, or the path of a netCDF file that
    ``Posterior.save_netcdf`` wrote); None for None. Raises naming the file when it is
    missing, not netCDF, or has no ``posterior`` group."""
    if source is None:
        return None
    import arviz as az

    where = "inference_data"
    if isinstance(source, str | Path):
        where = str(source)
        if not Path(source).is_file():
            raise RattlefitError(f"{where}: no such file")
        try:
            source = az.from_netcdf(str(source))
        except Exception as exc:
            raise RattlefitError(f"{where}: not an ArviZ netCDF file ({exc})") from None
    if not hasattr(source, "groups") or "posterior" not in source.groups():
        raise RattlefitError(f"{where}: /posterior: missing; not a rattlefit posterior")
    return source


def idata_recordings(idata) -> list[str] | None:
    """The recordings' paths an ``InferenceData`` of rattlefit names (its ``recordings``
    attribute), or None when it names none."""
    text = idata.posterior.attrs.get("recordings")
    if text is None:
        return None
    try:
        return list(json.loads(text))
    except (TypeError, ValueError):
        return None

"""A fit as a table file: one row per parameter, for spreadsheets and the rig's own tools."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

from ..util import atomic_write

#: The columns of :func:`fit_rows`, in order (SI units, as the JSON).
FIT_COLUMNS = (
    "parameter",
    "estimate",
    "lower",
    "upper",
    "unit",
    "identified",
    "bound",
    "chi2",
    "dof",
    "p_value",
    "poor_fit",
    "converged",
    "seed",
    "rattlefit_version",
    "recordings",
)


def fit_rows(doc: dict) -> list[dict]:
    """One row per parameter of a fit's JSON (``FitResult.to_json()``, what ``identify -o``
    writes): its estimate and 95 % interval (SI), whether identified, and the fit's χ², dof, p,
    poor fit, convergence, seed, rattlefit's version and recordings (joined by ``;``)."""
    fit = doc["fit"]
    common = {
        "chi2": fit["chi2"],
        "dof": fit["dof"],
        "p_value": fit["p_value"],
        "poor_fit": bool(fit["poor_fit"]),
        "converged": bool(fit.get("success", True)),
        "seed": fit.get("seed"),
        "rattlefit_version": fit.get("platform", {}).get("rattlefit", ""),
        "recordings": ";".join(Path(p).name for p in fit.get("recordings", [])),
    }
    return [
        {
            "parameter": name,
            "estimate": p.get("estimate"),
            "lower": p["lower"],
            "upper": p["upper"],
            "unit": p["unit"],
            "identified": bool(p["identified"]),
            "bound": p.get("bound") or "",
            **common,
        }
        for name, p in doc["parameters"].items()
    ]


def write_fit_csv(path: str | os.PathLike[str], doc: dict) -> Path:
    """:func:`fit_rows` of ``doc`` as CSV at ``path`` (12 significant digits), written through a
    temporary file renamed into place; returns ``path``."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=FIT_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in fit_rows(doc):
        writer.writerow({k: f"{v:.12g}" if isinstance(v, float) else v for k, v in row.items()})
    text = buffer.getvalue()
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))

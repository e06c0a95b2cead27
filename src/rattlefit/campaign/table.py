"""The campaign's results table: one row per recording × parameter, tidy, as Parquet and CSV.

A unit's rows come from its identification's JSON and its recordings' descriptions
(:func:`unit_rows`); a joint fit gives each of its recordings the parameters that apply to it
(the shared ones, its lubrication's film, its own backlash). The columns (SI units, as the
JSON):

* the identification: ``fit`` (the unit's name), ``joint``, ``key`` (the content hash the
  campaign resumes by);
* the recording: ``recording`` (its file), ``recording_name``, ``recording_sha256``,
  ``pair``, ``center_distance_mm``, ``lubrication``, ``oil_temperature_c``,
  ``mean_speed_rad_s``, ``fluctuation_pct``, ``frequency_hz``, ``duration_s``;
* the parameter: ``parameter`` (its quantity, e.g. ``film_half_length``, ``backlash``),
  ``fit_parameter`` (its name in the fit, e.g. ``film_half_length[boundary]``,
  ``backlash[1]``), ``unit``, ``estimate``, ``lower``, ``upper`` (the 95 % interval; the
  viscosity at the recording's own oil temperature), ``bound``, ``identified``, ``truth`` (a
  synthetic recording's, else empty);
* the fit: ``chi2``, ``dof``, ``p_value``, ``poor_fit``, ``converged`` (False where a search
  stopped at its step limit), ``below_optimum`` (how far the profiles reach below the
  optimum's cost; 0 where they do not), ``seed``, ``rattlefit_version``;
* when asked for: ``posterior_median``, ``posterior_lower``, ``posterior_upper`` (the 95 %
  credible interval) and ``diagnosis`` (the verdict).
"""

from __future__ import annotations

from pathlib import Path

from ..quantities import VISCOSITY, base_name, index_of
from ..util import atomic_write
from .manifest import Unit

#: The recording's fields of :func:`rattlefit.campaign.work.describe` the rows repeat.
RECORDING_FIELDS = (
    "pair",
    "center_distance_mm",
    "lubrication",
    "oil_temperature_c",
    "mean_speed_rad_s",
    "fluctuation_pct",
    "frequency_hz",
    "duration_s",
)
#: The table's columns, in order.
COLUMNS = (
    "fit",
    "joint",
    "key",
    "recording",
    "recording_name",
    "recording_sha256",
    *RECORDING_FIELDS,
    "parameter",
    "fit_parameter",
    "unit",
    "estimate",
    "lower",
    "upper",
    "bound",
    "identified",
    "truth",
    "chi2",
    "dof",
    "p_value",
    "poor_fit",
    "converged",
    "below_optimum",
    "seed",
    "rattlefit_version",
    "posterior_median",
    "posterior_lower",
    "posterior_upper",
    "diagnosis",
)
#: The file names of the table in the campaign's directory.
PARQUET, CSV = "results.parquet", "results.csv"


def applies_to(name: str, k: int, lubrication: str) -> bool:
    """Whether fit parameter ``name`` belongs to the fit's recording ``k`` of
    ``lubrication``: shared (no index), its lubrication's (``[boundary]``) or its own
    (``[k]``)."""
    index = index_of(name)
    return index is None or index == lubrication or index == str(k)


def unit_rows(unit: Unit, doc: dict, recordings: list[dict], *, version: str) -> list[dict]:
    """The table rows of one identification: ``doc`` is its JSON
    (:meth:`rattlefit.FitResult.to_json`), ``recordings`` its recordings' descriptions in
    the fit's order; ``version`` the rattlefit version that fitted it. The fit reports the
    viscosity at its first recording's oil temperature; each recording's row gives it at its
    own, scaled by the description's ``viscosity_factor`` (its oil's viscosity over the first
    recording's; 1 when absent), which the row keeps as ``scale`` (not a table column)."""
    fit = doc["fit"]
    rows = []
    for k, rec in enumerate(recordings):
        for name, p in doc["parameters"].items():
            if not applies_to(name, k, rec["lubrication"]):
                continue
            quantity = base_name(name)
            scale = rec.get("viscosity_factor", 1.0) if quantity == VISCOSITY else 1.0
            rows.append(
                {
                    "fit": unit.name,
                    "joint": unit.joint,
                    "recording": rec["recording"],
                    "recording_name": rec["name"],
                    "recording_sha256": rec["sha256"],
                    **{f: rec[f] for f in RECORDING_FIELDS},
                    "parameter": quantity,
                    "fit_parameter": name,
                    "unit": p["unit"],
                    "estimate": None if p.get("estimate") is None else p["estimate"] * scale,
                    "lower": p["lower"] * scale,
                    "upper": p["upper"] * scale,
                    "bound": p.get("bound") or "",
                    "identified": bool(p["identified"]),
                    "truth": rec.get("truth", {}).get(quantity),
                    "chi2": fit["chi2"],
                    "dof": fit["dof"],
                    "p_value": fit["p_value"],
                    "poor_fit": bool(fit["poor_fit"]),
                    "converged": bool(fit.get("success", True)),
                    "below_optimum": (fit.get("below_optimum") or {}).get("depth", 0.0),
                    "seed": fit["seed"],
                    "rattlefit_version": version,
                    "scale": scale,
                }
            )
    return rows


def with_posterior(rows: list[dict], posterior: dict | None) -> list[dict]:
    """``rows`` with the posterior's median and 95 % credible interval of each fit
    parameter (``sample -o``'s JSON); unchanged without one."""
    if posterior is None:
        return rows
    found = posterior["parameters"]
    out = []
    for row in rows:
        p = found.get(row["fit_parameter"])
        if p is not None:
            scale = row.get("scale", 1.0)
            row = {
                **row,
                "posterior_median": p["median"] * scale,
                "posterior_lower": p["lower"] * scale,
                "posterior_upper": p["upper"] * scale,
            }
        out.append(row)
    return out


def with_diagnosis(rows: list[dict], diagnosis: dict | None) -> list[dict]:
    """``rows`` with the diagnosis' verdict (``diagnose -o``'s ``verdict``)."""
    if diagnosis is None:
        return rows
    return [{**row, "diagnosis": diagnosis["verdict"]} for row in rows]


def results_frame(rows: list[dict]):
    """The rows as a pandas DataFrame with :data:`COLUMNS` (missing values empty)."""
    import pandas as pd

    frame = pd.DataFrame.from_records(rows, columns=list(COLUMNS))
    for column in ("truth", "posterior_median", "posterior_lower", "posterior_upper"):
        frame[column] = pd.to_numeric(frame[column], errors="coerce")
    frame["diagnosis"] = frame["diagnosis"].astype(object).fillna("").astype(str)
    return frame


def write_table(directory: str | Path, rows: list[dict]) -> tuple[Path, Path]:
    """Write the rows as ``results.parquet`` (full precision) and ``results.csv`` (12
    significant digits) in ``directory``, each atomically; returns both paths."""
    frame = results_frame(rows)
    directory = Path(directory)
    parquet = atomic_write(directory / PARQUET, lambda tmp: frame.to_parquet(tmp, index=False))
    # 12 significant digits: a value's float noise (65.40000000000002) is not printed
    csv = atomic_write(
        directory / CSV, lambda tmp: frame.to_csv(tmp, index=False, float_format="%.12g")
    )
    return parquet, csv


def read_table(directory: str | Path):
    """The results table a campaign wrote in ``directory`` (a pandas DataFrame)."""
    import pandas as pd

    return pd.read_parquet(Path(directory) / PARQUET)

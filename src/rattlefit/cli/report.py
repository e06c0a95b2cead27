"""``rattlefit report``: one HTML file of a fit, a posterior and a diagnosis."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import RattlefitError
from .common import (
    clean_errors,
)


@click.command()
@click.option(
    "--fit",
    "fit_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="identify's JSON (-o).",
)
@click.option(
    "--posterior",
    "posterior_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="sample's JSON (-o).",
)
@click.option(
    "--netcdf",
    type=click.Path(dir_okay=False, path_type=Path),
    help="sample's ArviZ netCDF file, for the trace, pair and predictive plots [default: the "
    ".nc beside --posterior or beside its chain file, when there is one].",
)
@click.option(
    "--diagnosis",
    "diagnosis_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="diagnose's JSON (-o).",
)
@click.option(
    "--recording",
    "recording_files",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The fitted recordings, in the fit's order (repeatable) [default: the paths the fit "
    "names, also looked for beside --fit].",
)
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The HTML report to write.",
)
@clean_errors
def report(fit_file, posterior_file, netcdf, diagnosis_file, recording_files, output) -> None:
    """Write one self-contained HTML report (figures inside, nothing fetched) of an
    identification and, when given, its posterior and diagnosis."""
    from ..io.recording import read_recording
    from ..report import write_report
    from ..report.inputs import load_json

    fit = load_json(fit_file, "fit")
    posterior = None if posterior_file is None else load_json(posterior_file, "posterior")
    diagnosis = None if diagnosis_file is None else load_json(diagnosis_file, "diagnosis")
    if netcdf is None and posterior is not None:
        netcdf = netcdf_beside(posterior_file, posterior)
        if netcdf is not None:
            click.echo(f"using {netcdf} (ArviZ netCDF beside the posterior)", err=True)
    if recording_files:
        recordings = [read_recording(f) for f in recording_files]
    else:
        recordings = [read_recording(f) for f in fit_recording_paths(fit, fit_file)]
    write_report(
        output,
        fit=fit,
        posterior=posterior,
        inference_data=netcdf,
        diagnosis=diagnosis,
        recordings=recordings,
    )
    click.echo(f"wrote {output}", err=True)


def netcdf_beside(posterior_file: Path, posterior: dict) -> Path | None:
    """The netCDF file ``sample`` wrote beside the posterior's JSON or its chain file."""
    candidates = [posterior_file.with_suffix(".nc")]
    backend = posterior["sampler"].get("backend")
    if backend:
        candidates.append(Path(backend).with_suffix(".nc"))
    return next((c for c in candidates if c.is_file()), None)


def fit_recording_paths(fit: dict, fit_file: Path) -> list[Path]:
    """The recordings the fit names, a relative one also looked for beside the fit's JSON;
    raises naming one found in neither place."""
    out = []
    for name in fit["fit"]["recordings"]:
        path = Path(name)
        if not path.is_file() and not path.is_absolute() and (fit_file.parent / path).is_file():
            path = fit_file.parent / path
        if not path.is_file():
            raise RattlefitError(
                f"{name}: recording named in {fit_file} (fit/recordings) not found; give it "
                "with --recording FILE"
            )
        out.append(path)
    return out

"""``rattlefit identify``: a fit, its table, JSON, CSV, plots and report."""

from __future__ import annotations

from pathlib import Path

import click

from .common import (
    clean_errors,
    drive_option,
    emit,
    likelihood_keywords,
    likelihood_options,
    output_options,
    prior_option,
    priors_of,
    progress_printer,
    realisations_option,
    report_option,
    seed_option,
    write_learned_beside,
    write_report_file,
)

#: Re-simulations of the fitted model behind the report's rattle index (``fit.igr``).
IGR_RESIMULATIONS = 8


def igr_document(result, recordings, seed: int) -> list[dict]:
    """``fit.igr`` of the JSON: each recording's measured IGR and that of
    :data:`IGR_RESIMULATIONS` recordings of the fitted model
    (:func:`~rattlefit.inference.realisation.fitted_igr`, seeded by ``seed``)."""
    from ..inference.realisation import fitted_igr
    from ..rig import setup

    model = fitted_igr(result, recordings, IGR_RESIMULATIONS, seed=seed)
    return [
        {"measured": float(setup(rec).rattle_index()), "model": m, "seed": seed}
        for rec, m in zip(recordings, model, strict=True)
    ]


@click.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@output_options("the result", "plots")
@seed_option("the realisations and the starts")
@realisations_option(
    "Simulated realisations per evaluation of the synthetic likelihood  [default: 6; 3 with "
    "--quick]"
)
@click.option(
    "--starts",
    type=click.IntRange(min=1),
    default=None,
    help="Starting points of the search  [default: 64, twice as many per further lubrication; 16 "
    "with --quick]",
)
@drive_option()
@click.option(
    "--features",
    type=click.Choice(["bands", "bands+folded"]),
    default="bands",
    show_default=True,
    help="What the fit compares: the band PSDs, or those and the drive-cycle-folded "
    "statistics of Δθ* (FitOptions.features).",
)
@likelihood_options
@click.option(
    "--quick",
    is_flag=True,
    help="A rough first look, several times faster, with wider intervals.",
)
@click.option(
    "--suggest",
    is_flag=True,
    help="Also predict which one more recording (longer, another centre distance, "
    "fluctuation, frequency or lubrication) would narrow the intervals most (a minute or two).",
)
@report_option("the fit")
@prior_option
@click.option(
    "--csv",
    "csv_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the parameter table as CSV here (a row per parameter, SI units).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@clean_errors
def identify(
    files,
    output,
    plot_dir,
    seed,
    realisations,
    starts,
    drive,
    features,
    likelihood,
    reuse,
    quick,
    suggest,
    report_file,
    priors,
    csv_file,
    quiet,
) -> None:
    """Fit a, T_b and the viscosity to one recording, or jointly to several of one pair
    (e.g. a backlash sweep; under several lubrications each gets its own a[LUBRICATION])."""
    from ..inference.identify import identify as run
    from ..inference.realisation import fitted_realisations
    from ..io.recording import read_recording
    from ..problem.options import FitOptions
    from ..report import format_table, plot_fit, plot_igr

    recordings = [read_recording(f) for f in files]
    given = {"n_realisations": realisations, "n_starts": starts}
    make = FitOptions.quick if quick else FitOptions
    options = make(
        seed=seed,
        drive=drive,
        features=features,
        priors=priors_of(priors),
        **likelihood_keywords(likelihood, reuse),
        **{k: v for k, v in given.items() if v},
    )
    result = run(recordings, options, progress=progress_printer(quiet))
    text, doc = format_table(result), result.to_json()
    write_learned_beside(result, output, doc)
    if suggest:
        from ..inference.design import plan_document
        from ..inference.design import suggest as plan
        from ..likelihood.information import SIMULATED_REALISATIONS
        from ..report import format_suggestions

        planned = plan(result, recordings, seed=seed, progress=progress_printer(quiet))
        doc["suggest"] = plan_document(planned, seed=seed, realisations=SIMULATED_REALISATIONS)
        text += "\n\n" + format_suggestions(doc["suggest"])
    if report_file is not None or plot_dir is not None:
        doc["fit"]["igr"] = igr_document(result, recordings, seed)
    emit(
        text,
        doc,
        output,
        plot_dir,
        lambda d: [
            *plot_fit(result, recordings, d, fitted_realisations(result, recordings)),
            *plot_igr(doc, d),
        ],
    )
    write_report_file(report_file, fit=doc, recordings=recordings)
    if csv_file is not None:
        from ..report.export import write_fit_csv

        click.echo(f"wrote {write_fit_csv(csv_file, doc)}", err=True)

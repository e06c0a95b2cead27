"""``rattlefit diagnose``: where the model misses a recording, and which effect explains it."""

from __future__ import annotations

from pathlib import Path

import click

from .common import (
    clean_errors,
    emit,
    likelihood_keywords,
    likelihood_options,
    output_options,
    prior_option,
    priors_of,
    progress_printer,
    quick_start_option,
    report_option,
    saved_fit,
    seed_option,
    write_report_file,
)


@click.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--effects",
    default=None,
    help="Comma-separated effects to try [default: rattlefit.physics.effects.DEFAULT_EFFECTS, "
    "every effect but pitch_point_friction].",
)
@seed_option("the fit and the tries")
@quick_start_option
@click.option(
    "--iterations",
    type=click.IntRange(min=0),
    default=3,
    show_default=True,
    help="Gauss–Newton iterations per effect.",
)
@click.option(
    "--every-effect",
    is_flag=True,
    help="Fit every effect to the band spectrum, also those the encoders show no sign of and "
    "when the model fits within its noise (they cannot be named; by default they are skipped).",
)
@likelihood_options
@output_options("the diagnosis", "the band residuals with and without each effect")
@report_option("the diagnosis and the identification it starts from")
@click.option(
    "--fit",
    "fit_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="identify's JSON (-o) of these files: start from it instead of identifying again.",
)
@prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@clean_errors
def diagnose(
    files,
    effects,
    seed,
    quick_fit,
    iterations,
    every_effect,
    likelihood,
    reuse,
    output,
    plot_dir,
    report_file,
    fit_file,
    priors,
    quiet,
):
    """Where the model misses the recordings, which unmodelled effect explains it, and how
    much of the misfit it removes (each effect fitted on top of an identification)."""
    from ..diagnosis.diagnose import DiagnoseOptions
    from ..diagnosis.diagnose import diagnose as run
    from ..io.recording import read_recording
    from ..physics.effects import DEFAULT_EFFECTS, EFFECTS
    from ..problem.options import FitOptions
    from ..report import diagnosis_document, format_diagnosis, plot_diagnosis

    names = DEFAULT_EFFECTS if effects is None else tuple(e.strip() for e in effects.split(","))
    unknown = [n for n in names if n not in EFFECTS]
    if unknown or not names:
        raise click.BadParameter(
            f"unknown effect(s) {', '.join(unknown) or '(none given)'}; known: "
            f"{', '.join(EFFECTS)}",
            param_hint="--effects",
        )
    recordings = [read_recording(f) for f in files]
    make = FitOptions.quick if quick_fit else FitOptions.optimum_only
    fit_options = make(
        seed=seed, priors=priors_of(priors), **likelihood_keywords(likelihood, reuse)
    )
    options = DiagnoseOptions(
        effects=names, fit=fit_options, iterations=iterations, every_effect=every_effect
    )
    baseline = None if fit_file is None else saved_fit(fit_file, recordings, "diagnose")
    diag = run(recordings, options, baseline=baseline, progress=progress_printer(quiet))
    emit(
        format_diagnosis(diag),
        diagnosis_document(diag),
        output,
        plot_dir,
        lambda d: plot_diagnosis(diag, d, recordings=recordings),
    )
    write_report_file(
        report_file,
        fit=diag.baseline.to_json(),
        diagnosis=diagnosis_document(diag),
        recordings=recordings,
    )

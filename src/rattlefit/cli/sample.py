"""``rattlefit sample``: the posterior by emcee, resumable."""

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
    "--backend",
    type=click.Path(dir_okay=False, path_type=Path),
    help="HDF5 file the chain is saved to as it runs; if it holds a chain of these files, "
    "that chain is continued (no refit).",
)
@click.option(
    "--steps",
    type=click.IntRange(min=2),
    default=300,
    show_default=True,
    help="Steps of the chain (more continue a --backend chain).",
)
@click.option(
    "--walkers", type=click.IntRange(min=2), default=16, show_default=True, help="emcee walkers."
)
@click.option(
    "--discard",
    type=click.IntRange(min=0),
    default=None,
    help="Steps discarded as the chain's warm-up (burn-in) [default: a third of --steps].",
)
@seed_option("the fit and the chain")
@quick_start_option
@likelihood_options
@output_options(
    "the credible intervals and diagnostics", "the trace, pairwise-marginal and predictive plots"
)
@report_option("the posterior and the identification the chain started from")
@click.option(
    "--fit",
    "fit_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="identify's JSON (-o) of these files: a new chain starts from it instead of "
    "identifying again (a fit on the synthetic likelihood); a continued chain's --report shows "
    "it.",
)
@prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@clean_errors
def sample(
    files,
    backend,
    steps,
    walkers,
    discard,
    seed,
    quick_fit,
    likelihood,
    reuse,
    output,
    plot_dir,
    report_file,
    fit_file,
    priors,
    quiet,
):
    """Sample the Bayesian posterior of a, T_b, the viscosity and the nuisances (emcee),
    starting from an identification of the same files. The posterior is also saved in
    ArviZ's netCDF format beside the chain file (--backend chain.h5 → chain.nc) or, without
    one, beside the JSON (-o post.json → post.nc)."""
    from ..inference.identify import identify
    from ..inference.posterior import SampleOptions, read_context
    from ..inference.posterior import sample as run
    from ..io.recording import read_recording
    from ..problem.options import FitOptions
    from ..report import format_posterior, plot_posterior
    from ..report.inputs import load_json

    if discard is not None and discard >= steps:
        raise click.BadParameter(f"must be below --steps ({steps})", param_hint="--discard")
    recordings = [read_recording(f) for f in files]
    continued = backend is not None and read_context(backend) is not None
    fit_doc = None
    if report_file is not None and continued:
        if fit_file is None:
            raise click.BadParameter(
                f"{backend} holds a chain to continue, and a chain file does not hold the "
                "identification the report shows: give it with --fit FILE (identify -o)",
                param_hint="--report",
            )
        fit_doc = load_json(fit_file, "fit")  # checked before the chain runs
    fit_options = (FitOptions.quick if quick_fit else FitOptions)(
        seed=seed, priors=priors_of(priors), **likelihood_keywords(likelihood, reuse)
    )
    options = SampleOptions(
        n_walkers=walkers, n_steps=steps, discard=discard, seed=seed, fit=fit_options
    )
    fit = None
    if not continued and fit_file is not None:
        fit = saved_fit(fit_file, recordings, "sample")
    elif not continued:  # identified here, as sample() would, so that the report can show it
        fit = identify(recordings, fit_options, progress=progress_printer(quiet))
    post = run(recordings, fit, options, backend=backend, progress=progress_printer(quiet))
    emit(
        format_posterior(post),
        post.to_json(),
        output,
        plot_dir,
        lambda d: plot_posterior(
            post, d, recordings, predictive=post.predictive_features(recordings)
        ),
    )
    beside = backend if backend is not None else output
    idata = None
    if beside is not None:
        idata = post.save_netcdf(beside.with_suffix(".nc"), recordings)
        click.echo(f"wrote {idata} (ArviZ netCDF)", err=True)
    elif report_file is not None:
        idata = post.to_inference_data(recordings)
    if report_file is not None:
        write_report_file(
            report_file,
            fit=fit.to_json() if fit is not None else fit_doc,
            posterior=post.to_json(),
            inference_data=idata,
            recordings=recordings,
        )

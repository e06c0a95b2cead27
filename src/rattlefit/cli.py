"""The ``rattlefit`` command line: parse → library call → print or write JSON.

Every library error (:class:`~rattlefit.errors.RattlefitError`) becomes one line on stderr,
``rattlefit: error: <file>: <field>: <problem>``, and exit status 2; nothing is half-written
because every output goes through a temporary file that is renamed into place.
"""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import click

from .errors import RattlefitError

EXIT_INPUT = 2


def _clean_errors(func):
    """Run a command after :func:`_configure`, with every library error, and every file that
    cannot be read or written, as one line on stderr and exit status 2."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        _configure()
        try:
            return func(*args, **kwargs)
        except RattlefitError as exc:
            click.echo(f"rattlefit: error: {exc}", err=True)
            sys.exit(EXIT_INPUT)
        except OSError as exc:  # a file that cannot be read or written: named, no traceback
            where = f"{exc.filename}: " if exc.filename else ""
            click.echo(f"rattlefit: error: {where}{exc.strerror or exc}", err=True)
            sys.exit(EXIT_INPUT)

    return wrapper


def _configure() -> None:
    """64-bit mode, the instruction-set cap, one JAX CPU device per core and compiled programs
    kept on disk ($RATTLEFIT_CACHE_DIR), before a command runs (not for --help or --version,
    which then start without JAX); the device count is left as it is (silently) when JAX has
    already started in this process, e.g. under a test runner."""
    from .config import quietly_configure

    quietly_configure(compilation_cache=True)


def _write_json(path: Path, doc: dict) -> None:
    """Write ``doc`` as JSON through a temporary file renamed into place."""
    from .util import write_json

    write_json(path, doc)
    click.echo(f"wrote {path}", err=True)


def _progress(quiet: bool):
    """The progress callback of a fitting command: indented lines on stderr, or none."""
    return None if quiet else (lambda msg: click.echo(f"  {msg}", err=True))


def _emit(text: str, doc: dict, output: Path | None, plot_dir: Path | None, plot) -> None:
    """Print ``text``; write ``doc`` to ``output`` and ``plot(plot_dir)``'s PNGs when asked."""
    click.echo(text)
    if output is not None:
        _write_json(output, doc)
    if plot_dir is not None:
        for path in plot(plot_dir):
            click.echo(f"wrote {path}", err=True)


def _output_options(what: str, plots: str):
    """The ``-o/--output`` (JSON) and ``--plot DIR`` (PNG) options of a fitting command."""

    def decorate(func):
        func = click.option(
            "--plot",
            "plot_dir",
            type=click.Path(file_okay=False, path_type=Path),
            help=f"Write {plots} (PNG) into this directory.",
        )(func)
        return click.option(
            "-o",
            "--output",
            type=click.Path(dir_okay=False, path_type=Path),
            help=f"Write {what} as JSON here.",
        )(func)

    return decorate


def _report_option(what: str):
    """The ``--report FILE`` option of a fitting command: the HTML report of its result."""
    return click.option(
        "--report",
        "report_file",
        type=click.Path(dir_okay=False, path_type=Path),
        help=f"Write the HTML report of {what} here (one self-contained file).",
    )


def _write_report(path: Path | None, **documents) -> None:
    """Write the HTML report of ``documents`` (:func:`rattlefit.report.write_report`'s
    keywords) to ``path``, when one is given."""
    if path is None:
        return
    from .report import write_report

    write_report(path, **documents)
    click.echo(f"wrote {path}", err=True)


def _prior_option(func):
    """The ``--prior NAME=CENTER:LOG_SD`` option (repeatable) of the fitting commands."""
    return click.option(
        "--prior",
        "priors",
        multiple=True,
        metavar="NAME=CENTER:LOG_SD",
        help="Give a parameter a log-normal prior (repeatable): NAME is film_half_length (or "
        "film_half_length[LUBRICATION]), drag_torque, viscosity (Pa s, at the first "
        "recording's oil temperature), viscosity_scale, stiffness_scale or min_film; CENTER "
        "its median in the unit the table shows (named where it is not SI: mm, um); LOG_SD "
        "the sd of its natural log. E.g. --prior min_film=2um:0.1 when h_min is known to "
        "about 10 %, --prior drag_torque=0.025:0.3.",
    )(func)


def _quick_start_option(func):
    """``--quick`` (``--quick-fit``, its old name) of the commands that start from an
    identification."""
    return click.option(
        "--quick",
        "--quick-fit",
        "quick_fit",
        is_flag=True,
        help="Start from a quick identification (as identify --quick; --quick-fit is the old "
        "name).",
    )(func)


def _likelihood_options(func):
    """``--likelihood`` and ``--reuse-likelihood`` (FitOptions.likelihood)."""
    func = click.option(
        "--reuse-likelihood",
        "reuse",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        default=None,
        help="A learned likelihood of this test point (identify -o X.json writes "
        "X.likelihood.h5) to start from instead of learning; implies --likelihood learned.",
    )(func)
    return click.option(
        "--likelihood",
        type=click.Choice(["synthetic", "learned"]),
        default="synthetic",
        show_default=True,
        help="How features are compared with the model: the mean of a few seeded "
        "realisations at each point, or a likelihood learned from simulations over the priors "
        "and the posterior (smooth; χ²₁'s 3.84 is its profile threshold).",
    )(func)


def _likelihood(method: str, reuse: Path | None) -> dict:
    """FitOptions' likelihood keywords from ``--likelihood`` and ``--reuse-likelihood``."""
    if reuse is None:
        return {"likelihood": method}
    return {"likelihood": "learned", "reuse_likelihood": str(reuse)}


def _write_learned(result, output: Path | None, doc: dict) -> None:
    """Store a learned likelihood beside the JSON (X.json → X.likelihood.h5)."""
    if output is None or result.state.learned is None:
        return
    from .likelihood.store import write_learned

    learned = result.state.learned
    path = output.with_suffix(".likelihood.h5")
    write_learned(
        path,
        learned.likelihood,
        learned.design,
        key=learned.key,
        seed=learned.seed,
        options=learned.options,
    )
    doc["fit"]["likelihood"]["file"] = str(path)
    click.echo(f"wrote {path} (the learned likelihood; --reuse-likelihood reuses it)", err=True)


#: Re-simulations of the fitted model behind the report's rattle index (``fit.igr``).
IGR_RESIMULATIONS = 8


def igr_document(result, recordings, seed: int) -> list[dict]:
    """``fit.igr`` of the JSON: each recording's measured IGR and that of
    :data:`IGR_RESIMULATIONS` recordings of the fitted model
    (:func:`~rattlefit.inference.realisation.fitted_igr`, seeded by ``seed``)."""
    from .inference.realisation import fitted_igr
    from .rig import setup

    model = fitted_igr(result, recordings, IGR_RESIMULATIONS, seed=seed)
    return [
        {"measured": float(setup(rec).rattle_index()), "model": m, "seed": seed}
        for rec, m in zip(recordings, model, strict=True)
    ]


def _priors(texts) -> dict:
    """``--prior`` values → ``FitOptions.priors``; a bad one is a usage error naming it."""
    from .inference.parameters import parse_prior

    priors = {}
    for text in texts:
        try:
            name, spec = parse_prior(text)
        except RattlefitError as exc:
            raise click.BadParameter(str(exc), param_hint="--prior") from None
        priors[name] = spec
    return priors


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="rattlefit")
def main() -> None:
    """Identify the physics of idle gear rattle from encoder recordings."""


@main.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@_clean_errors
def info(file: Path, as_json: bool) -> None:
    """Summarise a recording: gear pair, operating point, backlash, IGR, suspicious data."""
    from .io.recording import read_recording
    from .report.summary import format_summary, recording_summary

    summary = recording_summary(read_recording(file), file)
    click.echo(json.dumps(summary, indent=2) if as_json else format_summary(summary))


@main.command("import")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--map",
    "channel_map",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="TOML channel map: the encoder channels, counts per revolution, sample rate, gear "
    "pair, operating point and oil (docs/recording-format.md).",
)
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The recording to write (HDF5, recording format v1).",
)
@_clean_errors
def import_(source: Path, channel_map: Path, output: Path) -> None:
    """Turn a rig file (LabView TDMS or CSV) into a recording (HDF5 format v1)."""
    from .io.recording import inspect_warnings
    from .io.rig_files import import_recording

    rec = import_recording(source, channel_map, output)
    click.echo(f"wrote {output}: {rec.n_samples} samples at {rec.sample_rate_hz:g} Hz", err=True)
    for warning in inspect_warnings(rec):
        click.echo(f"note: {warning}", err=True)


@main.command()
@click.option("--pair", type=click.Choice(["I", "II"]), help="Gear pair of the paper's Table 2.")
@click.option(
    "--center-distance-mm",
    "center_distance",
    type=float,
    default=65.0,
    show_default=True,
    help="Centre distance, mm.",
)
@click.option(
    "--template",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Take gear pair, operating point and oil from this recording instead of --pair.",
)
@click.option(
    "--lubrication",
    type=click.Choice(["dry", "boundary", "oil_jet"]),
    default="boundary",
    show_default=True,
    help="How the flanks are lubricated.",
)
@click.option(
    "--oil-temperature-c",
    "temperature",
    type=float,
    default=20.0,
    show_default=True,
    help="Oil temperature, °C.",
)
@click.option(
    "--mean-speed",
    type=float,
    default=52.36,
    show_default=True,
    help="Drive mean speed Ω_m, rad/s.",
)
@click.option(
    "--fluctuation-pct",
    "fluctuation",
    type=float,
    default=20.0,
    show_default=True,
    help="Drive speed fluctuation ΔΩ, % of Ω_m.",
)
@click.option(
    "--frequency", type=float, default=16.0, show_default=True, help="Drive fluctuation f, Hz."
)
@click.option(
    "--film-half-length-mm",
    "film_half_length",
    type=float,
    required=True,
    help="Oil-film half-length a, mm (0 for dry).",
)
@click.option("--drag-torque", type=float, required=True, help="Bearing drag torque T_b, N m.")
@click.option(
    "--viscosity", type=float, help="μ, Pa s  [default: the paper's oil at --oil-temperature-c]"
)
@click.option(
    "--min-film-um",
    "min_film",
    type=float,
    default=2.0,
    show_default=True,
    help="Adsorbed film h_min, µm.",
)
@click.option(
    "--stiffness-scale",
    type=float,
    default=1.0,
    show_default=True,
    help="Factor on the ISO mesh stiffness.",
)
@click.option("--duration", type=float, default=3.0, show_default=True, help="Length, s.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds the simulation.")
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The recording to write (HDF5, with its truth).",
)
@_clean_errors
def simulate(**o) -> None:
    """Write a synthetic recording with known parameters (stored in its /truth group)."""
    from .io.recording import OperatingPoint, read_recording, write_recording
    from .physics.geometry import GearGeometry, table2_pair
    from .physics.oil import dynamic_viscosity
    from .simulation.synthetic import PAPER_OIL, synthesize

    if o["template"] is not None:
        tpl = read_recording(o["template"])
        geometry, operating, oil = GearGeometry.from_spec(tpl.gear_pair), tpl.operating, tpl.oil
    elif o["pair"] is not None:
        geometry = table2_pair(o["pair"], center_distance_mm=o["center_distance"])
        operating = OperatingPoint(
            lubrication=o["lubrication"],
            oil_temperature_c=o["temperature"],
            drive_mean_speed_rad_s=o["mean_speed"],
            drive_speed_amplitude_rad_s=o["mean_speed"] * o["fluctuation"] / 100.0,
            drive_frequency_hz=o["frequency"],
        )
        oil = PAPER_OIL
    else:
        raise click.UsageError("give --pair I|II or --template FILE")
    mu = o["viscosity"] or dynamic_viscosity(
        operating.oil_temperature_c,
        oil.viscosity_40c_cst,
        oil.viscosity_100c_cst,
        oil.density_kg_m3,
    )
    from .physics.model import RattleParams
    from .quantities import QUANTITIES

    film, h_min = (QUANTITIES[n] for n in ("film_half_length", "min_film"))
    params = RattleParams(
        o["film_half_length"] / film.scale,
        o["drag_torque"],
        mu,
        geometry.backlash,
        min_film=o["min_film"] / h_min.scale,
        stiffness_scale=o["stiffness_scale"],
    )
    click.echo(f"simulating {o['duration']:g} s (seed {o['seed']}) …", err=True)
    rec, truth = synthesize(
        geometry,
        operating,
        params,
        oil=oil,
        duration=o["duration"],
        seed=o["seed"],
        title=f"synthetic: pair z={geometry.teeth_driving}/{geometry.teeth_driven}, "
        f"{operating.lubrication}, centre distance {geometry.center_distance * 1e3:.1f} mm",
    )
    write_recording(rec, o["output"], extra_attrs=truth)
    click.echo(
        f"wrote {o['output']}  (a = {o['film_half_length']:.3g} mm, T_b = "
        f"{float(params.drag_torque):.3g} N m, μ = {mu:.3g} Pa s)"
    )


@main.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@_output_options("the result", "plots")
@click.option(
    "--seed", type=int, default=0, show_default=True, help="Seeds realisations and starts."
)
@click.option(
    "--realisations",
    type=click.IntRange(min=2),
    default=None,
    help="Simulated realisations per evaluation of the synthetic likelihood  [default: 6; 3 "
    "with --quick]",
)
@click.option(
    "--starts",
    type=click.IntRange(min=1),
    default=None,
    help="Starting points of the search  [default: 64, twice as many per further lubrication; 16 "
    "with --quick]",
)
@click.option(
    "--drive",
    type=click.Choice(["measured", "commanded"]),
    default="measured",
    show_default=True,
    help="Drive the model with the driving encoder's measured speed, or with eq. (9)'s "
    "commanded sine.",
)
@click.option(
    "--features",
    type=click.Choice(["bands", "bands+folded"]),
    default="bands",
    show_default=True,
    help="What the fit compares: the band PSDs, or those and the drive-cycle-folded "
    "statistics of Δθ* (FitOptions.features).",
)
@_likelihood_options
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
@_report_option("the fit")
@_prior_option
@click.option(
    "--csv",
    "csv_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the parameter table as CSV here (a row per parameter, SI units).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@_clean_errors
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
    from .inference.identify import identify as run
    from .inference.options import FitOptions
    from .inference.realisation import fitted_realisations
    from .io.recording import read_recording
    from .report import format_table, plot_fit, plot_igr

    recordings = [read_recording(f) for f in files]
    given = {"n_realisations": realisations, "n_starts": starts}
    make = FitOptions.quick if quick else FitOptions
    options = make(
        seed=seed,
        drive=drive,
        features=features,
        priors=_priors(priors),
        **_likelihood(likelihood, reuse),
        **{k: v for k, v in given.items() if v},
    )
    result = run(recordings, options, progress=_progress(quiet))
    text, doc = format_table(result), result.to_json()
    _write_learned(result, output, doc)
    if suggest:
        from .inference.design import DESIGN_REALISATIONS, plan_document
        from .inference.design import suggest as plan
        from .report import format_suggestions

        planned = plan(result, recordings, seed=seed, progress=_progress(quiet))
        doc["suggest"] = plan_document(planned, seed=seed, realisations=DESIGN_REALISATIONS)
        text += "\n\n" + format_suggestions(doc["suggest"])
    if report_file is not None or plot_dir is not None:
        doc["fit"]["igr"] = igr_document(result, recordings, seed)
    _emit(
        text,
        doc,
        output,
        plot_dir,
        lambda d: [
            *plot_fit(result, recordings, d, fitted_realisations(result, recordings)),
            *plot_igr(doc, d),
        ],
    )
    _write_report(report_file, fit=doc, recordings=recordings)
    if csv_file is not None:
        from .report.export import write_fit_csv

        click.echo(f"wrote {write_fit_csv(csv_file, doc)}", err=True)


@main.command()
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
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds the fit and chain.")
@_quick_start_option
@_likelihood_options
@_output_options(
    "the credible intervals and diagnostics", "the trace, pairwise-marginal and predictive plots"
)
@_report_option("the posterior and the identification the chain started from")
@click.option(
    "--fit",
    "fit_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="identify's JSON (-o) for the --report of a continued chain, whose file does not hold "
    "the identification; a new chain's report uses the one it starts from.",
)
@_prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@_clean_errors
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
    from .inference.identify import identify
    from .inference.options import FitOptions
    from .inference.posterior import SampleOptions, read_context
    from .inference.posterior import sample as run
    from .io.recording import read_recording
    from .report import format_posterior, plot_posterior
    from .report.inputs import load_json

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
    elif fit_file is not None:
        click.echo(
            "note: --fit is used only for the report of a continued chain; this new chain's "
            "report shows the identification it starts from",
            err=True,
        )
    fit_options = (FitOptions.quick if quick_fit else FitOptions)(
        seed=seed, priors=_priors(priors), **_likelihood(likelihood, reuse)
    )
    options = SampleOptions(
        n_walkers=walkers, n_steps=steps, discard=discard, seed=seed, fit=fit_options
    )
    fit = None
    if not continued:  # identified here, as sample() would, so that the report can show it
        fit = identify(recordings, fit_options, progress=_progress(quiet))
    post = run(recordings, fit, options, backend=backend, progress=_progress(quiet))
    _emit(
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
        _write_report(
            report_file,
            fit=fit.to_json() if fit is not None else fit_doc,
            posterior=post.to_json(),
            inference_data=idata,
            recordings=recordings,
        )


@main.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--effects",
    default=None,
    help="Comma-separated effects to try [default: rattlefit.physics.effects.DEFAULT_EFFECTS, "
    "every effect but pitch_point_friction].",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds the fit and tries.")
@_quick_start_option
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
@_likelihood_options
@_output_options("the diagnosis", "the band residuals with and without each effect")
@_report_option("the diagnosis and the identification it starts from")
@_prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@_clean_errors
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
    priors,
    quiet,
):
    """Where the model misses the recordings, which unmodelled effect explains it, and how
    much of the misfit it removes (each effect fitted on top of an identification)."""
    from .diagnosis.diagnose import DiagnoseOptions
    from .diagnosis.diagnose import diagnose as run
    from .inference.options import FitOptions
    from .io.recording import read_recording
    from .physics.effects import DEFAULT_EFFECTS, EFFECTS
    from .report import diagnosis_document, format_diagnosis, plot_diagnosis

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
    fit_options = make(seed=seed, priors=_priors(priors), **_likelihood(likelihood, reuse))
    options = DiagnoseOptions(
        effects=names, fit=fit_options, iterations=iterations, every_effect=every_effect
    )
    diag = run(recordings, options, progress=_progress(quiet))
    _emit(
        format_diagnosis(diag),
        diagnosis_document(diag),
        output,
        plot_dir,
        lambda d: plot_diagnosis(diag, d, recordings=recordings),
    )
    _write_report(
        report_file,
        fit=diag.baseline.to_json(),
        diagnosis=diagnosis_document(diag),
        recordings=recordings,
    )


@main.command()
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
@_clean_errors
def report(fit_file, posterior_file, netcdf, diagnosis_file, recording_files, output) -> None:
    """Write one self-contained HTML report (figures inside, nothing fetched) of an
    identification and, when given, its posterior and diagnosis."""
    from .io.recording import read_recording
    from .report import write_report
    from .report.inputs import load_json

    fit = load_json(fit_file, "fit")
    posterior = None if posterior_file is None else load_json(posterior_file, "posterior")
    diagnosis = None if diagnosis_file is None else load_json(diagnosis_file, "diagnosis")
    if netcdf is None and posterior is not None:
        netcdf = _netcdf_beside(posterior_file, posterior)
        if netcdf is not None:
            click.echo(f"using {netcdf} (ArviZ netCDF beside the posterior)", err=True)
    if recording_files:
        recordings = [read_recording(f) for f in recording_files]
    else:
        recordings = [read_recording(f) for f in _fit_recording_paths(fit, fit_file)]
    write_report(
        output,
        fit=fit,
        posterior=posterior,
        inference_data=netcdf,
        diagnosis=diagnosis,
        recordings=recordings,
    )
    click.echo(f"wrote {output}", err=True)


def _netcdf_beside(posterior_file: Path, posterior: dict) -> Path | None:
    """The netCDF file ``sample`` wrote beside the posterior's JSON or its chain file."""
    candidates = [posterior_file.with_suffix(".nc")]
    backend = posterior["sampler"].get("backend")
    if backend:
        candidates.append(Path(backend).with_suffix(".nc"))
    return next((c for c in candidates if c.is_file()), None)


def _fit_recording_paths(fit: dict, fit_file: Path) -> list[Path]:
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


class _DefaultCommandGroup(click.Group):
    """A group whose first argument, when it names none of its commands, is the first
    argument of its default command (``rattlefit campaign MANIFEST`` runs ``campaign run``)."""

    default_command = "run"

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = [self.default_command, *args]
        return super().parse_args(ctx, args)


def _numbers(text: str, hint: str) -> tuple[float, ...]:
    """``"65.0,65.4"`` → ``(65.0, 65.4)``; a bad list is a usage error naming ``hint``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        message = f"expected numbers separated by commas, got {text!r}"
        raise click.BadParameter(message, param_hint=hint) from None
    if not values:
        raise click.BadParameter("give at least one number", param_hint=hint)
    return values


@main.group(cls=_DefaultCommandGroup)
def campaign() -> None:
    """A whole test campaign at once, on a dask cluster: `rattlefit campaign MANIFEST -o DIR`
    identifies every recording (see `rattlefit campaign run -h`); `rattlefit campaign
    simulate` writes a synthetic one with known truth."""


@campaign.command("run")
@click.argument("manifest", type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="The campaign's directory: results.parquet/.csv, runs/, report.html (a re-run into "
    "it skips the work done).",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="A running dask scheduler (tcp://host:8786, e.g. of dask-jobqueue or "
    "dask-kubernetes)  [default: a local cluster of worker processes]",
)
@click.option(
    "--workers", type=click.IntRange(min=1), help="Local worker processes  [default: one a core]"
)
@click.option(
    "--cores-per-worker",
    type=click.IntRange(min=1),
    help="JAX CPU devices of each worker  [default: the cores shared among the local workers]",
)
@click.option(
    "--compile-cache",
    type=click.Path(file_okay=False, path_type=Path),
    help="The compilation cache every worker shares  [default: $RATTLEFIT_CACHE_DIR or "
    "~/.cache/rattlefit/jax]",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seeds every fit.")
@click.option("--quick", is_flag=True, help="Fit each unit as identify --quick.")
@click.option("--starts", type=click.IntRange(min=1), help="As identify --starts.")
@click.option("--realisations", type=click.IntRange(min=2), help="As identify --realisations.")
@click.option(
    "--iterations",
    type=click.IntRange(min=1),
    help="Levenberg–Marquardt iterations of each refined start  [default: as identify's]",
)
@click.option(
    "--drive",
    type=click.Choice(["measured", "commanded"]),
    default="measured",
    show_default=True,
    help="As identify --drive (the learned likelihood is shared within a test point only "
    "with 'commanded': a measured drive makes each recording its own).",
)
@click.option(
    "--likelihood",
    type=click.Choice(["synthetic", "learned"]),
    default="synthetic",
    show_default=True,
    help="As identify --likelihood; learned: one learning per test point, reused by its "
    "other recordings.",
)
@click.option("--diagnose", "run_diagnose", is_flag=True, help="Also diagnose every unit.")
@click.option(
    "--effects",
    help="Comma-separated effects diagnose tries  [default: diagnose's: every effect but "
    "pitch_point_friction]",
)
@click.option(
    "--sample-steps",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Also sample each unit's posterior with this many steps (0: no sampling).",
)
@click.option(
    "--resimulations",
    type=click.IntRange(min=1),
    default=4,
    show_default=True,
    help="Realisations re-simulated at each recording's fit for the report's model IGR.",
)
@_prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@_clean_errors
def campaign_run(**o) -> None:
    """Identify every recording of MANIFEST (a directory of recordings, or a CSV/TOML file
    naming them and their joint-fit groups) on a dask cluster; write a tidy table, every
    run's JSON and one HTML report into -o. Exit status 1 when any recording or stage failed
    (the rest are done and written), 2 for a bad manifest."""
    from .campaign import CampaignOptions, ClusterOptions, run_campaign
    from .inference.options import FitOptions

    given = {
        "n_realisations": o["realisations"],
        "n_starts": o["starts"],
        "max_iterations": o["iterations"],
    }
    fit = (FitOptions.quick if o["quick"] else FitOptions)(
        seed=o["seed"],
        drive=o["drive"],
        likelihood=o["likelihood"],
        priors=_priors(o["priors"]),
        **{k: v for k, v in given.items() if v},
    )
    effects = None if o["effects"] is None else tuple(e.strip() for e in o["effects"].split(","))
    options = CampaignOptions(
        fit=fit,
        diagnose=o["run_diagnose"],
        effects=effects,
        sample_steps=o["sample_steps"],
        resimulations=o["resimulations"],
    )
    cache = True if o["compile_cache"] is None else o["compile_cache"]
    cluster = ClusterOptions(
        scheduler=o["scheduler"],
        workers=o["workers"],
        cores_per_worker=o["cores_per_worker"],
        compilation_cache=cache,
    )
    result = run_campaign(
        o["manifest"], o["output"], options=options, cluster=cluster, progress=_progress(o["quiet"])
    )
    click.echo(
        f"{result.units} identifications: {result.ran} run, {result.skipped} already done, "
        f"{len(result.failures)} failure(s) ({result.wall_s:.0f} s)"
    )
    for f in result.failures:
        click.echo(f"failed: {f['unit']} ({f['stage']}): {f['error']}")
    for path in (result.table, result.csv, result.report):
        if path is not None:
            click.echo(f"wrote {path}", err=True)
    if result.failures:
        sys.exit(1)


@campaign.command("simulate")
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="The directory for the recordings and their manifest.csv.",
)
@click.option(
    "--pair",
    "pairs",
    multiple=True,
    type=click.Choice(["I", "II"]),
    help="Gear pair (repeatable)  [default: both]",
)
@click.option(
    "--lubrication",
    "lubrications",
    multiple=True,
    type=click.Choice(["dry", "boundary", "oil_jet"]),
    help="Lubrication (repeatable; pair I was tested under boundary and oil jet only)  "
    "[default: all the paper tested]",
)
@click.option(
    "--center-distances-mm",
    default="65.0,65.2,65.4,65.6,65.8,66.0",
    show_default=True,
    help="Centre distances, mm, comma-separated.",
)
@click.option(
    "--fluctuations-pct",
    default="10,20",
    show_default=True,
    help="Speed fluctuations ΔΩ, % of Ω_m, comma-separated.",
)
@click.option(
    "--frequencies", default="4,8,16", show_default=True, help="Fluctuation frequencies f, Hz."
)
@click.option(
    "--repeats",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Recordings per test point.",
)
@click.option("--duration", type=float, default=3.0, show_default=True, help="Length, s (≥ 1).")
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Recording i: the i-th child spawned from this seed.",
)
@click.option(
    "--joint",
    type=click.Choice(["none", "sweeps", "companions"]),
    default="none",
    show_default=True,
    help="Group the manifest: a joint fit per backlash sweep, or each boundary recording "
    "with its oil-jet companion.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@_clean_errors
def campaign_simulate(**o) -> None:
    """Write a synthetic campaign with known truth: the paper's test grid (2 gear pairs,
    their lubrications, 6 centre distances, 6 speed settings: 180 recordings) or the part
    of it chosen, and its manifest.csv."""
    from .campaign import CampaignGrid, simulate_campaign

    grid = CampaignGrid(
        pairs=o["pairs"] or ("I", "II"),
        lubrications=o["lubrications"] or ("dry", "boundary", "oil_jet"),
        center_distances_mm=_numbers(o["center_distances_mm"], "--center-distances-mm"),
        fluctuations_pct=_numbers(o["fluctuations_pct"], "--fluctuations-pct"),
        frequencies_hz=_numbers(o["frequencies"], "--frequencies"),
        repeats=o["repeats"],
    )
    manifest = simulate_campaign(
        o["output"],
        grid=grid,
        duration=o["duration"],
        seed=o["seed"],
        joint=o["joint"],
        progress=_progress(o["quiet"]),
    )
    click.echo(f"wrote {len(grid.points())} recordings and {manifest}")


if __name__ == "__main__":  # pragma: no cover
    main()

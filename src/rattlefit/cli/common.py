"""Shared pieces of the command line: errors as one line, JAX configured before a command
runs, the options several commands take, and writing outputs through a temporary file."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import click

from ..errors import RattlefitError

#: The exit status of a refused input.
EXIT_INPUT = 2


def clean_errors(func):
    """Run a command after :func:`configure_jax`, with every library error, and every file that
    cannot be read or written, as one line on stderr and exit status 2."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        configure_jax()
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


def configure_jax() -> None:
    """64-bit mode, the instruction-set cap, one JAX CPU device per core and compiled programs
    kept on disk ($RATTLEFIT_CACHE_DIR), before a command runs (not for --help or --version,
    which then start without JAX); the device count is left as it is (silently) when JAX has
    already started in this process, e.g. under a test runner."""
    from ..config import quietly_configure

    quietly_configure(compilation_cache=True)


def write_json_output(path: Path, doc: dict) -> None:
    """Write ``doc`` as JSON through a temporary file renamed into place."""
    from ..util import write_json

    write_json(path, doc)
    click.echo(f"wrote {path}", err=True)


def progress_printer(quiet: bool):
    """The progress callback of a fitting command: indented lines on stderr, or none."""
    return None if quiet else (lambda msg: click.echo(f"  {msg}", err=True))


def emit(text: str, doc: dict, output: Path | None, plot_dir: Path | None, plot) -> None:
    """Print ``text``; write ``doc`` to ``output`` and ``plot(plot_dir)``'s PNGs when asked."""
    click.echo(text)
    if output is not None:
        write_json_output(output, doc)
    if plot_dir is not None:
        for path in plot(plot_dir):
            click.echo(f"wrote {path}", err=True)


def output_options(what: str, plots: str):
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


def report_option(what: str):
    """The ``--report FILE`` option of a fitting command: the HTML report of its result."""
    return click.option(
        "--report",
        "report_file",
        type=click.Path(dir_okay=False, path_type=Path),
        help=f"Write the HTML report of {what} here (one self-contained file).",
    )


def write_report_file(path: Path | None, **documents) -> None:
    """Write the HTML report of ``documents`` (:func:`rattlefit.report.write_report`'s
    keywords) to ``path``, when one is given."""
    if path is None:
        return
    from ..report import write_report

    write_report(path, **documents)
    click.echo(f"wrote {path}", err=True)


def prior_option(func):
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


def quick_start_option(func):
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


def seed_option(what: str):
    """``--seed`` (an integer, default 0), with what it seeds in this command."""
    return click.option("--seed", type=int, default=0, show_default=True, help=f"Seeds {what}.")


def realisations_option(help_text: str):
    """``--realisations``: simulated realisations per evaluation of the synthetic likelihood
    (``FitOptions.n_realisations``; unset keeps the preset's)."""
    return click.option("--realisations", type=click.IntRange(min=2), default=None, help=help_text)


def drive_option(note: str = ""):
    """``--drive``: the model driven by the driving encoder's measured speed or by the
    commanded sine (``FitOptions.drive``)."""
    return click.option(
        "--drive",
        type=click.Choice(["measured", "commanded"]),
        default="measured",
        show_default=True,
        help="Drive the model with the driving encoder's measured speed, or with eq. (9)'s "
        "commanded sine" + (f" ({note})" if note else "") + ".",
    )


def likelihood_method_option(help_text: str):
    """``--likelihood``: synthetic or learned (``FitOptions.likelihood``)."""
    return click.option(
        "--likelihood",
        type=click.Choice(["synthetic", "learned"]),
        default="synthetic",
        show_default=True,
        help=help_text,
    )


def likelihood_options(func):
    """``--likelihood`` and ``--reuse-likelihood`` (FitOptions.likelihood)."""
    func = click.option(
        "--reuse-likelihood",
        "reuse",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        default=None,
        help="A learned likelihood of this test point (identify -o X.json writes "
        "X.likelihood.h5) to start from instead of learning; implies --likelihood learned.",
    )(func)
    return likelihood_method_option(
        "How features are compared with the model: the mean of a few seeded realisations at "
        "each point, or a likelihood learned from simulations over the priors and the "
        "posterior (smooth; its profiles are cut at critical values found by simulating "
        "recordings near the optimum, never below χ²₁'s 3.84)."
    )(func)


def likelihood_keywords(method: str, reuse: Path | None) -> dict:
    """FitOptions' likelihood keywords from ``--likelihood`` and ``--reuse-likelihood``."""
    if reuse is None:
        return {"likelihood": method}
    return {"likelihood": "learned", "reuse_likelihood": str(reuse)}


def write_learned_beside(result, output: Path | None, doc: dict) -> None:
    """Store a learned likelihood beside the JSON (X.json → X.likelihood.h5)."""
    from ..likelihood.store import Learned, write_learned

    if output is None or not isinstance(result.state.likelihood, Learned):
        return
    path = write_learned(output.with_suffix(".likelihood.h5"), result.state.likelihood)
    doc["fit"]["likelihood"]["file"] = str(path)
    click.echo(f"wrote {path} (the learned likelihood; --reuse-likelihood reuses it)", err=True)


def priors_of(texts) -> dict:
    """``--prior`` values → ``FitOptions.priors``; a bad one is a usage error naming it."""
    from ..problem.parameters import parse_prior

    priors = {}
    for text in texts:
        try:
            name, spec = parse_prior(text)
        except RattlefitError as exc:
            raise click.BadParameter(str(exc), param_hint="--prior") from None
        priors[name] = spec
    return priors


def saved_fit(path: Path, recordings, command: str):
    """The fit ``identify -o`` wrote to ``path``, of ``recordings`` (matched by their counts),
    for ``command`` to start from; a fit on the learned likelihood whose likelihood file is
    not beside it is refused for ``sample``, whose chain needs the likelihood itself."""
    from ..inference.fit_document import read_fit

    fit = read_fit(path, recordings)
    method = fit.provenance.likelihood.get("method", "synthetic")
    if command == "sample" and method != fit.state.likelihood.kind:
        raise RattlefitError(
            f"{path}: fit/likelihood/file: a fit on the learned likelihood whose file "
            f"({path.with_suffix('.likelihood.h5').name}) is not beside it; put it there, or "
            "sample these files with --reuse-likelihood FILE instead of --fit"
        )
    return fit

"""``rattlefit campaign``: a whole test campaign at once, and a synthetic one."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .common import (
    clean_errors,
    drive_option,
    likelihood_method_option,
    prior_option,
    priors_of,
    progress_printer,
    realisations_option,
    seed_option,
)


class DefaultCommandGroup(click.Group):
    """A group whose first argument, when it names none of its commands, is the first
    argument of its default command (``rattlefit campaign MANIFEST`` runs ``campaign run``)."""

    default_command = "run"

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = [self.default_command, *args]
        return super().parse_args(ctx, args)


def numbers(text: str, hint: str) -> tuple[float, ...]:
    """``"65.0,65.4"`` → ``(65.0, 65.4)``; a bad list is a usage error naming ``hint``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        message = f"expected numbers separated by commas, got {text!r}"
        raise click.BadParameter(message, param_hint=hint) from None
    if not values:
        raise click.BadParameter("give at least one number", param_hint=hint)
    return values


@click.group(cls=DefaultCommandGroup)
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
@seed_option("every fit")
@click.option("--quick", is_flag=True, help="Fit each unit as identify --quick.")
@click.option("--starts", type=click.IntRange(min=1), help="As identify --starts.")
@realisations_option("As identify --realisations.")
@click.option(
    "--iterations",
    type=click.IntRange(min=1),
    help="Levenberg–Marquardt iterations of each refined start  [default: as identify's]",
)
@drive_option(
    "the learned likelihood is shared within a test point only with 'commanded': a measured "
    "drive makes each recording its own"
)
@likelihood_method_option(
    "As identify --likelihood; learned: one learning per test point, reused by its other "
    "recordings."
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
@prior_option
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@clean_errors
def campaign_run(**o) -> None:
    """Identify every recording of MANIFEST (a directory of recordings, or a CSV/TOML file
    naming them and their joint-fit groups) on a dask cluster; write a tidy table, every
    run's JSON and one HTML report into -o. Exit status 1 when any recording or stage failed
    (the rest are done and written), 2 for a bad manifest."""
    from ..campaign import CampaignOptions, ClusterOptions, run_campaign
    from ..problem.options import FitOptions

    given = {
        "n_realisations": o["realisations"],
        "n_starts": o["starts"],
        "max_iterations": o["iterations"],
    }
    fit = (FitOptions.quick if o["quick"] else FitOptions)(
        seed=o["seed"],
        drive=o["drive"],
        likelihood=o["likelihood"],
        priors=priors_of(o["priors"]),
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
        o["manifest"],
        o["output"],
        options=options,
        cluster=cluster,
        progress=progress_printer(o["quiet"]),
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
@seed_option("the recordings: recording i is the i-th child spawned from this seed")
@click.option(
    "--joint",
    type=click.Choice(["none", "sweeps", "companions"]),
    default="none",
    show_default=True,
    help="Group the manifest: a joint fit per backlash sweep, or each boundary recording "
    "with its oil-jet companion.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
@clean_errors
def campaign_simulate(**o) -> None:
    """Write a synthetic campaign with known truth: the paper's test grid (2 gear pairs,
    their lubrications, 6 centre distances, 6 speed settings: 180 recordings) or the part
    of it chosen, and its manifest.csv."""
    from ..campaign import CampaignGrid, simulate_campaign

    grid = CampaignGrid(
        pairs=o["pairs"] or ("I", "II"),
        lubrications=o["lubrications"] or ("dry", "boundary", "oil_jet"),
        center_distances_mm=numbers(o["center_distances_mm"], "--center-distances-mm"),
        fluctuations_pct=numbers(o["fluctuations_pct"], "--fluctuations-pct"),
        frequencies_hz=numbers(o["frequencies"], "--frequencies"),
        repeats=o["repeats"],
    )
    manifest = simulate_campaign(
        o["output"],
        grid=grid,
        duration=o["duration"],
        seed=o["seed"],
        joint=o["joint"],
        progress=progress_printer(o["quiet"]),
    )
    click.echo(f"wrote {len(grid.points())} recordings and {manifest}")

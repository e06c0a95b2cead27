"""``rattlefit info``, ``import`` and ``simulate``: recordings in, summarised and made."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ..quantities import DRAG_TORQUE, FILM, MIN_FILM, STIFFNESS_SCALE, VISCOSITY
from .common import (
    clean_errors,
    seed_option,
)


@click.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@clean_errors
def info(file: Path, as_json: bool) -> None:
    """Summarise a recording: gear pair, operating point, backlash, IGR, suspicious data."""
    from ..io.recording import read_recording
    from ..report.summary import format_summary, recording_summary

    summary = recording_summary(read_recording(file), file)
    click.echo(json.dumps(summary, indent=2) if as_json else format_summary(summary))


@click.command("import")
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
@clean_errors
def import_(source: Path, channel_map: Path, output: Path) -> None:
    """Turn a rig file (LabView TDMS or CSV) into a recording (HDF5 format v1)."""
    from ..io.recording import inspect_warnings
    from ..io.rig_files import import_recording

    rec = import_recording(source, channel_map, output)
    click.echo(f"wrote {output}: {rec.n_samples} samples at {rec.sample_rate_hz:g} Hz", err=True)
    for warning in inspect_warnings(rec):
        click.echo(f"note: {warning}", err=True)


@click.command()
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
    FILM,
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
    MIN_FILM,
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
@seed_option("the simulation")
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The recording to write (HDF5, with its truth).",
)
@clean_errors
def simulate(**o) -> None:
    """Write a synthetic recording with known parameters (stored in its /truth group)."""
    from ..io.recording import OperatingPoint, read_recording, write_recording
    from ..physics.geometry import GearGeometry, table2_pair
    from ..physics.oil import dynamic_viscosity
    from ..simulation.synthetic import PAPER_OIL, synthesize

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
    mu = o[VISCOSITY] or dynamic_viscosity(
        operating.oil_temperature_c,
        oil.viscosity_40c_cst,
        oil.viscosity_100c_cst,
        oil.density_kg_m3,
    )
    from ..physics.model import RattleParams
    from ..quantities import QUANTITIES

    film, h_min = (QUANTITIES[n] for n in (FILM, MIN_FILM))
    params = RattleParams(
        o[FILM] / film.scale,
        o[DRAG_TORQUE],
        mu,
        geometry.backlash,
        min_film=o[MIN_FILM] / h_min.scale,
        stiffness_scale=o[STIFFNESS_SCALE],
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

"""A recording's summary: gear pair, operating point, backlash, IGR and data-quality notes
(what ``rattlefit info`` prints and the HTML report's first section shows)."""

from __future__ import annotations

from pathlib import Path

from ..io.recording import Recording, inspect_warnings, read_provenance


def recording_summary(rec: Recording, file: str | Path | None = None) -> dict:
    """The summary of ``rec`` as a JSON-ready dict (``rattlefit info --json``).

    ``file`` names the recording (default: its path). Angles in rad, lengths in m unless the
    key says mm, torques in N m, viscosity in Pa s, speeds in rad/s, frequencies in Hz;
    ``notes`` holds :func:`~rattlefit.io.recording.inspect_warnings`' sentences (empty when
    nothing looks wrong); ``provenance`` what an imported recording came from
    (:func:`~rattlefit.io.recording.read_provenance`; None for any other). Raises
    :class:`~rattlefit.errors.RattlefitError` for a recording whose gear pair cannot be built.
    """
    from ..rig import setup

    rig = setup(rec)
    g, op = rig.geometry, rec.operating
    return {
        "file": str(file if file is not None else rec.path),
        "title": rec.title,
        "gear_pair": {
            "teeth": [g.teeth_driving, g.teeth_driven],
            "center_distance_mm": rec.gear_pair.center_distance_mm,
            "angular_backlash_rad": g.angular_backlash,
            "backlash_m": g.backlash,
            **g.describe(),
        },
        "operating": {
            "lubrication": op.lubrication,
            "oil_temperature_c": op.oil_temperature_c,
            "viscosity_Pa_s": rig.viscosity,
            "drive_mean_speed_rad_s": op.drive_mean_speed_rad_s,
            "drive_speed_amplitude_rad_s": op.drive_speed_amplitude_rad_s,
            "drive_frequency_hz": op.drive_frequency_hz,
            "measured_mean_speed_rad_s": float(rig.drive.mean_speed),
        },
        "samples": rec.n_samples,
        "sample_rate_hz": rec.sample_rate_hz,
        "duration_s": rec.duration,
        "relative_motion_ptp_rad": float(rec.relative_motion.max() - rec.relative_motion.min()),
        "rattle_index_rad_hz": rig.rattle_index(),
        "no_rattle_drag_torque_Nm": rig.no_rattle_drag_torque(),
        "provenance": read_provenance(rec.path) if rec.path else None,
        "notes": inspect_warnings(rec),
    }


def summary_rows(summary: dict) -> list[tuple[str, str]]:
    """``(label, text)`` rows of a :func:`recording_summary`, as ``rattlefit info`` prints
    them (without the title line and the notes)."""
    gp, o = summary["gear_pair"], summary["operating"]
    z1, z2 = gp["teeth"]
    return [
        (
            "gear pair",
            f"z1/z2 = {z1}/{z2}, centre distance {gp['center_distance_mm']:.2f} mm, "
            f"εα = {gp['transverse_contact_ratio']:.2f}, εβ = {gp['overlap_contact_ratio']:.2f}, "
            f"mesh mode ≈ {gp['mesh_frequency_hz']:.0f} Hz",
        ),
        (
            "backlash",
            f"{gp['angular_backlash_rad']:.4f} rad (Δθ*) = {gp['backlash_m'] * 1e3:.3f} mm on "
            "the pitch circle",
        ),
        (
            "lubrication",
            f"{o['lubrication']}, {o['oil_temperature_c']:g} °C → μ = "
            f"{o['viscosity_Pa_s']:.3f} Pa s (ASTM D341)",
        ),
        (
            "drive",
            f"Ω = {o['drive_mean_speed_rad_s']:g} ± {o['drive_speed_amplitude_rad_s']:g} rad/s "
            f"at {o['drive_frequency_hz']:g} Hz (measured mean "
            f"{o['measured_mean_speed_rad_s']:.3f} rad/s)",
        ),
        (
            "recording",
            f"{summary['samples']} samples at {summary['sample_rate_hz']:g} Hz = "
            f"{summary['duration_s']:g} s",
        ),
        *imported_row(summary.get("provenance")),
        ("IGR", f"{summary['rattle_index_rad_hz']:.4g} rad·Hz (20–5000 Hz, eq. 10)"),
        (
            "rattle",
            f"expected unless T_b > {summary['no_rattle_drag_torque_Nm']:.4f} N m "
            "(Singh et al. 1989: I2·(r1/r2)·max θ̈1)",
        ),
    ]


def imported_row(provenance: dict | None) -> list[tuple[str, str]]:
    """The ``imported`` row of an imported recording's summary (none for any other)."""
    if not provenance:
        return []
    return [
        (
            "imported",
            f"from {provenance.get('source', '?')} (SHA-256 "
            f"{str(provenance.get('source_sha256', ''))[:12]}…, modified "
            f"{provenance.get('source_modified_utc', '?')}) by "
            f"{provenance.get('imported_by', '?')}",
        )
    ]


def format_summary(summary: dict) -> str:
    """The text ``rattlefit info`` prints for a :func:`recording_summary`."""
    lines = [f"{summary['file']}  {summary['title']}".rstrip()]
    lines += [f"  {label:<14} {text}" for label, text in summary_rows(summary)]
    lines += [f"  note: {n}" for n in summary["notes"]] or ["  notes          none"]
    return "\n".join(lines)

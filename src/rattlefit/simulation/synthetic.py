"""Synthetic recordings with known truth: simulate the model and write what the rig would.

Used by ``rattlefit simulate`` and by the tests and benchmarks that need data with known
parameters. The encoders' arbitrary zeros are drawn from a seeded generator; the seed is stored
in the file's ``/truth`` group with the parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np
from numpy.typing import ArrayLike

from ..errors import RattlefitError
from ..io.recording import GearPairSpec, OilSpec, OperatingPoint, Recording
from ..physics.drive import Drive
from ..physics.geometry import GearGeometry, table2_pair
from ..physics.model import PARAM_UNITS, Effect, RattleModel, RattleParams
from .solve import Solution, encoder_counts, raise_if_failed, simulate

#: The seed paper's oil, Table 3.
PAPER_OIL = OilSpec(viscosity_40c_cst=156.5, viscosity_100c_cst=15.7, density_kg_m3=890.0)


def gear_pair_spec(geometry: GearGeometry) -> GearPairSpec:
    """The ``/gear_pair`` metadata of a geometry."""
    mm = 1e3
    return GearPairSpec(
        teeth_driving=geometry.teeth_driving,
        teeth_driven=geometry.teeth_driven,
        pitch_diameter_driving_mm=2 * geometry.pitch_radius_driving * mm,
        pitch_diameter_driven_mm=2 * geometry.pitch_radius_driven * mm,
        face_width_driving_mm=geometry.face_width * mm,
        face_width_driven_mm=geometry.face_width * mm,
        normal_module_mm=geometry.normal_module * mm,
        normal_pressure_angle_deg=math.degrees(geometry.normal_pressure_angle),
        helix_angle_deg=math.degrees(geometry.helix_angle),
        driven_inertia_kg_m2=geometry.driven_inertia,
        center_distance_mm=geometry.center_distance * mm,
        angular_backlash_rad=geometry.angular_backlash,
        angular_backlash_std_rad=geometry.angular_backlash_std,
    )


def recording_from_trajectory(
    geometry: GearGeometry,
    operating: OperatingPoint,
    theta1: ArrayLike,
    q: ArrayLike,
    *,
    oil: OilSpec = PAPER_OIL,
    sample_rate: float = 10_000.0,
    counts_per_rev: int = 40_000,
    zeros: Sequence[int] = (0, 0),
    title: str = "",
) -> Recording:
    """The recording the rig's two encoders latch along a trajectory of the gear pair.

    ``theta1`` is the primary shaft's angle θ1 (rad) and ``q`` the relative displacement
    r2·θ2 − r1·θ1 on the pitch circle (m), both shape (N,) at the sample times
    k / ``sample_rate`` (Hz), from any solver (:func:`~rattlefit.simulation.solve.simulate`,
    :func:`~rattlefit.simulation.reference.simulate_reference`, ...). Each shaft's angle is
    quantised to ``counts_per_rev`` counts per revolution by
    :func:`~rattlefit.simulation.solve.encoder_counts`, and ``zeros`` (primary, secondary; in
    counts) are added as the encoders' arbitrary zeros. ``/gear_pair`` is the geometry's
    (:func:`gear_pair_spec`); ``operating`` and ``oil`` are written as given.
    """
    model = RattleModel.from_geometry(geometry)
    q = jnp.asarray(q, dtype=float)
    theta1 = jnp.asarray(theta1, dtype=float)
    if q.ndim != 1 or q.shape != theta1.shape:
        raise RattlefitError(
            f"recording_from_trajectory: q {q.shape} and theta1 {theta1.shape} must be two "
            "1-D arrays of the same length"
        )
    # the encoders read θ1 and q only; the trajectory's velocity is not needed
    trajectory = Solution(
        time=jnp.arange(q.size) / float(sample_rate),
        q=q,
        velocity=jnp.zeros_like(q),
        relative_motion=-q / model.r1,
        theta1=theta1,
        result=jnp.zeros((), dtype=int),
        num_steps=jnp.zeros((), dtype=int),
    )
    primary, secondary = encoder_counts(trajectory, model, counts_per_rev=counts_per_rev)
    zero_primary, zero_secondary = (int(z) for z in zeros)
    return Recording(
        primary=primary + zero_primary,
        secondary=secondary + zero_secondary,
        sample_rate_hz=float(sample_rate),
        counts_per_rev=int(counts_per_rev),
        gear_pair=gear_pair_spec(geometry),
        operating=operating,
        oil=oil,
        title=title,
    )


def synthesize(
    geometry: GearGeometry,
    operating: OperatingPoint,
    params: RattleParams,
    *,
    oil: OilSpec = PAPER_OIL,
    drive: Drive | None = None,
    duration: float = 3.0,
    sample_rate: float = 10_000.0,
    counts_per_rev: int = 40_000,
    burn_in: float = 0.5,
    seed: int = 0,
    title: str = "",
    rtol: float = 1e-7,
    effects: Sequence[Effect] = (),
) -> tuple[Recording, dict[str, float | int | str]]:
    """Simulate a recording and return it with its truth (SI values, seed, model notes).

    The drive defaults to the commanded law of ``operating``. The backlash written in the
    metadata is the geometry's (as measured); the simulation uses ``params.backlash``, so a
    measurement error of the backlash can be imitated by making them differ. ``effects``
    (:mod:`rattlefit.physics.effects`) are added to the model; the truth names them in
    ``unmodelled_effects`` (comma-separated) and gives each fitted field as
    ``"<effect>.<field>"``.
    """
    model = RattleModel.from_geometry(geometry).with_effects(*effects)
    if drive is None:
        drive = Drive.commanded(
            operating.drive_mean_speed_rad_s,
            operating.drive_speed_amplitude_rad_s,
            operating.drive_frequency_hz,
        )
    rng = np.random.default_rng(seed)
    # a seeded start-up (different released position across the gap) makes repeat runs
    # independent realisations of the chaotic motion
    c = 0.5 * float(params.backlash)
    y0 = np.array([rng.uniform(-c, c), 0.0])
    sol = raise_if_failed(
        simulate(
            model,
            params,
            drive,
            duration=duration,
            sample_rate=sample_rate,
            burn_in=burn_in,
            rtol=rtol,
            atol=rtol * 1e-3,
            y0=y0,
        )
    )
    rec = recording_from_trajectory(
        geometry,
        operating,
        sol.theta1,
        sol.q,
        oil=oil,
        sample_rate=sample_rate,
        counts_per_rev=counts_per_rev,
        zeros=rng.integers(-(10**6), 10**6, size=2),
        title=title or "rattlefit synthetic recording",
    )
    truth: dict[str, float | int | str] = {
        name: float(value) for name, value in params.as_dict().items()
    }
    truth.update(
        {f"{name}_unit": unit for name, unit in PARAM_UNITS.items()},
        seed=int(seed),
        generator="rattlefit.simulation.synthetic",
        rtol=float(rtol),
    )
    if effects:  # flat, so that they fit the /truth group's attributes
        truth["unmodelled_effects"] = ",".join(e.name for e in effects)
        truth.update(
            {f"{e.name}.{k}": float(getattr(e, k)) for e in effects for k in type(e).ranges}
        )
    return rec, truth


def backlash_sweep(
    center_distances_mm: Sequence[float] = (65.0, 65.4, 66.0),
    seeds: Sequence[int] = (21, 22, 23),
    *,
    pair: str = "II",
    operating: OperatingPoint | None = None,
    film_half_length: float = 0.085e-3,
    drag_torque: float = 0.025,
    viscosity: float = 0.4942,
) -> list[tuple[Recording, RattleParams]]:
    """A backlash sweep of one gear pair and one lubrication, as in the paper's Figs. 10–12:
    one recording per centre distance (mm), each with its own ``seed``, and the parameters it
    was simulated with (the film half-length ``a`` in m, the drag torque in N m and the
    viscosity in Pa s shared; the backlash the centre distance's). The defaults are the sweep
    of the joint-fit criterion (tests/test_fit.py): pair II in boundary lubrication at
    20 °C, 10 % speed fluctuation at 8 Hz, at the ends and the middle of the paper's range of
    centre distances."""
    if len(center_distances_mm) != len(seeds):
        raise RattlefitError(
            f"backlash_sweep: {len(seeds)} seed(s) for {len(center_distances_mm)} centre "
            "distance(s)"
        )
    if operating is None:
        operating = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
    sweep = []
    for cd, seed in zip(center_distances_mm, seeds, strict=True):
        g = table2_pair(pair, center_distance_mm=cd)
        p = RattleParams(film_half_length, drag_torque, viscosity, g.backlash)
        sweep.append((synthesize(g, operating, p, seed=seed)[0], p))
    return sweep

"""A synthetic campaign with known truth: the paper's test grid, simulated.

The seed paper's campaign (Section 5, Figs. 10–11) runs gear pair I under boundary and
oil-jet lubrication and pair II under dry contact, boundary and oil-jet lubrication, each at
centre distances from 65.0 to 66.0 mm and at six speed settings (ΔΩ = 10 and 20 % of
Ω_m = 52.36 rad/s, at f = 4, 8 and 16 Hz): 5 × 6 × 6 = 180 recordings. :class:`CampaignGrid`
chooses a part of it; :func:`simulate_campaign` writes one recording per point (and
repeat), each with its truth in its ``/truth`` group, and a CSV manifest that groups them as
asked.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import RattlefitError
from ..io.recording import OperatingPoint, read_truth, write_recording
from ..physics.geometry import TABLE2, table2_pair
from ..physics.model import RattleParams
from ..physics.oil import dynamic_viscosity
from ..quantities import DRAG_TORQUE, FILM
from ..simulation.synthetic import PAPER_OIL, synthesize
from .manifest import write_manifest

#: The lubrications the paper tested on each gear pair.
PAPER_LUBRICATIONS = {"I": ("boundary", "oil_jet"), "II": ("dry", "boundary", "oil_jet")}
#: The paper's centre distances (mm), speed fluctuations (% of Ω_m) and frequencies (Hz).
PAPER_CENTER_DISTANCES = (65.0, 65.2, 65.4, 65.6, 65.8, 66.0)
PAPER_FLUCTUATIONS = (10.0, 20.0)
PAPER_FREQUENCIES = (4.0, 8.0, 16.0)
#: The paper's mean drive speed Ω_m, rad/s (500 rev/min).
MEAN_SPEED = 52.36
#: How a synthetic campaign groups its recordings into joint fits.
JOINT = ("none", "sweeps", "companions")


@dataclasses.dataclass(frozen=True)
class CampaignGrid:
    """Which of the paper's test points to simulate: every combination of ``pairs``
    ("I", "II"), ``lubrications`` (of "dry", "boundary", "oil_jet"; only those the paper
    tested on a pair, :data:`PAPER_LUBRICATIONS`), ``center_distances_mm``,
    ``fluctuations_pct`` (ΔΩ, % of Ω_m) and ``frequencies_hz`` (f), ``repeats`` times each
    (independent realisations). The defaults are the paper's 180 points. Raises
    :class:`~rattlefit.errors.RattlefitError` naming the field for an empty or invalid
    choice."""

    pairs: tuple[str, ...] = ("I", "II")
    lubrications: tuple[str, ...] = ("dry", "boundary", "oil_jet")
    center_distances_mm: tuple[float, ...] = PAPER_CENTER_DISTANCES
    fluctuations_pct: tuple[float, ...] = PAPER_FLUCTUATIONS
    frequencies_hz: tuple[float, ...] = PAPER_FREQUENCIES
    repeats: int = 1

    def __post_init__(self):
        for name in (
            "pairs",
            "lubrications",
            "center_distances_mm",
            "fluctuations_pct",
            "frequencies_hz",
        ):
            value = tuple(getattr(self, name))
            object.__setattr__(self, name, value)
            if not value:
                raise RattlefitError(f"CampaignGrid.{name}: empty")
        unknown = [p for p in self.pairs if p not in TABLE2]
        if unknown:
            raise RattlefitError(
                f"CampaignGrid.pairs: unknown pair {unknown[0]!r}; Table 2 has I, II"
            )
        bad = [lub for lub in self.lubrications if lub not in ("dry", "boundary", "oil_jet")]
        if bad:
            raise RattlefitError(
                f"CampaignGrid.lubrications: unknown {bad[0]!r}; expected dry, boundary, oil_jet"
            )
        if self.repeats < 1:
            raise RattlefitError(f"CampaignGrid.repeats must be ≥ 1, got {self.repeats}")
        if not self.points():
            raise RattlefitError(
                "CampaignGrid: no point the paper tested (pair I was run under boundary and "
                "oil-jet lubrication only)"
            )

    def points(self) -> list[dict]:
        """The grid's points in order (pair, lubrication, fluctuation, frequency, centre
        distance, repeat), each a dict of those keys."""
        out = []
        for pair, lub, pct, freq, cd, k in itertools.product(
            self.pairs,
            self.lubrications,
            self.fluctuations_pct,
            self.frequencies_hz,
            self.center_distances_mm,
            range(self.repeats),
        ):
            if lub in PAPER_LUBRICATIONS[pair]:
                out.append(
                    dict(
                        pair=pair,
                        lubrication=lub,
                        fluctuation_pct=float(pct),
                        frequency_hz=float(freq),
                        center_distance_mm=float(cd),
                        repeat=k,
                    )
                )
        return out


@dataclasses.dataclass(frozen=True)
class SyntheticTruth:
    """The parameters a synthetic campaign is simulated with (SI): the film half-length per
    lubrication (m; the paper's dry flanks have none), the drag torque (N m), the oil
    temperature per lubrication (°C, which sets the viscosity of the paper's oil) and the
    adsorbed film h_min (m)."""

    film_half_length: tuple[tuple[str, float], ...] = (
        ("dry", 0.0),
        ("boundary", 0.085e-3),
        ("oil_jet", 1.0e-3),
    )
    drag_torque: float = 0.025
    temperature_c: tuple[tuple[str, float], ...] = (
        ("dry", 20.0),
        ("boundary", 20.0),
        ("oil_jet", 25.0),
    )
    min_film: float = 2e-6

    def __post_init__(self):
        if self.drag_torque <= 0 or self.min_film <= 0:
            raise RattlefitError("SyntheticTruth: drag_torque and min_film must be > 0")

    def film(self, lubrication: str) -> float:
        return dict(self.film_half_length)[lubrication]

    def temperature(self, lubrication: str) -> float:
        return dict(self.temperature_c)[lubrication]


def recording_name(point: dict) -> str:
    """``pairII_boundary_65.0mm_10pct_8Hz_r0.h5``."""
    return (
        f"pair{point['pair']}_{point['lubrication']}_{point['center_distance_mm']:.1f}mm_"
        f"{point['fluctuation_pct']:g}pct_{point['frequency_hz']:g}Hz_r{point['repeat']}.h5"
    )


def group_of(point: dict, joint: str, grid: CampaignGrid) -> str | None:
    """The joint fit a point's recording belongs to: ``sweeps`` puts each pair,
    lubrication, speed setting and repeat's centre distances together (with more than one
    distance), ``companions`` each boundary recording with the oil-jet one of the same pair,
    distance, setting and repeat (where the grid has both), ``none`` none."""
    p = point
    setting = f"{p['fluctuation_pct']:g}pct_{p['frequency_hz']:g}Hz_r{p['repeat']}"
    if joint == "sweeps" and len(grid.center_distances_mm) > 1:
        return f"sweep_pair{p['pair']}_{p['lubrication']}_{setting}"
    if (
        joint == "companions"
        and p["lubrication"] in ("boundary", "oil_jet")
        and {"boundary", "oil_jet"} <= set(grid.lubrications)
    ):
        return f"companions_pair{p['pair']}_{p['center_distance_mm']:.1f}mm_{setting}"
    return None


def simulate_campaign(
    directory: str | os.PathLike[str],
    *,
    grid: CampaignGrid | None = None,
    truth: SyntheticTruth | None = None,
    duration: float = 3.0,
    seed: int = 0,
    joint: str = "none",
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Simulate ``grid``'s recordings (default: the paper's 180) into ``directory`` with
    ``truth`` (default :class:`SyntheticTruth`), ``duration`` seconds each, recording ``i``
    seeded by the ``i``-th child spawned from ``seed`` (:func:`recording_seed`), and write
    ``manifest.csv`` beside them, grouped by ``joint``
    (:func:`group_of`); returns the manifest's path. A recording already there with the
    same truth and seed is kept (a repeated call simulates only what is missing). Raises
    :class:`~rattlefit.errors.RattlefitError` for an unknown ``joint`` or a duration under
    1 s (the IGR's block)."""
    if joint not in JOINT:
        raise RattlefitError(f"simulate_campaign: joint: expected one of {', '.join(JOINT)}")
    if duration < 1.0:
        raise RattlefitError(f"simulate_campaign: duration must be ≥ 1 s, got {duration}")
    grid = grid or CampaignGrid()
    truth = truth or SyntheticTruth()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda msg: None)
    rows = []
    points = grid.points()
    children = np.random.SeedSequence(seed).spawn(len(points))
    for i, point in enumerate(points):
        path = directory / recording_name(point)
        rows.append((str(path), group_of(point, joint, grid)))
        point_seed = recording_seed(children[i])
        if same_recording(path, point_seed, truth, point, duration):
            continue
        say(f"[{i + 1}/{len(points)}] simulating {path.name}")
        rec, known = synthesize_point(point, truth, duration=duration, seed=point_seed)
        write_recording(rec, path, extra_attrs=known)
    return write_manifest(directory / "manifest.csv", rows)


def recording_seed(child: np.random.SeedSequence) -> int:
    """The integer seed (< 2³¹) of one recording from its spawned ``child``."""
    return int(child.generate_state(1)[0] >> 1)


def synthesize_point(point: dict, truth: SyntheticTruth, *, duration: float, seed: int):
    """One grid point's recording and its truth (:func:`rattlefit.synthesize`)."""
    lub = point["lubrication"]
    g = table2_pair(point["pair"], center_distance_mm=point["center_distance_mm"])
    temperature = truth.temperature(lub)
    op = OperatingPoint(
        lub,
        temperature,
        MEAN_SPEED,
        MEAN_SPEED * point["fluctuation_pct"] / 100.0,
        point["frequency_hz"],
    )
    oil = PAPER_OIL
    mu = dynamic_viscosity(
        temperature, oil.viscosity_40c_cst, oil.viscosity_100c_cst, oil.density_kg_m3
    )
    params = RattleParams(
        truth.film(lub), truth.drag_torque, mu, g.backlash, min_film=truth.min_film
    )
    return synthesize(
        g,
        op,
        params,
        oil=oil,
        duration=duration,
        seed=seed,
        title=f"synthetic campaign: pair {point['pair']}, {lub}, "
        f"{point['center_distance_mm']:.1f} mm, {point['fluctuation_pct']:g} % at "
        f"{point['frequency_hz']:g} Hz, repeat {point['repeat']}",
    )


def same_recording(path: Path, seed: int, truth: SyntheticTruth, point: dict, duration) -> bool:
    """Whether ``path`` already holds this point's recording (same seed, film, drag torque
    and duration)."""
    if not path.is_file():
        return False
    try:
        known = read_truth(path)
        from ..io.recording import read_recording

        rec = read_recording(path)
    except Exception:
        return False
    return (
        known is not None
        and known.get("seed") == seed
        and abs(float(known.get(FILM, -1)) - truth.film(point["lubrication"])) < 1e-15
        and abs(float(known.get(DRAG_TORQUE, -1)) - truth.drag_torque) < 1e-15
        and abs(rec.duration - duration) < 1e-9
    )

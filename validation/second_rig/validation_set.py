"""A frozen validation set for ``rattlefit diagnose``, made by a second, different rig model.

    python -m validation.second_rig.validation_set --out DIR [--seed S]

writes 48 recordings of 3 s (recording format version 1, through ``rattlefit.io.recording.
write_recording``), ``truth.json`` and ``manifest.json`` into DIR (default
``studies/cache/validation_v2``). Half are clean (none of the effects below, but this
model's structure: torsional chain, servo speed loop, load sharing over helical contact lines,
exact involute backlash, cavitating Reynolds film, encoder on the secondary shaft's far end);
half carry one effect of :mod:`rig_effects` and four of them two. Both pairs of Table 2, the
three lubrications, centre distances 65.0–66.0 mm, 10–20 % speed fluctuation at 4–16 Hz.

Everything is drawn from the seed: the set's seed S (default :data:`SEED`) and the file's
number n give each case's seed ``1000·S + n``, from which its operating point, structural
values, effect sizes, initial state and encoder zeros follow. The set's plan (which effect on
which pair and lubrication) is fixed. A file that exists, whose truth entry is unchanged and
whose SHA-256 is the manifest's, is skipped; the rest are simulated together in one
vectorised run and written. ``manifest.json`` holds the seed, the generator version and every
file's SHA-256 (and that of its count data), which identify a frozen set, and
``method_commit``: the checkout's HEAD when the seed was drawn, the only method
``studies/diagnose_study.py --full`` scores the set at. Commit the method first, then draw.

Truth entries, by file stem: ``a_mm`` (the rattlefit film half-length with this film's squeeze
momentum — see :mod:`rig_film`; oil jet: the flooded film's wetted half-length, beyond what
rattlefit's saturated film can match, whose viscosity factor ``film`` states; dry: 0),
``drag_torque_Nm`` (T_b, the mean drag at the mean driven speed), ``viscosity_Pa_s`` (μ at the
stated oil temperature), ``unmodelled_effects`` (this model's names), ``expected`` (acceptable
verdicts; combinations joined by "+"), ``form``, ``effects`` (SI parameters, description,
physical reference), ``seed``, and ``film``, ``backlash`` and ``model`` (the structural values).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import itertools
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize

from rattlefit.diagnosis.verdict import NAMES_NOTHING as CLEAN
from rattlefit.io.recording import (
    GearPairSpec,
    OilSpec,
    OperatingPoint,
    Recording,
    counts_sha256,
    write_recording,
)

from .rig_chain import Rig, natural_frequencies
from .rig_effects import (
    FlexibleSecondaryCoupling,
    HystereticContact,
    MotorTorqueRipple,
    OilWarmUp,
    PittedToothWithBurr,
    ViscousChurningDrag,
    WheelEccentricity,
)
from .rig_film import equivalent_film
from .rig_geometry import OIL, TABLE2, Pair, dynamic_viscosity
from .rig_mesh import MeshLaw
from .rig_solver import STEP, simulate

#: The set's default seed, and the generator's version (part of the manifest).
SEED = 7321
VERSION = "1"
DEFAULT_OUT = Path(__file__).resolve().parents[2] / "studies" / "cache" / "validation_v2"
#: Recorded duration and burn-in, s; the rig's mean speed (500 rpm), rad/s.
DURATION = 3.0
BURN_IN = 0.5
MEAN_SPEED = 52.36
#: Fluctuation frequencies, Hz (even: a whole number of periods in the 0.5 s burn-in).
FREQUENCIES = (4, 6, 8, 10, 12, 14, 16)
#: Encoders: counts per revolution and sample rate.
COUNTS, RATE = 40_000, 10_000.0
#: Stated standard uncertainty of the angular backlash, and the true error's spread, rad.
BACKLASH_STD, BACKLASH_ERROR = 2e-4, 1e-4
#: Largest ratio of inertial forcing to drag at the speed-dependent-drag cases' points.
DRAG_FORCING = 5.0
LUBRICATIONS = ("dry", "boundary", "oil_jet")

#: The effect cases: (pair, lubrication, effect kinds), interleaved with 24 clean ones.
EFFECT_PLAN = (
    ("I", "boundary", ("ripple",)),
    ("II", "oil_jet", ("ripple4",)),
    ("I", "dry", ("ripple4",)),
    ("II", "boundary", ("drag",)),
    ("I", "oil_jet", ("drag",)),
    ("II", "oil_jet", ("drag",)),
    ("I", "boundary", ("runout_pinion",)),
    ("II", "dry", ("runout_both",)),
    ("II", "oil_jet", ("runout_driven",)),
    ("II", "boundary", ("defect",)),
    ("I", "dry", ("defect",)),
    ("II", "oil_jet", ("defect",)),
    ("II", "dry", ("hysteresis",)),
    ("I", "dry", ("hysteresis",)),
    ("II", "boundary", ("hysteresis",)),
    ("II", "boundary", ("flex",)),
    ("I", "oil_jet", ("flex",)),
    ("II", "dry", ("flex",)),
    ("II", "oil_jet", ("warmup",)),
    ("I", "boundary", ("warmup",)),
    ("I", "dry", ("runout_both", "hysteresis")),
    ("II", "oil_jet", ("ripple", "warmup")),
    ("I", "boundary", ("defect", "drag")),
    ("II", "boundary", ("flex", "runout_pinion")),
)


@dataclass(frozen=True)
class Case:
    """One recording of the set: its number (1-based), pair, lubrication, effect kinds, seed."""

    number: int
    pair: str
    lubrication: str
    kinds: tuple[str, ...]
    seed: int


def plan(seed: int = SEED) -> list[Case]:
    """The set's 48 cases, clean and effect cases alternating."""
    cases = []
    for i, effect in enumerate(EFFECT_PLAN):
        clean = ("I" if i % 2 else "II", LUBRICATIONS[i % 3], ())
        for pair, lub, kinds in (clean, effect):
            n = len(cases) + 1
            cases.append(Case(n, pair, lub, kinds, 1000 * seed + n))
    return cases


# --- drawing a case ------------------------------------------------------------------------


@dataclass(frozen=True)
class Drawn:
    """A case made concrete: the operating point, the rig with its effects, and the rest."""

    case: Case
    center_distance_mm: float
    percent: int
    frequency: int
    rig: Rig
    clean_rig: Rig
    effects: tuple
    stated_backlash: float
    zeros: tuple[int, int]


def _uniform(rng, lo, hi, digits=None):
    x = float(rng.uniform(lo, hi))
    return round(x, digits) if digits is not None else x


def _operating(rng, pair_name: str, most: float = math.inf):
    """(centre distance mm, fluctuation %, frequency Hz, T_b N m) with rattle guaranteed:
    the inertial forcing I2 (z1/z2) ΔΩ 2πf at least three and at most ``most`` times the
    drag (a drag law matters only where the forcing is not much larger than the drag)."""
    cd = _uniform(rng, 65.0, 66.0, 1)
    ratio = TABLE2[pair_name]["z"][1] / TABLE2[pair_name]["z"][0]
    inertia = TABLE2[pair_name]["driven_inertia"]
    while True:
        drag = _uniform(rng, 0.015, 0.04, 3)
        pct, f = int(rng.integers(10, 21)), int(rng.choice(FREQUENCIES))
        forcing = inertia / ratio * MEAN_SPEED * pct / 100 * 2 * math.pi * f
        if 3 * drag <= forcing <= most * drag:
            return cd, pct, f, drag


def _film_values(rng, pair: Pair, mesh: MeshLaw, lubrication, temperature, h_min):
    """(a_max, h_oil) of the film: boundary a starved layer with a rattlefit-equivalent a
    drawn in 0.05–0.15 mm, oil jet flooded over 1 mm, dry none."""
    if lubrication == "oil_jet":
        return 1e-3, math.inf
    if lubrication == "dry":
        return math.inf, math.inf
    target = _uniform(rng, 0.05e-3, 0.15e-3)
    table = mesh.table()
    mu = float(dynamic_viscosity(temperature))

    def miss(h_oil):
        a = equivalent_film(pair, table, mu, math.inf, h_oil, h_min)["a_equivalent_m"]
        return (a if a is not None else 1.0) - target

    return math.inf, optimize.brentq(miss, h_min * 1.01, 6 * h_min, xtol=1e-10)


def _structure(rng, pair: Pair, lubrication: str) -> dict:
    """The clean rig's structural values (seeded)."""
    pinion = (5e-5, 7e-5) if pair.name == "I" else (7e-5, 9e-5)
    hot = lubrication == "oil_jet"
    return dict(
        motor_inertia=_uniform(rng, 1.2e-4, 1.8e-4),
        pinion_inertia=_uniform(rng, *pinion),
        far_inertia=_uniform(rng, 2e-5, 4e-5),
        drive_stiffness=_uniform(rng, 5.5e3, 8e3),
        drive_damping=_uniform(rng, 0.02, 0.05),
        shaft_stiffness=_uniform(rng, 3e4, 5e4),
        shaft_damping=_uniform(rng, 0.01, 0.03),
        bandwidth_hz=_uniform(rng, 80.0, 150.0),
        integral_hz=_uniform(rng, 20.0, 40.0),
        ff_error=_uniform(rng, -0.1, 0.1),
        drag_gear_share=_uniform(rng, 0.4, 0.6),
        h_min=_uniform(rng, 1.7e-6, 2.3e-6),
        temperature_c=_uniform(rng, 22.0, 28.0, 1) if hot else _uniform(rng, 19.0, 23.0, 1),
        mesh_phase=_uniform(rng, 0.0, float(pair.z2)),
        start_fraction=_uniform(rng, -0.8, 0.8),
    )


def drawn_effect(kind: str, rng, pair: Pair):
    """The effect of ``kind`` with sizes drawn from ``rng``."""
    um, turn = 1e-6, 2 * math.pi
    if kind in ("ripple", "ripple4"):
        cog = _uniform(rng, 0.04, 0.08)
        return MotorTorqueRipple(
            cog,
            _uniform(rng, 0, turn),
            _uniform(rng, 0.2, 0.4) * cog,
            _uniform(rng, 0, turn),
            _uniform(rng, 0.04, 0.06) if kind == "ripple4" else 0.0,
            _uniform(rng, 0, turn),
        )
    if kind == "drag":
        return ViscousChurningDrag(_uniform(rng, 0.1, 0.2), _uniform(rng, 0.7, 0.85))
    if kind.startswith("runout"):
        e1, e2, e3 = _uniform(rng, 12, 25), _uniform(rng, 8, 20), _uniform(rng, 3, 8)
        keep = {"runout_pinion": (1, 0, 1), "runout_both": (1, 1, 0), "runout_driven": (0, 1, 1)}
        k1, k2, k3 = keep[kind]
        return WheelEccentricity(
            k1 * e1 * um,
            _uniform(rng, 0, turn),
            k2 * e2 * um,
            _uniform(rng, 0, turn),
            k3 * e3 * um,
            _uniform(rng, 0, turn),
        )
    if kind == "defect":
        heights = (_uniform(rng, 8, 14) * um, _uniform(rng, 4, 8) * um)
        return PittedToothWithBurr(
            int(rng.integers(0, pair.z2)),
            heights,
            _uniform(rng, 0.3, 0.5),
            _uniform(rng, 0.3, 0.45),
        )
    if kind == "hysteresis":
        return HystereticContact(_uniform(rng, 0.6, 0.8))
    if kind == "flex":
        return FlexibleSecondaryCoupling(
            _uniform(rng, 0.3, 0.45),
            _uniform(rng, 350, 700),
            _uniform(rng, 0.05, 0.08),
            _uniform(rng, 0.5, 0.7),
        )
    if kind == "warmup":
        return OilWarmUp(_uniform(rng, 8, 14), _uniform(rng, 1.0, 2.0))
    raise ValueError(f"unknown effect kind {kind!r}")


def draw(case: Case) -> Drawn:
    """Everything about ``case`` that follows from its seed."""
    rng = np.random.default_rng(case.seed)
    most = DRAG_FORCING if "drag" in case.kinds else math.inf
    cd, pct, f, drag = _operating(rng, case.pair, most)
    pair = Pair(case.pair, cd * 1e-3)
    values = _structure(rng, pair, case.lubrication)
    mesh = MeshLaw(pair, _uniform(rng, 0.3, 0.4), _uniform(rng, 0.4, 0.6))
    a_max, h_oil = _film_values(
        rng, pair, mesh, case.lubrication, values["temperature_c"], values["h_min"]
    )
    rig = Rig(
        pair,
        mesh,
        case.lubrication,
        drag_torque=drag,
        mean_speed=MEAN_SPEED,
        speed_amplitude=MEAN_SPEED * pct / 100,
        drive_frequency=float(f),
        a_max=a_max,
        h_oil=h_oil,
        **values,
    )
    effects = tuple(drawn_effect(kind, rng, pair) for kind in case.kinds)
    clean = dataclasses.replace(rig, table=mesh.table())
    for e in effects:
        rig = e.apply(rig)
    rig = dataclasses.replace(rig, table=rig.mesh_table())
    stated = pair.backlash_angle() + float(rng.normal(0.0, BACKLASH_ERROR))
    zeros = tuple(int(z) for z in rng.integers(-(10**6), 10**6, size=2))
    return Drawn(case, cd, pct, f, rig, clean, effects, stated, zeros)


# --- naming and truth ----------------------------------------------------------------------


def name_of(d: Drawn) -> str:
    """``v2_<pair>_<lubrication>_<cd>_<pct>pct_<f>Hz_<n>``."""
    lub = d.case.lubrication.replace("_", "")
    return (
        f"v2_pair{d.case.pair}_{lub}_{d.center_distance_mm:.1f}_{d.percent}pct_"
        f"{d.frequency}Hz_{d.case.number:02d}"
    )


def expected(effects) -> list[str]:
    """Acceptable verdicts: clean's, or each combination of the effects' names joined by +."""
    if not effects:
        return list(CLEAN)
    return ["+".join(c) for c in itertools.product(*(e.expected for e in effects))]


def film_truth(d: Drawn) -> dict:
    """The film's own values and its rattlefit equivalent."""
    r = d.rig
    out = {"lubrication": r.lubrication, "min_film_m": r.h_min}
    if r.lubrication == "dry":
        return out
    eq = equivalent_film(r.pair, r.mesh_table(), r.viscosity, r.a_max, r.h_oil, r.h_min)
    out.update(
        wetted_half_length_m=None if math.isinf(r.a_max) else r.a_max,
        oil_layer_m=None if math.isinf(r.h_oil) else r.h_oil,
        squeeze_momentum_N_s=eq["squeeze_momentum_N_s"],
        rattlefit_a_equivalent_m=eq["a_equivalent_m"],
        rattlefit_viscosity_factor=float(eq["viscosity_factor"]),
    )
    return out


def a_truth_mm(film: dict) -> float:
    """Truth ``a_mm``: the rattlefit-equivalent film, else the flooded film's wetted length."""
    if film["lubrication"] == "dry":
        return 0.0
    a = film["rattlefit_a_equivalent_m"] or film["wetted_half_length_m"]
    return round(a * 1e3, 4)


def model_truth(d: Drawn) -> dict:
    """The rig's structural values (SI) and its modes."""
    r, p = d.rig, d.rig.pair
    k_mean = float(np.mean(r.mesh_table()[:-1, 0]))
    names = (
        "motor_inertia",
        "pinion_inertia",
        "gear_inertia",
        "far_inertia",
        "drive_stiffness",
        "drive_damping",
        "shaft_stiffness",
        "shaft_damping",
        "bandwidth_hz",
        "integral_hz",
        "ff_error",
        "drag_gear_share",
        "temperature_c",
        "mesh_phase",
        "start_fraction",
    )
    out = {n: float(getattr(r, n)) for n in names}
    out.update(
        kappa=r.mesh.kappa,
        coast_offset=r.mesh.coast_offset,
        eps_alpha=p.eps_alpha,
        eps_beta=p.eps_beta,
        mean_mesh_stiffness_N_per_m=k_mean,
        modes_free_flight_hz=[round(x, 1) for x in natural_frequencies(r) if x > 1.0],
        modes_in_contact_hz=[round(x, 1) for x in natural_frequencies(r, k_mean) if x > 1.0],
        step_s=STEP,
        burn_in_s=BURN_IN,
    )
    return out


def form_text(d: Drawn) -> str:
    r, m = d.rig, model_truth(d)
    free = ", ".join(f"{x:.0f}" for x in m["modes_free_flight_hz"])
    contact = ", ".join(f"{x:.0f}" for x in m["modes_in_contact_hz"])
    parts = [
        "second rig model: torsional chain servo rotor–coupling/shaft–pinion–mesh–gear–"
        f"secondary shaft–far end (modes {free} Hz in free flight, {contact} Hz in contact)",
        f"speed loop PI {r.bandwidth_hz:.0f} Hz, torque limit {r.torque_limit} N m, "
        f"feed-forward inertia {100 * r.ff_error:+.0f} %",
        f"load sharing over helical contact lines (εα {m['eps_alpha']:.2f}, εβ "
        f"{m['eps_beta']:.2f}, tip/root softening {r.mesh.kappa:.2f})",
        "exact involute backlash, cavitating Reynolds squeeze film over every contact line",
        "secondary encoder on the far end of the secondary shaft",
        f"drag {100 * r.drag_gear_share:.0f} % on the gear's bearing, the rest on the far one",
        f"velocity Verlet, {STEP * 1e6:g} µs steps",
    ]
    parts += [e.describe(d.clean_rig) for e in d.effects]
    return "; ".join(parts) + f"; seed {d.case.seed}"


def truth_of(d: Drawn) -> dict:
    """The case's truth entry (JSON-ready)."""
    film = film_truth(d)
    entry = {
        "a_mm": a_truth_mm(film),
        "drag_torque_Nm": d.rig.drag_torque,
        "viscosity_Pa_s": round(d.rig.viscosity, 4),
        "unmodelled_effects": [e.name for e in d.effects],
        "expected": expected(d.effects),
        "form": form_text(d),
        "effects": [
            {
                "name": e.name,
                **e.sizes(d.clean_rig),
                "description": e.describe(d.clean_rig),
                "reference": e.reference,
            }
            for e in d.effects
        ],
        "seed": d.case.seed,
        "film": film,
        "backlash": {"true_rad": d.rig.pair.backlash_angle(), "stated_rad": d.stated_backlash},
        "model": model_truth(d),
    }
    return json.loads(json.dumps(entry))


# --- recordings ----------------------------------------------------------------------------


def gear_pair_spec(d: Drawn) -> GearPairSpec:
    p, t = d.rig.pair, TABLE2[d.case.pair]
    return GearPairSpec(
        teeth_driving=p.z1,
        teeth_driven=p.z2,
        pitch_diameter_driving_mm=t["d_mm"][0],
        pitch_diameter_driven_mm=t["d_mm"][1],
        face_width_driving_mm=t["b_mm"][0],
        face_width_driven_mm=t["b_mm"][1],
        normal_module_mm=p.mn * 1e3,
        normal_pressure_angle_deg=20.0,
        helix_angle_deg=math.degrees(p.beta),
        driven_inertia_kg_m2=p.driven_inertia,
        center_distance_mm=d.center_distance_mm,
        angular_backlash_rad=d.stated_backlash,
        angular_backlash_std_rad=BACKLASH_STD,
    )


def counts(theta) -> np.ndarray:
    """Encoder counts floor(θ·N/2π) of angles θ (rad), int64."""
    return np.floor(np.asarray(theta) * (COUNTS / (2 * math.pi))).astype(np.int64)


def at_drive_frequency(d: Drawn, frequency: float) -> Drawn:
    """``d`` with its drive (and its clean twin's) fluctuating at ``frequency`` Hz."""
    return dataclasses.replace(
        d,
        frequency=frequency,
        rig=dataclasses.replace(d.rig, drive_frequency=frequency),
        clean_rig=dataclasses.replace(d.clean_rig, drive_frequency=frequency),
    )


def recording_of(d: Drawn, theta_primary, theta_secondary) -> Recording:
    """The recording the two encoders latch: the pinion and the secondary shaft's far end."""
    op = OperatingPoint(
        d.case.lubrication,
        d.rig.temperature_c,
        MEAN_SPEED,
        MEAN_SPEED * d.percent / 100,
        float(d.frequency),
    )
    return Recording(
        primary=counts(theta_primary) + d.zeros[0],
        secondary=counts(theta_secondary) + d.zeros[1],
        sample_rate_hz=RATE,
        counts_per_rev=COUNTS,
        gear_pair=gear_pair_spec(d),
        operating=op,
        oil=OilSpec(**OIL),
        title=f"pair {d.case.pair}, {d.case.lubrication}, centre distance "
        f"{d.center_distance_mm:.1f} mm",
    )


def simulate_cases(drawn, duration=DURATION, burn_in=BURN_IN, say=None):
    """Simulate the drawn cases together; returns (recordings, trajectory)."""
    traj = simulate([d.rig for d in drawn], duration, burn_in=burn_in, say=say)
    recs = [recording_of(d, traj.theta[1, b], traj.theta[3, b]) for b, d in enumerate(drawn)]
    return recs, traj


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# --- the set -------------------------------------------------------------------------------


def _load(path: Path) -> dict:
    return json.loads(path.read_text()) if path.is_file() else {}


def _dump(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    os.replace(tmp, path)


def unchanged(path: Path, entry: dict, old_truth: dict, manifest: dict, seed: int) -> bool:
    """The file exists, its truth entry and the set's seed and version are the manifest's,
    and its bytes hash to the manifest's SHA-256."""
    same_set = manifest.get("seed") == seed and manifest.get("version") == VERSION
    recorded = manifest.get("files", {}).get(path.name, {}).get("sha256")
    return (
        path.is_file()
        and same_set
        and old_truth.get(path.stem) == entry
        and recorded == sha256(path)
    )


def method_commit() -> str:
    """The full hash of this checkout's HEAD, where the set's method is fixed; "" outside git."""
    out = subprocess.run(
        ["git", "rev-parse", "HEAD"],
        cwd=Path(__file__).resolve().parent,
        capture_output=True,
        text=True,
        check=False,
    )
    return out.stdout.strip()


def build(out: Path, seed: int = SEED, say=print) -> dict:
    """Generate the set into ``out`` (see the module notes); returns the manifest."""
    out.mkdir(parents=True, exist_ok=True)
    old_truth, old_manifest = _load(out / "truth.json"), _load(out / "manifest.json")
    drawn = [draw(c) for c in plan(seed)]
    truth = {name_of(d): truth_of(d) for d in drawn}
    files = dict(old_manifest.get("files", {})) if old_manifest.get("seed") == seed else {}
    todo = []
    for d in drawn:
        path = out / f"{name_of(d)}.h5"
        if unchanged(path, truth[path.stem], old_truth, old_manifest, seed):
            say(f"{path.name}: exists and matches the manifest")
        else:
            todo.append(d)
    if todo:
        say(
            f"simulating {len(todo)} recordings together ({DURATION:g} s each after a "
            f"{BURN_IN:g} s burn-in)"
        )
        t0 = time.perf_counter()
        recs, traj = simulate_cases(todo, say=say)
        for i, (d, rec) in enumerate(zip(todo, recs, strict=True)):
            path = write_recording(rec, out / f"{name_of(d)}.h5")
            files[path.name] = {"sha256": sha256(path), "counts_sha256": counts_sha256(rec)}
            say(
                f"[{i + 1}/{len(todo)}] {path.name}: built in {traj.seconds / len(todo):.1f} s "
                f"(its share of a {time.perf_counter() - t0:.0f} s batch of {len(todo)})"
            )
    _dump(out / "truth.json", truth)
    for stray in sorted(set(out.glob("*.h5")) - {out / f"{n}.h5" for n in truth}):
        say(f"{stray.name}: not part of this set (left alone)")
    same = old_manifest.get("seed") == seed and old_manifest.get("version") == VERSION
    manifest = {
        "generator": "validation/second_rig/validation_set.py",
        "version": VERSION,
        "seed": seed,
        # the method the set is to be scored at: the checkout's when the seed was first drawn
        "method_commit": old_manifest.get("method_commit") if same else method_commit(),
        "truth_sha256": sha256(out / "truth.json"),
        "files": {f"{n}.h5": files[f"{n}.h5"] for n in truth},
    }
    _dump(out / "manifest.json", manifest)
    return manifest


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="directory of the set")
    ap.add_argument("--seed", type=int, default=SEED, help=f"the set's seed (default {SEED})")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    build(args.out, args.seed, say=lambda s: print(s, flush=True))
    print(f"done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()

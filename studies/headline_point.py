"""What one 3 s recording of the paper's headline point pins: `identify`'s 95 % intervals per
feature set, the squeeze-film group among them, and `a` once h_min is known.

The point is pair II at 65.6 mm, boundary, 20 % at 16 Hz, recorded twice: the independent
simulator's shared file and rattlefit's bundled one (same truth: a 0.085 mm, T_b 0.025 N m,
μ 0.4942 Pa s). Each is identified with the default options (seed 0) by the band PSDs alone,
by the bands and the drive-cycle-folded statistics, and by those with h_min known to 10 %
(``--prior min_film=2e-6:0.1``). The squeeze-film group is the squeeze film's momentum per
approach, ``squeeze_momentum`` (N s); its truth takes the paper's h_min (2 µm), which both
simulators use, and pair II's flanks.

The checks here: the T_b interval two-sided and at most a factor of 2 wide; the group's
interval at least 3× narrower, in log, than the band PSDs alone give; with h_min known to 10 %,
``a`` two-sided and at most a factor of 2 wide.

    python studies/headline_point.py [--from DIR] [--json out.json]

``--from DIR`` (default ``studies/results/raw/headline``) keeps each identify JSON there,
named ``<file>_<variant>.json``, and reads those present instead of running them.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from common import identified, tree_state, write_result

from rattlefit.physics.geometry import table2_pair
from rattlefit.physics.model import DEFAULT_MIN_FILM, squeeze_momentum
from rattlefit.reproducibility import platform_info
from rattlefit.testing.shared import recordings_dir

ROOT = Path(__file__).resolve().parents[1]
FILES = {
    "shared": recordings_dir(ROOT) / "pairII_boundary_65.6_20pct_16Hz.h5",
    "rattlefit": ROOT / "data" / "pairII_boundary_65.6_20pct_16Hz.h5",
}
#: variant → (features, extra identify arguments)
VARIANTS = {
    "bands": ("bands", ()),
    "bands+folded": ("bands+folded", ()),
    "bands+folded, h_min 10 %": ("bands+folded", ("--prior", "min_film=2e-6:0.1")),
}
A, T_B, MU = 0.085e-3, 0.025, 0.4942
GEOMETRY = table2_pair("II", center_distance_mm=65.6)
TRUTH = {
    "film_half_length": A,
    "drag_torque": T_B,
    "viscosity": MU,
    "squeeze_momentum": float(
        squeeze_momentum(A, MU, DEFAULT_MIN_FILM, GEOMETRY.curvature_radius, GEOMETRY.axial_width)
    ),
}


def interval_row(p: dict, truth: float) -> dict:
    """An interval's ends, factor (None when one-sided) and whether it holds ``truth``."""
    two_sided = p["lower"] > 0 and p["bound"] not in ("lower", "upper")
    return {
        "estimate": p["estimate"],
        "lower": p["lower"],
        "upper": p["upper"],
        "bound": p["bound"],
        "factor": p["upper"] / p["lower"] if two_sided else None,
        "truth_inside": bool(p["lower"] <= truth <= p["upper"]),
    }


def study(directory: Path, say) -> list[dict]:
    rows = []
    for label, path in FILES.items():
        for variant, (features, extra) in VARIANTS.items():
            tag = variant.replace("+", "_").replace(", ", "_").replace(" %", "pct").replace(" ", "")
            doc, wall = identified(path, features, directory / f"{label}_{tag}.json", extra)
            params = {k: interval_row(doc["parameters"][k], t) for k, t in TRUTH.items()}
            rows.append(
                {
                    "file": label,
                    "variant": variant,
                    "identify_s": doc["fit"]["wall_time_s"],
                    "process_s": wall,
                    "chi2": doc["fit"]["chi2"],
                    "dof": doc["fit"]["dof"],
                    "parameters": params,
                }
            )
            say(f"{label:9s} {variant:25s} " + phrase(params))
    return rows


def phrase(params: dict) -> str:
    """Each interval in words: ``T_b [0.012, 0.03] (×2.5)``."""
    out = []
    for name, short in (
        ("drag_torque", "T_b"),
        ("film_half_length", "film_half_length"),
        ("squeeze_momentum", "M"),
    ):
        p = params[name]
        scale = 1e3 if name == "film_half_length" else 1.0
        span = f"[{p['lower'] * scale:.3g}, {p['upper'] * scale:.3g}]"
        out.append(f"{short} {span} (×{p['factor']:.2f})" if p["factor"] else f"{short} {span}")
    return ", ".join(out)


def checks(rows: list[dict]) -> dict:
    """The three width checks per file (None where a row is missing)."""
    by = {(r["file"], r["variant"]): r["parameters"] for r in rows}
    out = {}
    for label in FILES:
        bands, folded = by.get((label, "bands")), by.get((label, "bands+folded"))
        known = by.get((label, "bands+folded, h_min 10 %"))
        t_b = folded and folded["drag_torque"]["factor"]
        g_ratio = None
        if bands and folded and bands["squeeze_momentum"]["factor"]:
            wide = math.log(bands["squeeze_momentum"]["factor"])
            narrow = folded["squeeze_momentum"]["factor"]
            g_ratio = wide / math.log(narrow) if narrow else None
        a_known = known and known["film_half_length"]["factor"]
        out[label] = {
            "drag_torque_factor": t_b,
            "drag_torque_met": bool(t_b and t_b <= 2.0),
            "group_log_width_ratio": g_ratio,
            "group_met": bool(g_ratio and g_ratio >= 3.0),
            "a_factor_h_min_known": a_known,
            "a_met": bool(a_known and a_known <= 2.0),
        }
    return out


def factor_phrase(factor: float | None) -> str:
    """``×2.08``, or ``one-sided`` for an interval without a factor."""
    return f"×{factor:.2f}" if factor else "one-sided"


def check_phrase(label: str, v: dict, rows: list[dict]) -> str:
    """One file's checks in words: T_b and the group with the folded statistics (the group
    also with the bands alone), and a with h_min known."""
    by = {r["variant"]: r["parameters"] for r in rows if r["file"] == label}
    group = {k: by[k]["squeeze_momentum"]["factor"] for k in ("bands", "bands+folded") if k in by}
    ratio = v["group_log_width_ratio"]
    return (
        f"{label}: T_b {factor_phrase(v['drag_torque_factor'])}; the group "
        f"{factor_phrase(group.get('bands'))} → {factor_phrase(group.get('bands+folded'))} with "
        f"the folded statistics"
        + (f" ({ratio:.1f}× narrower in log)" if ratio else "")
        + f"; a with h_min known {factor_phrase(v['a_factor_h_min_known'])}"
    )


def result_document(rows: list[dict]) -> dict:
    """The result file (``studies/results/``) of ``rows``."""
    c = checks(rows)
    held = all(p["truth_inside"] for r in rows for p in r["parameters"].values())
    met = [
        f"{k} {label}"
        for label, v in c.items()
        for k in ("T_b", "M", "film_half_length")
        if v[{"T_b": "drag_torque_met", "M": "group_met", "film_half_length": "a_met"}[k]]
    ]
    words = {label: check_phrase(label, v, rows) for label, v in c.items()}
    return {
        "order": 12.5,
        "what": "what one 3 s recording of the headline point pins (pair II, 65.6 mm, boundary, "
        "20 % at 16 Hz; the shared file and the bundled one): identify's 95 % intervals per "
        "feature set, the squeeze-film group (the film's momentum per approach, ∝ μa³/h_min² "
        "for a short film), and a with h_min known to 10 %",
        "summary": "; ".join(words.values())
        + ("; every truth inside" if held else "; a truth outside")
        + " (T_b and a with the bands and the folded statistics)",
        "aim": "T_b two-sided and ≤ ×2; the group ≥ 3× narrower in log than the bands alone give; "
        "a ≤ ×2 with h_min known to 10 %",
        "verdict": "met"
        if len(met) == 3 * len(FILES)
        else ("met: " + ", ".join(met) if met else "missed"),
        "measured": "rattlefit identify FILE --features F [--prior min_film=2e-6:0.1] with the "
        "default options, seed 0; the group's truth takes the paper's h_min, 2 µm",
        "command": "python studies/headline_point.py --json OUT",
        "checks": c,
        "results": rows,
        "platform": platform_info(),
        **tree_state(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="directory", default="studies/results/raw/headline")
    ap.add_argument("--json")
    args = ap.parse_args()
    directory = Path(args.directory).resolve()
    directory.mkdir(parents=True, exist_ok=True)
    rows = study(directory, print)
    if args.json:
        write_result(args.json, result_document(rows))


if __name__ == "__main__":
    main()

"""The campaign's HTML report: one self-contained file (figures inline, nothing fetched).

It shows, after a summary of the campaign, the gear rattle index IGR (eq. 10) against the
centre distance per lubrication as the paper's Figs. 10–11 do, one panel per speed setting,
measured (markers) and re-simulated at each recording's fitted parameters (lines: the mean
of the realisations; bars: their range); each target parameter against centre distance,
lubrication and speed setting with its 95 % interval; a table of every recording's
estimates; the diagnosis verdicts; and the recordings that failed, with why. It draws only:
the re-simulated IGR comes with the results (:mod:`rattlefit.campaign.work`). The drawing
and the tables reuse :mod:`rattlefit.report`'s building blocks (its style sheet, PNG
figures, units and interval cells).
"""

from __future__ import annotations

import base64
import textwrap
from collections import defaultdict
from html import escape
from pathlib import Path

import numpy as np

from ..quantities import TARGETS, axis_label, display
from ..report.document import CSS
from ..report.explain import display_unit, estimate_cells
from ..report.figures import png
from ..report.plots import pyplot
from ..util import atomic_write
from ..version import __version__

#: Each lubrication's marker and colour (the paper's: □ dry, ○ boundary, ◇ oil jet).
STYLE = {
    "dry": ("s", "C3"),
    "boundary": ("o", "C0"),
    "oil_jet": ("D", "C2"),
}
OTHER_STYLE = ("^", "C4")


def lubrication_order(lubrication: str) -> int:
    """Dry, boundary, oil jet, then any other."""
    return list(STYLE).index(lubrication) if lubrication in STYLE else len(STYLE)


def setting_of(info: dict) -> tuple[float, float]:
    """A recording's speed setting: (fluctuation %, frequency Hz)."""
    return (float(info["fluctuation_pct"]), float(info["frequency_hz"]))


def setting_label(setting: tuple[float, float]) -> str:
    return f"ΔΩ = {setting[0]:g} %, f = {setting[1]:g} Hz"


def igr_figure(recordings: list[dict], pair: str):
    """IGR (rad·Hz) against centre distance (mm) of gear pair ``pair``'s recordings, one
    panel per speed setting (rows: fluctuation, columns: frequency), per lubrication the
    measured values (open markers) and the model's re-simulated mean (line) and range
    (bars). ``recordings`` are :func:`rattlefit.campaign.work.describe` dicts with
    ``igr_model``."""
    mine = [r for r in recordings if r["pair"] == pair]
    rows = sorted({setting_of(r)[0] for r in mine})
    cols = sorted({setting_of(r)[1] for r in mine})
    fig, axes = pyplot().subplots(
        len(rows), len(cols), figsize=(3.6 * len(cols) + 0.6, 2.9 * len(rows) + 0.4), squeeze=False
    )
    for i, pct in enumerate(rows):
        for j, freq in enumerate(cols):
            ax = axes[i, j]
            here = [r for r in mine if setting_of(r) == (pct, freq)]
            draw_igr(ax, here)
            ax.set_title(setting_label((pct, freq)), fontsize=9)
            ax.set_xlabel("centre distance (mm)")
            ax.set_ylabel("IGR (rad·Hz)")
            ax.grid(True, color="0.9", lw=0.6)
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    title = (
        f"gear pair {pair}: IGR against centre distance, measured (markers) and the model at "
        "the fitted parameters (lines; bars: the realisations' range)"
    )
    fig.suptitle(wrapped(title, fig), fontsize=10)
    fig.tight_layout()
    ncol = 6 if len(cols) > 1 else 2
    fig.legend(
        handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=ncol, fontsize=8
    )
    return fig


def wrapped(title: str, fig) -> str:
    """``title`` broken into lines that fit ``fig``'s width (about 13 characters an inch at
    the titles' size)."""
    return textwrap.fill(title, width=max(40, int(13 * fig.get_figwidth())))


def draw_igr(ax, recordings: list[dict]) -> None:
    """One panel of :func:`igr_figure`."""
    by_lub = defaultdict(list)
    for r in recordings:
        by_lub[r["lubrication"]].append(r)
    for lub in sorted(by_lub, key=lubrication_order):
        marker, colour = STYLE.get(lub, OTHER_STYLE)
        recs = sorted(by_lub[lub], key=lambda r: r["center_distance_mm"])
        x = np.array([r["center_distance_mm"] for r in recs])
        ax.plot(
            x,
            [r["igr_measured"] for r in recs],
            marker,
            mfc="none",
            color=colour,
            ms=6,
            label=f"{lub} measured",
        )
        cds = sorted(set(x.tolist()))
        model = [
            np.concatenate([r["igr_model"] for r in recs if r["center_distance_mm"] == cd])
            for cd in cds
        ]
        mean = [float(np.mean(m)) for m in model]
        lo = [float(np.min(m)) for m in model]
        hi = [float(np.max(m)) for m in model]
        ax.plot(cds, mean, "-", color=colour, lw=1.2, label=f"{lub} model")
        ax.vlines(cds, lo, hi, color=colour, lw=3, alpha=0.35)


def parameter_figure(rows: list[dict], name: str):
    """Parameter ``name``'s estimate and 95 % interval against centre distance (mm), one
    panel per gear pair; colour and marker the lubrication, the speed settings side by side
    (offset in x, in their order), filled where identified; a synthetic recording's truth
    as a black bar. ``rows`` are the table's rows."""
    mine = [r for r in rows if r["parameter"] == name]
    pairs = sorted({r["pair"] for r in mine})
    settings = sorted({setting_of(r) for r in mine})
    lubs = sorted({r["lubrication"] for r in mine}, key=lubrication_order)
    fig, axes = pyplot().subplots(1, len(pairs), figsize=(5.2 * len(pairs), 3.4), squeeze=False)
    unit = mine[0]["unit"] if mine else None
    mult = display(name, unit)[0]
    slots = len(settings) * len(lubs)
    for ax, pair in zip(axes[0], pairs, strict=True):
        for r in (r for r in mine if r["pair"] == pair):
            marker, colour = STYLE.get(r["lubrication"], OTHER_STYLE)
            slot = settings.index(setting_of(r)) * len(lubs) + lubs.index(r["lubrication"])
            x = r["center_distance_mm"] + 0.03 * (slot - (slots - 1) / 2)
            est, hi = r["estimate"] * mult, r["upper"] * mult
            lo = max(r["lower"] * mult, 1e-3 * hi)
            ax.vlines(x, lo, hi, color=colour, lw=1.2)
            ax.plot(x, est, marker, color=colour, mfc=colour if r["identified"] else "none", ms=5)
            if r.get("truth") is not None and np.isfinite(r["truth"]):
                ax.plot(x, r["truth"] * mult, "_", color="k", ms=9, mew=1.5)
        ax.set_yscale("log")
        ax.set_title(f"gear pair {pair}", fontsize=9)
        ax.set_xlabel("centre distance (mm)")
        ax.set_ylabel(axis_label(name, unit))
        ax.grid(True, color="0.9", lw=0.6)
    from matplotlib.lines import Line2D

    styles = [(lub, *STYLE.get(lub, OTHER_STYLE)) for lub in lubs]
    handles = [Line2D([], [], marker=m, color=c, ls="", label=lub) for lub, m, c in styles]
    handles.append(Line2D([], [], marker="_", color="k", ls="", ms=9, label="truth"))
    order = "; ".join(f"{k + 1}: {setting_label(s)}" for k, s in enumerate(settings))
    title = (
        f"{name}: estimate and 95 % interval (filled: identified); settings left to right "
        f"at each distance, {order}"
    )
    fig.suptitle(wrapped(title, fig), fontsize=9)
    fig.tight_layout()
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=4, fontsize=8)
    return fig


def img(data: bytes, alt: str) -> str:
    """An ``<img>`` of PNG ``data`` as a ``data:`` URI."""
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return f'<img src="{uri}" alt="{escape(alt)}">'


def table_html(head: list[str], body: list[list[str]]) -> str:
    """An HTML table of escaped text cells."""
    th = "".join(f"<th>{escape(h)}</th>" for h in head)
    trs = "".join("<tr>" + "".join(f"<td>{escape(c)}</td>" for c in row) + "</tr>" for row in body)
    return f"<table><tr>{th}</tr>{trs}</table>"


def estimates_table(rows: list[dict]) -> str:
    """Each recording's target parameters: estimate and 95 % interval in display units, a
    ``*`` where identified, χ²/dof of its fit marked as a poor fit or unconverged."""
    by_rec: dict[str, dict] = {}
    for r in rows:
        by_rec.setdefault(r["recording"], {"row": r})[r["parameter"]] = r
    head = ["recording", "fit", "pair", "centre distance (mm)", "lubrication", "setting"]
    head += [f"{n} ({display_unit(n)})" for n in TARGETS] + ["χ²/dof"]
    body = []
    for found in by_rec.values():
        r = found["row"]
        cells = [
            r["recording_name"],
            r["fit"],
            r["pair"],
            f"{r['center_distance_mm']:g}",
            r["lubrication"],
            setting_label(setting_of(r)),
        ]
        for n in TARGETS:
            p = found.get(n)
            if p is None:
                cells.append("—")
                continue
            estimate, interval = estimate_cells(n, {**p, "bound": p["bound"] or None})
            if not interval.startswith("["):
                interval = f"({interval})"  # "0.08 (≤ 0.2)", not a comparison "0.08 ≤ 0.2"
            cells.append(f"{estimate} {interval}" + (" *" if p["identified"] else ""))
        cells.append(fit_cell(r))
        body.append(cells)
    return table_html(head, body)


def fit_cell(row: dict) -> str:
    """A fit's χ²/dof, marked as a poor fit, as unconverged and as having profiles below its
    optimum where it is."""
    depth = row.get("below_optimum") or 0.0
    marks = [
        m
        for m, on in (
            ("poor fit", row["poor_fit"]),
            ("not converged", not row.get("converged", True)),
            (f"profiles {depth:.1f} below the optimum", depth > 0),
        )
        if on
    ]
    return f"{row['chi2']:.1f}/{row['dof']}" + (f" ({', '.join(marks)})" if marks else "")


def diagnosis_table(diagnoses: list[dict]) -> str:
    """The verdict of every diagnosed identification."""
    body = [
        [d["unit"], ", ".join(Path(p).name for p in d["recordings"]), d["verdict"], d["sentence"]]
        for d in diagnoses
    ]
    return table_html(["fit", "recordings", "verdict", "in words"], body)


def failures_table(failures: list[dict]) -> str:
    """The units that failed, the stage and why."""
    body = [
        [f["unit"], ", ".join(Path(p).name for p in f["recordings"]), f["stage"], f["error"]]
        for f in failures
    ]
    return table_html(["fit", "recordings", "stage", "error"], body)


def campaign_figures(recordings: list[dict], rows: list[dict]) -> dict[str, bytes]:
    """The report's figures as PNG bytes, by file name: ``igr_pair<P>.png`` per gear pair and
    ``parameter_<name>.png`` per target parameter."""
    out = {}
    for pair in sorted({r["pair"] for r in recordings}):
        out[f"igr_pair{pair}.png"] = png(igr_figure(recordings, pair))
    for name in TARGETS:
        if any(r["parameter"] == name for r in rows):
            out[f"parameter_{name}.png"] = png(parameter_figure(rows, name))
    return out


def campaign_html(
    *,
    recordings: list[dict],
    rows: list[dict],
    diagnoses: list[dict],
    failures: list[dict],
    meta: dict,
    figures: dict[str, bytes],
) -> str:
    """The report as one HTML document (a string); arguments as :func:`write_campaign_report`,
    ``figures`` from :func:`campaign_figures`."""
    n_fits = len({r["fit"] for r in rows})
    parts = [
        f"<h1>Gear-rattle campaign: {escape(Path(meta['manifest']).name)}</h1>",
        f'<p class="meta">rattlefit {escape(__version__)}; every fit seeded with '
        f"{meta['seed']}; manifest {escape(meta['manifest'])}.</p>",
        f"<p>{len(recordings)} recordings in {n_fits} identifications of {meta['units']}; "
        f"{len(failures)} failure(s). The table (one row per recording and parameter) is "
        "<code>results.parquet</code> / <code>results.csv</code>; every run's JSON is in "
        "<code>runs/</code>.</p>",
    ]
    if failures:
        parts.append(
            f'<div class="warn">{len(failures)} identification(s) or stages failed: see '
            '<a href="#failures">the last section</a>.</div>'
        )
    parts.append("<h2>Gear rattle index against centre distance</h2>")
    parts += [img(data, name) for name, data in figures.items() if name.startswith("igr_")]
    parts.append("<h2>The parameters against centre distance, lubrication and speed</h2>")
    parts += [img(data, name) for name, data in figures.items() if name.startswith("parameter_")]
    parts.append("<h2>Estimates</h2>")
    parts.append(
        "<p>Estimate and 95 % interval of each recording's fit (* identified); a joint fit's "
        "shared parameters repeat on each of its recordings.</p>"
    )
    parts.append(estimates_table(rows))
    if diagnoses:
        parts.append("<h2>Diagnoses</h2>")
        parts.append(diagnosis_table(diagnoses))
    parts.append('<h2 id="failures">Failures</h2>')
    parts.append(failures_table(failures) if failures else "<p>None.</p>")
    title = escape(Path(meta["manifest"]).name)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>rattlefit campaign: {title}</title>\n<style>{CSS}</style>\n</head>\n"
        "<body>\n" + "\n".join(parts) + "\n</body>\n</html>\n"
    )


def write_campaign_report(
    path: str | Path,
    *,
    recordings: list[dict],
    rows: list[dict],
    diagnoses: list[dict],
    failures: list[dict],
    meta: dict,
    figures: str | Path | None = None,
) -> Path:
    """Write the campaign's report to ``path`` (atomically) and, when ``figures`` names a
    directory, its figures there as PNG; returns ``path``.

    recordings : the identified recordings (:func:`rattlefit.campaign.work.describe` dicts
        with ``igr_model``).
    rows : the results table's rows (:mod:`rattlefit.campaign.table`).
    diagnoses : ``diagnose -o``'s JSON of each diagnosed unit, with its ``unit`` and
        ``recordings``.
    failures : dicts of ``unit``, ``recordings``, ``stage`` and ``error``.
    meta : ``manifest`` (its path), ``units`` (how many), ``seed``.
    """
    drawn = campaign_figures(recordings, rows)
    if figures is not None:
        for name, data in drawn.items():
            atomic_write(Path(figures) / name, lambda tmp, data=data: tmp.write_bytes(data))
    text = campaign_html(
        recordings=recordings,
        rows=rows,
        diagnoses=diagnoses,
        failures=failures,
        meta=meta,
        figures=drawn,
    )
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))

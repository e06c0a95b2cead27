"""The uncertainty report: one self-contained HTML file (figures as base64 PNG ``data:`` URIs,
inline CSS, no script, nothing fetched) that an engineer can mail to a colleague."""

from __future__ import annotations

import base64
from html import escape
from pathlib import Path

from ..diagnosis.policy import MISSED_Z
from ..io.recording import Recording
from ..problem.options import unfinished_fit_advice
from ..util import atomic_write
from . import figures
from .explain import (
    below_optimum_sentence,
    display_unit,
    explain,
    meaning,
    parameter_rows,
    shown,
)
from .inputs import (
    check,
    idata_recordings,
    load_inference_data,
    recordings_of,
    same_recordings,
)
from .summary import recording_summary, summary_rows
from .tables import suggestion_note, suggestion_table
from .wording import (
    diagnosis_caveats,
    interval_label,
    profile_sentence,
    profile_thresholds,
    search_sentence,
)

CSS = """
body { font-family: -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; color: #1d1d1f;
       max-width: 1100px; margin: 1.5em auto; padding: 0 1em; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc;
     padding-bottom: 0.2em; margin-top: 1.8em; } h3 { margin-bottom: 0.3em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #d0d0d0; padding: 0.3em 0.55em; text-align: left;
         vertical-align: top; overflow-wrap: anywhere; }
th { background: #f2f2f2; } td.num { font-variant-numeric: tabular-nums;
     white-space: nowrap; }
tr.identified td.status { color: #0a6b2b; font-weight: 600; }
tr.unidentified td.status { color: #8a5a00; }
.warn { background: #fff4e0; border-left: 5px solid #e08a00; padding: 0.5em 0.8em;
        margin: 0.8em 0; }
.note { background: #eef4fb; border-left: 5px solid #4a7ab5; padding: 0.5em 0.8em;
        margin: 0.8em 0; }
.verdict { font-size: 1.1em; font-weight: 600; }
img { max-width: 100%; height: auto; display: block; margin: 0.6em 0; }
.meta { color: #666; font-size: 0.85em; }
dl.summary { display: grid; grid-template-columns: max-content auto; gap: 0.15em 1em; }
dl.summary dt { font-weight: 600; } dl.summary dd { margin: 0; }
"""


def _img(data: bytes, alt: str) -> str:
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return f'<img src="{uri}" alt="{escape(alt)}">'


def _name(path: str) -> str:
    return Path(path).name


def _summary_section(recordings: list[Recording], paths: list[str]) -> str:
    parts = ["<h2>Recordings</h2>"]
    for rec, path in zip(recordings, paths, strict=True):
        s = recording_summary(rec, path)
        parts.append(f"<h3>{escape(_name(path))}</h3>")
        if s["title"]:
            parts.append(f"<p>{escape(s['title'])}</p>")
        rows = "".join(
            f"<dt>{escape(label)}</dt><dd>{escape(text)}</dd>" for label, text in summary_rows(s)
        )
        parts.append(f'<dl class="summary">{rows}</dl>')
        if s["notes"]:
            parts += [f'<p class="warn">data quality: {escape(n)}</p>' for n in s["notes"]]
        else:
            parts.append("<p>Data-quality checks: nothing suspicious.</p>")
    return "\n".join(parts)


def _fit_notes(f: dict) -> list[str]:
    """Warnings on the fit itself: a poor χ², an unfinished search, profiles that reach below
    the optimum, a minority regime."""
    out = []
    if f.get("poor_fit"):
        which = ", ".join(_name(p) for p in f.get("poorly_fitted_recordings") or [])
        out.append(
            f"χ² = {f['chi2']:.1f} is far above its {f['dof']} degrees of freedom "
            f"(p = {f['p_value']:.1e}): the model does not explain "
            f"{escape(which) or 'the data'} within its run-to-run spread. The intervals are "
            "widened by √(χ²/dof) but may still miss."
        )
    if f.get("success") is False:
        out.append(
            f"The search {escape(search_sentence(f['search']))}: the optimum "
            f"and the intervals are rough; {escape(unfinished_fit_advice(f.get('options', {})))}."
        )
    if f.get("below_optimum"):
        sentence = below_optimum_sentence(f["below_optimum"])
        out.append(escape(sentence[0].upper() + sentence[1:]) + ".")
    for path, share in zip(
        f["recordings"], f.get("regime_share_per_recording") or [], strict=False
    ):
        if share < 0.5:
            out.append(
                f"{escape(_name(path))} is in a regime that {share:.0%} of the model's releases "
                "reach at the fitted parameters; the fit compares it with that regime."
            )
    return out


def _parameter_section(fit: dict, lubrications: list[str]) -> str:
    f = fit["fit"]
    head = (
        "<tr><th>parameter</th><th>estimate</th><th>95 % interval</th><th>unit</th>"
        "<th>status</th><th>how well the data pin it down</th></tr>"
    )
    rows = []
    for r in parameter_rows(fit["parameters"]):
        name, p = r.name, fit["parameters"][r.name]
        cls = "identified" if r.identified else "unidentified"
        data = " ".join(f'data-{k}="{p[k]!r}"' for k in ("lower", "upper") if p.get(k) is not None)
        if p.get("estimate") is not None:
            data += f' data-estimate="{p["estimate"]!r}"'
        what = meaning(name)
        rows.append(
            f'<tr class="{cls}" data-param="{escape(name)}" {data}>'
            f'<td><b>{escape(name)}</b><br><span class="meta">{escape(what)}</span></td>'
            f'<td class="num">{escape(r.estimate)}</td><td class="num">{escape(r.interval)}</td>'
            f"<td>{escape(r.unit)}</td>"
            f'<td class="status">{escape(r.status)}</td>'
            f"<td>{escape(explain(name, p, lubrications))}</td></tr>"
        )
    per = f.get("chi2_per_recording") or []
    per_text = ""
    if len(per) > 1:
        per_text = " (" + " + ".join(f"{c:.1f}" for c in per) + " by recording)"
    stats = (
        f"<p>χ² = {f['chi2']:.1f}{per_text} on {f['dof']} degrees of freedom "
        f"(p = {f['p_value']:.2g}); seed {f.get('seed')}; "
        f"{f.get('wall_time_s', 0.0):.0f} s.</p>"
    )
    if "threshold" in f.get("profile", {}):
        stats += f'<p class="meta">{escape(profile_sentence(f["profile"]))}.</p>'
    notes = "".join(f'<p class="warn">{n}</p>' for n in _fit_notes(f))
    return (
        "<h2>Parameters</h2>"
        + notes
        + f'<table class="parameters">{head}{"".join(rows)}</table>'
        + stats
    )


def _suggest_section(fit: dict) -> str:
    """The table of ``identify --suggest`` (the fit document's ``suggest``), if there is one."""
    plan = fit.get("suggest")
    if not plan:
        return ""
    head, *rows = suggestion_table(plan)
    cells = "".join(f"<th>{escape(c)}</th>" for c in head)
    body = "".join(
        f"<tr><td>{escape(r[0])}</td>"
        + "".join(f'<td class="num">{escape(c)}</td>' for c in r[1:])
        + "</tr>"
        for r in rows
    )
    note = suggestion_note(plan)
    return (
        f"<h2>What to record next</h2><p>{escape(note[0].upper() + note[1:])}.</p>"
        f'<table class="parameters"><tr>{cells}</tr>{body}</table>'
    )


def _spectra_section(fit: dict, recordings: list[Recording], paths: list[str]) -> str:
    parts = [
        "<h2>Measured against fitted</h2>",
        "<p>Band PSDs of the relative motion Δθ*: the recording (points) against the fitted "
        "model's mean over its simulated realisations, with their ±2σ spread (shaded). "
        "Below, the start of the recording itself.</p>",
    ]
    for k, (rec, path) in enumerate(zip(recordings, paths, strict=True)):
        name = _name(path)
        parts.append(_img(figures.spectrum(fit["spectra"], k, name), f"band spectrum {name}"))
        parts.append(
            _img(
                figures.time_history(
                    rec.time, rec.relative_motion, rec.gear_pair.angular_backlash_rad, name
                ),
                f"time history {name}",
            )
        )
    curves = fit["fit"].get("profiles") or {}
    if curves:
        threshold = profile_thresholds(fit["fit"].get("profile", {}))
        parts.append("<h2>Profiles</h2>")
        parts.append(
            "<p>Each free parameter held fixed in turn and the others re-fitted: the rise of "
            "the cost above the optimum's. The 95 % interval is where it stays below the "
            "dashed threshold; a curve that stays below it up to an end of the range gives a "
            "one-sided bound.</p>"
        )
        parts.append(_img(figures.profiles(curves, threshold, fit["parameters"]), "profile curves"))
    return "\n".join(parts)


def _igr_section(fit: dict, paths: list[str]) -> str:
    """The rattle index measured and of the fitted model's re-simulations (``fit.igr``, which
    ``identify`` adds with ``--report`` or ``--plot``); empty without it."""
    igr = fit["fit"].get("igr")
    if not igr:
        return ""
    rows = []
    for path, entry in zip(paths, igr, strict=True):
        model = entry["model"]
        mean = sum(model) / len(model)
        rows.append(
            f"<li>{escape(_name(path))}: measured {entry['measured']:.4g} rad·Hz; the fitted "
            f"model's {len(model)} re-simulations {mean:.4g} rad·Hz on average "
            f"({min(model):.4g}–{max(model):.4g})</li>"
        )
    names = [Path(p).stem for p in paths]
    return "\n".join(
        [
            "<h2>Rattle index</h2>",
            "<p>The IGR of the seed paper's eq. (10) (20–5000 Hz) of each recording and of "
            "recordings of the fitted model from other release states: a fit that holds the "
            "spectrum should hold the IGR within the re-simulations' spread.</p>",
            f"<ul>{''.join(rows)}</ul>",
            _img(figures.igr(igr, names), "rattle index, measured and at the fit"),
        ]
    )


def _posterior_table(posterior: dict) -> str:
    s = posterior["sampler"]
    head = (
        "<tr><th>parameter</th><th>median</th><th>95 % credible interval</th><th>unit</th>"
        "<th>ESS</th><th>τ (steps)</th></tr>"
    )
    rows = []
    for name, q in posterior["parameters"].items():
        unit = q["unit"]
        tau = s.get("autocorr_time", {}).get(name, float("nan"))
        rows.append(
            f'<tr data-posterior="{escape(name)}" data-median="{q["median"]!r}">'
            f'<td>{escape(name)}</td><td class="num">{shown(q["median"], name, unit)}</td>'
            f'<td class="num">[{shown(q["lower"], name, unit)}, {shown(q["upper"], name, unit)}]'
            f"</td><td>{escape(display_unit(name, unit))}</td>"
            f'<td class="num">{s["ess"].get(name, float("nan")):.0f}</td>'
            f'<td class="num">{tau:.1f}</td></tr>'
        )
    meta = (
        f"<p>{s.get('walkers')} walkers × {s.get('steps')} steps (the first "
        f"{s.get('discard')} discarded as warm-up); mean acceptance "
        f"{s.get('acceptance_mean', float('nan')):.2f}; seed {s.get('seed')}.</p>"
    )
    return f'<table class="posterior">{head}{"".join(rows)}</table>{meta}'


def _posterior_section(posterior: dict | None, idata, paths: list[str]) -> str:
    if posterior is None and idata is None:
        return ""
    parts = ["<h2>Posterior</h2>"]
    if posterior is not None:
        if not posterior["sampler"]["reliable"]:
            parts.append(
                '<p class="warn"><b>Short chain:</b> the kept chain is shorter than 50 '
                "autocorrelation times, so τ, the ESS and the credible intervals are rough. "
                "Continue it (rattlefit sample with the same --backend and more --steps) "
                "before relying on them.</p>"
            )
        parts.append(_posterior_table(posterior))
    if idata is None:
        parts.append(
            '<p class="note">No ArviZ posterior given (--netcdf): the trace, pair and '
            "posterior-predictive plots are left out.</p>"
        )
        return "\n".join(parts)
    parts.append("<h3>Trace</h3>")
    parts.append(_img(figures.trace(idata), "ArviZ trace plot"))
    parts.append("<h3>Pairwise marginals</h3>")
    parts.append(_img(figures.pairs(idata), "ArviZ pair plot"))
    if "posterior_predictive" in idata.groups() and "observed_data" in idata.groups():
        parts.append("<h3>Posterior predictive</h3>")
        for k, path in enumerate(paths):
            name = _name(path)
            parts.append(_img(figures.predictive(idata, k, name), f"posterior predictive {name}"))
    return "\n".join(parts)


def _verdict(diag: dict) -> str:
    if "sentence" in diag:
        return f"{diag['verdict']}: {diag['sentence']}"
    effects = diag["effects"]  # a diagnosis JSON without a verdict sentence
    best = next((e for e in effects if e["name"] == diag["verdict"]), None)
    if best is None:
        return f"No unmodelled effect is supported among the {len(effects)} tried."
    return (
        f"{best['name']} explains the gap: χ² {best['chi2_without']:.1f} → "
        f"{best['chi2_with']:.1f}, {100 * best['gap_closed']:.0f} % of the excess misfit "
        f"removed (p = {best['p_value']:.2g})."
    )


def _findings_table(diag: dict, paths: list[str]) -> str:
    rows = []
    for f in diag.get("findings", []):
        if f["name"] == "drift":
            size = f"{f['amplitude']:+.3g} ({f['detail'].get('statistic')})"
        elif f["name"] == "drive_order":
            size = f"{f['amplitude']:.3g} rad/s² (order {f['detail'].get('order')})"
        else:
            size = f"{1e6 * f['amplitude']:.1f} ± {1e6 * f['amplitude_sd']:.1f} µm"
        where = _name(paths[f["recording"]]) if f["recording"] < len(paths) else ""
        rows.append(
            f'<tr data-finding="{escape(f["name"])}"><td>{escape(where)}</td>'
            f"<td>{escape(f['name'])}</td><td>{escape(f['effect'])}</td>"
            f'<td class="num">{escape(size)}</td><td class="num">{f["p_value"]:.2g}</td>'
            f"<td>{'yes' if f['significant'] else 'no'}</td></tr>"
        )
    if not rows:
        return ""
    head = (
        "<tr><th>recording</th><th>test</th><th>points to</th><th>size</th><th>p</th>"
        "<th>named</th></tr>"
    )
    level = diag["findings"][0]["level"]
    return (
        f"<p>Model-free tests of the recordings (named below p = {level:.2g} and the size "
        f'worth naming):</p><table class="findings">{head}{"".join(rows)}</table>'
    )


def _interval_words(interval, name: str, unit: str, caveat: str = "") -> str:
    """`` (95 %: lo–hi)`` in display units (the fit's precision with a ``caveat``), or
    nothing without an interval."""
    if not interval:
        return ""
    span = interval_label(bool(caveat))
    return f" ({span}: {shown(interval[0], name, unit)}–{shown(interval[1], name, unit)})"


def _diagnosis_section(diag: dict | None, paths: list[str], recordings) -> str:
    if diag is None:
        return ""
    parts = ["<h2>Diagnosis</h2>", f'<p class="verdict">{escape(_verdict(diag))}</p>']
    parts.append(_findings_table(diag, paths))
    for rec, path in zip(recordings, paths, strict=False):
        parts.append(_img(figures.flanks(rec, _name(path)), f"flank contacts {_name(path)}"))
    head = (
        "<tr><th>effect</th><th>χ² without → with</th><th>gap closed</th><th>p</th>"
        "<th>supported</th><th>fitted size</th></tr>"
    )
    rows = []
    for e in diag["effects"]:
        size = ", ".join(
            f"{k} {shown(v['value'], k, v['unit'])} {display_unit(k, v['unit'])}".rstrip()
            + _interval_words(
                e.get("intervals", {}).get(k), k, v["unit"], e.get("interval_caveat", "")
            )
            for k, v in e.get("parameters", {}).items()
        )
        if e.get("failure"):
            judged = ("failed", "—", escape(e["failure"]))
        else:
            judged = (
                f"{e['chi2_with']:.1f}",
                f"{100 * e['gap_closed']:.0f} %",
                f"{e['p_value']:.2g}",
            )
        rows.append(
            f'<tr data-effect="{escape(e["name"])}"><td>{escape(e["name"])}</td>'
            f'<td class="num">{e["chi2_without"]:.1f} → {judged[0]}</td>'
            f'<td class="num">{judged[1]}</td><td class="num">{judged[2]}</td>'
            f"<td>{'yes' if e['supported'] else 'no'}</td><td>{escape(size)}</td></tr>"
        )
    parts.append(f'<table class="effects">{head}{"".join(rows)}</table>')
    missed = diag["missed_bands"]
    if missed:
        items = "".join(
            f"<li>{escape(_name(paths[m['recording']]) if m['recording'] < len(paths) else '')}"
            f": {m['band_hz'][0]:.1f}–{m['band_hz'][1]:.1f} Hz, z = {m['z']:+.1f} (the "
            f"recording has {'more' if m['z'] > 0 else 'less'} power)</li>"
            for m in missed
        )
        parts.append(
            f"<p>Where the fitted model misses (|z| &gt; {MISSED_Z:g}):</p><ul>{items}</ul>"
        )
    else:
        parts.append(f"<p>No band misses by more than {MISSED_Z:g} σ.</p>")
    parts += [f'<p class="warn">{escape(w)}</p>' for w in diagnosis_caveats(diag)]
    names = [_name(p) for p in paths]
    if len(diag["residuals"]) == len(names):
        parts.append(_img(figures.residuals(diag, names, MISSED_Z), "band residuals"))
    cycle = diag.get("drive_cycle")
    if cycle and len(cycle["measured"]) == len(names):
        verdict = "misses" if cycle["significant"] else "fits"
        parts.append(
            f"<p>The drive-cycle statistics (not fitted): the model without effects {verdict}"
            f" them (largest |z| threshold {cycle['threshold']:.2f}, p = "
            f"{cycle['p_value']:.2g}).</p>"
        )
        parts.append(_img(figures.drive_cycle(cycle, names), "drive-cycle statistics"))
    return "\n".join(parts)


def html_report(
    *,
    fit: dict,
    posterior: dict | None = None,
    inference_data=None,
    diagnosis: dict | None = None,
    recordings: list[Recording] | None = None,
) -> str:
    """The report as one self-contained HTML document (a string).

    fit, posterior, diagnosis : the JSON documents of ``FitResult.to_json()``,
        ``Posterior.to_json()`` and ``Diagnosis.to_json()`` (what ``identify -o``,
        ``sample -o`` and ``diagnose -o`` write); only ``fit`` is required.
    inference_data : an ``arviz.InferenceData`` of the posterior or the path of its netCDF
        file (``Posterior.save_netcdf``), for the trace, pair and predictive plots.
    recordings : the fit's recordings, in its order; default: read from the paths in
        ``fit["fit"]["recordings"]``.

    Raises :class:`~rattlefit.errors.RattlefitError` naming the document, file or field for
    a document that is not what it should be, a recording that cannot be found or read, and
    a posterior or diagnosis of other recordings than the fit's.
    """
    from ..version import __version__

    check(fit, "fit")
    paths = [str(p) for p in fit["fit"]["recordings"]]
    if posterior is not None:
        check(posterior, "posterior")
        same_recordings(posterior["sampler"].get("recordings", paths), paths, "posterior")
    if diagnosis is not None:
        check(diagnosis, "diagnosis")
        same_recordings(diagnosis.get("recordings", paths), paths, "diagnosis")
    idata = load_inference_data(inference_data)
    if idata is not None:
        named = idata_recordings(idata)
        if named is not None:
            same_recordings(
                named,
                paths,
                str(inference_data) if isinstance(inference_data, str | Path) else "inference_data",
            )
    recs = recordings_of(fit, recordings)
    lubrications = [r.operating.lubrication for r in recs]
    title = ", ".join(_name(p) for p in paths)
    body = [
        f"<h1>Gear-rattle identification: {escape(title)}</h1>",
        f'<p class="meta">rattlefit {escape(__version__)}; the fit\'s seed '
        f"{fit['fit'].get('seed')}.</p>",
        _summary_section(recs, paths),
        _parameter_section(fit, lubrications),
        _suggest_section(fit),
        _spectra_section(fit, recs, paths),
        _igr_section(fit, paths),
        _posterior_section(posterior, idata, paths),
        _diagnosis_section(diagnosis, paths, recs),
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>rattlefit report: {escape(title)}</title>\n<style>{CSS}</style>\n</head>\n"
        "<body>\n" + "\n".join(b for b in body if b) + "\n</body>\n</html>\n"
    )


def write_report(
    path: str | Path,
    *,
    fit: dict,
    posterior: dict | None = None,
    inference_data=None,
    diagnosis: dict | None = None,
    recordings: list[Recording] | None = None,
) -> Path:
    """Write :func:`html_report` (same keywords) to ``path`` atomically (a temporary file
    beside it, renamed into place: on any error nothing is written and an earlier file stays
    whole); returns ``path``. Raises as :func:`html_report`."""
    text = html_report(
        fit=fit,
        posterior=posterior,
        inference_data=inference_data,
        diagnosis=diagnosis,
        recordings=recordings,
    )
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))

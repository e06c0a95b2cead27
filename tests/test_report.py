"""The identification table: what a person reads first."""

import base64
import dataclasses
import json
import math
import subprocess
from html import escape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from rattlefit import FitOptions, FitResult
from rattlefit.documents import DIAGNOSIS, FIT, POSTERIOR
from rattlefit.inference.fit_document import fit_of
from rattlefit.inference.outcome import SearchEnd, SearchOutcome
from rattlefit.inference.profile import profile_threshold
from rattlefit.inference.result import (
    Estimates,
    FittedState,
    ParameterEstimate,
    Provenance,
    Spectra,
    Statistics,
)
from rattlefit.report import format_table
from rattlefit.report.explain import parameter_rows


def _result(
    chi2,
    dof,
    chi2_recordings=(),
    recordings=(),
    regime_share=(),
    profile=None,
    *,
    success=True,
    profiles=None,
):
    a = ParameterEstimate("film_half_length", "m", 8.5e-5, 6e-5, 1.1e-4, True)
    tb = ParameterEstimate("drag_torque", "N m", 0.02, 0.0, 0.05, False, "upper")
    mu = ParameterEstimate("viscosity", "Pa s", 0.45, 0.3, 0.6, False, "interval")
    return FitResult(
        Estimates(
            parameters={"film_half_length": a, "drag_torque": tb, "viscosity": mu},
            names=["film_half_length", "drag_torque", "viscosity"],
            correlation=np.eye(3),
            map_params=[],
            profile=profile or {},
            profiles=profiles or {},
        ),
        Statistics(
            chi2=chi2,
            dof=dof,
            chi2_recordings=list(chi2_recordings),
            regime_share=list(regime_share),
            n_iterations=3,
            search=SearchEnd(SearchOutcome.CONVERGED if success else SearchOutcome.STEP_LIMIT),
        ),
        Spectra(measured=[], fitted=[], sigma=[], band_centers=np.zeros(1)),
        Provenance(recordings=list(recordings), seed=7, wall_time=1.0),
        FittedState(FitOptions(), np.zeros(3), np.eye(3)),
    )


def test_p_value_is_the_chi2_tail():
    # with two degrees of freedom the χ² tail is exp(−χ²/2) in closed form
    assert _result(3.0, 2).statistics.p_value == pytest.approx(math.exp(-1.5), rel=1e-12)
    assert _result(20.0, 2).statistics.p_value == pytest.approx(math.exp(-10.0), rel=1e-12)


def test_table_warns_only_about_a_poor_fit():
    good = format_table(_result(30.0, 28))
    assert "warning" not in good
    assert "0.085" in good and "[0.06, 0.11]" in good  # mm
    assert "≤ 0.05" in good and "upper bound only" in good
    # two-sided but wider than an identified interval: how much wider is said
    assert "[0.3, 0.6]" in good and "interval too wide (×2.00 > ×1.5)" in good
    bad = _result(120.0, 28)
    assert bad.statistics.poor_fit and bad.to_json()["fit"]["poor_fit"] is True
    text = format_table(bad)
    assert "warning: χ² is far above its 28 degrees of freedom" in text
    assert "√(χ²/dof) = 2.1" in text


def test_the_table_states_the_search_state_and_p():
    # p from the χ² tail in closed form (two dof: exp(−χ²/2)); the stop as the search ended
    done = format_table(_result(3.0, 2))
    assert f"p = {math.exp(-1.5):.2g}" in done and "converged after 3 steps" in done
    stopped = format_table(_result(3.0, 2, success=False))
    assert "stopped at its step limit after 3 steps" in stopped
    assert "converged" not in stopped
    # a stalled run is a converged search, counted; a re-centred one says so
    stalled = dataclasses.replace(
        _result(3.0, 2),
        statistics=dataclasses.replace(
            _result(3.0, 2).statistics, search=SearchEnd(SearchOutcome.STALLED, 3, 2, 1)
        ),
    )
    text = format_table(stalled)
    assert "converged (2 of 3 runs stalled at the cost's noise" in text
    assert "re-centred 1× on the profiles' minimum" in text
    assert stalled.statistics.success and not _result(3.0, 2, success=False).statistics.success
    # the JSON holds the outcome as a value, and it reads back
    doc = stalled.to_json()["fit"]
    assert doc["search"] == {"outcome": "stalled", "runs": 3, "stalled_runs": 2, "recentred": 1}
    assert SearchEnd.from_dict(doc["search"]) == stalled.statistics.search
    assert "below the optimum" not in done
    low = {"drag_torque": [(0.01, 5.0), (0.02, 0.0), (0.03, -14.2)]}
    assert "the profiles reach 14.2 below the optimum's cost" in format_table(
        _result(3.0, 2, profiles=low)
    )


def test_the_table_shows_the_physics_first_and_a_measured_nuisance_as_measured():
    res = _result(30.0, 28)
    params = {
        "backlash[0]": ParameterEstimate("backlash[0]", "m", 8e-4, 7.9e-4, 8.1e-4, False, "prior"),
        "min_film": ParameterEstimate("min_film", "m", 2e-6, 5e-7, 8e-6, False, "prior"),
        **res.estimates.parameters,
        "squeeze_momentum": ParameterEstimate(
            "squeeze_momentum", "N s", 1e-3, 5e-4, 2e-3, False, "interval"
        ),
    }
    estimates = dataclasses.replace(res.estimates, parameters=params)
    text = format_table(dataclasses.replace(res, estimates=estimates))
    order = [line.split()[0] for line in text.splitlines()[2:8]]
    assert order == [
        "film_half_length",
        "drag_torque",
        "viscosity",
        "squeeze_momentum",
        "nuisances:",
        "backlash[0]",
    ]
    backlash = next(line for line in text.splitlines() if line.startswith("backlash[0]"))
    film = next(line for line in text.splitlines() if line.startswith("min_film"))
    assert "as measured" in backlash and "prior-dominated" not in backlash  # ×1.03
    assert "prior-dominated" in film  # ×16: the data do not narrow it


def test_a_joint_fit_names_the_recording_the_model_does_not_explain():
    # 57 dof over two recordings: 28.5 each. 30 is an ordinary χ² on 28.5 (p ≈ 0.4), 400 is not
    files = ["/data/pairII_boundary_65.6.h5", "/data/pairII_oiljet_65.6.h5"]
    bad = _result(430.0, 57, chi2_recordings=[30.0, 400.0], recordings=files)
    assert bad.statistics.poorly_fitted == [1]
    assert bad.to_json()["fit"]["poorly_fitted_recordings"] == [files[1]]
    text = format_table(bad)
    assert "does not explain pairII_oiljet_65.6.h5 within" in text
    assert "each recording's own √(χ²/dof)" in text and "boundary" not in text
    # both merely mediocre, poor only together: no single file is blamed
    both = _result(100.0, 57, chi2_recordings=[50.0, 50.0], recordings=files)
    assert both.statistics.poor_fit and both.statistics.poorly_fitted == []
    assert "does not explain these recordings together" in format_table(both)
    # recordings made in memory (rf.synthesize) have no file: named by their place
    memory = _result(430.0, 57, chi2_recordings=[30.0, 400.0], recordings=["None", "None"])
    assert memory.provenance.recording_names == ["recording 1", "recording 2"]
    assert "does not explain recording 2 within" in format_table(memory)


def test_a_recording_in_a_minority_regime_is_named():
    # the fit compares each recording with its own regime; where that is a minority of the
    # model's releases at the optimum, the reader must learn it (and which file, when several)
    assert "note" not in format_table(_result(30.0, 28, regime_share=[0.9]))
    one = format_table(_result(30.0, 28, recordings=["x/r.h5"], regime_share=[0.25]))
    assert "note: the recording is in a regime that 25% of the model's releases reach" in one
    two = format_table(
        _result(60.0, 57, [30.0, 30.0], ["x/a.h5", "x/b.h5"], regime_share=[1.0, 0.2])
    )
    assert "note: b.h5 is in a regime that 20%" in two and "a.h5 is in" not in two


def _allowance(line):
    # "… (χ²₁ 3.84 + 1.645 × X, <source>)": the sd the line says the allowance is made of
    return float(line.split("1.645 × ")[1].split(",")[0])


@pytest.mark.parametrize(
    ("mc", "jitter", "source"),
    [
        (4.0, np.array([[1.0, -2.0, 1.5, -1.0]]), "Monte Carlo"),  # below the analytic
        (4.0, np.array([[14.1, 10.0, -7.4, 13.7]]), "roughness"),  # one set: its rms
        (4.9, np.array([[55.7, 10.9, -11.0, 24.5], [51.6, 17.4, -8.1, 42.7]]), "spread"),
    ],
)
def test_the_table_says_what_set_the_profile_threshold(mc, jitter, source):
    # the line must name the allowance profile_threshold used, with the sd that reproduces it
    threshold = profile_threshold(mc, jitter)
    profile = {"threshold": threshold, "monte_carlo_sd": mc, "realisation_sets": len(jitter)}
    profile["roughness_rms"] = float(np.sqrt(np.mean(jitter[0] ** 2)))
    if len(jitter) > 1:
        profile["roughness_sd"] = float(np.sqrt(np.mean(np.var(jitter, axis=0, ddof=1))))
    res = _result(30.0, 28, profile=profile)
    (line,) = [x for x in format_table(res).splitlines() if x.startswith("95 % intervals")]
    assert source in line and f"within {threshold:.1f} " in line
    assert 3.84 + 1.645 * _allowance(line) == pytest.approx(threshold, abs=0.1)
    assert res.to_json()["fit"]["profile"]["threshold"] == threshold
    assert "95 % intervals" not in format_table(_result(30.0, 28))  # nothing to say


# -- the HTML report ---------------------------------------------------------------------------

DATA = Path(__file__).resolve().parents[1] / "data"
BOUNDARY = DATA / "pairII_boundary_65.6_20pct_16Hz.h5"
CHROMIUM = Path("/usr/bin/chromium")
#: The display units the report must use (the registry's, spelt out here): lengths in mm,
#: h_min in µm, everything else in SI.
SHOWN = {"min_film": (1e6, "µm"), "m": (1e3, "mm")}


class _Page(HTMLParser):
    """What a test reads from a report: images, links, the parameter rows and the text."""

    def __init__(self):
        super().__init__()
        self.images, self.links, self.rows, self.text = [], [], {}, []
        self.alts = []
        self._row = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.images.append(a.get("src", ""))
            self.alts.append(a.get("alt", ""))
        for key in ("src", "href", "action", "poster"):
            if key in a:
                self.links.append(a[key])
        if tag == "tr" and "data-param" in a:
            self._row = a["data-param"]
            self.rows[self._row] = {"attrs": a, "text": ""}
        if tag in ("script", "link", "iframe", "object", "embed"):
            self.links.append(f"<{tag}>")

    def handle_endtag(self, tag):
        if tag == "tr":
            self._row = None

    def handle_data(self, data):
        self.text.append(data)
        if self._row is not None:
            self.rows[self._row]["text"] += data + "|"


def _parse(html: str) -> _Page:
    page = _Page()
    page.feed(html)
    page.close()
    return page


def _g4(value, name, unit):
    scale = SHOWN.get(name.split("[")[0], SHOWN.get(unit, (1.0, unit)))[0]
    return f"{value * scale:.4g}"


def _check_self_contained(html: str) -> _Page:
    page = _parse(html)
    assert page.images, "the report has no figure"
    for src in page.images:
        assert src.startswith("data:image/png;base64,"), src[:60]
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 1000
    assert not [x for x in page.links if not x.startswith("data:")], page.links
    for marker in ("http://", "https://", 'src="//', 'href="//', "url(", "@import"):
        assert marker not in html, marker
    return page


def _check_parameters(page: _Page, fit: dict) -> None:
    """Every parameter of the JSON is a row whose numbers are the JSON's, as shown."""
    assert list(page.rows) == list(fit["parameters"])
    for name, p in fit["parameters"].items():
        row = page.rows[name]
        assert float(row["attrs"]["data-lower"]) == p["lower"]
        assert float(row["attrs"]["data-upper"]) == p["upper"]
        # every parameter has its estimate (the optimum), identified or not
        assert float(row["attrs"]["data-estimate"]) == p["estimate"]
        assert f"|{_g4(p['estimate'], name, p['unit'])}|" in row["text"]
        if p["bound"] == "lower":
            assert f"|≥ {_g4(p['lower'], name, p['unit'])}|" in row["text"]
        elif p["bound"] == "upper":
            assert f"|≤ {_g4(p['upper'], name, p['unit'])}|" in row["text"]
        else:
            lo, hi = _g4(p["lower"], name, p["unit"]), _g4(p["upper"], name, p["unit"])
            assert f"|[{lo}, {hi}]|" in row["text"]


@pytest.fixture(scope="module")
def bundled_fits():
    """identify's JSON of each bundled recording (seeded, cheaper than quick): real inputs."""
    import rattlefit as rf

    out = {}
    for path in sorted(DATA.glob("*.h5")):
        rec = rf.read_recording(path)
        cheap = FitOptions.quick(
            seed=0,
            n_starts=2,
            max_iterations=1,
            n_noise_realisations=4,
            n_covariance_realisations=4,
        )  # about 15 s a recording: real fits, profiles and intervals, rough optima
        fit = rf.identify([rec], cheap)
        out[path.name] = (json.loads(json.dumps(fit.to_json())), rec)
    return out


def test_reports_of_the_bundled_recordings(bundled_fits, tmp_path):
    from rattlefit.report import html_report, write_report

    assert len(bundled_fits) == 3
    for name, (fit, rec) in bundled_fits.items():
        html = html_report(fit=fit, recordings=[rec])
        page = _check_self_contained(html)
        _check_parameters(page, fit)
        # the terminal's table and the HTML's show every parameter's row alike
        table = format_table(fit_of(fit)).splitlines()
        for r in parameter_rows(fit["parameters"]):
            line = next(row for row in table if row.split()[:1] == [r.name])
            assert r.estimate in line and r.interval in line and line.endswith(r.status), line
            assert f'<td class="status">{escape(r.status)}</td>' in html
        # spectrum, time history and profiles; the recording's summary as info prints it
        assert len(page.images) == 3
        text = " ".join(page.text)
        assert name in text and "IGR" in text and "backlash" in text
        assert f"χ² = {fit['fit']['chi2']:.1f}" in text
        lub = rec.operating.lubrication
        a = page.rows["film_half_length"]["text"]
        if lub == "boundary":
            assert "μ·a³/h_min²" in a  # the film trades against h_min and μ
        if lub == "oil_jet" and fit["parameters"]["film_half_length"]["bound"] == "lower":
            assert "saturates" in a
        # the default: the recordings read from the paths the fit names; atomic write
        out = write_report(tmp_path / f"{name}.html", fit=fit)
        assert out.read_text(encoding="utf-8") == html
    assert not list(tmp_path.glob(".*.tmp"))


def _handmade_fit(recording=BOUNDARY) -> dict:
    """A fit document written by hand (not by identify): three parameters, 30 bands."""
    f = np.geomspace(5.0, 4000.0, 30)
    measured = -6.0 - 1.5 * np.log10(f / 5.0)
    p = {
        "film_half_length": ("m", 8.5e-5, 7.1e-5, 9.9e-5, True, None),
        "drag_torque": ("N m", 0.0152, 0.0, 0.0437, False, "upper"),
        "viscosity": ("Pa s", 0.49, 0.3, 0.81, False, "prior"),
    }
    keys = ("unit", "estimate", "lower", "upper", "identified", "bound")
    return {
        **FIT.header(),
        "parameters": {n: {"name": n, **dict(zip(keys, v, strict=True))} for n, v in p.items()},
        "fit": {
            "chi2": 31.25,
            "dof": 28,
            "p_value": 0.31,
            "poor_fit": False,
            "success": True,
            "seed": 3,
            "recordings": [str(recording)],
            "profile": {"threshold": 6.5},
            "profiles": {"film_half_length": [[5e-5, 20.0], [8.5e-5, 0.0], [1.2e-4, 15.0]]},
        },
        "spectra": {
            "band_centers_hz": f.tolist(),
            "measured": [measured.tolist()],
            "fitted": [(measured + 0.05).tolist()],
            "sigma": [np.full(30, 0.1).tolist()],
        },
    }


def _handmade_posterior():
    """A short chain (reliable False) as sample's JSON and as an ArviZ InferenceData."""
    import arviz as az

    rng = np.random.default_rng(1)
    names = {"film_half_length": "m", "drag_torque": "N m", "viscosity": "Pa s"}
    centre = {"film_half_length": 8.5e-5, "drag_torque": 0.02, "viscosity": 0.5}
    draws = {n: centre[n] * np.exp(0.1 * rng.standard_normal((4, 50))) for n in names}
    bands = np.geomspace(5.0, 4000.0, 30)
    observed = -6.0 - 1.5 * np.log10(bands / 5.0)
    idata = az.from_dict(
        posterior=draws,
        observed_data={"log10_psd": observed[None]},
        posterior_predictive={
            "log10_psd": (observed + 0.1 * rng.standard_normal((8, 30)))[None, :, None]
        },
        coords={"band": bands, "recording": [0]},
        dims={"log10_psd": ["recording", "band"]},
    )
    doc = {
        **POSTERIOR.header(),
        "parameters": {
            n: {
                "median": float(np.median(v)),
                "lower": float(np.percentile(v, 2.5)),
                "upper": float(np.percentile(v, 97.5)),
                "unit": names[n],
            }
            for n, v in draws.items()
        },
        "sampler": {
            "walkers": 4,
            "steps": 75,
            "discard": 25,
            "acceptance_mean": 0.3,
            "autocorr_time": {n: 9.0 for n in names},
            "ess": {n: 22.2 for n in names},
            "reliable": False,
            "seed": 0,
            "recordings": [str(BOUNDARY)],
        },
    }
    return doc, idata


def test_report_with_a_posterior_shows_its_plots_and_warns_of_a_short_chain(tmp_path):
    from rattlefit.report import html_report

    fit = _handmade_fit()
    post, idata = _handmade_posterior()
    nc = tmp_path / "chain.nc"
    idata.to_netcdf(str(nc))
    html = html_report(fit=fit, posterior=post, inference_data=nc)
    page = _check_self_contained(html)
    _check_parameters(page, fit)
    text = " ".join(page.text)
    assert "Short chain" in text and "22" in text  # the ESS
    # spectrum, time history, profiles + trace, pairs, posterior predictive
    assert len(page.images) == 6
    post["sampler"]["reliable"] = True
    assert "Short chain" not in html_report(fit=fit, posterior=post)


def test_report_with_a_diagnosis_gives_verdict_misfit_and_missed_bands():
    from rattlefit.report import html_report

    fit = _handmade_fit()
    residuals = np.zeros((1, 30))
    residuals[0, 4] = 4.2
    diag = {
        **DIAGNOSIS.header(),
        "verdict": "drive_ripple",
        "baseline": {"chi2": 80.0, "dof": 28},
        "band_centers_hz": fit["spectra"]["band_centers_hz"],
        "residuals": residuals.tolist(),
        "missed_bands": [{"recording": 0, "band_hz": [12.0, 14.5], "z": 4.2}],
        "effects": [
            {
                "name": "drive_ripple",
                "chi2_without": 80.0,
                "chi2_with": 33.5,
                "gap_closed": 0.9,
                "p_value": 1e-4,
                "supported": True,
                "parameters": {"amplitude": {"value": 30.0, "unit": "rad/s²"}},
                "residuals": np.zeros((1, 30)).tolist(),
            }
        ],
        "warnings": [],
        "recordings": [str(BOUNDARY)],
    }
    page = _check_self_contained(html_report(fit=fit, diagnosis=diag))
    text = " ".join(page.text)
    assert "drive_ripple explains the gap: χ² 80.0 → 33.5, 90 % of the excess misfit" in text
    assert "12.0–14.5 Hz, z = +4.2" in text
    # a diagnosis with a verdict sentence and model-free findings: the sentence, the findings
    # table, and the flank contacts of the recording
    finding = {
        "recording": 0,
        "effect": "runout",
        "level": 0.01 / 7,
        "significant": True,
        "name": "runout.secondary",
        "chi2": 900.0,
        "dof": 4,
        "p_value": 1e-190,
        "amplitude": 33.7e-6,
        "amplitude_sd": 1.2e-6,
        "detail": {},
    }
    diag |= {"verdict": "runout", "sentence": "Found runout (…).", "findings": [finding]}
    page2 = _check_self_contained(html_report(fit=fit, diagnosis=diag))
    text = " ".join(page2.text)
    assert "runout: Found runout (…)." in text
    assert "33.7 ± 1.2 µm" in text and "runout.secondary" in text
    assert len(page2.images) == len(page.images)  # the flank figure is drawn in both
    assert any("flank contacts" in alt for alt in page2.alts)


def test_report_refuses_bad_inputs_naming_them(tmp_path):
    from rattlefit.errors import RattlefitError
    from rattlefit.report import write_report

    out = tmp_path / "r.html"
    with pytest.raises(RattlefitError, match=r"missing\.h5: recording named in the fit"):
        write_report(out, fit=_handmade_fit(tmp_path / "missing.h5"))
    bad = _handmade_fit()
    del bad["spectra"]["sigma"]
    with pytest.raises(RattlefitError, match="fit: spectra/sigma: missing"):
        write_report(out, fit=bad)
    post, _ = _handmade_posterior()
    post["sampler"]["recordings"] = ["elsewhere/other.h5"]
    with pytest.raises(RattlefitError, match=r"posterior: made on other\.h5"):
        write_report(out, fit=_handmade_fit(), posterior=post)
    old = {**_handmade_fit(), "version": 1}
    with pytest.raises(RattlefitError, match=r"fit: format: expected 'rattlefit\.fit' version 2"):
        write_report(out, fit=old)
    post, _ = _handmade_posterior()
    with pytest.raises(RattlefitError, match=r"posterior: format: .*\(sample again"):
        write_report(out, fit=_handmade_fit(), posterior={**post, "format": None})
    with pytest.raises(RattlefitError, match=r"nothing\.nc: no such file"):
        write_report(out, fit=_handmade_fit(), inference_data=tmp_path / "nothing.nc")
    assert list(tmp_path.iterdir()) == []


def test_report_renders_in_a_headless_browser(tmp_path):
    if not CHROMIUM.exists():
        pytest.skip(f"needs a headless browser at {CHROMIUM} (apt-get install chromium)")
    from PIL import Image

    from rattlefit.report import write_report

    post, idata = _handmade_posterior()
    page = write_report(
        tmp_path / "report.html", fit=_handmade_fit(), posterior=post, inference_data=idata
    )
    shot = tmp_path / "shot.png"
    cmd = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={tmp_path / 'profile'}",
        f"--screenshot={shot}",
        "--window-size=1200,3000",
        page.as_uri(),
    ]
    subprocess.run(cmd, capture_output=True, timeout=120, check=False)
    assert shot.is_file(), "the browser wrote no screenshot"
    pixels = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert pixels.shape == (3000, 1200)
    # not blank: dark text and figure lines on a light page, over much of its height
    dark_rows = np.flatnonzero((pixels < 128).any(axis=1))
    assert pixels.std() > 10 and dark_rows.size > 500 and dark_rows.max() > 1500


def test_the_report_shows_what_to_record_next_when_the_fit_has_it():
    # identify --suggest's table, written by hand: a row without a bound reads "—", and a
    # fit document without it has no such section
    from rattlefit.report import html_report

    fit = _handmade_fit()
    assert "What to record next" not in html_report(fit=fit)
    fit["suggest"] = {
        "seed": 4,
        "realisations": 24,
        "candidates": [
            {
                "recording": "now",
                "factors": {"film_half_length[boundary]": 5.2, "drag_torque": None},
            },
            {
                "recording": "an oil-jet companion",
                "factors": {
                    "film_half_length[boundary]": 1.91,
                    "drag_torque": 1.32,
                    "viscosity_scale": 1.11,
                },
            },
        ],
    }
    page = _check_self_contained(html_report(fit=fit))
    text = " ".join(page.text)
    assert "What to record next" in text
    assert "+ an oil-jet companion" in text and "×1.32" in text and "×1.11" in text
    assert "this fit alone" in text and "×5.20" in text and "—" in text
    assert "seed 4" in text  # the randomness it used is reported


def test_every_name_and_unit_comes_from_the_one_registry(tmp_path):
    """The table, the JSON, ``--prior``, the profile plots' axes and the report name each
    parameter alike and show it in the registry's unit (h_min in µm, lengths in mm)."""
    import rattlefit as rf
    from rattlefit.problem.parameters import NUISANCES, parse_prior
    from rattlefit.quantities import QUANTITIES, quantity
    from rattlefit.report import html_report
    from rattlefit.report.figures import profile_figure

    assert (QUANTITIES["min_film"].display_unit, QUANTITIES["film_half_length"].display_unit) == (
        "µm",
        "mm",
    )
    rec = rf.read_recording(DATA / "pairII_boundary_65.6_20pct_16Hz.h5")
    cheap = FitOptions.quick(seed=0, n_starts=2, max_iterations=1, n_noise_realisations=4)
    result = rf.identify([rec], cheap)
    doc = json.loads(json.dumps(result.to_json()))
    table = {
        line.split()[0]: line
        for line in format_table(result).splitlines()[2:]
        if line and line.split()[0] in doc["parameters"]
    }
    page = _parse(html_report(fit=doc, recordings=[rec]))
    fig = profile_figure(
        doc["fit"]["profiles"], doc["fit"]["profile"]["threshold"], doc["parameters"]
    )
    axes = {ax.get_xlabel() for ax in fig.axes}
    assert set(table) == set(doc["parameters"]) == set(page.rows)
    for name, p in doc["parameters"].items():
        q = quantity(name)
        assert p["unit"] == q.unit, name  # JSON: SI, as the registry says
        shown = q.display_unit
        assert f"  {shown}  " in table[name] if shown else True, table[name]
        if shown:  # (an empty cell is not in the parsed text)
            assert f"|{shown}|" in page.rows[name]["text"], page.rows[name]["text"]
        assert q.meaning in page.rows[name]["text"]
        if name in doc["fit"]["profiles"]:
            assert (f"{name} ({shown})" if shown else name) in axes
        if name in NUISANCES:  # --prior takes the name and the unit the table shows
            typed = {"µm": "um"}.get(shown, shown)
            prior_name, spec = parse_prior(f"{name}={q.shown(p['estimate']):.6g}{typed}:0.2")
            assert prior_name == name and spec.unit == p["unit"]
            assert spec.center == pytest.approx(p["estimate"], rel=1e-5)


def test_a_result_written_with_the_old_film_name_is_read_with_the_new_one():
    from rattlefit.report.inputs import renamed

    old = {
        "parameters": {"a[boundary]": {"unit": "m"}, "drag_torque": {"unit": "N m"}, "a": {}},
        "fit": {"profiles": {"a[boundary]": [[1e-4, 0.0]]}},
    }
    renamed(old)  # in place, in order, as check() and load_json() do on every document
    assert list(old["parameters"]) == [
        "film_half_length[boundary]",
        "drag_torque",
        "film_half_length",
    ]
    assert list(old["fit"]["profiles"]) == ["film_half_length[boundary]"]


def test_the_profile_figure_shades_the_printed_interval_on_a_non_negative_cost_axis():
    # the shapes a real fit gives: a drag-torque profile with a point 17.6 below the optimum
    # and an upper bound only (its lower end reads 0), and a film whose interval is two-sided
    from rattlefit.report.plots import profile_figure

    threshold = 14.7
    curves = {
        "drag_torque": [[0.004, 3.0], [0.0145, 0.0], [0.03, -17.6], [0.0577, 14.0], [0.2, 80.0]],
        "film_half_length": [[2e-5, 30.0], [5e-5, 9.0], [7.86e-5, 0.0], [1.2e-4, 5.0],
                             [1.6e-4, 15.0], [3e-4, 60.0]],
    }  # fmt: skip
    parameters = {
        "drag_torque": {"estimate": 0.0145, "lower": 0.0, "upper": 0.05775, "unit": "N m"},
        "film_half_length": {"estimate": 7.86e-5, "lower": 1.951e-5, "upper": 1.559e-4,
                             "unit": "m"},
    }  # fmt: skip
    fig = profile_figure(curves, threshold, parameters)
    for ax, name in zip(fig.axes, curves, strict=True):
        p, pts = parameters[name], np.asarray(curves[name])
        mult = 1e3 if name == "film_half_length" else 1.0  # the table's display units
        (line,) = [x for x in ax.get_lines() if x.get_label() == "profile"]
        assert np.min(line.get_ydata()) >= 0 and ax.get_ylim()[0] >= 0
        # the threshold keeps its place relative to the profile: shifted as the points are
        (dashed,) = [x for x in ax.get_lines() if x.get_label() == "95 % threshold"]
        shift = line.get_ydata()[0] - pts[0, 1]
        assert dashed.get_ydata()[0] == pytest.approx(threshold + shift)
        # the shaded region is the printed interval (from the axis' edge where it reads 0)
        (span,) = ax.patches
        x0, x1 = span.get_x(), span.get_x() + span.get_width()
        assert x1 == pytest.approx(p["upper"] * mult)
        assert x0 == pytest.approx(max(p["lower"] * mult, ax.get_xlim()[0]))
        # the value axis fits what is drawn: within a factor 2 of the points and the ends
        lo, hi = ax.get_xlim()
        assert lo >= 0.5 * pts[:, 0].min() * mult and hi <= 2 * pts[:, 0].max() * mult
    assert "below the optimum" in fig.axes[0].get_title()
    assert fig.axes[1].get_title() == ""


def test_an_unconverged_fit_is_told_what_to_run_and_one_state_reaches_every_output():
    # the HTML names the next step for the fit that was run: a quick fit is told to run a full
    # one, a full fit is not told to drop --quick
    from rattlefit.io.recording import read_recording
    from rattlefit.report import html_report

    path = "data/pairII_boundary_65.6_20pct_16Hz.h5"
    rec = read_recording(path)
    for options, wanted, unwanted in (
        (FitOptions.quick(), "without --quick", "iterations of each search"),
        (FitOptions(), "iterations of each search", "--quick"),
    ):
        bands = np.full((1, 5), -9.0)
        res = dataclasses.replace(
            _result(30.0, 28, recordings=[path], success=False),
            state=FittedState(options, np.zeros(3), np.eye(3)),
            spectra=Spectra(bands, bands, 0.1 + 0 * bands, np.geomspace(10.0, 1e3, 5)),
        )
        doc = res.to_json()
        html = html_report(fit=doc, recordings=[rec])
        (note,) = [p for p in html.split("<p") if "stopped at its step limit" in p]
        assert wanted in note and unwanted not in note
    # profiles below the optimum: one state in the JSON, the table and the HTML
    low = {"drag_torque": [(0.01, 5.0), (0.02, 0.0), (0.03, -17.6)]}
    res = dataclasses.replace(
        _result(30.0, 28, recordings=[path], profiles=low),
        spectra=Spectra(bands, bands, 0.1 + 0 * bands, np.geomspace(10.0, 1e3, 5)),
    )
    doc = res.to_json()
    assert doc["fit"]["below_optimum"] == {"depth": 17.6, "parameter": "drag_torque"}
    assert "reach 17.6 below the optimum's cost" in format_table(res)
    assert "reach 17.6 below the optimum" in html_report(fit=doc, recordings=[rec])
    assert _result(30.0, 28).to_json()["fit"]["below_optimum"] is None


def test_the_fit_csv_holds_the_json_parameters_row_by_row(tmp_path):
    import csv

    from rattlefit.report.export import FIT_COLUMNS, write_fit_csv

    doc = _result(71.0, 28, recordings=["data/x.h5"], success=False).to_json()
    path = write_fit_csv(tmp_path / "fit.csv", doc)
    rows = list(csv.DictReader(path.open()))
    assert list(rows[0]) == list(FIT_COLUMNS)
    assert [r["parameter"] for r in rows] == list(doc["parameters"])
    for r in rows:
        p = doc["parameters"][r["parameter"]]
        assert float(r["estimate"]) == pytest.approx(p["estimate"], rel=1e-11)
        assert float(r["upper"]) == pytest.approx(p["upper"], rel=1e-11)
        assert r["unit"] == p["unit"] and r["identified"] == str(p["identified"])
        assert (r["converged"], r["chi2"], r["recordings"]) == ("False", "71", "x.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.csv"]  # nothing left behind


def test_the_report_and_the_plots_show_the_rattle_index_measured_and_at_the_fit(tmp_path):
    from rattlefit.io.recording import read_recording
    from rattlefit.report import html_report, plot_igr

    path = "data/pairII_boundary_65.6_20pct_16Hz.h5"
    bands = np.full((1, 5), -9.0)
    res = dataclasses.replace(
        _result(30.0, 28, recordings=[path]),
        spectra=Spectra(bands, bands, 0.1 + 0 * bands, np.geomspace(10.0, 1e3, 5)),
    )
    doc = res.to_json()
    rec = read_recording(path)
    assert "Rattle index" not in html_report(fit=doc, recordings=[rec])  # only with fit.igr
    assert plot_igr(doc, tmp_path) == []
    doc["fit"]["igr"] = [{"measured": 0.1123, "model": [0.107, 0.112, 0.120], "seed": 0}]
    html = html_report(fit=doc, recordings=[rec])
    assert "Rattle index" in html and "measured 0.1123 rad·Hz" in html
    assert "3 re-simulations 0.113 rad·Hz on average (0.107–0.12)" in html
    (png,) = plot_igr(doc, tmp_path)
    assert png.name == "igr.png" and png.read_bytes()[:4] == b"\x89PNG"

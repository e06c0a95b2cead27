"""The posterior sampler against closed forms: priors, a linear-Gaussian posterior, resuming.

The sampler's parts that do not simulate (priors and their Jacobian, the weighted Gaussian
likelihood, the chain loop and its HDF5 backend) are checked on targets whose posterior is
known in closed form; the synthetic-recording check of the whole posterior is marked slow
(run it with --run-slow).
"""

import dataclasses
import json
import math
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import ClassVar

import emcee
import h5py
import numpy as np
import pytest
from scipy import stats

import rattlefit as rf
from rattlefit import FitOptions, identify, sample, synthesize
from rattlefit.errors import RattlefitError
from rattlefit.features.spectra import BandSpec, spectral_features
from rattlefit.inference.posterior import (
    ChainContext,
    LogPosterior,
    Posterior,
    SampleOptions,
    run_chain,
    write_context,
)
from rattlefit.io.recording import OperatingPoint, write_recording
from rattlefit.likelihood.noise import NoiseModel
from rattlefit.likelihood.protocol import Likelihood, load_likelihood, save_likelihood
from rattlefit.likelihood.synthetic import SyntheticLikelihood
from rattlefit.problem.forward import evaluate
from rattlefit.problem.parameters import ParameterSpec
from rattlefit.problem.problem import build_problem

# Seeds: the chains' (emcee's stream), the draws' and the synthetic recording's.
PRIOR_CHAIN_SEED = 3  # the chain without data
LINEAR_SEED = 0  # the linear-Gaussian target's design and data
LINEAR_CHAIN_SEED = 1  # its chain
RESUMED_CHAIN_SEED = 5  # the chain run whole and in pieces
NORMAL_DRAWS_SEED = 2  # iid normal draws standing in for a chain
JITTER_SEED = 1  # the spread of a chain about the truth
MILD_RECORDING_SEED = 11  # the mild boundary recording of pair II (as in test_fit)
FIT_SEED = 0  # the identification the slow posterior starts from
CHAIN_SEED = 0  # and its chain
BUILD_SEED = 0  # release states and dither draws of the problem built without a fit
SHORT_CHAIN_SEED = 4  # the short real chain saved in ArviZ's format
PREDICTIVE_SEED = 7  # its predictive draws

# Margins.
KS_P = 1e-3  # a KS test of the draws against the prior fails only this rarely by chance
MEAN_TOLERANCE = 0.1  # of a posterior sd: the chain's mean after 2500 steps of 32 walkers
CORRELATION_TOLERANCE = 0.08  # of the posterior correlations, from the same chain
INTERVAL_TOLERANCE = (0.01, 0.02)  # the median's and the 95 % ends' about μ ± 1.96 s (s 0.2)
ESS_FACTOR = 0.3  # arviz's ESS of iid draws is their count, within ±30 %
PREDICTIVE_RMS = 0.15  # log10: the run-to-run spread of this mild rattle's bands is about 0.1
SUMMARY_RTOL = 1e-12  # arviz's quantiles and numpy's percentiles: one formula, rounding apart


def _log_values(specs, z):
    """log v of each parameter for z (..., P), as ParameterSpec.value defines it."""
    u = 1.0 / (1.0 + np.exp(-z))
    return np.stack(
        [math.log(s.lower) + s.log_range * u[..., i] for i, s in enumerate(specs)], axis=-1
    )


def _independent(chain, burn):
    """Draws thinned by twice the largest autocorrelation time (close to independent)."""
    tau = np.max(emcee.autocorr.integrated_time(chain[burn:], tol=0, quiet=True))
    return chain[burn :: max(1, int(2 * tau))].reshape(-1, chain.shape[-1])


def _posterior(chain, names, units, *, discard, **extra):
    """A Posterior around ``chain`` (steps, walkers, P) with placeholder diagnostics."""
    steps, walkers, p = chain.shape
    fields = dict(
        log_prob=np.zeros((steps, walkers)),
        acceptance=np.full(walkers, 0.3),
        autocorr_time=np.ones(p),
        ess=np.full(p, 100.0),
        reliable=False,
        seed=0,
        wall_time=1.0,
        n_evaluations=0,
        recordings=[],
    )
    fields.update(extra)
    return Posterior(names=names, units=units, chain=chain, discard=discard, **fields)


@dataclasses.dataclass(frozen=True)
class MeanLikelihood:
    """A Gaussian likelihood of ``data`` about ``mean_features(zs)`` (K, R, F), weighted by
    ``noise``: a third kind, made only through the likelihood contract."""

    kind: ClassVar[str] = "closed_form"
    noise: NoiseModel
    data: np.ndarray
    mean_features: Callable

    def bind(self, problem):
        return self

    def log_density(self, zs):
        return self.noise.log_density(self.data, self.mean_features(zs))

    def information(self, z, names, *, rng):
        raise NotImplementedError

    def save(self, g):
        raise NotImplementedError


def _target(specs, data, noise, mean_features):
    return LogPosterior(specs, MeanLikelihood(noise, np.asarray(data, float), mean_features))


def _identity_noise(n_band, sigma=1.0):
    return NoiseModel(
        np.full((1, n_band), sigma), np.eye(n_band), np.ones(n_band), np.zeros(1), 100
    )


def test_without_data_the_chain_draws_the_priors():
    # a log-uniform prior over a range of 5000 and a log-normal one truncated at ±3.2 sd: the
    # chain moves in the logit coordinate z, so without the Jacobian term the log-uniform
    # draws would pile up at the range's ends (KS statistic ≈ 0.3 instead of ≈ 0.03)
    specs = (
        ParameterSpec("film_half_length", "m", 1e-6, 5e-3),
        ParameterSpec("viscosity_scale", "1", 0.2, 5.0, center=1.0, log_sd=0.5),
    )
    data = np.zeros((1, 3))
    target = _target(specs, data, _identity_noise(3), lambda zs: np.zeros((len(zs), 1, 3)))
    sampler = run_chain(
        target,
        np.zeros(2),
        np.eye(2),
        n_walkers=32,
        n_steps=2500,
        seed=PRIOR_CHAIN_SEED,
        init_scale=1.0,
    )
    draws = _log_values(specs, _independent(sampler.get_chain(), 500))
    assert len(draws) > 1000
    lo, hi = math.log(1e-6), math.log(5e-3)
    uniform = stats.kstest(draws[:, 0], stats.uniform(lo, hi - lo).cdf)
    bound = (math.log(0.2) / 0.5, math.log(5.0) / 0.5)
    truncated = stats.kstest(draws[:, 1], stats.truncnorm(*bound, loc=0.0, scale=0.5).cdf)
    assert uniform.pvalue > KS_P, uniform
    assert truncated.pvalue > KS_P, truncated


def test_linear_gaussian_posterior_matches_the_closed_form():
    # features linear in log v, correlated bands (whitening), an inflated recording
    # (row_scale) and log-normal priors wide enough that their truncation does not matter:
    # the posterior of log v is Gaussian with precision AᵀC⁻¹A + P⁻¹
    rng = np.random.default_rng(LINEAR_SEED)
    n_band, specs = (
        6,
        tuple(
            ParameterSpec(f"p{i}", "1", math.exp(-4.0), math.exp(4.0), center=1.0, log_sd=0.4)
            for i in range(3)
        ),
    )
    a = rng.normal(size=(n_band, 3))
    corr = 0.5 ** np.abs(np.subtract.outer(np.arange(n_band), np.arange(n_band)))
    whiten = np.linalg.inv(np.linalg.cholesky(corr))
    sigma, scale = 0.3, 1.0 / math.sqrt(2.0)
    noise = NoiseModel(
        np.full((1, n_band), sigma), whiten, np.full(n_band, scale), np.zeros(1), 100
    )
    truth = np.array([0.3, -0.2, 0.1])
    data = (a @ truth + sigma * rng.normal(size=n_band))[None]
    target = _target(specs, data, noise, lambda zs: (_log_values(specs, zs) @ a.T)[:, None, :])
    c_inv = whiten.T @ np.diag(np.full(n_band, scale**2)) @ whiten / sigma**2
    precision = a.T @ c_inv @ a + np.eye(3) / 0.4**2
    cov = np.linalg.inv(precision)
    mean = cov @ (a.T @ c_inv @ data[0])
    z0 = np.array([s.z_of(math.exp(m)) for s, m in zip(specs, mean, strict=True)])
    sampler = run_chain(
        target, z0, 0.1 * np.eye(3), n_walkers=32, n_steps=3000, seed=LINEAR_CHAIN_SEED
    )
    draws = _log_values(specs, sampler.get_chain(discard=500, flat=True))
    sd = np.sqrt(np.diag(cov))
    assert np.all(np.abs(draws.mean(axis=0) - mean) < MEAN_TOLERANCE * sd), (draws.mean(0), mean)
    ratio = np.cov(draws.T) / np.outer(sd, sd)
    assert np.allclose(ratio, cov / np.outer(sd, sd), atol=CORRELATION_TOLERANCE), (ratio, cov)


def test_a_resumed_chain_equals_an_uninterrupted_one(tmp_path):
    specs = (ParameterSpec("film_half_length", "m", 1e-6, 5e-3), ParameterSpec("b", "1", 0.1, 10.0))
    target = _target(
        specs,
        np.zeros((1, 2)),
        _identity_noise(2, 0.5),
        lambda zs: np.tanh(zs)[:, None, :],
    )

    def chain(path, steps):
        backend = emcee.backends.HDFBackend(str(path), name="mcmc")
        for n in steps:  # each call continues the chain in the file to n steps
            backend = emcee.backends.HDFBackend(str(path), name="mcmc")
            run_chain(
                target,
                np.zeros(2),
                np.eye(2),
                n_walkers=8,
                n_steps=n,
                seed=RESUMED_CHAIN_SEED,
                backend=backend,
            )
        return backend.get_chain()

    whole = chain(tmp_path / "whole.h5", [60])
    pieces = chain(tmp_path / "pieces.h5", [25, 60])
    assert whole.shape == (60, 8, 2)
    np.testing.assert_array_equal(whole, pieces)
    other = chain(tmp_path / "other.h5", [60])  # the seed decides, so the same seed repeats
    np.testing.assert_array_equal(whole, other)


@pytest.fixture(scope="module")
def small_recording():
    g = rf.table2_pair("II", center_distance_mm=65.0)
    op = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    rec, _ = synthesize(g, op, p, seed=MILD_RECORDING_SEED, duration=1.0)
    return rec


def test_a_chain_file_of_other_recordings_is_refused(tmp_path, small_recording):
    path = tmp_path / "chain.h5"
    n_band = 30
    ctx = ChainContext(
        FitOptions(),
        np.zeros(6),
        np.eye(6),
        np.zeros((1, n_band)),  # not this recording's features
        SyntheticLikelihood(_identity_noise(n_band)),
        ["elsewhere.h5"],
        0,
    )
    write_context(path, ctx)
    with pytest.raises(RattlefitError, match=r"chain\.h5: /rattlefit/data: .*elsewhere\.h5"):
        sample([small_recording], backend=path)


def test_the_synthetic_kind_scores_by_its_noise_model_and_is_stored_with_its_kind(
    tmp_path, small_recording
):
    options = FitOptions(n_realisations=3, seed=BUILD_SEED)
    problem, _ = build_problem([small_recording], options, np.random.default_rng(BUILD_SEED))
    data = np.asarray(problem.data)
    n = data.size
    corr = 0.4 ** np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    whiten = np.linalg.inv(np.linalg.cholesky(corr))
    noise = NoiseModel(np.full(data.shape, 0.2), whiten, np.full(n, 0.8), np.zeros(1), 100)
    like = SyntheticLikelihood.of_fit(noise, problem, options)
    assert isinstance(like, Likelihood) and like.kind == "synthetic"
    zs = np.zeros((2, len(problem.specs)))
    zs[1, 0] = 0.5
    mean = np.asarray(problem.mean_of(evaluate(problem, zs)))  # (2, 1, F)
    r = (data - mean).reshape(2, -1) / 0.2
    closed_form = -0.5 * np.sum((0.8 * (r @ whiten.T)) ** 2, axis=1)
    np.testing.assert_allclose(like.log_density(zs), closed_form, rtol=1e-12)
    with h5py.File(tmp_path / "l.h5", "w") as f:
        save_likelihood(f.create_group("likelihood"), like)
    with h5py.File(tmp_path / "l.h5", "r") as f:
        back = load_likelihood(f["likelihood"], problem, "l.h5: /likelihood")
        np.testing.assert_array_equal(back.log_density(zs), like.log_density(zs))
    with h5py.File(tmp_path / "l.h5", "a") as f:
        f["likelihood"].attrs["kind"] = "tabulated"
        with pytest.raises(RattlefitError, match=r"l\.h5: /likelihood@kind: unknown .*tabulated"):
            load_likelihood(f["likelihood"], problem, "l.h5: /likelihood")


def test_a_foreign_hdf5_file_is_refused_and_kept(tmp_path, small_recording):
    path = tmp_path / "notes.h5"
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(RattlefitError, match=r"notes\.h5: /rattlefit: missing"):
        sample([small_recording], backend=path)
    with h5py.File(path, "r") as f:  # nothing lost
        np.testing.assert_array_equal(f["x"][:], np.arange(3))


@pytest.mark.slow  # a fit and a 6-parameter chain
def test_posterior_of_a_synthetic_recording_holds_the_truth(tmp_path):
    g = rf.table2_pair("II", center_distance_mm=65.0)
    op = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    rec, _ = synthesize(g, op, p, seed=MILD_RECORDING_SEED)
    fit = identify([rec], FitOptions(seed=FIT_SEED))
    options = SampleOptions(n_steps=150, seed=CHAIN_SEED)
    post = sample([rec], fit, options, backend=tmp_path / "c.h5")
    ci = post.intervals()
    for name, truth in (
        ("film_half_length", 0.085e-3),
        ("drag_torque", 0.025),
        ("viscosity", 0.4942),
    ):
        _, lo, hi = ci[name]
        assert lo <= truth <= hi, (name, lo, truth, hi)


def test_posterior_summaries_of_independent_normal_draws():
    # iid N(μ, s²) draws: the credible interval is μ ± 1.96 s, and arviz's ESS is about the
    # number of draws (every walker is one chain)
    import arviz as az

    rng = np.random.default_rng(NORMAL_DRAWS_SEED)
    chain = 1.5 + 0.2 * rng.standard_normal((400, 16, 1))
    post = _posterior(chain, ["x"], ["1"], discard=100, ess=np.full(1, 16 * 300.0))
    med, lo, hi = post.intervals()["x"]
    near_median, near_end = INTERVAL_TOLERANCE
    assert abs(med - 1.5) < near_median and abs(lo - (1.5 - 1.96 * 0.2)) < near_end, (lo, med)
    assert abs(hi - (1.5 + 1.96 * 0.2)) < near_end
    ess = float(az.ess(post.to_arviz())["x"])
    assert (1 - ESS_FACTOR) * 4800 < ess < (1 + ESS_FACTOR) * 4800, ess
    doc = post.to_json()
    assert doc["parameters"]["x"]["unit"] == "1" and doc["sampler"]["discard"] == 100


def test_predictive_plot_draws_from_the_kept_chain(tmp_path, small_recording):
    # a chain that sits at the true parameters: its predictive band spectra must lie on the
    # measured ones within the run-to-run spread (PREDICTIVE_RMS)
    from rattlefit.report import plot_posterior

    options = FitOptions(n_realisations=3)
    problem, _ = build_problem([small_recording], options, np.random.default_rng(BUILD_SEED))
    truth = {"film_half_length": 0.085e-3, "drag_torque": 0.025, "viscosity_scale": 1.0}
    z = np.array([s.z_of(truth.get(s.name, s.center)) for s in problem.specs])
    jitter = np.random.default_rng(JITTER_SEED).normal(size=(20, 12, 6))
    chain_z = np.tile(z, (20, 12, 1)) + 1e-3 * jitter
    post = _posterior(
        chain_z,
        [s.name for s in problem.specs],
        [s.unit for s in problem.specs],
        discard=5,
        chain_z=chain_z,
        fit_options=options,
    )
    draws, data, centres = post.predictive_features([small_recording], n_draws=3)
    assert draws.shape == (3, 1, len(centres)) and data.shape == (1, len(centres))
    assert np.sqrt(np.mean((draws - data) ** 2)) < PREDICTIVE_RMS
    paths = plot_posterior(post, tmp_path, [small_recording], predictive=(draws, data, centres))
    assert any(p.name.startswith("posterior_predictive_0_") for p in paths)
    assert all(p.stat().st_size > 0 for p in paths)


# -- the posterior in ArviZ's format -------------------------------------------------------


@pytest.fixture(scope="module")
def short_chain(tmp_path_factory, small_recording):
    """A real 6-step chain of 12 walkers on the small recording (read back from its file),
    its target centred on the truth (a chain file whose context stands in for the fit), saved
    in ArviZ's format: (posterior, recording, chain file, netCDF file)."""
    directory = tmp_path_factory.mktemp("short_chain")
    small_recording = rf.read_recording(write_recording(small_recording, directory / "r.h5"))
    options = FitOptions(n_realisations=3, seed=BUILD_SEED)
    problem, _ = build_problem([small_recording], options, np.random.default_rng(BUILD_SEED))
    truth = {"film_half_length": 0.085e-3, "drag_torque": 0.025, "viscosity_scale": 1.0}
    z = np.array([s.z_of(truth.get(s.name, s.center)) for s in problem.specs])
    data = np.asarray(problem.data)
    noise = NoiseModel(
        np.full(data.shape, 0.1), np.eye(data.size), np.ones(data.size), np.zeros(1), 100
    )
    chain_file = directory / "chain.h5"
    ctx = ChainContext(
        options,
        z,
        0.01 * np.eye(len(z)),
        data,
        SyntheticLikelihood(noise),
        [small_recording.path],
        SHORT_CHAIN_SEED,
    )
    write_context(chain_file, ctx)
    chain_options = SampleOptions(n_walkers=12, n_steps=6, discard=2)
    post = sample([small_recording], options=chain_options, backend=chain_file)
    with warnings.catch_warnings():  # arviz warns of a chain shorter than its walkers
        warnings.filterwarnings("ignore", "More chains", UserWarning)
        nc = post.save_netcdf(
            directory / "chain.nc", [small_recording], n_draws=3, seed=PREDICTIVE_SEED
        )
    return post, small_recording, chain_file, nc


def test_a_saved_posterior_reopens_as_the_kept_chain(short_chain):
    import arviz as az

    post, recording, chain_file, nc = short_chain
    idata = az.from_netcdf(nc)
    assert post.chain.shape == (6, 12, 6) and post.discard == 2
    for i, (name, unit) in enumerate(zip(post.names, post.units, strict=True)):
        var = idata.posterior[name]
        assert var.dims == ("chain", "draw") and var.attrs["units"] == unit
        np.testing.assert_array_equal(var.values, post.chain[2:, :, i].T)
    # the log densities as emcee stored them in the chain file
    stored = emcee.backends.HDFBackend(str(chain_file), name="mcmc", read_only=True)
    np.testing.assert_array_equal(idata.sample_stats["lp"].values, stored.get_log_prob()[2:].T)
    attrs = idata.posterior.attrs
    assert (attrs["seed"], attrs["discard"]) == (SHORT_CHAIN_SEED, 2)
    assert json.loads(attrs["recordings"]) == [str(recording.path)] == post.recordings
    assert attrs["rattlefit_version"] == rf.__version__
    assert json.loads(attrs["platform"])["jax"] == post.platform["jax"]
    # and without rattlefit: a Python in which importing it fails reads the same numbers
    script = (
        "import json, sys; sys.modules['rattlefit'] = None; import arviz as az; "
        f"idata = az.from_netcdf({str(nc)!r}); "
        "print(json.dumps(idata.posterior['film_half_length'].values.tolist()))"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    np.testing.assert_array_equal(np.array(json.loads(out)), post.chain[2:, :, 0].T)


def test_arviz_summary_gives_the_printed_intervals(short_chain):
    # az.summary's equal-tailed interval (stat_focus="median": median, eti_2.5%, eti_97.5%) of
    # the saved file is the credible interval that `rattlefit sample` prints
    import arviz as az

    from rattlefit.quantities import display
    from rattlefit.report import format_posterior

    post, _, _, nc = short_chain
    summary = az.summary(
        az.from_netcdf(nc), kind="stats", stat_focus="median", hdi_prob=0.95, round_to="none"
    )
    printed = {line.split()[0]: line for line in format_posterior(post).splitlines()[2:]}
    for name, unit in zip(post.names, post.units, strict=True):
        row = summary.loc[name]
        med, lo, hi = row["median"], row["eti_2.5%"], row["eti_97.5%"]
        assert lo < med < hi, row
        np.testing.assert_allclose([med, lo, hi], post.intervals()[name], rtol=SUMMARY_RTOL, atol=0)
        mult = display(name, unit)[0]
        assert printed[name].split()[1] == f"{med * mult:.4g}", printed[name]
        assert f"[{lo * mult:.4g}, {hi * mult:.4g}]" in printed[name], printed[name]


def test_the_saved_observed_data_are_the_measured_features(short_chain):
    import arviz as az

    post, small_recording, chain_file, nc = short_chain
    idata = az.from_netcdf(nc)
    bands = BandSpec.for_recording(small_recording.sample_rate_hz)
    measured = np.asarray(spectral_features(small_recording.relative_motion, bands))
    observed = idata.observed_data["log10_psd"]
    assert observed.dims == ("recording", "band")
    np.testing.assert_allclose(observed.values[0], measured, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(observed["band"].values, bands.centers)
    np.testing.assert_array_equal(idata.constant_data["band_center"].values, bands.centers)
    with h5py.File(chain_file, "r") as f:  # what the chain's likelihood compared with
        np.testing.assert_array_equal(observed.values, f["rattlefit/data"][:])
    # each predictive draw is the mean simulated features at the kept walker and step it names
    pp = idata.posterior_predictive["log10_psd"]
    assert pp.dims == ("chain", "draw", "recording", "band") and pp.shape == (1, 3, 1, 30)
    assert pp.attrs["units"] == observed.attrs["units"] == "log10(rad^2/Hz)"
    assert idata.posterior_predictive.attrs["predictive_seed"] == PREDICTIVE_SEED
    walker, step = pp["walker"].values, pp["step"].values
    assert np.all((step >= post.discard) & (step < 6)) and np.all((walker >= 0) & (walker < 12))
    problem, _ = build_problem(
        [small_recording], post.fit_options, np.random.default_rng(BUILD_SEED)
    )
    expected = problem.mean_of(evaluate(problem, post.chain_z[step, walker]))
    np.testing.assert_allclose(pp.values[0], np.asarray(expected), rtol=0, atol=1e-9)
    assert np.sqrt(np.mean((pp.values - observed.values) ** 2)) < PREDICTIVE_RMS


def test_a_failed_save_leaves_the_earlier_file(tmp_path, monkeypatch):
    import arviz as az

    chain = np.random.default_rng(NORMAL_DRAWS_SEED).standard_normal((10, 4, 1))
    post = _posterior(chain, ["x"], ["1"], discard=2)
    path = post.save_netcdf(tmp_path / "p.nc")

    def broken(self, filename, **kw):
        Path(filename).write_bytes(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(az.InferenceData, "to_netcdf", broken)
    with pytest.raises(OSError, match="disk full"):
        _posterior(2 * chain, ["x"], ["1"], discard=2).save_netcdf(path)
    monkeypatch.undo()
    np.testing.assert_array_equal(az.from_netcdf(path).posterior["x"].values, chain[2:, :, 0].T)
    assert [p.name for p in tmp_path.iterdir()] == ["p.nc"]
    with pytest.raises(RattlefitError, match="no chain in fit coordinates"):
        post.to_inference_data([object()])

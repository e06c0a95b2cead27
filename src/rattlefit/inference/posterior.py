"""Bayesian posterior of the identified parameters by affine-invariant ensemble MCMC (emcee).

The target is the posterior density in the fit's unconstrained coordinates ``z``
(:class:`~rattlefit.problem.parameters.ParameterSpec`: ``v = lower·(upper/lower)^sigmoid(z)``),

    log p(z | d) = −½ Σ (row_scale · W · (d − μ̄_M(z)) / σ)² + log π(v(z)) + Σ log |∂log v/∂z|,

* ``μ̄_M(z)``: the mean features of the same ``M`` seeded realisations the fit uses (release
  states, dither and encoder phases fixed: common random numbers), so the target is a
  deterministic function of ``z``. This is a Gaussian synthetic likelihood (Wood 2010; Price
  et al. 2018) whose band spread ``σ`` (which holds the Monte Carlo variance of an
  M-realisation mean), band correlations ``W`` and per-recording χ² inflation are those of the
  fit at its optimum (:class:`~rattlefit.likelihood.noise.NoiseModel`). Re-estimating them at
  every point would make the target itself noisy, and a noisy target makes ensemble MCMC
  sticky.
* priors ``π``: log-uniform over the range for the free parameters (``a``, ``drag_torque``);
  log-normal (``center``, ``log_sd``) truncated to the range for the nuisance parameters
  (viscosity factor, stiffness scale, ``h_min``, each backlash). The chain moves in ``z``, and
  the Jacobian term makes these the priors of the values themselves.

The likelihood is the fit's own (:class:`~rattlefit.likelihood.protocol.Likelihood`): the
synthetic one above, or a learned one, whose density needs no simulation. The user-function
contract is emcee's with ``vectorize=True``: :class:`LogPosterior` maps a
batch of points ``(K, P)`` to ``(K,)`` log densities (``-inf`` outside the support, never NaN),
and the half-ensemble that each move updates is simulated in one batch.

The chain is written step by step to an HDF5 file (emcee's ``HDFBackend``, group ``mcmc``),
together with everything needed to continue it (group ``rattlefit``: the fit's options, seed,
optimum, covariance, likelihood and the measured features). Running :func:`sample` again on
the same file continues the chain to ``n_steps`` without refitting; the random state is
restored, so an interrupted and resumed chain equals an uninterrupted one.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import emcee
import h5py
import numpy as np

from ..documents import POSTERIOR
from ..errors import RattlefitError
from ..io.recording import Recording
from ..likelihood.protocol import Likelihood, load_likelihood, save_likelihood
from ..problem.forward import evaluate
from ..problem.options import FitOptions
from ..problem.parameters import Z_END, ParameterSpec
from ..problem.problem import problem_from
from ..quantities import VISCOSITY, VISCOSITY_SCALE
from ..reproducibility import platform_info
from . import arviz_io
from .identify import identify
from .result import FitResult

#: Walkers beyond this |z| have a value within e^-20 of its range's end: zero density there.
Z_LIMIT = 20.0
#: Format tag and version of the ``rattlefit`` group of a chain file.
CHAIN_FORMAT, CHAIN_VERSION = "rattlefit-chain", 2
#: The group of a chain file's ``rattlefit`` that stores the likelihood.
LIKELIHOOD = "likelihood"


@dataclasses.dataclass(frozen=True)
class SampleOptions:
    """Options of :func:`sample`.

    n_walkers : emcee walkers (at least twice the number of parameters; rounded up to even).
    n_steps : total length of the chain; a resumed chain is continued to this length.
    discard : steps discarded as the chain's warm-up (burn-in) before the summaries, as
        emcee's ``discard``; None (default): a third of the chain.
    seed : seeds the walkers' start and emcee's moves (reported in the result).
    init_scale : the walkers start at the fit's optimum plus this fraction of a draw from its
        Laplace covariance (each coordinate's offset clipped to ±2 in z).
    fit : options of the fit that :func:`sample` runs when it is given none (its seed, its
        realisations and its tolerance define the target).
    """

    n_walkers: int = 16
    n_steps: int = 300
    discard: int | None = None
    seed: int = 0
    init_scale: float = 0.5
    fit: FitOptions = dataclasses.field(default_factory=FitOptions)

    def __post_init__(self):
        if self.n_steps < 2:
            raise RattlefitError("SampleOptions.n_steps must be at least 2")
        if self.n_walkers < 2:
            raise RattlefitError("SampleOptions.n_walkers must be at least 2")
        if self.discard is not None and not (0 <= self.discard < self.n_steps):
            raise RattlefitError("SampleOptions.discard must lie in [0, n_steps)")


def log_prior(specs: Sequence[ParameterSpec], zs) -> np.ndarray:
    """log π(v(z)) + log |∂log v/∂z| at each point of ``zs`` (K, P), up to a constant.

    Free parameters (no ``log_sd``) are log-uniform over their range, the others log-normal
    about ``center`` with ``log_sd``, truncated to the range; ``-inf`` beyond |z| > Z_LIMIT.
    """
    zs = np.atleast_2d(np.asarray(zs, dtype=float))
    # log of the Jacobian d log v / dz = L·s(1−s), s = sigmoid(z), without the constant log L
    out = -np.sum(np.logaddexp(0.0, zs) + np.logaddexp(0.0, -zs), axis=1)
    for i, s in enumerate(specs):
        if s.log_sd is not None:
            log_v = math.log(s.lower) + s.log_range / (1.0 + np.exp(-zs[:, i]))
            out -= 0.5 * ((log_v - math.log(s.center)) / s.log_sd) ** 2
    return np.where(np.all(np.abs(zs) <= Z_LIMIT, axis=1), out, -np.inf)


class LogPosterior:
    """log p(z | d) of a batch of points ``(K, P)`` → ``(K,)`` (emcee's ``vectorize=True``):
    the priors of ``specs`` plus ``likelihood``'s log density
    (:class:`~rattlefit.likelihood.protocol.Likelihood`, bound to the recordings). Points
    outside the support get ``-inf`` without being evaluated, and so does any non-finite
    value. ``n_evaluations`` counts the points the likelihood evaluated.
    """

    def __init__(self, specs: Sequence[ParameterSpec], likelihood: Likelihood):
        self.specs = tuple(specs)
        self.likelihood = likelihood
        self.n_evaluations = 0

    def log_likelihood(self, zs) -> np.ndarray:
        zs = np.atleast_2d(np.asarray(zs, dtype=float))
        self.n_evaluations += len(zs)
        return np.asarray(self.likelihood.log_density(zs), dtype=float)

    def __call__(self, zs) -> np.ndarray:
        zs = np.atleast_2d(np.asarray(zs, dtype=float))
        out = log_prior(self.specs, zs)
        ok = np.isfinite(out)
        if np.any(ok):
            out[ok] += self.log_likelihood(zs[ok])
        return np.where(np.isfinite(out), out, -np.inf)


@dataclasses.dataclass(frozen=True)
class Posterior:
    """What :func:`sample` returns: the chain in SI values and its diagnostics.

    names, units : the parameters (``viscosity`` in Pa s at the first recording's temperature).
    chain : (n_steps, n_walkers, P) values; ``log_prob`` (n_steps, n_walkers).
    acceptance : each walker's acceptance fraction.
    autocorr_time : (P,) integrated autocorrelation time of each parameter after the burn-in,
        in steps (emcee's estimator; ``reliable`` is False while the kept chain is shorter than
        50 of them, emcee's own criterion).
    ess : (P,) effective sample size, walkers × kept steps / autocorr_time.
    """

    names: list[str]
    units: list[str]
    chain: np.ndarray
    log_prob: np.ndarray
    acceptance: np.ndarray
    autocorr_time: np.ndarray
    ess: np.ndarray
    reliable: bool
    discard: int
    seed: int
    wall_time: float
    n_evaluations: int
    recordings: list[str]
    backend: str | None = None
    #: the chain in the fit's unconstrained coordinates (for predictive simulations)
    chain_z: np.ndarray | None = dataclasses.field(default=None, repr=False)
    #: the options of the fit whose realisations and noise model define the target
    fit_options: FitOptions | None = dataclasses.field(default=None, repr=False)
    #: what a seeded result depends on (:func:`~rattlefit.reproducibility.platform_info`),
    #: captured when the chain ran
    platform: dict = dataclasses.field(default_factory=dict, compare=False)

    @property
    def kept(self) -> np.ndarray:
        """Draws after the burn-in, flattened over walkers: (n, P)."""
        return self.chain[self.discard :].reshape(-1, self.chain.shape[-1])

    def predictive_features(self, recordings: Sequence[Recording], n_draws: int = 8, seed=0):
        """Mean simulated features at ``n_draws`` seeded draws of the kept chain, with the
        measured features and the band centres: ``(draws (n, R, B), data (R, B), centres (B,))``.
        The draws (:func:`~rattlefit.inference.arviz_io.predictive_pick` with ``seed``) use the
        target's own realisations (a posterior predictive check of the statistic the
        likelihood compares); the features are log10 band-mean PSDs (rad²/Hz), the centres Hz.
        Raises :class:`~rattlefit.errors.RattlefitError` without a chain in fit coordinates or
        for ``n_draws`` outside [1, kept draws]."""
        if self.chain_z is None or self.fit_options is None:
            raise RattlefitError("posterior: no chain in fit coordinates to draw from")
        kept = self.chain_z[self.discard :].reshape(-1, self.chain_z.shape[-1])
        pick = arviz_io.predictive_pick(len(kept), n_draws, seed)
        problem, _, _ = problem_from(recordings, self.fit_options)
        draws = np.asarray(problem.mean_of(evaluate(problem, kept[pick])))
        nb = problem.n_bands  # the bands only, whatever else the fit compared
        return draws[..., :nb], np.asarray(problem.data)[:, :nb], problem.bands.centers

    def intervals(self, level: float = 0.95) -> dict[str, tuple[float, float, float]]:
        """name → (median, lower, upper) of the central credible interval at ``level``."""
        q = 50 * (1 - level)
        lo, med, hi = np.percentile(self.kept, [q, 50, 100 - q], axis=0)
        return {
            n: (float(m), float(a), float(b))
            for n, m, a, b in zip(self.names, med, lo, hi, strict=True)
        }

    def to_inference_data(
        self, recordings: Sequence[Recording] | None = None, *, n_draws: int = 8, seed: int = 0
    ):
        """An ``arviz.InferenceData``: ``posterior`` (each parameter by name, SI, walkers as
        chains, the kept draws) and ``sample_stats`` (``lp``); given the chain's
        ``recordings``, also ``observed_data``, ``constant_data`` and a
        ``posterior_predictive`` of ``n_draws`` draws chosen with ``seed``. The groups and
        attributes are described in :mod:`rattlefit.inference.arviz_io`; raises as
        :meth:`predictive_features`."""
        return arviz_io.inference_data(self, recordings, n_draws=n_draws, seed=seed)

    def to_arviz(self):
        """:meth:`to_inference_data` without recordings (``posterior`` and ``sample_stats``)."""
        return self.to_inference_data()

    def save_netcdf(
        self, path: str | Path, recordings: Sequence[Recording] | None = None, **kw
    ) -> Path:
        """Write :meth:`to_inference_data` (``recordings`` and ``kw`` passed on) to the netCDF
        file ``path`` atomically and return ``path``; ``arviz.from_netcdf(path)`` reopens it
        without rattlefit."""
        return arviz_io.save_netcdf(self, path, recordings, **kw)

    def to_json(self) -> dict:
        """The ``--output`` document (:data:`rattlefit.documents.POSTERIOR`): credible
        intervals (SI) and the chain's diagnostics."""
        return {
            **POSTERIOR.header(),
            "parameters": {
                n: {"median": m, "lower": lo, "upper": hi, "unit": u}
                for (n, (m, lo, hi)), u in zip(self.intervals().items(), self.units, strict=True)
            },
            "sampler": {
                "walkers": int(self.chain.shape[1]),
                "steps": int(self.chain.shape[0]),
                "discard": self.discard,
                "acceptance_mean": float(np.mean(self.acceptance)),
                "autocorr_time": dict(zip(self.names, map(float, self.autocorr_time), strict=True)),
                "ess": dict(zip(self.names, map(float, self.ess), strict=True)),
                "reliable": self.reliable,
                "seed": self.seed,
                "platform": self.platform,  # seeded results depend on it
                "wall_time_s": self.wall_time,
                "evaluations": self.n_evaluations,
                "recordings": self.recordings,
                "backend": self.backend,
            },
        }


# -- the chain file -------------------------------------------------------------------------


def _options_json(options: FitOptions) -> str:
    return json.dumps(options.to_dict())


def _options_from_json(text: str) -> FitOptions:
    return FitOptions.from_dict(json.loads(text))


@dataclasses.dataclass(frozen=True)
class ChainContext:
    """What a chain needs besides the recordings: stored in the chain file's ``rattlefit``.

    likelihood : the fit's :class:`~rattlefit.likelihood.protocol.Likelihood` (a fit in this
        process), or the chain file that stores it (group ``rattlefit/likelihood``, read once
        the recordings' problem is known).
    """

    fit_options: FitOptions
    z: np.ndarray
    covariance_z: np.ndarray
    data: np.ndarray
    likelihood: Likelihood | Path
    recordings: list[str]
    seed: int


def write_context(path: Path, ctx: ChainContext) -> None:
    """Store ``ctx`` in the group ``rattlefit`` of the chain file ``path`` (replacing any)."""
    with h5py.File(path, "a") as f:
        if "rattlefit" in f:
            del f["rattlefit"]
        g = f.create_group("rattlefit")
        g.attrs["format"] = CHAIN_FORMAT
        g.attrs["version"] = CHAIN_VERSION
        g.attrs["fit_options"] = _options_json(ctx.fit_options)
        g.attrs["recordings"] = json.dumps(ctx.recordings)
        g.attrs["seed"] = ctx.seed
        for name, value in (("z", ctx.z), ("covariance_z", ctx.covariance_z), ("data", ctx.data)):
            g.create_dataset(name, data=np.asarray(value, dtype=float))
        save_likelihood(g.create_group(LIKELIHOOD), ctx.likelihood)


def read_context(path: Path) -> ChainContext | None:
    """The context stored in the chain file ``path``; None for a new (absent or empty) file.
    Raises :class:`~rattlefit.errors.RattlefitError` naming the file and group for a file
    that is not a rattlefit chain, of another format version, or unreadable."""
    if not path.exists() or path.stat().st_size == 0:
        return None
    try:
        with h5py.File(path, "r") as f:
            if "rattlefit" not in f:
                if len(f.keys()):
                    raise RattlefitError(
                        f"{path}: /rattlefit: missing; this HDF5 file is not a rattlefit chain "
                        "(choose a new --backend file)"
                    )
                return None
            g = f["rattlefit"]
            if g.attrs.get("format") != CHAIN_FORMAT or g.attrs.get("version") != CHAIN_VERSION:
                raise RattlefitError(
                    f"{path}: /rattlefit@format: expected {CHAIN_FORMAT} version "
                    f"{CHAIN_VERSION}, got {g.attrs.get('format')} {g.attrs.get('version')}"
                )
            if LIKELIHOOD not in g:
                raise RattlefitError(f"{path}: /rattlefit/{LIKELIHOOD}: missing")
            arr = {k: np.asarray(g[k]) for k in ("z", "covariance_z", "data")}
            return ChainContext(
                _options_from_json(g.attrs["fit_options"]),
                arr["z"],
                arr["covariance_z"],
                arr["data"],
                path,
                json.loads(g.attrs["recordings"]),
                int(g.attrs["seed"]),
            )
    except RattlefitError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise RattlefitError(f"{path}: /rattlefit: unreadable chain file ({exc})") from exc


# -- sampling -------------------------------------------------------------------------------


def _summarise(sampler, specs, viscosity, discard):
    """(chain in SI values, names, units, τ, reliable) of the sampler's stored chain."""
    z = sampler.get_chain()
    values = np.empty_like(z)
    names, units = [], []
    for i, s in enumerate(specs):
        values[..., i] = s.value(np.asarray(z[..., i]))
        if s.name == VISCOSITY_SCALE:
            values[..., i] *= viscosity
            names.append(VISCOSITY)
            units.append("Pa s")
        else:
            names.append(s.name)
            units.append(s.unit)
    kept = z.shape[0] - discard
    tau = np.asarray(sampler.get_autocorr_time(discard=discard, tol=0, quiet=True))
    # an integrated autocorrelation time below one step is an artefact of a short chain
    tau = np.where(np.isfinite(tau), np.maximum(tau, 1.0), float(kept))
    return values, names, units, tau, bool(kept >= 50 * np.max(tau))


def _moves():
    """Differential-evolution proposals (70 %) mixed with stretch moves (30 %).

    On a correlated 6-parameter Gaussian with 16 walkers this mix's integrated
    autocorrelation time is about a third of emcee's default stretch move's; the
    DE-with-snooker mix is as fast but draws variances that are too small
    (``tests/test_sample.py`` checks the variances against the closed form).
    """
    return [(emcee.moves.DEMove(), 0.7), (emcee.moves.StretchMove(), 0.3)]


def run_chain(
    log_prob: Callable[[np.ndarray], np.ndarray],
    z: np.ndarray,
    covariance_z: np.ndarray,
    *,
    n_walkers: int,
    n_steps: int,
    seed: int,
    init_scale: float = 0.5,
    backend: emcee.backends.Backend | None = None,
    progress: Callable[[str], None] | None = None,
) -> emcee.EnsembleSampler:
    """Run (or continue) emcee's ensemble sampler on ``log_prob`` to ``n_steps`` in all.

    ``log_prob`` follows emcee's ``vectorize=True`` contract. A fresh chain starts its walkers
    at ``z`` (clipped to ±:data:`~rattlefit.problem.parameters.Z_END`) plus ``init_scale``
    times a draw from ``covariance_z`` (each coordinate's standard deviation capped at 4, each
    offset clipped to ±2), both the draw and emcee's moves seeded
    by ``seed``. A ``backend`` that already holds steps is continued from its last state and
    random state, with its own number of walkers.
    """
    say = progress or (lambda msg: None)
    z = np.asarray(z, dtype=float)
    n_dim = z.size
    n_walkers = max(n_walkers, 2 * n_dim)
    n_walkers += n_walkers % 2
    if backend is not None and backend.initialized and backend.iteration > 0:
        n_walkers = backend.shape[0]
    sampler = emcee.EnsembleSampler(
        n_walkers, n_dim, log_prob, vectorize=True, backend=backend, moves=_moves()
    )
    done = sampler.iteration
    say(f"{n_walkers} walkers × {n_steps} steps over {n_dim} parameters (seed {seed})")
    if done == 0:
        rng = np.random.default_rng(seed)
        cov = np.asarray(covariance_z, dtype=float)
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        corr = cov / np.outer(np.maximum(sd, 1e-300), np.maximum(sd, 1e-300))
        chol = np.linalg.cholesky(corr + 1e-9 * np.eye(n_dim))
        draws = rng.standard_normal((n_walkers, n_dim)) @ chol.T * np.minimum(sd, 4.0)
        # an optimum at a range's end can lie beyond the prior's support in z: start inside
        initial = np.clip(z, -Z_END, Z_END) + np.clip(init_scale * draws, -2.0, 2.0)
        sampler.random_state = np.random.RandomState(seed).get_state()
    else:
        initial = sampler.get_last_sample()
        say(f"{done} steps already in the chain")
    remaining = max(n_steps - done, 0)
    every = max(1, remaining // 20)
    t_run = time.perf_counter()
    for k, _ in enumerate(sampler.sample(initial, iterations=remaining, store=True), start=1):
        if k % every == 0 or k == remaining:
            rate = (time.perf_counter() - t_run) / k
            say(
                f"step {done + k}/{n_steps}: acceptance "
                f"{np.mean(sampler.acceptance_fraction):.2f}, {rate:.2f} s/step, "
                f"about {rate * (remaining - k) / 60:.1f} min left"
            )
    return sampler


def _context_of(fit: FitResult, recordings: Sequence[Recording], seed: int) -> ChainContext:
    """A new chain's context from the fit it starts at."""
    if fit.state.likelihood is None:
        raise RattlefitError("sample: the fit result holds no likelihood (run identify first)")
    return ChainContext(
        fit.state.options,
        np.asarray(fit.state.z),
        np.asarray(fit.state.covariance_z),
        np.stack(fit.spectra.measured),
        fit.state.likelihood,
        [str(r.path) for r in recordings],
        seed,
    )


def _target(
    recordings: Sequence[Recording],
    ctx: ChainContext,
    path: Path | None,
    fit: FitResult | None = None,
):
    """The fit's problem (``fit``'s own when it ran in this process, else rebuilt from
    ``recordings``) and the chain's :class:`LogPosterior`; raises when the recordings are not
    the chain's."""
    problem = fit.problem_for(recordings) if fit is not None else None
    if problem is None:
        problem, _, _ = problem_from(recordings, ctx.fit_options)
    data = np.asarray(problem.data)
    if data.shape != ctx.data.shape or not np.allclose(data, ctx.data, rtol=0, atol=1e-9):
        raise RattlefitError(
            f"{path}: /rattlefit/data: this chain was run on other recordings "
            f"({', '.join(ctx.recordings)}); give those, or a new --backend file"
        )
    likelihood = ctx.likelihood
    if isinstance(likelihood, Path):  # stored in the chain file
        with h5py.File(likelihood, "r") as f:
            where = f"{likelihood}: /rattlefit/{LIKELIHOOD}"
            likelihood = load_likelihood(f["rattlefit"][LIKELIHOOD], problem, where)
    return problem, LogPosterior(problem.specs, likelihood.bind(problem))


def _chain_backend(path: Path, ctx: ChainContext, resumed: bool) -> emcee.backends.HDFBackend:
    """emcee's HDF5 backend on ``path``; a new chain's file is started with its context."""
    if not resumed:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.unlink(missing_ok=True)
        write_context(path, ctx)
    return emcee.backends.HDFBackend(str(path), name="mcmc")


def sample(
    recordings: Sequence[Recording],
    fit: FitResult | None = None,
    options: SampleOptions | None = None,
    *,
    backend: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> Posterior:
    """Sample the posterior of ``a``, ``drag_torque``, the viscosity and the nuisances.

    ``fit`` is :func:`~rattlefit.inference.identify.identify`'s result on the same recordings
    (run here with ``options.fit`` when not given); its optimum and Laplace covariance start
    the walkers and its noise model weights the bands. With ``backend`` (an HDF5 path) the
    chain is saved as it runs; if that file already holds a chain of these recordings, it is
    continued to ``options.n_steps`` and ``fit`` is not needed. Raises
    :class:`~rattlefit.errors.RattlefitError` for a backend file that is not a rattlefit chain
    or holds a chain of other recordings.
    """
    options = options or SampleOptions()
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    platform = platform_info()
    path = None if backend is None else Path(backend)
    ctx = None if path is None else read_context(path)
    resumed = ctx is not None
    if resumed:
        say(f"continuing the chain in {path}")
    else:
        if fit is None:
            say("no fit given: identifying first …")
            fit = identify(recordings, options.fit, progress=progress)
        ctx = _context_of(fit, recordings, options.seed)
    problem, target = _target(recordings, ctx, path, None if resumed else fit)
    specs = problem.specs
    hdf = None if path is None else _chain_backend(path, ctx, resumed)
    say(f"each point scored on the {target.likelihood.kind} likelihood")
    sampler = run_chain(
        target,
        ctx.z,
        ctx.covariance_z,
        n_walkers=options.n_walkers,
        n_steps=options.n_steps,
        seed=ctx.seed,
        init_scale=options.init_scale,
        backend=hdf,
        progress=say,
    )
    n_walkers = sampler.nwalkers
    discard = options.n_steps // 3 if options.discard is None else options.discard
    discard = min(discard, sampler.iteration - 2)
    values, names, units, tau, reliable = _summarise(
        sampler, specs, float(problem.viscosities[0]), discard
    )
    kept = sampler.iteration - discard
    wall = time.perf_counter() - t0
    ess = n_walkers * kept / tau
    say(
        f"done in {wall:.1f} s; ESS "
        + ", ".join(f"{n} {e:.0f}" for n, e in zip(names, ess, strict=True))
    )
    return Posterior(
        names=names,
        units=units,
        chain=values,
        log_prob=sampler.get_log_prob(),
        acceptance=np.asarray(sampler.acceptance_fraction),
        autocorr_time=tau,
        ess=ess,
        reliable=reliable,
        discard=discard,
        seed=ctx.seed,
        wall_time=wall,
        n_evaluations=target.n_evaluations,
        recordings=[str(r.path) for r in recordings],
        backend=None if path is None else str(path),
        chain_z=sampler.get_chain(),
        fit_options=ctx.fit_options,
        platform=platform,
    )

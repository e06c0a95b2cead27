"""What a fit returns: each parameter's estimate and interval, and the fit's diagnostics."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import PurePath

import jax.numpy as jnp
import numpy as np
from scipy import stats

from ..confidence import Z95
from ..documents import FIT
from ..errors import RattlefitError
from ..io.recording import counts_sha256
from ..likelihood.protocol import Likelihood
from ..physics.model import RattleParams
from ..problem.options import FitOptions
from ..problem.parameters import MOMENTUM, ParameterSpec
from ..problem.problem import Problem, problem_from
from ..quantities import DRAG_TORQUE, VISCOSITY, VISCOSITY_SCALE
from .advice import what_would_pin
from .outcome import SearchEnd

#: χ² p-value below which a fit is flagged as poor (:attr:`FitResult.poor_fit`).
POOR_FIT_P = 1e-3
#: A parameter counts as identified when its 95 % interval is two-sided, inside the range,
#: and narrower than this factor (about ±20 % around its middle): if the log estimate is
#: Gaussian with the interval's own spread it then lands within 20 % of the truth with
#: probability ≥ 92 %.
IDENTIFIED_RATIO = 1.5


@dataclasses.dataclass(frozen=True)
class ParameterEstimate:
    """A fitted parameter: its estimate and 95 % interval, in SI units (``unit``).

    name, unit : the parameter (e.g. ``film_half_length``, ``"m"``).
    estimate : the best estimate: the value at the optimum (the least cost the profiles
        found), identified or not.
    lower, upper : the 95 % interval; for ``a`` and ``drag_torque`` a lower end of 0 means
        the interval runs into dry flanks or no drag.
    identified : two-sided, inside the range, narrower than :data:`IDENTIFIED_RATIO` and,
        with a prior, at most half the prior's own 95 % width.
    bound : when not identified, what the data support: ``"lower"`` or ``"upper"`` (one side
        only), ``"interval"`` (two-sided but wide), ``"prior"`` (mostly the prior's), or
        None (neither side).
    would_pin : when not identified, what extra data would pin it
        (:func:`~rattlefit.inference.advice.what_would_pin`); empty otherwise.
    """

    name: str
    unit: str
    estimate: float
    lower: float
    upper: float
    identified: bool
    bound: str | None = None
    would_pin: str = ""

    def as_dict(self) -> dict:
        """The fields as a dict (the result JSON's ``parameters`` entries)."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Estimates:
    """What a fit estimated. P fitted parameters (:attr:`names`), R recordings.

    parameters : name → :class:`ParameterEstimate`: the film half-length(s) (``a`` or
        ``a[lubrication]``), ``drag_torque``, ``viscosity`` (Pa s at the first recording's
        temperature), any squeeze-film groups, then the nuisances.
    names : the P fitted parameters, in the order of :attr:`FittedState.z`
        (``viscosity_scale`` unconverted).
    correlation : (P, P) correlation of the Laplace covariance in z.
    map_params : R dicts of the :class:`~rattlefit.physics.model.RattleParams` at the optimum.
    profile : what set the interval ends: ``threshold`` (Δcost above the optimum's),
        ``monte_carlo_sd`` and, with the roughness allowance, ``roughness_rms``,
        ``realisation_sets`` and ``roughness_sd``.
    profiles : each free parameter's profile, ``(value in SI, Δcost above the optimum's)``
        pairs in increasing value; an interval is where Δcost < ``profile["threshold"]``.
    """

    parameters: dict[str, ParameterEstimate]
    names: list[str]
    correlation: np.ndarray
    map_params: list[dict[str, float]]
    profile: dict[str, float] = dataclasses.field(default_factory=dict)
    profiles: dict[str, list[tuple[float, float]]] = dataclasses.field(default_factory=dict)

    def rattle_params(self, k: int = 0) -> RattleParams:
        """The MAP :class:`RattleParams` of recording ``k``."""
        return RattleParams.from_dict(self.map_params[k])


@dataclasses.dataclass(frozen=True)
class Statistics:
    """How well the model fits, and how the search ended.

    chi2, dof : χ² of the data rows at the optimum (band correlations included) and its
        degrees of freedom (R·F minus the free parameters).
    chi2_recordings : (R,) each recording's χ² at the optimum.
    regime_share : (R,) share of the realisations in the regime each recording is compared
        with; below one half the recording is in a rarer regime than another (empty on the
        learned likelihood).
    n_iterations : optimiser steps over all starts.
    search : how the search ended (:class:`~rattlefit.inference.outcome.SearchEnd`).
    """

    chi2: float
    dof: int
    chi2_recordings: list[float] = dataclasses.field(default_factory=list)
    regime_share: list[float] = dataclasses.field(default_factory=list)
    n_iterations: int = 0
    search: SearchEnd = dataclasses.field(default_factory=SearchEnd)

    @property
    def success(self) -> bool:
        """Every optimiser run ended by its own criterion (none at its step limit)."""
        return self.search.outcome.success

    @property
    def p_value(self) -> float:
        """Probability of a χ² at least this large if the model explained the data within
        their run-to-run spread (χ² with ``dof`` degrees of freedom)."""
        return float(stats.chi2.sf(self.chi2, max(self.dof, 1)))

    @property
    def poor_fit(self) -> bool:
        """True when ``p_value`` < :data:`POOR_FIT_P`: the model's regime nearest the recording
        does not explain it. The intervals are then widened by √(χ²/dof), but they can still
        miss (for instance when the recording's regime is reached by too few realisations near
        its true parameters to be found)."""
        return self.p_value < POOR_FIT_P

    @property
    def poorly_fitted(self) -> list[int]:
        """In a joint fit, the recordings whose own χ² is poor on their share of the degrees
        of freedom (p < :data:`POOR_FIT_P`): where to look first when :attr:`poor_fit`."""
        share = max(self.dof, 1) / max(len(self.chi2_recordings), 1)
        return [
            k for k, c in enumerate(self.chi2_recordings) if stats.chi2.sf(c, share) < POOR_FIT_P
        ]


@dataclasses.dataclass(frozen=True)
class Spectra:
    """The features compared: R arrays (F,) each. The first B of a recording's F features are
    the log10 band PSDs of Δθ* (rad²/Hz), any further ones the drive-cycle-folded statistics
    (``FitOptions.features``).

    measured : the recordings' features.
    fitted : the model's mean features at the optimum.
    sigma : each feature's standard deviation at the optimum.
    band_centers : (B,) band centre frequencies, Hz.
    """

    measured: list[np.ndarray]
    fitted: list[np.ndarray]
    sigma: list[np.ndarray]
    band_centers: np.ndarray

    def bands_of(self, features) -> list[float]:
        """The band part (the first B) of one recording's feature vector, as a list."""
        return np.asarray(features)[: len(self.band_centers)].tolist()


@dataclasses.dataclass(frozen=True)
class Provenance:
    """Where a fit came from.

    recordings : the recordings' paths.
    seed : the fit's seed (``FitOptions.seed``).
    wall_time : seconds the fit took.
    platform : what a seeded result depends on besides its inputs
        (:func:`~rattlefit.reproducibility.platform_info`), captured when the fit ran.
    recordings_sha256 : each recording's counts' SHA-256
        (:func:`~rattlefit.io.recording.counts_sha256`): what a fit read back is matched by.
    likelihood : with ``FitOptions(likelihood="learned")``, how the likelihood was learned
        (simulations, rounds, their wall times and rate) and its check against fresh
        simulations (:mod:`rattlefit.likelihood.check`); empty otherwise.
    """

    recordings: list[str]
    seed: int
    wall_time: float
    platform: dict = dataclasses.field(default_factory=dict, compare=False)
    likelihood: dict = dataclasses.field(default_factory=dict)
    recordings_sha256: list[str] = dataclasses.field(default_factory=list)

    @property
    def recording_names(self) -> list[str]:
        """Each recording's file name, or ``"recording k"`` (from 1) for one made in memory
        (:func:`~rattlefit.simulation.synthetic.synthesize`), which has no file."""
        return [
            PurePath(p).name if p not in (None, "None") else f"recording {k + 1}"
            for k, p in enumerate(self.recordings)
        ]


@dataclasses.dataclass(frozen=True)
class FittedState:
    """What :func:`~rattlefit.sample` and :func:`~rattlefit.diagnose` start from.

    options : the :class:`~rattlefit.problem.options.FitOptions` of the fit.
    z : (P,) the optimum in the unconstrained coordinates.
    covariance_z : (P, P) Laplace covariance in z.
    likelihood : the fit's :class:`~rattlefit.likelihood.protocol.Likelihood`, its noise
        model at the optimum; read back from a fit's document, the synthetic likelihood's
        noise model not yet bound to a problem, or the learned likelihood stored beside it.
    problem : the fit's :class:`~rattlefit.problem.problem.Problem` at the optimum (its
        realisations and band spread, the noise model's ``sigma``); None when the fit did
        not run in this process (:meth:`problem_for` rebuilds it).
    """

    options: FitOptions
    z: np.ndarray
    covariance_z: np.ndarray
    likelihood: Likelihood | None = dataclasses.field(default=None, repr=False, compare=False)
    problem: Problem | None = dataclasses.field(default=None, repr=False, compare=False)

    def problem_for(self, recordings, sigma) -> Problem:
        """The fit's problem, with its band spread ``sigma`` (R arrays (F,)) at the optimum:
        :attr:`problem` when the fit ran in this process, else rebuilt from ``recordings``
        (the fitted ones) and :attr:`options`
        (:func:`~rattlefit.problem.problem.problem_from`)."""
        if self.problem is not None:
            return self.problem
        problem, _, _ = problem_from(recordings, self.options)
        return dataclasses.replace(problem, sigma=jnp.asarray(np.stack(sigma)))

    def likelihood_for(self, recordings, sigma) -> Likelihood:
        """The fit's likelihood bound to its problem (:meth:`problem_for`). Raises
        :class:`~rattlefit.errors.RattlefitError` for a fit that holds none."""
        if self.likelihood is None:
            raise RattlefitError("the fit holds no likelihood (run identify in this process)")
        return self.likelihood.bind(self.problem_for(recordings, sigma))


@dataclasses.dataclass(frozen=True)
class FitResult:
    """What :func:`~rattlefit.inference.identify.identify` returns: the :class:`Estimates`,
    the fit's :class:`Statistics`, the :class:`Spectra` compared, its :class:`Provenance`
    and the :class:`FittedState` that sampling and diagnosis start from. ``to_json`` is the
    ``identify -o`` document."""

    estimates: Estimates
    statistics: Statistics
    spectra: Spectra
    provenance: Provenance
    state: FittedState

    def problem_for(self, recordings) -> Problem:
        """The fit's problem at the optimum (:meth:`FittedState.problem_for` with the fit's
        spread)."""
        return self.state.problem_for(recordings, self.spectra.sigma)

    def likelihood_for(self, recordings) -> Likelihood:
        """The fit's likelihood bound to its problem (:meth:`FittedState.likelihood_for`)."""
        return self.state.likelihood_for(recordings, self.spectra.sigma)

    def to_json(self) -> dict:
        """The ``--output`` document (format :data:`rattlefit.documents.FIT`):
        parameters (SI), fit diagnostics, the spectra (log10 band PSDs of Δθ*, rad²/Hz, per
        recording: measured, fitted mean, σ) and the state sampling and diagnosis start from
        (:func:`state_document`; read back by
        :func:`rattlefit.inference.fit_document.read_fit`)."""
        est, st, sp, pr = self.estimates, self.statistics, self.spectra, self.provenance
        return {
            **FIT.header(),
            "parameters": {k: v.as_dict() for k, v in est.parameters.items()},
            "fit": {
                "chi2": st.chi2,
                "dof": st.dof,
                "reduced_chi2": st.chi2 / max(st.dof, 1),
                "p_value": st.p_value,
                "poor_fit": st.poor_fit,
                "poorly_fitted_recordings": [pr.recordings[k] for k in st.poorly_fitted],
                "chi2_per_recording": st.chi2_recordings,
                "regime_share_per_recording": st.regime_share,
                "iterations": st.n_iterations,
                "success": st.success,
                "search": st.search.to_dict(),
                "below_optimum": below_optimum(est.profiles),
                "seed": pr.seed,
                "platform": pr.platform,  # seeded results depend on it
                "wall_time_s": pr.wall_time,
                "recordings": pr.recordings,
                "profile": est.profile,
                "profiles": {k: [list(p) for p in v] for k, v in est.profiles.items()},
                "correlation": {"names": est.names, "matrix": est.correlation.tolist()},
                "likelihood": pr.likelihood or {"method": "synthetic"},
                "options": self.state.options.to_dict(),  # flat, priors as their specs
            },
            "spectra": {
                "band_centers_hz": np.asarray(sp.band_centers).tolist(),
                "measured": [sp.bands_of(f) for f in sp.measured],
                "fitted": [sp.bands_of(f) for f in sp.fitted],
                "sigma": [sp.bands_of(s) for s in sp.sigma],
            },
            "state": state_document(self),
        }


#: A profile point this far below the optimum's cost is reported (``fit.below_optimum`` in the
#: JSON, the table, the HTML report, the campaign's table): the optimum was not the lowest
#: point the profiles found, and the intervals about it are rough.
BELOW_OPTIMUM = 0.5


def below_optimum(profiles: dict) -> dict | None:
    """How far the lowest profile point lies below the optimum's cost (``depth``, ≥ 0) and
    whose profile it is on (``parameter``), when more than :data:`BELOW_OPTIMUM`; else None.
    ``profiles``: parameter name → (value, Δcost) pairs (:attr:`Estimates.profiles`)."""
    lows = [(min(d for _, d in pts), name) for name, pts in profiles.items() if len(pts)]
    if not lows or min(lows)[0] >= -BELOW_OPTIMUM:
        return None
    low, name = min(lows)
    return {"depth": float(-low), "parameter": name}


#: The noise model's arrays as the document stores them
#: (:class:`~rattlefit.likelihood.noise.NoiseModel`'s fields).
NOISE_ARRAYS = ("sigma", "whiten", "row_scale", "chi2_recordings")


def state_document(result: FitResult) -> dict | None:
    """The document's ``state``: what :func:`read_fit` needs to restore
    :attr:`FitResult.state`; None without a noise model (nothing to start from)."""
    st = result.state
    model = None if st.likelihood is None else st.likelihood.noise
    if model is None:
        return None
    noise = {k: np.asarray(getattr(model, k)).tolist() for k in NOISE_ARRAYS}
    noise["sigma_dof"] = int(model.sigma_dof)
    share = model.regime_share
    noise["regime_share"] = None if share is None else np.asarray(share).tolist()
    return {
        "z": np.asarray(st.z, dtype=float).tolist(),
        "covariance_z": np.asarray(st.covariance_z, dtype=float).tolist(),
        "noise": noise,
        "features": [np.asarray(f, dtype=float).tolist() for f in result.spectra.measured],
        "fitted_features": [np.asarray(f, dtype=float).tolist() for f in result.spectra.fitted],
        "sigma_features": [np.asarray(f, dtype=float).tolist() for f in result.spectra.sigma],
        "map_params": result.estimates.map_params,
        "recordings_sha256": result.provenance.recordings_sha256,
    }


def map_params_of(problem: Problem, z) -> list[dict[str, float]]:
    """Each recording's :class:`~rattlefit.physics.model.RattleParams` at ``z`` as a dict
    (:attr:`Estimates.map_params`)."""
    zeros = jnp.zeros(len(problem.specs))
    return [
        {k: float(v) for k, v in problem.params_for(jnp.asarray(z), i, zeros).as_dict().items()}
        for i in range(problem.n_rec)
    ]


def spectra_of(problem: Problem, fitted, sigma) -> Spectra:
    """The :class:`Spectra` of ``problem``'s recordings: its data, and the model's mean
    ``fitted`` and spread ``sigma`` at the optimum (each (R, F))."""
    return Spectra(
        measured=[np.asarray(d) for d in problem.data],
        fitted=[np.asarray(f) for f in fitted],
        sigma=[np.asarray(s) for s in sigma],
        band_centers=problem.bands.centers,
    )


def provenance_of(rigs, options: FitOptions, wall: float, platform: dict, likelihood=None):
    """The :class:`Provenance` of a fit of ``rigs`` (:class:`~rattlefit.rig.RigSetup`) with
    ``options`` that took ``wall`` seconds on ``platform``."""
    return Provenance(
        recordings=[str(r.recording.path) for r in rigs],
        seed=options.seed,
        wall_time=wall,
        platform=platform,
        likelihood=likelihood or {},
        recordings_sha256=[counts_sha256(r.recording) for r in rigs],
    )


def identified_ratio(name: str) -> float:
    """The widest interval (upper/lower) that counts as identified: :data:`IDENTIFIED_RATIO`,
    cubed for a squeeze-film group (∝ a³ for a short film, :mod:`rattlefit.inference.group`)."""
    return IDENTIFIED_RATIO**3 if name.startswith(MOMENTUM) else IDENTIFIED_RATIO


def estimate(spec: ParameterSpec, z: float, lo_z: float, hi_z: float) -> ParameterEstimate:
    """95 % interval through the transform; one-sided when it runs into the range's end.

    ``identified`` needs a two-sided interval no wider than :func:`identified_ratio` (else
    ``bound="interval"``), and for a parameter with a prior at most half the prior's own 95 %
    width, so that the data, not the prior, pin it down (else ``bound="prior"``, and the
    interval spans the prior's central 95 % too). The estimate is the optimum's value in
    every case. For every parameter that is not a nuisance (``a``, ``drag_torque``, an
    effect's size) the lower end of the range stands for zero (dry flanks, no drag, no
    effect), and a bound that runs into it reads 0.
    """
    value = float(spec.value(z))
    lower, upper = float(spec.value(lo_z)), float(spec.value(hi_z))
    edge = 0.05  # within 5 % of the log range of an end counts as "runs into it"
    u_lo = (math.log(lower) - math.log(spec.lower)) / spec.log_range
    u_hi = (math.log(upper) - math.log(spec.lower)) / spec.log_range
    at_top, at_bottom = u_hi > 1 - edge, u_lo < edge
    floor = spec.lower if spec.nuisance else 0.0

    def result(lo, hi, identified, bound):
        return ParameterEstimate(spec.name, spec.unit, value, lo, hi, identified, bound)

    if at_top and at_bottom:
        return result(floor, spec.upper, False, None)
    if at_top:
        return result(lower, spec.upper, False, "lower")
    if at_bottom:
        return result(floor, upper, False, "upper")
    width = math.log(upper / lower)
    if spec.log_sd is not None and width > Z95 * spec.log_sd:
        # the data barely narrow it, so they cannot move it far from the prior either: an
        # interval shifted off the prior's centre comes from the rough cost or an unfinished
        # optimum, and the prior's own 95 % interval stays in
        reach = math.exp(Z95 * spec.log_sd)
        lower = max(min(lower, spec.center / reach), spec.lower)
        upper = min(max(upper, spec.center * reach), spec.upper)
        return result(lower, upper, False, "prior")
    if width <= math.log(identified_ratio(spec.name)):
        return result(lower, upper, True, None)
    return result(lower, upper, False, "interval")


#: The fitted coordinates the results report under another quantity's name: the viscosity
#: factor is reported as the viscosity (Pa s, at the first recording's temperature).
REPORTED_AS = {VISCOSITY_SCALE: VISCOSITY}


def reported_name(name: str) -> str:
    """The name a fitted coordinate ``name`` is reported under (tables, JSON, plots)."""
    return REPORTED_AS.get(name, name)


def estimates_of(
    problem: Problem, z, z_lo, z_hi, lubrications: Sequence[str] = ()
) -> dict[str, ParameterEstimate]:
    """Every parameter's :class:`ParameterEstimate` from the optimum ``z`` and its interval
    ends in z: the film half-lengths, ``drag_torque`` and ``viscosity`` first (the viscosity
    factor converted to Pa s at the first recording's temperature), then the nuisances; each
    that is not identified says what would pin it, given the recordings' ``lubrications``."""
    found = {s.name: estimate(s, z[i], z_lo[i], z_hi[i]) for i, s in enumerate(problem.specs)}
    vs = found.pop(VISCOSITY_SCALE)
    mu0 = float(np.asarray(problem.viscosities)[0])
    found[reported_name(VISCOSITY_SCALE)] = ParameterEstimate(
        reported_name(VISCOSITY_SCALE),
        "Pa s",
        vs.estimate * mu0,
        vs.lower * mu0,
        vs.upper * mu0,
        vs.identified,
        vs.bound,
    )
    found = {
        k: dataclasses.replace(p, would_pin=what_would_pin(k, list(lubrications), p.identified))
        for k, p in found.items()
    }
    first = [*dict.fromkeys(problem.films), DRAG_TORQUE, VISCOSITY]
    ordered = {k: found[k] for k in first}
    ordered.update({k: v for k, v in found.items() if k not in ordered})
    return ordered


def with_groups(
    found: dict[str, ParameterEstimate], groups: dict[str, ParameterEstimate]
) -> dict[str, ParameterEstimate]:
    """``found`` (:func:`estimates_of`) with the squeeze-film groups after the viscosity."""
    names = list(found)
    cut = names.index(VISCOSITY) + 1
    return {
        **{k: found[k] for k in names[:cut]},
        **groups,
        **{k: found[k] for k in names[cut:]},
    }


def profiles_in_si(problem: Problem, profiles: dict) -> dict[str, list[tuple[float, float]]]:
    """Profiles ``{index: {t: (Δcost, z)}}`` in z as ``{name: [(value, Δcost), …]}`` in SI
    units, in increasing value (see :attr:`FitResult.profiles`)."""
    out = {}
    for i, prof in profiles.items():
        spec = problem.specs[i]
        out[spec.name] = [(float(spec.value(t)), float(prof[t][0])) for t in sorted(prof)]
    return out

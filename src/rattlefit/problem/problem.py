"""The fit's problem: recordings, parameters and realisations, and the batched feature map.

A :class:`Problem` holds everything a simulation of the fit needs, stacked over recordings:
each recording's model and drive, the seeded realisations (release states, dither offsets,
encoder count phases), the measured features and their current band spread. It is a pytree,
so the feature map compiles once for the whole fit.

:func:`problem_from` is the one definition of a fit's realisations: they are the first
draws of ``numpy.random.default_rng(options.seed)``. :func:`~rattlefit.inference.identify.identify`
continues with the generator it returns, and :mod:`~rattlefit.diagnosis` and
:mod:`~rattlefit.inference.posterior` rebuild the same problem from the recordings and the
fit's options alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import RattlefitError
from ..features.ensemble import regime_weights, weighted_mean
from ..features.folded import cycle_phase, folded_statistics
from ..features.spectra import spectral_features
from ..io.recording import Recording
from ..physics.model import (
    Effect,
    RattleModel,
    film_for_squeeze_momentum,
    share_stiffness_tables,
)
from ..quantities import MIN_FILM, VISCOSITY_SCALE
from ..rig import RigSetup, setup
from ..simulation.solve import (
    absolute_tolerances,
    quantised_relative_motion,
    solve_rows,
    static_options,
)
from ..util import array_namespace
from .options import FitOptions
from .parameters import VISCOSITY, default_specs, films_of, momentum_name
from .space import ParameterSpace


def _stack(trees):
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *trees)


class Problem(eqx.Module):
    """Recordings, parameters, realisations and the batched feature map (a pytree).

    Arrays are stacked over the R recordings, M realisations, P parameters and B bands.
    Build one with :func:`problem_from` (or :func:`build_problem`); ``sigma`` starts at ones
    and is replaced (``eqx.tree_at``) as the fit estimates the band spread.
    """

    models: RattleModel  # stacked over recordings
    drives: object  # stacked Drive
    y0: jax.Array  # (R, M, 2) release states
    dither: jax.Array  # (M, P) fixed log-offsets of each realisation's parameters
    encoder_phase: jax.Array  # (M, 2) each realisation's encoder count phases
    counts_per_rev: jax.Array  # (R,)
    floors: jax.Array  # (R,)
    viscosities: jax.Array  # (R,) catalogue μ at each recording's temperature
    data: jax.Array  # (R, F) measured features: B bands, then any folded statistics
    sigma: jax.Array  # (R, F)
    specs: tuple = eqx.field(static=True)
    bands: object = eqx.field(static=True)
    quantise: bool = eqx.field(static=True)
    regime_threshold: float | None = eqx.field(static=True)
    recording_regime: bool = eqx.field(static=True)  # FitOptions.regime == "recording"
    static: tuple = eqx.field(static=True)  # simulator options as sorted items
    films: tuple = eqx.field(static=True)  # (R,) each recording's film half-length's name
    #: extra effects whose fitted fields are specs named "<effect>.<field>" (diagnose); one
    #: compiled program holds them all, each at its absent end unless its fields move
    effects: tuple[Effect, ...] = ()
    #: what each simulation is measured by: ``"bands"``, the log band PSDs, or
    #: ``"bands+folded"``, those followed by the drive-cycle-folded statistics of
    #: :mod:`rattlefit.features.folded` (``FitOptions.features``; diagnose's drive-cycle
    #: comparison measures its fresh realisations so too); :attr:`data` holds the same
    statistics: str = eqx.field(static=True, default="bands")

    @property
    def n_rec(self) -> int:
        return self.y0.shape[0]

    @property
    def n_bands(self) -> int:
        """B, the number of band features: the first B of every feature vector."""
        return len(self.bands.centers)

    @property
    def space(self) -> ParameterSpace:
        """The fitted parameters (:attr:`specs`, :attr:`films`) as a
        :class:`~rattlefit.problem.space.ParameterSpace`."""
        return ParameterSpace(self.specs, self.films)

    def index(self, name: str) -> int:
        """The index of parameter ``name`` in :attr:`specs`."""
        return self.space.index(name)

    def film_of_group(self, values: dict, film: str):
        """The half-length of ``film`` (m) whose squeeze momentum
        (:func:`~rattlefit.physics.model.squeeze_momentum`, on the film's first recording's
        flanks and viscosity) is ``values``' group of it, at ``values``' viscosity factor and
        ``h_min`` (parameter name → value)."""
        r = self.films.index(film)
        return film_for_squeeze_momentum(
            values[momentum_name(film)],
            values[VISCOSITY_SCALE] * self.viscosities[r],
            values[MIN_FILM],
            self.models.curvature_radius[r],
            self.models.axial_width[r],
        )

    def params_for(self, z, r, dither):
        """RattleParams of recording r from the unconstrained vector z (log-dithered). A film
        whose coordinate is its squeeze-film group (:mod:`rattlefit.inference.group`) gets
        the ``a`` of that group at the undithered viscosity and ``h_min``
        (:meth:`film_of_group`), dithered by the group's column: each realisation is the
        same as with the film's own coordinate."""
        space = self.space
        raw = space.values(z)
        v = {s.name: raw[s.name] * jnp.exp(dither[i]) for i, s in enumerate(self.specs)}
        for film, group in space.group_names().items():
            # the film's coordinate is its squeeze-film group
            v[film] = self.film_of_group(raw, film) * jnp.exp(dither[space.index(group)])
        return space.rattle_params(v, r, self.viscosities)

    def effects_at(self, z) -> tuple[Effect, ...]:
        """:attr:`effects` with their fitted fields set from ``z``."""
        out = []
        for effect in self.effects:
            prefix = effect.name + "."
            values = {
                s.name[len(prefix) :]: s.value(z[i])
                for i, s in enumerate(self.specs)
                if s.name.startswith(prefix)
            }
            out.append(effect.replace(**values) if values else effect)
        return tuple(out)

    def rows(self, zs, y0=None, realisations=None):
        """One simulation per row for each point of ``zs`` (K, P), recording and realisation.

        Returns ``(z, recording, release state, dither, encoder phase)`` with K·R·M rows,
        ordered point, recording, realisation; ``y0`` (R, M, 2) replaces the problem's release
        states. ``realisations`` (indices into the M) keeps only those, each exactly as in the
        full set (its release state, its dither centred over all M, its encoder phase), so
        that a point's realisations can be simulated in parts (:class:`ProfileCosts`).
        """
        xp = array_namespace(zs, self.y0)  # numpy outside a trace: nothing to compile
        y0 = xp.asarray(self.y0 if y0 is None else y0)
        k, m = zs.shape[0], y0.shape[1]
        idx = np.arange(m) if realisations is None else np.asarray(realisations)
        n = idx.shape[0]
        return (
            xp.repeat(xp.asarray(zs), self.n_rec * n, axis=0),
            xp.tile(xp.repeat(xp.arange(self.n_rec), n), k),
            xp.tile(y0[:, idx].reshape(-1, 2), (k, 1)),
            xp.tile(self._dither(m, xp)[idx], (k * self.n_rec, 1)),
            xp.tile(xp.asarray(self.encoder_phase)[:m][idx], (k * self.n_rec, 1)),
        )

    def _dither(self, m, xp=np):
        """The first ``m`` realisations' log-offsets (m, P), centred: their mean is zero, so
        that the dither smooths the mean features without shifting them."""
        d = xp.asarray(self.dither)[:m]
        return d - d.mean(axis=0)

    def dither_offsets(self, m) -> np.ndarray:
        """The dithered columns of :meth:`_dither` (m, q), for
        :func:`~rattlefit.features.ensemble.chaotic_part`."""
        d = self._dither(m)
        return d[:, np.any(d != 0, axis=0)]

    def features_of_rows(self, rows):
        """Features of every row (see :meth:`rows`): (N, B).

        The rows are solved in one lockstep batch on one device
        (:func:`~rattlefit.simulation.solve.solve_rows`;
        :func:`~rattlefit.problem.forward.evaluate_rows` spreads blocks of rows over the
        devices); every row has its own recording's model and drive, its parameters and its
        release state.
        """
        opts = dict(self.static)
        rate = opts["sample_rate"]
        # each row reads its recording's stiffness table out of the shared stack (a copy per
        # row would be read from memory at every vector-field call: 25–30 % slower)
        untabled, opts["stiffness_tables"] = share_stiffness_tables(self.models)

        def row_inputs(z, r, d):
            model = jax.tree_util.tree_map(lambda x: x[r], untabled)
            drive = jax.tree_util.tree_map(lambda x: x[r], self.drives)
            if self.effects:
                model = model.with_effects(*self.effects_at(z))
            return model, self.params_for(z, r, d), drive

        def measure(sol, model, r, phase):
            if self.quantise:  # read through the rig's encoders (see FitOptions.quantisation)
                motion = quantised_relative_motion(
                    sol, model, counts_per_rev=self.counts_per_rev[r], phase=phase
                )
            else:
                motion = sol.relative_motion
            floor = 0.0 if self.quantise else self.floors[r]
            f = spectral_features(motion, self.bands, noise_floor=floor)
            if self.statistics == "bands+folded":
                drive = jax.tree_util.tree_map(lambda x: x[r], self.drives)
                phase = cycle_phase(drive, motion.shape[-1], rate)
                f = jnp.concatenate([f, folded_statistics(motion, phase)])
            # a failed solve gives a far-off, finite feature vector: the step is rejected
            return jnp.where(sol.result == 0, f, -30.0)

        def block(rows):
            z, r, y0, d, phase = rows
            models, params, drives = jax.vmap(row_inputs)(z, r, d)
            sol = solve_rows(models, params, drives, y0, **opts)
            return jax.vmap(measure)(sol, models, r, phase)

        return block(rows)

    def regime_target(self):
        """The band features whose regime the ensemble statistics describe
        (``FitOptions.regime``): the recordings' (R, B), or None for the common regime."""
        return self.data[..., : self.n_bands] if self.recording_regime else None

    def mean_of(self, features):
        """Mean features of the realisations (second-last axis) in the regime kept: the
        recording's own (:func:`~rattlefit.features.ensemble.regime_weights`), or the common
        one; the regimes are told apart by the band features."""
        f = array_namespace(features, self.data).asarray(features)
        return weighted_mean(f, self.mean_weights(f))

    def mean_weights(self, features):
        """The weights (..., M) of :meth:`mean_of`: 1 for the realisations of features
        ``features`` (..., M, F) whose bands (the first B) are in the regime kept, 0 for the
        others."""
        bands = features[..., : self.n_bands]
        return regime_weights(bands, self.regime_threshold, target=self.regime_target())

    def prior_rows(self, z):
        """The residual's prior rows at ``z``: ``(log v − log center) / log_sd`` of every
        parameter with a prior."""
        xp = array_namespace(z)
        rows = [
            (xp.log(s.value(z[i])) - math.log(s.center)) / s.log_sd
            for i, s in enumerate(self.specs)
            if s.log_sd is not None
        ]
        return xp.stack(rows) if rows else xp.zeros((0,))

    def prior_jacobian(self, z):
        """d :meth:`prior_rows` / dz (n_prior, P): each row the prior's parameter's
        ``dlog_dz / log_sd``."""
        xp = array_namespace(z)
        eye = xp.eye(len(self.specs))
        rows = [
            eye[i] * (s.dlog_dz(z[i]) / s.log_sd)
            for i, s in enumerate(self.specs)
            if s.log_sd is not None
        ]
        return xp.stack(rows) if rows else xp.zeros((0, len(self.specs)))

    def data_rows(self, mean_features):
        """The residual's data rows ``(data − mean) / σ`` (R·B,)."""
        xp = array_namespace(mean_features, self.data, self.sigma)
        return ((xp.asarray(self.data) - mean_features) / xp.asarray(self.sigma)).reshape(-1)

    def fd_steps(self, z):
        """Steps in z that change each parameter's log by its ``fd_log_step``."""
        xp = array_namespace(z)
        return xp.stack([s.fd_log_step / s.dlog_dz(z[i]) for i, s in enumerate(self.specs)])


def problem_from(
    recordings: Sequence[Recording], options: FitOptions
) -> tuple[Problem, list[RigSetup], np.random.Generator]:
    """The problem of a fit of ``recordings`` with ``options``, its rigs, and the seeded
    generator after the problem's draws (which the fit continues with).

    The realisations are the first draws of ``numpy.random.default_rng(options.seed)``, so
    the same recordings and options give the same problem wherever it is rebuilt.
    """
    rng = np.random.default_rng(options.seed)
    problem, rigs = build_problem(recordings, options, rng)
    return problem, rigs, rng


def check_joint(rigs: Sequence[RigSetup]) -> None:
    """Raise :class:`~rattlefit.errors.RattlefitError` unless ``rigs`` share one gear pair
    and one sample rate, naming the file and field that differ."""
    first = rigs[0]
    for rig in rigs[1:]:
        gp0, gp = first.recording.gear_pair, rig.recording.gear_pair
        if (gp0.teeth_driving, gp0.teeth_driven) != (gp.teeth_driving, gp.teeth_driven):
            raise RattlefitError(
                f"{rig.recording.path}: /gear_pair: a joint fit needs one gear pair, but this "
                f"file has z = {gp.teeth_driving}/{gp.teeth_driven} and "
                f"{first.recording.path} has z = {gp0.teeth_driving}/{gp0.teeth_driven}"
            )
        if rig.sample_rate != first.sample_rate:
            raise RattlefitError(
                f"{rig.recording.path}: /encoders@sample_rate_hz: a joint fit needs one "
                f"sample rate, got {rig.sample_rate} and {first.sample_rate} Hz"
            )


def build_problem(
    recordings: Sequence[Recording], options: FitOptions, rng: np.random.Generator
) -> tuple[Problem, list[RigSetup]]:
    """The :class:`Problem` of ``recordings`` and its rigs, drawing the realisations (release
    states, then dither offsets and encoder phases) from ``rng``.

    Raises :class:`~rattlefit.errors.RattlefitError` when the recordings cannot be fitted
    jointly or ``options.priors`` names a parameter this fit does not have.
    """
    rigs = [setup(r, drive=options.drive) for r in recordings]
    check_joint(rigs)
    first = rigs[0]
    n = min(r.recording.n_samples for r in rigs)
    duration = n / first.sample_rate
    m = options.n_realisations
    y0 = np.zeros((len(rigs), m, 2))
    for k, rig in enumerate(rigs):
        c = 0.5 * rig.geometry.backlash
        y0[k, :, 0] = rng.uniform(-0.9 * c, 0.9 * c, size=m)
    data = []
    for rig in rigs:
        rm = rig.recording.relative_motion[:n]
        f = np.asarray(spectral_features(rm, rig.bands))
        if options.features == "bands+folded":
            f = np.concatenate([f, rig.folded(n)])
        data.append(f)
    specs = (
        ParameterSpace(default_specs(rigs, options.priors))
        .extended(*options.extra_parameters)
        .specs
    )
    unused = sorted(set(options.priors) - {s.name for s in specs} - {VISCOSITY})
    if unused:  # e.g. "a" in a fit across lubrications, or a backlash beyond the files
        raise RattlefitError(
            f"FitOptions.priors: {', '.join(map(repr, unused))} is not a parameter of this fit "
            f"(its parameters: {', '.join(s.name for s in specs)})"
        )
    n_dither = max(m, options.n_noise_realisations, options.n_covariance_realisations)
    films = films_of(rigs)
    dither, encoder_phase = dither_draws(specs, n_dither, options.dither, rng)
    static = tuple(
        sorted(
            static_options(
                duration,
                first.sample_rate,
                options.burn_in,
                options.rtol,
                absolute_tolerances(
                    options.rtol, [r.recording.operating.lubrication for r in rigs]
                ),
                None,  # the step budget scales with the simulated time (step_budget)
                "forward",
            ).items()
        )
    )
    problem = Problem(
        models=_stack([r.model for r in rigs]),
        drives=_stack([r.drive for r in rigs]),
        y0=jnp.asarray(y0),
        dither=jnp.asarray(dither),
        encoder_phase=jnp.asarray(encoder_phase),
        counts_per_rev=jnp.asarray([float(r.recording.counts_per_rev) for r in rigs]),
        floors=jnp.asarray([r.noise_floor for r in rigs]),
        viscosities=jnp.asarray([r.viscosity for r in rigs]),
        data=jnp.asarray(np.stack(data)),
        sigma=jnp.asarray(np.ones((len(rigs), data[0].size))),
        specs=specs,
        bands=first.bands,
        quantise=options.quantisation == "encoders",
        regime_threshold=options.regime_threshold,
        recording_regime=options.regime == "recording",
        static=static,
        films=films,
        statistics=options.features,
    )
    return problem, rigs


def dither_draws(specs, n: int, dither: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """Each of ``n`` realisations' log-offsets of the parameters, (n, P) — ``dither`` × each
    spec's own weight (:attr:`~rattlefit.problem.parameters.ParameterSpec.dither`: the films
    and the drag torque 1, the viscosity half that, the nuisances none) × N(0, 1) — and its
    encoder count phases, (n, 2), uniform in [0, 1)."""
    scale = np.array([sp.dither or 0.0 for sp in specs])
    offsets = rng.normal(size=(n, len(specs))) * scale * dither
    return offsets, rng.uniform(size=(n, 2))


def redrawn(problem: Problem, dither: float, rng, n: int | None = None) -> Problem:
    """``problem`` with its realisations' dither (``dither`` × N(0, 1) on the dithered
    parameters, :func:`dither_draws`) and encoder phases drawn afresh from ``rng``, for ``n``
    realisations (default: as many as it has): an independent set of realisation settings
    (with fresh release states, an independent set of realisations)."""
    n = problem.dither.shape[0] if n is None else n
    dither, phases = dither_draws(problem.specs, n, dither, rng)
    return eqx.tree_at(
        lambda q: (q.dither, q.encoder_phase), problem, (jnp.asarray(dither), jnp.asarray(phases))
    )


def release_states(problem: Problem, z, n: int, rng) -> np.ndarray:
    """``n`` seeded release states per recording, at rest across ±90 % of the gap: (R, n, 2)."""
    c = 0.5 * np.asarray(
        [float(s.value(z[i])) for i, s in enumerate(problem.specs) if s.name.startswith("backlash")]
    )
    y0 = np.zeros((problem.n_rec, n, 2))
    y0[:, :, 0] = rng.uniform(-0.9, 0.9, size=(problem.n_rec, n)) * c[:, None]
    return y0

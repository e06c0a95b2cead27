"""Test planning: which extra recording would narrow the parameters most.

At the fitted point, each candidate recording (the same test run longer, another centre
distance, fluctuation, frequency or lubrication) is simulated and its Fisher information about
the film half-lengths, the drag torque and the nuisances is estimated from realisations
(:func:`~rattlefit.likelihood.information.simulated_information`: ``F = Dᵀ C⁻¹ D``, ``D``
by central differences at ``e^{±δ}``, ``C`` the chaotic spread, floored as in the fit, less
the bias the Monte Carlo noise of ``D`` adds). The fitted recordings' information is their
likelihood's own (:meth:`~rattlefit.likelihood.protocol.Likelihood.information`: simulated for
the synthetic likelihood, from the learned mean and covariance for the learned one).
Information from independent recordings adds, so the prediction for "this fit plus a
candidate" is the sum of the fitted recordings' information, the candidate's and the priors'.
Each parameter's predicted 95 % interval factor is ``exp(2 · 1.96 · sd)``, sd from the
inverse.

This is a local, Gaussian prediction at the fitted point: it ranks candidates and says how much
they could narrow an interval, while the profile intervals of an actual fit are wider where
the cost is flat or rough. The backlashes are held at their measured values.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from ..confidence import Z95
from ..io.recording import Recording
from ..likelihood.information import (
    SIMULATED_REALISATIONS,
    SIMULATED_STEP,
    simulated_information,
)
from ..physics.geometry import GearGeometry, backlash_from_center_distance
from ..physics.model import RattleParams
from ..problem.options import FitOptions
from ..problem.problem import build_problem
from ..quantities import DRAG_TORQUE, FILM
from ..simulation.synthetic import synthesize
from .result import FitResult

#: How much longer the "longer run" candidate is.
LONGER = 10
#: Centre-distance changes tried, mm.
CENTER_STEPS_MM = (-0.6, -0.2, 0.4)
#: Film half-length assumed for a lubrication the fit has no film of, m.
TYPICAL_FILM = {"boundary": 0.085e-3, "oil_jet": 1.0e-3}


@dataclasses.dataclass(frozen=True)
class Planned:
    """One row of :func:`suggest`'s table.

    label : what is recorded in addition ("now" for the fit's own recordings alone).
    factors : parameter name → predicted 95 % interval factor (upper/lower), ``inf`` where
        the information is nil.
    """

    label: str
    factors: dict[str, float]

    def to_json(self) -> dict:
        """``{"recording": label, "factors": {name: factor or None where unbounded}}``."""
        return {
            "recording": self.label,
            "factors": {k: (v if math.isfinite(v) else None) for k, v in self.factors.items()},
        }


def parameter_names(problem) -> list[str]:
    """The parameters the information is about: each film half-length by its lubrication
    (``a[boundary]``), then the drag torque and the nuisances; the backlashes are held."""
    return [s.name for s in problem.specs if not s.name.startswith("backlash")]


def recording_information(
    recording: Recording,
    values: dict[str, float],
    options: FitOptions,
    *,
    n: int = SIMULATED_REALISATIONS,
    step: float = SIMULATED_STEP,
    rng: np.random.Generator,
) -> tuple[list[str], np.ndarray]:
    """The Fisher information (P, P) of one recording like ``recording`` at the parameter
    ``values`` (by the names of :func:`parameter_names`, the film as ``a``), and the names of
    its P parameters; per unit log of each."""
    opts = options.replace(
        regime="common", n_covariance_realisations=max(n, options.n_covariance_realisations)
    )
    problem, _ = build_problem([recording], opts, rng)
    names = parameter_names(problem)
    # the backlash at its measured value, everything else at the fitted one
    z0 = np.array(
        [
            s.z_of(s.center if s.name.startswith("backlash") else values[s.name])
            for s in problem.specs
        ]
    )
    info = simulated_information(
        problem, z0, names, n=n, step=step, floor=options.sigma_floor, rng=rng
    )
    return names, info


#: Information per unit log² below which a direction counts as uninformed (an sd of 10⁴ in
#: log): :func:`interval_factors` adds it to the diagonal, so that a direction nothing
#: informs gets an unbounded interval rather than the zero variance a pseudo-inverse gives it.
NIL_INFORMATION = 1e-8


def interval_factors(names: Sequence[str], info: np.ndarray) -> dict[str, float]:
    """Predicted 95 % interval factor of each parameter from the total information (P, P),
    positive semi-definite: ``exp(2 · 1.96 · sd)``, sd from the inverse of ``info`` plus
    :data:`NIL_INFORMATION` on its diagonal; ``inf`` where the factor would exceed ``e^50``
    (a parameter that moves along a direction nothing informs). Adding information never
    widens a factor."""
    info = np.asarray(info, dtype=float)
    cov = np.linalg.inv(info + NIL_INFORMATION * np.eye(len(names)))
    out = {}
    for j, name in enumerate(names):
        log_width = 2 * Z95 * math.sqrt(max(cov[j, j], 0.0))
        out[name] = math.exp(log_width) if log_width < 50 else math.inf
    return out


def candidates(recording: Recording) -> list[tuple[str, Recording | None, dict]]:
    """Candidate extra tests around ``recording``: ``(label, template recording or None for a
    longer run, changes)``; each template is re-simulated at the fitted point."""
    op, spec = recording.operating, recording.gear_pair
    out: list[tuple[str, Recording | None, dict]] = [
        (f"the same test, {LONGER}× as long ({LONGER * recording.duration:.0f} s)", None, {})
    ]
    for dcd in CENTER_STEPS_MM:
        out.append(
            (f"centre distance {spec.center_distance_mm + dcd:.1f} mm", recording, {"cd": dcd})
        )
    pct = op.drive_speed_amplitude_rad_s / op.drive_mean_speed_rad_s
    for scale in (0.5, 2.0):
        if pct * scale < 0.5:
            out.append((f"fluctuation {100 * pct * scale:.0f} %", recording, {"amp": scale}))
    for scale in (0.5, 2.0):
        f = op.drive_frequency_hz * scale
        out.append((f"drive frequency {f:g} Hz", recording, {"freq": scale}))
    for lub in ("boundary", "oil_jet"):
        if lub != op.lubrication and op.lubrication != "dry":
            out.append((f"an {lub.replace('_', '-')} companion", recording, {"lub": lub}))
    return out


def planned_recording(recording: Recording, changes: dict, params: RattleParams, seed: int):
    """A recording like ``recording`` with ``changes`` (see :func:`candidates`), simulated at
    ``params`` (the film of a new lubrication from :data:`TYPICAL_FILM`); None where the
    change makes an impossible gear pair."""
    op = recording.operating
    geometry = GearGeometry.from_spec(recording.gear_pair)
    if "cd" in changes:
        base = backlash_from_center_distance(geometry)
        try:
            moved = geometry.replace(
                center_distance=geometry.center_distance + changes["cd"] * 1e-3
            )
        except ValueError:
            return None
        jump = backlash_from_center_distance(moved) - base
        geometry = moved.replace(angular_backlash=geometry.angular_backlash + jump)
        params = dataclasses.replace(params, backlash=geometry.backlash)
    if "amp" in changes:
        op = dataclasses.replace(
            op, drive_speed_amplitude_rad_s=op.drive_speed_amplitude_rad_s * changes["amp"]
        )
    if "freq" in changes:
        op = dataclasses.replace(op, drive_frequency_hz=op.drive_frequency_hz * changes["freq"])
    if "lub" in changes:
        op = dataclasses.replace(op, lubrication=changes["lub"])
        params = dataclasses.replace(params, film_half_length=TYPICAL_FILM[changes["lub"]])
    rec, _ = synthesize(
        geometry, op, params, oil=recording.oil, duration=recording.duration, seed=seed
    )
    return rec


def suggest(
    fit: FitResult,
    recordings: Sequence[Recording],
    *,
    n: int = SIMULATED_REALISATIONS,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> list[Planned]:
    """What one more recording would do to the intervals of ``fit`` (of ``recordings``):
    the predicted 95 % factors now, then with each candidate of :func:`candidates` (around
    the first recording) added, the narrowest drag-torque interval first. Film half-lengths
    are named by lubrication (``a[boundary]``). Seeded by ``seed``; ``progress`` receives a
    line per recording simulated."""
    say = progress or (lambda msg: None)
    rng = np.random.default_rng(seed)
    problem = fit.problem_for(recordings)
    values = {s.name: float(s.value(fit.state.z[i])) for i, s in enumerate(problem.specs)}
    films = {
        r.operating.lubrication: values[f] for r, f in zip(recordings, problem.films, strict=True)
    }
    say("the information of the fitted recordings …")
    names, now = fitted_information(fit, problem, recordings, rng)
    rows = [Planned("now", interval_factors(names, now + prior_information(problem, names)))]
    params = fit.estimates.rattle_params(0)
    for label, template, changes in candidates(recordings[0]):
        if template is None:
            more_names, more = names, (LONGER - 1) * now / len(recordings)
        else:
            rec = planned_recording(template, changes, params, int(rng.integers(1 << 30)))
            if rec is None:
                continue
            say(f"simulating the information of {label} …")
            more_names, more = film_information(rec, values, films, fit.state.options, n, rng)
        union, total = add_information(names, now, more_names, more)
        rows.append(
            Planned(label, interval_factors(union, total + prior_information(problem, union)))
        )
    rows[1:] = sorted(rows[1:], key=lambda r: r.factors.get(DRAG_TORQUE, math.inf))
    return rows


def fitted_information(fit: FitResult, problem, recordings, rng) -> tuple[list[str], np.ndarray]:
    """The fitted recordings' information (P, P) at ``fit``'s optimum and its parameters'
    names (:func:`parameter_names`, the films named by lubrication), from the fit's own
    likelihood (:meth:`~rattlefit.likelihood.protocol.Likelihood.information`)."""
    names = parameter_names(problem)
    likelihood = fit.state.likelihood_for(recordings, fit.spectra.sigma)
    info = likelihood.information(np.asarray(fit.state.z, dtype=float), names, rng=rng)
    lubrication = dict(
        zip(problem.films, (r.operating.lubrication for r in recordings), strict=True)
    )
    return [f"{FILM}[{lubrication[n]}]" if n in lubrication else n for n in names], info


def plan_document(rows: Sequence[Planned], *, seed: int, realisations: int) -> dict:
    """:func:`suggest`'s ``rows`` as the fit document's ``suggest``: the ``seed`` and
    ``realisations`` per point it used, and each row's :meth:`Planned.to_json`."""
    return {
        "seed": seed,
        "realisations": realisations,
        "candidates": [r.to_json() for r in rows],
    }


def film_information(rec: Recording, values: dict, films: dict, options, n: int, rng):
    """:func:`recording_information` of ``rec`` at the fitted ``values``, its film named by
    its lubrication (the fitted film of that lubrication, else :data:`TYPICAL_FILM`)."""
    lub = rec.operating.lubrication
    at = values | {FILM: films.get(lub, TYPICAL_FILM.get(lub, 0.0))}
    local, info = recording_information(rec, at, options, n=n, rng=rng)
    return [f"{FILM}[{lub}]" if k == FILM else k for k in local], info


def add_information(names, info, more_names, more):
    """``info`` over ``names`` plus ``more`` over ``more_names``, on the union of the names."""
    union = list(names) + [k for k in more_names if k not in names]
    out = np.zeros((len(union), len(union)))
    for src_names, src in ((names, info), (more_names, more)):
        idx = [union.index(k) for k in src_names]
        out[np.ix_(idx, idx)] += src
    return union, out


def prior_information(problem, names: Sequence[str]) -> np.ndarray:
    """The priors' information (diagonal, per unit log) of ``problem``'s specs on ``names``."""
    sd = {s.name: s.log_sd for s in problem.specs if s.log_sd is not None}
    return np.diag([1.0 / sd[k] ** 2 if k in sd else 0.0 for k in names])

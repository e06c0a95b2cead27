"""Profile-likelihood intervals of a simulated, noisy cost.

:func:`~rattlefit.inference.identify.identify` reports each free parameter's 95 % interval from
its cost profile: the cost with the parameter held at a value and the others re-optimised, against a
threshold (:func:`profile_threshold`: χ²₁'s 95 % quantile plus an allowance for the Monte
Carlo noise and chaotic roughness of a difference of two costs). The cost is a synthetic
likelihood of simulated realisations, so every evaluation is a batch of simulations, and
the stages here are built to spend few of them:

1. :func:`profile_scan`: each free parameter over its whole range and near the optimum, the
   others set two ways (:func:`profile_guesses`), all in one batch.
2. :func:`bisect_profile_ends`: each interval end's bracket narrowed by bisection.
3. :func:`polish_profile`: the other parameters re-optimised (damped Gauss–Newton on finite
   differences) at the values that decide the ends.
4. :func:`continue_profiles`: each profile followed past its ends by predictor–corrector
   continuation, where its valley bends away from the scan's straight paths.

A profile is a dict ``{t: (Δcost, z)}`` of values ``t`` (in the unconstrained coordinate z
of :class:`~rattlefit.problem.parameters.ParameterSpec`) to the cost above the optimum's and the
point that attained it; :func:`profile_interval` reads its interval and the brackets of its
ends. Costs come from callables that map points (N, P) to Δcosts (N,): :class:`ProfileCosts`
in a fit, a closed form in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ...confidence import CHI2_1_95, Z95_ONE_SIDED
from ...problem.parameters import Z_END

#: More guesses for the other parameters at a profile value: ``valley(i, near, t)`` returns
#: points with parameter i at t where the model's physics puts the valley of the cost that
#: passes through ``near`` (:func:`profile_guesses`).
Valley = Callable[[int, np.ndarray, float], list[np.ndarray]]


#: Where :func:`profile_scan` evaluates each free parameter: fractions of its log range …
SCAN_FRACTIONS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
#: … and offsets from the optimum in Laplace standard deviations.
SCAN_OFFSETS = (-2.0, -1.0, 1.0, 2.0)
#: Largest difference (in z) between the scan's two guesses that still counts as one point.
SCAN_SAME = 0.05
#: :func:`bisect_profile_ends` narrows each end's bracket to this fraction of its interval …
PROFILE_RESOLUTION = 0.15
#: … but not below this step in z.
PROFILE_MIN_STEP = 0.01
#: The first step of a profile continuation past an interval's end, in log of the
#: parameter (:func:`continue_profiles`).
CONTINUATION_LOG_STEP = 0.15
#: The factor by which a continuation's step grows after a round that stayed inside.
CONTINUATION_GROWTH = 1.5
#: Steps (in z) from the optimum at which ``FitOptions.profile_roughness`` measures the cost.
PROFILE_JITTER = (-0.02, -0.01, 0.01, 0.02)
#: :class:`ProfileCosts` completes a profile point's realisations only where its screened
#: Δcost is below this multiple of the profile threshold …
SCREEN_FACTOR = 10.0
#: … or below the threshold plus this many rms screened Δcosts near the optimum.
SCREEN_SDS = 6.0


def profile_threshold(noise_sd: float, jitter_costs: np.ndarray | None = None) -> float:
    """The Δcost below which a profile value is inside the 95 % interval.

    χ²₁'s 95 % quantile, plus a one-sided 95 % allowance (1.645 standard deviations) for the
    noise of a difference of two costs: ``noise_sd``, the analytic Monte Carlo part, or where
    ``jitter_costs`` are given (the Δcost of points a step of 1–2 % from the optimum, where the
    profile's smooth part is negligible) and exceed it, their measured noise:

    * one row (or a 1-D array), from one set of realisations: their root mean square, which
      counts the cost's structure near the optimum (a slope where the optimum stopped short of
      the minimum, a kink) as noise too;
    * several rows, each from an independent set of realisations (release states, dither and
      encoder phases): their standard deviation over the sets, pooled over the points — the
      noise, since the structure repeats from set to set. It includes the slopes that the
      first set, on which the optimum was chosen, hides by that selection.
    """
    sd = noise_sd
    if jitter_costs is not None and np.size(jitter_costs):
        sd = max(sd, jitter_noise(jitter_costs))
    return CHI2_1_95 + Z95_ONE_SIDED * sd


def jitter_noise(jitter_costs) -> float:
    """The measured noise of a Δcost from the jitter points' Δcosts (sets × points, or one
    set as a 1-D array): one set's root mean square, or the standard deviation over several
    sets pooled over the points (:func:`profile_threshold`)."""
    costs = np.atleast_2d(np.asarray(jitter_costs, dtype=float))
    if len(costs) == 1:
        return float(np.sqrt(np.mean(np.square(costs))))
    return float(np.sqrt(np.mean(np.var(costs, axis=0, ddof=1))))


def profile_scan(
    specs: Sequence,
    z,
    cov,
    profile_costs,
    *,
    valley: Valley | None = None,
    only: Sequence[int] | None = None,
) -> dict:
    """Cost profiles of the free parameters over their whole range.

    The Laplace interval is local and Gaussian, and rattle's cost is neither: a weak film is
    nearly indistinguishable from dry flanks (a → 0), a long one from a saturated film, and
    the drag torque trades against the film along a curved valley where a linear
    extrapolation of the covariance runs off to the ends of the range. So each free parameter
    is scanned over its whole range (:data:`SCAN_FRACTIONS`) and near the optimum
    (:data:`SCAN_OFFSETS`). At each value the other parameters are set two ways — kept at the
    optimum, and moved along the Laplace profile path ``z + Σ[:, i]/Σ_ii · (t − z_i)`` — and
    the lower cost stands for the profile (:func:`polish_profile` then re-optimises the
    values that decide the interval's ends); ``valley`` adds the guesses the model's physics
    makes (:func:`profile_guesses`). Every point is simulated in one batch
    (:class:`ProfileCosts`, common random numbers with the optimum), so the costs are
    comparable.

    ``profile_costs`` maps points (N, P) to their costs above the optimum's (N,); ``only``
    (indices) limits the scan to those free parameters. Returns
    ``{index: {t: (Δcost, z)}}``: for each free parameter and scanned value t (in z), the cost
    above the optimum's and the point that attained it.
    """
    zs, owners = [], []
    for i, spec in enumerate(specs):
        if spec.nuisance or (only is not None and i not in only):
            continue
        sd = math.sqrt(max(cov[i, i], 0.0))
        ts = {spec.z_of(spec.lower * (spec.upper / spec.lower) ** f) for f in SCAN_FRACTIONS}
        ts |= {z[i] + o * sd for o in SCAN_OFFSETS if sd < Z_END}
        for t in sorted(float(np.clip(t, -Z_END, Z_END)) for t in ts):
            guesses = profile_guesses(z, cov, i, t, valley=valley)
            zs += guesses
            owners += [(i, t)] * len(guesses)
    if not owners:
        return {}
    zs = np.stack(zs)
    profiles: dict[int, dict[float, tuple]] = {}
    for (i, t), dc, zk in zip(owners, profile_costs(zs), zs, strict=True):
        prof = profiles.setdefault(i, {float(z[i]): (0.0, np.asarray(z, dtype=float))})
        keep_lower(prof, t, float(dc), zk)
    return profiles


class ProfileCosts:
    """The costs of profile points above the optimum's, simulated in two parts.

    Most of a profile scan's values lie far outside the 95 % interval (Δcost in the hundreds
    or thousands where the threshold is about 10), and the first few realisations already
    show it. So every point is first simulated with the first ``screen`` of the M
    realisations and costed against the optimum's same realisations; only where that Δcost
    is below :attr:`limit` are the other M − ``screen`` simulated, and its cost is then
    exactly that of all M at once (each realisation is the same simulation in either part).
    ``evaluate(points, realisations=…)`` simulates the realisations (indices, None for all M)
    of each point: features (N, R, len(realisations), B); ``cost_of(features, point)`` is a
    point's cost from the features of all its realisations. A point set aside keeps its
    screened Δcost until :meth:`complete_ends` finds it ending an interval's bracket: an
    interval end is interpolated towards the first value outside, so that value must be the
    full cost (a cost of few realisations is biased: with their own band spread from 6, a
    point whose Δcost of 24 was 26 read 358).

    The limit: :data:`SCREEN_FACTOR` × the profile ``threshold``, and at least
    :data:`SCREEN_SDS` × :attr:`noise` above it, :attr:`noise` being the rms screened
    Δcost of the points ``near[1:]`` near the optimum (``near[0]``; ``per_near`` their
    features of all M realisations), whose full Δcost is within the threshold's noise of 0.
    ``screen`` 0 (or ≥ M) simulates every point with all M (:attr:`limit` None), and so are
    batches too small for their screening part to fill one compiled chunk (a bisection round's
    few points, which lie near the threshold anyway): ``chunk`` is the rows of one compiled
    evaluation.
    """

    def __init__(
        self,
        evaluate: Callable,
        cost_of: Callable,
        per_near,
        near,
        threshold: float,
        screen: int,
        *,
        chunk: int,
    ):
        self.evaluate, self.cost_of, self.chunk = evaluate, cost_of, chunk
        self.m = m = per_near.shape[2]
        self.screen = screen if 0 < screen < m else 0
        self.cost_opt = cost_of(per_near[0], near[0])
        self.limit = self.noise = None
        if self.screen:
            k = self.screen
            screened = self._costs(per_near[:, :, :k], near)
            self.cost_opt_screen = screened[0]
            d = screened[1:] - screened[0]
            self.noise = float(np.sqrt(np.mean(d**2))) if len(d) else 0.0
            self.limit = max(SCREEN_FACTOR * threshold, threshold + SCREEN_SDS * self.noise)
        self.partial: dict[bytes, tuple] = {}  # set aside: (point, screened features)
        self.full: dict[bytes, tuple] = {}  # completed or whole: (point, Δcost)
        self.n_screened = self.n_set_aside = self.n_completed = 0

    def __call__(self, points) -> np.ndarray:
        points = np.atleast_2d(np.asarray(points, dtype=float))
        if not self.screen or len(points) * self.screen < self.chunk:
            # a batch whose screening part would not fill one compiled chunk is simulated
            # whole: the padding would cost as much as the realisations it saves
            return self._full(points, self.evaluate(points, realisations=None))
        self.n_screened += len(points)
        first = self.evaluate(points, realisations=np.arange(self.screen))
        dc = self._costs(first, points) - self.cost_opt_screen
        rest = np.flatnonzero(dc <= self.limit)
        for j in np.flatnonzero(dc > self.limit):
            self.partial[points[j].tobytes()] = (points[j], first[j])
        self.n_set_aside += len(points) - len(rest)
        if len(rest):
            dc[rest] = self._complete(points[rest], first[rest])
        return dc

    def _costs(self, per, points) -> np.ndarray:
        return np.array([self.cost_of(f, zk) for f, zk in zip(per, points, strict=True)])

    def _full(self, points, per) -> np.ndarray:
        """Δcosts of ``points`` from the features ``per`` of all M realisations, kept for
        :meth:`complete_ends`."""
        dc = self._costs(per, points) - self.cost_opt
        for zk, d in zip(points, dc, strict=True):
            self.full[zk.tobytes()] = (zk, float(d))
        return dc

    def _complete(self, points, first) -> np.ndarray:
        """Full Δcosts of ``points`` whose first realisations' features are ``first``."""
        more = self.evaluate(points, realisations=np.arange(self.screen, self.m))
        return self._full(points, np.concatenate([first, more], axis=2))

    def complete_ends(self, profiles: dict, threshold: float) -> int:
        """Give every profile interval's first value outside its full cost, in place.

        At a value t that ends a bracket (:func:`profile_interval`), every point set aside
        with parameter i at t (either of the scan's guesses: the one standing may be full
        while the other, lower in truth, read high from its few realisations) is completed,
        and the profile takes the lowest full cost at t. If that falls inside, the next
        value out may be another, so this repeats until none is left. Returns the number of
        points completed.
        """
        n = 0
        while True:
            todo: dict[bytes, tuple[int, float]] = {}
            for i, prof in profiles.items():
                for _, t_out in profile_interval(prof, threshold)[1]:
                    for key, (zk, _) in self.partial.items():
                        if zk[i] == t_out and key not in todo:
                            todo[key] = (i, t_out)
            if not todo:
                break
            keys = list(todo)
            points = np.stack([self.partial[k][0] for k in keys])
            first = np.stack([self.partial.pop(k)[1] for k in keys])
            self._complete(points, first)
            for i, t in set(todo.values()):
                full = [(dc, zk) for zk, dc in self.full.values() if zk[i] == t]
                standing = profiles[i][t]
                if standing[1].tobytes() not in todo:  # a full cost (a rival, a polish)
                    full.append(standing)
                profiles[i][t] = min(full, key=lambda v: v[0])
            n += len(keys)
        self.n_completed += n
        return n


def profile_guesses(
    z, cov, i: int, t: float, near=None, *, valley: Valley | None = None
) -> list[np.ndarray]:
    """Where to put the other parameters when parameter ``i`` is held at ``t``: as at the
    point ``near`` (default: the optimum ``z``; in a bisection, the value inside), and moved
    from the optimum along the Laplace profile path ``z + Σ[:, i]/Σ_ii · (t − z_i)``. Where
    the two nearly coincide (an uncorrelated parameter, or a value close to the optimum)
    they are one point, simulated once.

    ``valley(i, near, t)`` adds points on a valley that the model's physics knows and that
    neither straight path follows (:data:`Valley`; in a fit, the film half-length traded
    against the viscosity, :func:`rattlefit.inference.fit.identify`); a guess within
    :data:`SCAN_SAME` of one already made is dropped.
    """
    z = np.asarray(z, dtype=float)
    beta = np.clip(cov[:, i] / cov[i, i], -10, 10) if cov[i, i] > 0 else np.zeros_like(z)
    base = z if near is None else np.asarray(near, dtype=float)
    kept = base.copy()
    kept[i] = t
    moved = np.clip(z + beta * (t - z[i]), -Z_END, Z_END)
    moved[i] = t
    return _distinct([kept, moved, *(valley(i, base, t) if valley is not None else [])])


def _distinct(points) -> list[np.ndarray]:
    """``points`` in order, less each within :data:`SCAN_SAME` (in z) of one before it."""
    kept: list[np.ndarray] = []
    for g in points:
        if all(np.max(np.abs(g - h)) >= SCAN_SAME for h in kept):
            kept.append(np.asarray(g, dtype=float))
    return kept


def bisect_profile_ends(
    profiles: dict,
    threshold: float,
    z,
    cov,
    cost_of_points,
    *,
    rounds: int,
    valley: Valley | None = None,
) -> int:
    """Narrow the bracket of each profile interval's ends by bisection, in place.

    The scan's values lie far apart away from the optimum (fractions of the whole range),
    and an end interpolated linearly across such a gap can be anywhere in it (the cost can
    jump by a thousand between neighbouring scanned values, many Laplace standard deviations
    apart). Each round
    evaluates, in one batch, the midpoint of every bracket (last value inside, first
    outside) wider than :data:`PROFILE_RESOLUTION` of its interval (and at least
    :data:`PROFILE_MIN_STEP` in z), with the other parameters set both ways of
    :func:`profile_guesses` (as at the value inside, and along the Laplace path), the lower
    cost standing. One guess is not enough: where the valley bends (``a`` against ``h_min``
    in mild rattle) the value inside's overstates the profile, and bisection then ends the
    interval early. ``valley``
    adds the guesses the model's physics makes (:func:`profile_guesses`).

    ``cost_of_points`` maps points (N, P) to their costs above the optimum's (N,). Returns
    the number of points evaluated.
    """
    n_points = 0
    for _ in range(rounds):
        todo = []
        for i, prof in profiles.items():
            (lo, hi), brackets = profile_interval(prof, threshold)
            width = max(PROFILE_RESOLUTION * (hi - lo), PROFILE_MIN_STEP)
            for t_in, t_out in brackets:
                if abs(t_out - t_in) > width:
                    t = 0.5 * (t_in + t_out)
                    guesses = profile_guesses(z, cov, i, t, prof[t_in][1], valley=valley)
                    todo += [(i, t, g) for g in guesses]
        if not todo:
            break
        costs = cost_of_points(np.stack([g for _, _, g in todo]))
        n_points += len(todo)
        for (i, t, g), c in zip(todo, costs, strict=True):
            keep_lower(profiles[i], t, float(c), g)
    return n_points


def continue_profiles(
    profiles: dict,
    threshold: float,
    cost_of_points: Callable[[np.ndarray], np.ndarray],
    polish: Callable[[np.ndarray, list[int]], np.ndarray],
    step: Callable[[int, float], float],
    *,
    rounds: int,
    valley: Valley | None = None,
) -> int:
    """Follow each profile past its interval's ends by continuation, in place.

    For each end with a value outside (:func:`profile_interval`'s brackets), a round tries
    one value further out than the last value inside ``t_in``, by ``step(i, t_in)`` (in z)
    times :data:`CONTINUATION_GROWTH` to the power of the rounds in which this end moved out
    less those in which it did not (an end stops where the first step fails, at the range's
    end, or after ``rounds``). The other parameters start from two predictions, as at the
    value inside and along the secant through it and the nearest value inside at least half
    a step further in (a predictor–corrector continuation), and are re-optimised by
    ``polish(points, fixed)`` with parameter i held; the guesses of ``valley``
    (:func:`profile_guesses`) are costed as they are, since they already follow the valley
    that the secant leaves. ``cost_of_points`` maps points (N, P) to their Δcost, all of a
    round in one batch.

    The scan's straight paths leave a valley that bends (``a`` against the viscosity under
    oil jet, where the squeeze force saturates in ``a``); a continuation follows it as far
    as it stays below the threshold. Returns the number of points evaluated.
    """
    grown: dict[tuple[int, int], int] = {}
    stopped: set[tuple[int, int]] = set()
    n_points = 0
    for _ in range(rounds):
        todo, on_valley = [], []  # polished first; the valley's guesses are its own
        for i, prof in profiles.items():
            for t_in, t_out in profile_interval(prof, threshold)[1]:
                side = 1 if t_out > t_in else -1
                key = (i, side)
                if key in stopped:
                    continue
                h = step(i, t_in) * CONTINUATION_GROWTH ** grown.get(key, 0)
                # past a value outside if need be: its guesses may have left the valley
                t_new = float(np.clip(t_in + side * h, -Z_END, Z_END))
                if t_new == t_in:
                    stopped.add(key)
                    continue
                z_in = np.asarray(prof[t_in][1], dtype=float)
                inner = [
                    t
                    for t in sorted(prof, key=lambda t: abs(t - t_in))
                    if (t - t_in) * side < 0 and prof[t][0] < threshold
                ]
                far = [t for t in inner if abs(t - t_in) >= 0.5 * h]
                guesses = [z_in.copy()]
                if inner:
                    t_prev = far[0] if far else inner[-1]
                    slope = (z_in - np.asarray(prof[t_prev][1])) / (t_in - t_prev)
                    guesses.append(np.clip(z_in + slope * (t_new - t_in), -Z_END, Z_END))
                for g in guesses:
                    g[i] = t_new
                todo += [(key, t_new, g) for g in _distinct(guesses)]
                if valley is not None:
                    on_valley += [(key, t_new, g) for g in valley(i, z_in, t_new)]
        if not todo:
            break
        ends = polish(np.stack([g for _, _, g in todo]), [key[0] for key, _, _ in todo])
        todo += on_valley
        ends = np.concatenate([ends, *(g[None] for _, _, g in on_valley)])
        costs = cost_of_points(ends)
        n_points += len(todo)
        best: dict[tuple[int, int], float] = {}
        for (key, t_new, _), zk, dc in zip(todo, ends, costs, strict=True):
            keep_lower(profiles[key[0]], t_new, float(dc), zk)
            best[key] = min(best.get(key, np.inf), float(dc))
        for key, dc in best.items():
            if dc < threshold:
                grown[key] = grown.get(key, 0) + 1
            elif grown.get(key, 0) > 0:
                grown[key] -= 1  # too far for the predictor: a shorter step next round
            else:
                stopped.add(key)
    return n_points


def span_profile_points(profiles: dict, threshold: float, z_lo, z_hi, specs) -> None:
    """Widen the intervals of the nuisances, which are not profiled (``z_lo``, ``z_hi``, in
    place), to span every profile point inside the ``threshold``: each is inside the 95 %
    region, so its value of every parameter is inside that parameter's profile interval."""
    inside = [zk for prof in profiles.values() for dc, zk in prof.values() if dc < threshold]
    for j, s in enumerate(specs):
        if s.nuisance and inside:
            values = [float(zk[j]) for zk in inside]
            z_lo[j], z_hi[j] = min(z_lo[j], min(values)), max(z_hi[j], max(values))


def admit_rivals(profiles: dict, others, dcosts, threshold: float) -> list[np.ndarray]:
    """The candidates among ``others`` whose Δcost (``dcosts``, in the profiles' cost, above
    the optimum's) lies below the profile ``threshold``; each is entered into every free
    parameter's profile at its own value, in place, so that the intervals, their bisection and
    the check for a lower point (:func:`lower_profile_point`) all see it.

    A point below the threshold is inside the 95 % confidence region whatever it is: another
    optimum, or a Levenberg–Marquardt run stopped at its step limit. One above it is not,
    however close its cost in the fit (fewer realisations, the spread held fixed), so an
    unconverged iterate does not widen the intervals.
    """
    rivals = []
    for zr, dc in zip(others, dcosts, strict=True):
        if dc < threshold:
            rivals.append(np.asarray(zr, dtype=float))
            for i, prof in profiles.items():
                keep_lower(prof, float(zr[i]), float(dc), rivals[-1])
    return rivals


def lower_profile_point(profiles: dict, allowance: float):
    """The lowest ``(Δcost, z)`` of the profiles when it lies more than ``allowance`` below
    the optimum's cost, else None.

    The optimum should be the profiles' minimum. A value clearly below it means the
    Levenberg–Marquardt runs stopped short (at their step limit, or because the cost they
    minimise, with fewer realisations and the spread held fixed, differs from the profiles'
    synthetic likelihood), and intervals anchored at such an optimum are shifted. "Clearly":
    by more than ``allowance`` (the profile threshold's Monte Carlo part), because the
    minimum over many noisy values is biased low.
    """
    values = [v for prof in profiles.values() for v in prof.values()]
    if not values:
        return None
    lowest = min(values, key=lambda v: v[0])
    return lowest if lowest[0] < -allowance else None


def keep_lower(profile: dict, t: float, dcost: float, z) -> None:
    """Record ``(dcost, z)`` as the profile's value at ``t`` unless a lower one stands."""
    if t not in profile or dcost < profile[t][0]:
        profile[t] = (dcost, z)


def profile_interval(profile: dict[float, tuple], threshold: float):
    """The 95 % interval (in z) of one profile of :func:`profile_scan`, and the brackets of
    its ends: ``(last value inside, first value outside)`` for each end that has a value
    outside (none where the interval runs to the last value scanned).

    The interval spans every scanned value whose Δcost is below ``threshold``, its ends
    interpolated linearly towards the first value outside.
    """
    ts = np.asarray(sorted(profile))
    dc = np.asarray([profile[t][0] for t in ts])
    inside = np.flatnonzero(dc < threshold)
    lo_k, hi_k = inside.min(), inside.max()
    interval = (
        threshold_crossing(ts, dc, lo_k, lo_k - 1, threshold),
        threshold_crossing(ts, dc, hi_k, hi_k + 1, threshold),
    )
    brackets = [
        (float(ts[k_in]), float(ts[k_out]))
        for k_in, k_out in ((lo_k, lo_k - 1), (hi_k, hi_k + 1))
        if 0 <= k_out < len(ts)
    ]
    return interval, brackets


def polish_profile(
    residuals: Callable[[np.ndarray], np.ndarray],
    zs: np.ndarray,
    fixed: Sequence[int | Sequence[int]],
    steps: np.ndarray,
    *,
    iterations: int = 2,
    damping: Sequence[float] = (0.03, 0.3, 3.0),
) -> np.ndarray:
    """Re-optimise every coordinate but ``fixed[k]`` (an index or several) from each point
    ``zs[k]``: damped Gauss–Newton (Levenberg–Marquardt) on finite differences.

    ``residuals`` maps points (N, P) to residual vectors (N, n), all evaluated in one batch
    (common random numbers, so that the values at different points are comparable);
    ``steps`` (K, P) are the finite-difference steps. Each iteration evaluates the forward
    differences at every point, then one trial step per ``damping`` value λ (on the diagonal
    of JᵀJ, Marquardt's scaling), and keeps the best trial if it lowers the cost. A profile
    likelihood needs the other parameters at their optimum for each fixed value; the scan's
    two guesses (unchanged, or moved along the linearised path) overstate the cost where the
    valley bends, and that narrows the interval.
    """
    zs = np.array(zs, dtype=float)
    n, p = zs.shape
    free = [np.flatnonzero(~np.isin(np.arange(p), fixed[k])) for k in range(n)]
    for _ in range(iterations):
        h = np.where(zs > 0, -steps, steps)  # towards the middle of each range
        # each point, then its forward differences along its free coordinates only
        pts = [zs[k] + np.vstack([np.zeros(p), np.diag(h[k])[free[k]]]) for k in range(n)]
        res = np.split(residuals(np.concatenate(pts)), np.cumsum([len(x) for x in pts])[:-1])
        trials = []
        for k in range(n):
            r0, keep = res[k][0], free[k]
            j = ((res[k][1:] - r0) / h[k][keep][:, None]).T  # (rows, free)
            jtj, g = j.T @ j, j.T @ r0
            for lam in damping:
                step = np.zeros(p)
                step[keep] = -np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), g)
                trials.append(np.clip(zs[k] + step, -Z_END, Z_END))
        cost = np.sum(residuals(np.stack(trials)) ** 2, axis=1).reshape(n, len(damping))
        for k in range(n):
            best = int(np.argmin(cost[k]))
            if cost[k, best] < np.sum(res[k][0] ** 2):
                zs[k] = trials[k * len(damping) + best]
    return zs


def threshold_crossing(ts, dc, k_in: int, k_out: int, threshold: float) -> float:
    """Where Δcost, linear between scanned values ``ts[k_in]`` (inside) and ``ts[k_out]``
    (outside), reaches ``threshold``; ``ts[k_in]`` when there is no value outside."""
    if k_out < 0 or k_out >= len(ts):
        return float(ts[k_in])
    f = (threshold - dc[k_in]) / max(dc[k_out] - dc[k_in], 1e-12)
    return float(ts[k_in] + np.clip(f, 0.0, 1.0) * (ts[k_out] - ts[k_in]))

"""Angle-domain evidence: where the flanks are, against each wheel's angle and tooth.

The encoders give both wheels' angles exactly, so a recording says, without any model, where
the two flanks were met while each tooth of each wheel was in mesh. On a rig without
geometric errors the flanks sit at ±backlash/2 of Δθ* whatever the angles; mounting run-out
moves both flanks together once per revolution of a wheel, a transmission error once per
tooth, and a damaged tooth moves them while that tooth is in mesh.

:func:`contact_events` finds the flank contacts of a recording; :func:`flank_regression`
fits their positions with a constant per flank, the drive-cycle harmonics per flank (impact
depth varies over the drive cycle) and sinusoids of each wheel's angle shared by both flanks;
:func:`runout_evidence`, :func:`mesh_order_evidence` and :func:`tooth_evidence` test those
terms (Wald tests with a covariance that is robust to correlation within a contact episode).
Positions are in Δθ* (rad of the primary shaft); the flank moves by ``−g/r1`` for a gap error
``g`` (m on the pitch circle), since ``q = −r1 Δθ*``.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from scipy import linalg, stats

from ..io.recording import Recording

#: A sample belongs to a flank contact when it lies within this share of the play of the
#: flank's robust extreme (run-out and defects move the flank by a few per cent of the play).
CONTACT_BAND = 0.2
#: Contact episodes are cut into pieces of at most this share of a driving-wheel revolution,
#: so that a long dwell on a moving flank gives one observation per angle it passes.
PIECE_REVOLUTION = 1.0 / 72.0
#: Harmonics of the drive frequency fitted per flank (the impact depth follows the drive).
DRIVE_HARMONICS = 3
#: Observations further than this many robust standard deviations from the fit are dropped
#: (turning points short of the flank, e.g. in a thick oil film), and the fit repeated.
OUTLIER_Z = 4.0
#: A flank met fewer times than this is left out of the flank fit.
MIN_FLANK_EVENTS = 60
#: A tooth met fewer times than this (contacts kept by the flank fit), or in fewer contact
#: episodes than this, is not tested: its offset's cluster-robust standard error needs
#: several episodes (clusters), and from one it comes out near zero.
MIN_TOOTH_EVENTS = 3
#: Orders of a wheel's angle that run-out covers: eccentricity (1) and ovality (2).
RUNOUT_ORDERS = (1, 2)
#: A drive ripple is looked for at every integer order of the primary shaft whose frequency
#: stays below this share of the sample rate (an electric drive's slot and pole orders, an
#: engine's firing orders).
RIPPLE_BAND = 0.12
#: Half-integer orders each side of an order whose single-order χ² set its noise level (the
#: residual's spectrum is coloured: impacts and quantisation, not white noise).
RIPPLE_NEIGHBOURS = 20
#: Encoder quantisations of the recording's own smooth drive behind the null of each order: the
#: counts of a smoothly turning shaft leave lines at orders that depend on the speed law.
QUANTISATION_NULLS = 8
#: Orders whose projections are computed at once (a block of samples × orders).
ORDER_BLOCK = 64
#: Decoy orders behind each inflation estimate, and their clearance from the orders where
#: something is expected, in order resolutions (1 / revolutions recorded).
DECOY_COUNT = 15
DECOY_CLEARANCE = 1.5


@dataclasses.dataclass(frozen=True)
class ContactEvents:
    """Flank contacts of a recording, one row per contact piece.

    position : Δθ* at the contact (rad), the flank's extreme value within the piece.
    flank : +1 (upper flank, positive Δθ*) or −1 (lower flank).
    episode : index of the contact episode the piece belongs to (a run of contact samples).
    time : s; theta_primary, theta_secondary : the wheels' angles at the contact (rad).
    """

    position: np.ndarray
    flank: np.ndarray
    episode: np.ndarray
    time: np.ndarray
    theta_primary: np.ndarray
    theta_secondary: np.ndarray

    def __len__(self) -> int:
        return int(self.position.size)


def contact_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Start and stop indices of the runs of True in ``mask``."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2], edges[1::2], strict=True))


def contact_events(recording: Recording) -> ContactEvents:
    """The flank contacts of ``recording``: each run of samples within
    :data:`CONTACT_BAND` of the play from a flank's robust extreme, cut into pieces of at
    most :data:`PIECE_REVOLUTION` of a driving-wheel revolution, each represented by its
    extreme sample."""
    d = recording.relative_motion
    lo, hi = np.percentile(d, [0.1, 99.9])
    margin = CONTACT_BAND * (hi - lo)
    speed = recording.operating.drive_mean_speed_rad_s
    piece = max(1, round(PIECE_REVOLUTION * 2 * math.pi / speed * recording.sample_rate_hz))
    rows = []
    for flank, mask in ((1, d > hi - margin), (-1, d < lo + margin)):
        for episode, (start, stop) in enumerate(contact_runs(mask)):
            for s in range(start, stop, piece):
                seg = flank * d[s : min(stop, s + piece)]
                k = s + int(np.argmax(seg))
                rows.append((d[k], flank, flank * (episode + 1), k))
    rows.sort(key=lambda r: r[3])
    pos, side, episode, k = (
        (np.asarray(c) for c in zip(*rows, strict=True)) if rows else [np.zeros(0)] * 4
    )
    k = k.astype(int)
    return ContactEvents(
        position=pos.astype(float),
        flank=side.astype(int),
        episode=episode.astype(int),
        time=k / recording.sample_rate_hz,
        theta_primary=recording.theta_primary[k],
        theta_secondary=recording.theta_secondary[k],
    )


@dataclasses.dataclass(frozen=True)
class FlankFit:
    """A least-squares fit of the contact positions (:func:`flank_regression`).

    coef : (P,) coefficients; covariance : (P, P) cluster-robust covariance (clusters: the
    contact episodes); columns : (P,) column names; kept : (n,) bool, observations used;
    scale : robust standard deviation of the residuals (rad).
    """

    coef: np.ndarray
    covariance: np.ndarray
    columns: tuple[str, ...]
    kept: np.ndarray
    scale: float

    def block(self, prefix: str) -> np.ndarray:
        """Indices of the columns whose names start with ``prefix``."""
        return np.array([i for i, c in enumerate(self.columns) if c.startswith(prefix)], int)

    def wald(self, prefix: str) -> tuple[float, int]:
        """Wald χ² of the columns starting with ``prefix`` being zero, and its dof."""
        i = self.block(prefix)
        b = self.coef[i]
        return float(b @ np.linalg.solve(self.covariance[np.ix_(i, i)], b)), int(i.size)


def design(events: ContactEvents, recording: Recording, terms: dict[str, np.ndarray]):
    """Design matrix of the flank fit and its column names: a constant and the drive-cycle
    harmonics (halves up to :data:`DRIVE_HARMONICS`) per flank, then each of ``terms``
    (name → (n,) column); columns that are zero for every event are left out."""
    phase = 2 * math.pi * recording.operating.drive_frequency_hz * events.time
    cols, names = [], []
    for flank, tag in ((1, "upper"), (-1, "lower")):
        on = (events.flank == flank).astype(float)
        cols.append(on)
        names.append(f"offset.{tag}")
        for h in np.arange(1, 2 * DRIVE_HARMONICS + 1) / 2:
            cols += [on * np.cos(h * phase), on * np.sin(h * phase)]
            names += [f"drive.{tag}.cos{h}", f"drive.{tag}.sin{h}"]
    for name, col in terms.items():
        cols.append(col)
        names.append(name)
    x = np.stack(cols, axis=1)
    used = np.any(x != 0, axis=0)  # a flank without contacts has no columns
    return x[:, used], tuple(n for n, u in zip(names, used, strict=True) if u)


def robust_scale(residuals: np.ndarray) -> float:
    """1.4826 × the median absolute deviation (σ of a normal sample)."""
    return float(1.4826 * np.median(np.abs(residuals - np.median(residuals))))


def cluster_covariance(x: np.ndarray, residuals: np.ndarray, clusters: np.ndarray) -> np.ndarray:
    """Cluster-robust (sandwich) covariance of least-squares coefficients, with the usual
    small-sample factor G/(G−1)·(n−1)/(n−P)."""
    n, p = x.shape
    bread = np.linalg.pinv(x.T @ x)
    groups, inverse = np.unique(clusters, return_inverse=True)
    scores = np.zeros((groups.size, p))
    np.add.at(scores, inverse, x * residuals[:, None])
    meat = scores.T @ scores
    g = groups.size
    factor = g / max(g - 1, 1) * (n - 1) / max(n - p, 1)
    return factor * bread @ meat @ bread


def weighted_least_squares(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Coefficients minimising Σ (w (y − x b))², from the normal equations with the columns
    scaled to unit norm (the flanks' weights differ by orders of magnitude); a column that is
    zero on every row gets 0, and a system still ill-conditioned falls back to least squares
    (the minimum-norm solution)."""
    xw = x * w[:, None]
    gram = xw.T @ xw
    rhs = xw.T @ (y * w)
    norm = np.sqrt(np.diag(gram))
    active = norm > 0
    coef = np.zeros(x.shape[1])
    n = norm[active]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", linalg.LinAlgWarning)
            scaled = gram[np.ix_(active, active)] / np.outer(n, n)
            coef[active] = linalg.solve(scaled, rhs[active] / n, assume_a="pos") / n
    except (linalg.LinAlgError, linalg.LinAlgWarning, ValueError):
        coef = np.linalg.lstsq(xw, y * w, rcond=None)[0]
    return coef


def usable(events: ContactEvents) -> ContactEvents:
    """``events`` on the flanks met at least :data:`MIN_FLANK_EVENTS` times (a flank met a
    few times cannot carry its own drive-cycle harmonics)."""
    keep = np.zeros(len(events), bool)
    for flank in (1, -1):
        on = events.flank == flank
        if on.sum() >= MIN_FLANK_EVENTS:
            keep |= on
    return ContactEvents(*(getattr(events, f.name)[keep] for f in dataclasses.fields(events)))


def flank_regression(
    events: ContactEvents, recording: Recording, terms: dict[str, np.ndarray]
) -> FlankFit:
    """Fit the flanks' positions with :func:`design`, on the :func:`usable` flanks only.

    A flank bounds the motion: contact pieces lie on it (up to quantisation and the contact's
    deflection, outwards), turning points short of it lie inside. The fit therefore starts
    from each flank's outer half, keeps the observations within :data:`OUTLIER_Z` standard
    deviations of the fit, each flank's deviation estimated from its outward residuals
    alone, weights each flank by the inverse square of that deviation, and repeats until the
    kept set settles: an envelope of each flank.
    """
    keep = np.isin(events.flank, np.unique(usable(events).flank))
    events = ContactEvents(*(getattr(events, f.name)[keep] for f in dataclasses.fields(events)))
    terms = {k: v[keep] for k, v in terms.items()}
    x, names = design(events, recording, terms)
    y = events.position
    outer = events.flank * y
    kept = np.zeros(y.size, bool)
    for flank in (1, -1):
        on = events.flank == flank
        if on.any():
            kept |= on & (outer >= np.median(outer[on]))
    scale = np.ones(y.size)
    for _ in range(30):
        coef = weighted_least_squares(x[kept], y[kept], 1.0 / scale[kept])
        outward = events.flank * (y - x @ coef)
        for flank in (1, -1):
            on = events.flank == flank
            out = outward[kept & on & (outward > 0)]
            scale[on] = max(float(np.sqrt(np.mean(out**2))) if out.size else 0.0, 1e-12)
        new = np.abs(outward) <= OUTLIER_Z * scale
        if np.array_equal(new, kept) or new.sum() <= x.shape[1]:
            break
        kept = new
    res = y - x @ coef
    w = 1.0 / scale[kept]
    cov = cluster_covariance(x[kept] * w[:, None], res[kept] * w, events.episode[kept])
    full = np.zeros(keep.size, bool)
    full[np.flatnonzero(keep)[kept]] = True
    return FlankFit(coef, cov, names, full, float(np.median(scale)))


def wheel_terms(events: ContactEvents, order: float = 1.0, *, wheels=("primary", "secondary")):
    """Sinusoids of ``order`` × each wheel's angle, one pair per flank, named
    ``"<wheel>.<upper|lower>.cos|sin"`` at order 1 and ``"<wheel>.o<order>.<upper|lower>.…"``
    otherwise: a transmission error moves both flanks alike, a change of the centre distance
    moves them apart (it widens and narrows the play)."""
    out = {}
    for wheel in wheels:
        theta = order * getattr(events, f"theta_{wheel}")
        label = wheel if order == 1 else f"{wheel}.o{order:g}"
        for flank, tag in ((1, "upper"), (-1, "lower")):
            on = (events.flank == flank).astype(float)
            out[f"{label}.{tag}.cos"] = on * np.cos(theta)
            out[f"{label}.{tag}.sin"] = on * np.sin(theta)
    return out


def runout_terms(events: ContactEvents, wheels=("primary", "secondary")) -> dict[str, np.ndarray]:
    """:func:`wheel_terms` of ``wheels`` at each of :data:`RUNOUT_ORDERS`."""
    out = {}
    for order in RUNOUT_ORDERS:
        out |= wheel_terms(events, order, wheels=wheels)
    return out


def smooth_part_removed(teeth: int, tested: np.ndarray) -> np.ndarray:
    """The projector (T, T) that removes, over the ``tested`` teeth, the mean and the swings
    at :data:`RUNOUT_ORDERS` across the tooth index (a tooth at the angle of its centre);
    the rows and columns of the other teeth are zero."""
    angle = 2 * math.pi * (np.arange(teeth) + 0.5) / teeth
    smooth = [np.ones(teeth)]
    for order in RUNOUT_ORDERS:
        smooth += [np.cos(order * angle), np.sin(order * angle)]
    h = np.stack(smooth, axis=1)[tested]
    out = np.zeros((teeth, teeth))
    idx = np.flatnonzero(tested)
    out[np.ix_(idx, idx)] = np.eye(idx.size) - h @ np.linalg.pinv(h)
    return out


@dataclasses.dataclass(frozen=True)
class AngleTest:
    """One angle-domain test of a recording.

    name : what is tested (e.g. ``"runout.primary"``); chi2, dof, p_value : its Wald test;
    amplitude, amplitude_sd : the size of the pattern as a gap error on the pitch circle (m)
    and its standard error; detail : further numbers (e.g. the phase, the worst tooth).
    """

    name: str
    chi2: float
    dof: int
    p_value: float
    amplitude: float
    amplitude_sd: float
    detail: dict = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def pair_amplitude(fit: FlankFit, prefix: str) -> tuple[float, float, float]:
    """Amplitude (rad of Δθ*), its standard error and phase (rad) of the sinusoid whose
    ``cos`` and ``sin`` columns are ``prefix + "cos"`` and ``prefix + "sin"``."""
    i = np.array([fit.columns.index(prefix + "cos"), fit.columns.index(prefix + "sin")])
    c, s = fit.coef[i]
    amp = math.hypot(c, s)
    grad = np.array([c, s]) / max(amp, 1e-300)
    sd = math.sqrt(max(float(grad @ fit.covariance[np.ix_(i, i)] @ grad), 0.0))
    return amp, sd, math.atan2(c, s)


def sinusoid_test(fit: FlankFit, prefix: str, name: str, r1: float) -> AngleTest:
    """The Wald test of every column of ``fit`` starting with ``prefix`` (cos/sin pairs),
    the largest pair's amplitude as a gap error on the pitch circle (m), and each pair's
    amplitude and phase in ``detail``."""
    chi2, dof = fit.wald(prefix)
    pairs = sorted(
        {c[: -len("cos")] for c in fit.columns if c.startswith(prefix) and c.endswith("cos")}
    )
    detail, best = {}, (0.0, 0.0)
    for pair in pairs:
        amp, sd, phase = pair_amplitude(fit, pair)
        key = pair[len(prefix) :].strip(".") or "amplitude"
        detail[f"{key}_m"], detail[f"{key}_sd_m"], detail[f"{key}_phase_rad"] = (
            r1 * amp,
            r1 * sd,
            phase,
        )
        best = max(best, (amp, sd))
    return AngleTest(
        name=name,
        chi2=chi2,
        dof=dof,
        p_value=float(stats.chi2.sf(chi2, dof)),
        amplitude=r1 * best[0],
        amplitude_sd=r1 * best[1],
        detail=detail,
    )


def pitch_radius_driving(recording: Recording) -> float:
    """r1 of the recording's driving wheel, m."""
    return 0.5e-3 * recording.gear_pair.pitch_diameter_driving_mm


def decoy_orders(recording: Recording, wheel: str, count: int = DECOY_COUNT) -> np.ndarray:
    """``count`` orders of ``wheel``'s angle at which nothing is expected: between 0.5 and
    3.5, at least :data:`DECOY_CLEARANCE` order resolutions away from the integer orders of
    either wheel and from the fitted drive harmonics."""
    speed = recording.operating.drive_mean_speed_rad_s / (2 * math.pi)  # primary, rev/s
    wheel_speed = speed if wheel == "primary" else speed / recording.gear_ratio
    resolution = 1.0 / (wheel_speed * recording.duration)
    drive = recording.operating.drive_frequency_hz / wheel_speed
    other = recording.gear_ratio if wheel == "primary" else 1.0 / recording.gear_ratio
    busy = np.concatenate(
        [
            np.arange(0, 5),
            other * np.arange(1, 12),
            drive * np.arange(1, 2 * DRIVE_HARMONICS + 1) / 2,
        ]
    )
    grid = np.arange(0.5, 3.5, resolution / 4)
    free = grid[np.min(np.abs(grid[:, None] - busy[None]), axis=1) > DECOY_CLEARANCE * resolution]
    if free.size <= count:
        return free
    return free[np.linspace(0, free.size - 1, count).round().astype(int)]


def inflation(events: ContactEvents, recording: Recording, wheel: str) -> float:
    """How much the once-per-revolution Wald χ² of ``wheel`` is inflated by what the fit does
    not hold (chaotic patterns near the wheel's order, correlation between episodes):
    the median of the same statistic at :func:`decoy_orders` over its median under the
    null, at least 1."""
    chi2 = []
    for order in decoy_orders(recording, wheel):
        fit = flank_regression(events, recording, wheel_terms(events, order, wheels=(wheel,)))
        chi2.append(fit.wald(f"{wheel}.")[0])
    if not chi2:
        return 1.0
    return max(1.0, float(np.median(chi2)) / stats.chi2.median(4))


def within_play(test: AngleTest, recording: Recording) -> AngleTest:
    """``test``, or, when its pattern is larger than the play itself (the recording's
    angular backlash on the driving pitch circle), the test with χ² 0 and p 1 and
    ``detail["beyond_play"]``: the flanks cannot move further apart than the gap, so such a
    size is no pattern but a fit that cannot tell the wheel's angle from the drive cycle (a
    drive fluctuating once or twice per revolution makes them nearly the same columns)."""
    play = pitch_radius_driving(recording) * recording.gear_pair.angular_backlash_rad
    if test.amplitude <= play:
        return test
    return dataclasses.replace(
        test, chi2=0.0, p_value=1.0, detail=test.detail | {"beyond_play": True}
    )


def runout_evidence(recording: Recording, events: ContactEvents | None = None) -> list[AngleTest]:
    """Swings of the flanks once and twice per revolution of each wheel (run-out: eccentricity
    and ovality, a shift of both flanks and a change of the play), one test per wheel
    (``"runout.primary"``, ``"runout.secondary"``) over both orders, fitted jointly, each χ²
    divided by its :func:`inflation` and the amplitude's standard error multiplied by its
    square root; the amplitude is the largest pair's."""
    events = contact_events(recording) if events is None else events
    fit = flank_regression(events, recording, runout_terms(events))
    r1 = pitch_radius_driving(recording)
    out = []
    for wheel in ("primary", "secondary"):
        test = sinusoid_test(fit, f"{wheel}.", f"runout.{wheel}", r1)
        lam = inflation(events, recording, wheel)
        test = dataclasses.replace(
            test,
            chi2=test.chi2 / lam,
            p_value=float(stats.chi2.sf(test.chi2 / lam, test.dof)),
            amplitude_sd=test.amplitude_sd * math.sqrt(lam),
            detail=test.detail | {"inflation": lam},
        )
        out.append(within_play(test, recording))
    return out


def mesh_order_evidence(recording: Recording, events: ContactEvents | None = None) -> AngleTest:
    """A swing of the flanks once per tooth (a transmission error at the mesh order),
    fitted together with the run-out terms (:func:`runout_terms`)."""
    events = contact_events(recording) if events is None else events
    z1 = recording.gear_pair.teeth_driving
    terms = runout_terms(events) | {
        "mesh.shift.cos": np.cos(z1 * events.theta_primary),
        "mesh.shift.sin": np.sin(z1 * events.theta_primary),
    }
    fit = flank_regression(events, recording, terms)
    test = sinusoid_test(fit, "mesh.", "mesh_order", pitch_radius_driving(recording))
    return within_play(test, recording)


def tooth_index(theta: np.ndarray, teeth: int) -> np.ndarray:
    """Which tooth of a wheel with ``teeth`` teeth is at the mesh at angle ``theta`` (rad),
    counted from the encoder's zero."""
    return np.floor(np.mod(theta, 2 * math.pi) / (2 * math.pi) * teeth).astype(int) % teeth


def tooth_offsets(events: ContactEvents, recording: Recording, wheel: str, order: float = 1.0):
    """Each tooth's flank offset beyond the wheel's smooth run-out (rad), and its standard
    error; teeth counted on ``order`` × the wheel's angle (1: the real teeth; otherwise a
    decoy partition).

    One offset per tooth is fitted (sum-to-zero contrasts) with the other wheel's run-out
    terms; the mean and the once- and twice-per-revolution swings across the teeth are then
    projected out (:func:`smooth_part_removed`), the covariance with them. Fitting the wheel's
    own run-out sinusoids beside its tooth indicators instead would be nearly collinear (a
    smooth swing is almost a combination of the indicators). A tooth met fewer than
    :data:`MIN_TOOTH_EVENTS` times or in fewer contact episodes gets an infinite error."""
    teeth = wheel_teeth(recording, wheel)
    index = tooth_index(order * getattr(events, f"theta_{wheel}"), teeth)
    other = "secondary" if wheel == "primary" else "primary"
    terms = runout_terms(events, wheels=(other,)) | {
        f"tooth.{k}": (index == k).astype(float) - (index == 0) for k in range(1, teeth)
    }
    fit = flank_regression(events, recording, terms)
    # a tooth never met together with tooth 0's contrast has no column (design leaves it
    # out): its contrast is zero, and it is not tested below
    i = fit.block("tooth.")
    k = np.array([int(fit.columns[j].split(".")[1]) - 1 for j in i], int)
    coef, cov_k = np.zeros(teeth - 1), np.zeros((teeth - 1, teeth - 1))
    coef[k], cov_k[np.ix_(k, k)] = fit.coef[i], fit.covariance[np.ix_(i, i)]
    b = np.concatenate([[-coef.sum()], coef])
    contrast = np.vstack([-np.ones(teeth - 1), np.eye(teeth - 1)])
    cov = contrast @ cov_k @ contrast.T
    seen = np.bincount(index[fit.kept], minlength=teeth)
    pairs = np.unique(np.stack([index[fit.kept], events.episode[fit.kept]]), axis=1)
    episodes = np.bincount(pairs[0], minlength=teeth)
    tested = (seen >= MIN_TOOTH_EVENTS) & (episodes >= MIN_TOOTH_EVENTS)
    if tested.sum() <= 1 + 2 * len(RUNOUT_ORDERS):
        return np.zeros(teeth), np.full(teeth, np.inf)  # too few teeth for a local pattern
    proj = smooth_part_removed(teeth, tested)
    local = proj @ b
    sd = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", proj, cov, proj), 0.0))
    sd[~tested] = np.inf
    return local, sd


def encoder_statistics(
    recording: Recording, events: ContactEvents | None = None
) -> dict[str, float]:
    """The size (m, on the driving pitch circle) of the pattern each encoder test measures,
    by test name, before any inflation: each wheel's largest run-out swing
    (:func:`runout_evidence`'s amplitude), the mesh order's swing
    (:func:`mesh_order_evidence`'s) and each wheel's most significant tooth offset
    (:func:`tooth_evidence`'s)."""
    events = contact_events(recording) if events is None else events
    r1 = pitch_radius_driving(recording)
    fit = flank_regression(events, recording, runout_terms(events))
    out = {
        f"runout.{w}": sinusoid_test(fit, f"{w}.", f"runout.{w}", r1).amplitude
        for w in ("primary", "secondary")
    }
    out["mesh_order"] = mesh_order_evidence(recording, events).amplitude
    for wheel in ("primary", "secondary"):
        b, sd = tooth_offsets(events, recording, wheel)
        out[f"tooth.{wheel}"] = r1 * abs(float(b[max_t2(b, sd)[1]]))
    return out


def wheel_teeth(recording: Recording, wheel: str) -> int:
    """Tooth count of ``wheel`` (``"primary"`` or ``"secondary"``)."""
    g = recording.gear_pair
    return g.teeth_driving if wheel == "primary" else g.teeth_driven


def max_t2(b: np.ndarray, sd: np.ndarray) -> tuple[float, int]:
    """The largest squared t over the teeth, and which tooth."""
    t2 = np.where(np.isfinite(sd), b / np.maximum(sd, 1e-300), 0.0) ** 2
    worst = int(np.argmax(t2))
    return float(t2[worst]), worst


def tooth_evidence(recording: Recording, events: ContactEvents | None = None) -> list[AngleTest]:
    """A flank position that stands out on one tooth of a wheel (a local defect), one test per
    wheel: each tooth's offset from the mean of all (:func:`tooth_offsets`) and the largest
    squared t over the teeth, divided by its inflation at decoy partitions of the wheel
    (:func:`decoy_orders`), with a Šidák correction over the teeth; the offset's standard
    error is multiplied by the inflation's square root."""
    events = contact_events(recording) if events is None else events
    r1 = pitch_radius_driving(recording)
    out = []
    for wheel in ("primary", "secondary"):
        teeth = wheel_teeth(recording, wheel)
        b, sd = tooth_offsets(events, recording, wheel)
        t2, worst = max_t2(b, sd)
        decoys = [
            max_t2(*tooth_offsets(events, recording, wheel, o))[0]
            for o in decoy_orders(recording, wheel)
        ]
        null_median = stats.chi2.ppf(0.5 ** (1.0 / teeth), 1)  # of the max of `teeth` χ²₁
        lam = max(1.0, float(np.median(decoys)) / null_median) if decoys else 1.0
        p_one = stats.chi2.sf(t2 / lam, 1)
        test = AngleTest(
            name=f"tooth.{wheel}",
            chi2=t2 / lam,
            dof=1,
            p_value=float(1 - (1 - p_one) ** teeth),
            amplitude=r1 * abs(float(b[worst])),
            amplitude_sd=r1 * float(sd[worst]) * math.sqrt(lam),
            detail={
                "tooth": worst,
                "teeth": teeth,
                "events_per_tooth": len(events) / teeth,
                "inflation": lam,
            },
        )
        out.append(within_play(test, recording))
    return out


def drive_fit(recording: Recording, theta, n_harmonics: int) -> np.ndarray:
    """The fit (N,) of an angle ``theta`` (N,, rad) by a constant speed and ``n_harmonics``
    harmonics of the drive frequency (:meth:`~rattlefit.physics.drive.Drive.fit`), rad."""
    t = recording.time
    k = np.arange(1, n_harmonics + 1)
    phase = 2 * math.pi * recording.operating.drive_frequency_hz * np.outer(t, k)
    x = np.column_stack([np.ones_like(t), t, np.cos(phase), np.sin(phase)])
    coef, *_ = np.linalg.lstsq(x, theta, rcond=None)
    return x @ coef


def primary_residual(recording: Recording, n_harmonics: int) -> np.ndarray:
    """The primary encoder's angle less its :func:`drive_fit`, rad."""
    return recording.theta_primary - drive_fit(recording, recording.theta_primary, n_harmonics)


def order_projections(residual: np.ndarray, theta: np.ndarray, orders) -> tuple[np.ndarray, ...]:
    """For each of ``orders`` (M,), the least-squares fit of a sinusoid of ``order × theta``
    to ``residual`` (N,) alone: its Wald χ² under white noise (M,), its amplitude (M,, rad)
    and the fit's residual variance (M,)."""
    orders = np.asarray(orders, float)
    rr = float(residual @ residual)
    n = residual.size
    chi2, amp, var = (np.empty(orders.size) for _ in range(3))
    for start in range(0, orders.size, ORDER_BLOCK):
        o = orders[start : start + ORDER_BLOCK]
        phase = np.outer(theta, o)
        c, s = np.cos(phase), np.sin(phase)
        cc, ss, cs = (np.einsum("ij,ij->j", a, b) for a, b in ((c, c), (s, s), (c, s)))
        xc, xs = residual @ c, residual @ s
        det = cc * ss - cs**2
        a, b = (ss * xc - cs * xs) / det, (cc * xs - cs * xc) / det
        explained = a * xc + b * xs  # coefᵀ Xᵀ r = coefᵀ (XᵀX) coef
        v = (rr - explained) / max(n - 2, 1)
        block = slice(start, start + o.size)
        chi2[block], amp[block], var[block] = explained / v, np.hypot(a, b), v
    return chi2, amp, var


def ripple_orders(recording: Recording) -> np.ndarray:
    """The integer orders of the primary shaft where a drive ripple is looked for: 1 up to
    where its frequency reaches :data:`RIPPLE_BAND` of the sample rate, except the multiples of
    the mesh order (a transmission error: :func:`mesh_order_evidence`), the orders within
    :data:`DECOY_CLEARANCE` resolutions of the driven wheel's first two orders (its run-out),
    and the orders that fall on a harmonic of the drive frequency (at any harmonic number):
    there the rattle's impacts, which repeat with the drive cycle and push back on the
    primary shaft, and an angle-locked ripple are the same sinusoid (the residual's fitted
    drive harmonics among them)."""
    speed = recording.operating.drive_mean_speed_rad_s / (2 * math.pi)  # rev/s
    top = int(RIPPLE_BAND * recording.sample_rate_hz / speed)
    orders = np.arange(1, max(top, 1) + 1)
    resolution = 1.0 / (speed * recording.duration)
    drive = recording.operating.drive_frequency_hz / speed  # the drive frequency as an order
    runout = np.arange(1, 3) / recording.gear_ratio
    near_runout = np.min(np.abs(orders[:, None] - runout[None]), axis=1)
    harmonic = orders / drive
    near_drive = np.abs(harmonic - np.round(harmonic)) * drive
    clear = np.minimum(near_runout, near_drive) > DECOY_CLEARANCE * resolution
    return orders[clear & (orders % recording.gear_pair.teeth_driving != 0)]


def local_inflation(chi2_half: np.ndarray) -> np.ndarray:
    """The noise level near each scanned order: the median single-order χ² of the
    :data:`RIPPLE_NEIGHBOURS` half-integer orders each side of it (``chi2_half`` (M,), at each
    scanned order + ½) over χ²₂'s median (M,)."""
    m = chi2_half.size
    out = np.empty(m)
    for i in range(m):
        near = chi2_half[max(i - RIPPLE_NEIGHBOURS, 0) : i + RIPPLE_NEIGHBOURS + 1]
        out[i] = np.median(near)
    return out / stats.chi2.median(2)


def quantisation_inflation(recording: Recording, orders, n_harmonics: int) -> np.ndarray:
    """The χ² (M,) that encoder quantisation alone leaves at each of ``orders``, over χ²₂'s
    median: the recording's own :func:`drive_fit`, counted with :data:`QUANTISATION_NULLS`
    count offsets (evenly spaced over one count: deterministic), each run through the same
    residual and projections as the recording; the median over the offsets."""
    smooth = drive_fit(recording, recording.theta_primary, n_harmonics)
    cpr = recording.counts_per_rev
    chi2 = []
    for offset in (np.arange(QUANTISATION_NULLS) + 0.5) / QUANTISATION_NULLS:
        theta = np.floor(smooth * cpr / (2 * math.pi) + offset) * (2 * math.pi / cpr)
        residual = theta - drive_fit(recording, theta, n_harmonics)
        chi2.append(order_projections(residual, theta, orders)[0])
    return np.median(chi2, axis=0) / stats.chi2.median(2)


def drive_order_evidence(recording: Recording, *, n_harmonics: int = 6) -> AngleTest:
    """Speed ripple of the primary shaft at any of its integer orders
    (:func:`ripple_orders`) that a fit by harmonics of the drive frequency does not hold (a
    drive ripple: an engine's firing order, an electric motor's cogging at its slot order):
    each order's single-sinusoid Wald χ² in the primary encoder's residual
    (:func:`primary_residual`), divided by the larger of the noise level of its
    neighbourhood (:func:`local_inflation`) and what the encoder's quantisation of the smooth
    drive leaves there (:func:`quantisation_inflation`); the test is the order of least p,
    its p corrected for the number of orders scanned (Šidák). ``amplitude`` is that order's
    acceleration amplitude (rad/s²); ``detail`` holds the order, its inflation and the number
    of orders scanned. Where every order falls on a drive harmonic (a drive fluctuating once
    per revolution, or at a whole multiple of it), nothing is scanned: a ripple could not be
    told from the drive, and the test has χ² 0 and p 1."""
    theta = recording.theta_primary
    orders = ripple_orders(recording)
    if orders.size == 0:
        detail = {"order": 0, "inflation": 1.0, "orders_scanned": 0}
        return AngleTest("drive_order", 0.0, 2, 1.0, 0.0, 0.0, detail)
    residual = primary_residual(recording, n_harmonics)
    chi2, amps, var = order_projections(residual, theta, orders)
    lam = np.maximum(
        local_inflation(order_projections(residual, theta, orders + 0.5)[0]),
        quantisation_inflation(recording, orders, n_harmonics),
    )
    p = stats.chi2.sf(chi2 / lam, 2)
    best = int(np.argmin(p))
    to_acc = (orders[best] * recording.operating.drive_mean_speed_rad_s) ** 2
    sd = math.sqrt(2.0 * lam[best] * var[best] / residual.size) * to_acc
    return AngleTest(
        name="drive_order",
        chi2=float(chi2[best] / lam[best]),
        dof=2,
        p_value=float(-np.expm1(orders.size * np.log1p(-p[best]))),
        amplitude=float(amps[best] * to_acc),
        amplitude_sd=sd,
        detail={
            "order": int(orders[best]),
            "inflation": float(lam[best]),
            "orders_scanned": int(orders.size),
        },
    )

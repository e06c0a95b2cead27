"""Sharp-switching reference solver of the one-dof rattle model (numpy + scipy, no JAX).

This module is the *ground truth* for the smoothed JAX simulator of :mod:`rattlefit.physics.model` and
the baseline a gear-dynamics engineer would write. It integrates the **unsmoothed** equations
with :func:`scipy.integrate.solve_ivp`, locating every contact onset and exit as a terminal
event and restarting there, so that no step ever straddles a discontinuity of the force law.

It is deliberately independent of :mod:`rattlefit.physics.model`: the laws are written again below from
the formulas (no function of ``model.py`` is called). It reads only scalar attributes of
:class:`~rattlefit.physics.geometry.GearGeometry` and the coefficient arrays of a
:class:`~rattlefit.physics.drive.Drive`.

The sharp equations
-------------------
State ``(q, v)``: ``q = r2·θ2 − r1·θ1`` (m), ``v = q̇`` (m/s); ``c`` is half the backlash and the
flank gaps are ``h₊ = c − q`` (coast flank) and ``h₋ = c + q`` (drive flank)::

    m v̇ = F_mesh + F_squeeze − T_b / r2 − m r1 θ̈1(t)
    F_mesh    = −K(θ1)·(max(0, −h₊) − max(0, −h₋))
    F_squeeze = −S(h₊)·max(v, 0)·[h₊ > 0] + S(h₋)·max(−v, 0)·[h₋ > 0]
    K(θ1)     = s_k k_p Σ_{pairs in contact} exp(C_a |(u − ε/2) / (1.125 εα)|³)
    S(h)      = 3 μ Z R^{3/2} h_e^{−3/2} G(a / √(R h_e)),   h_e = max(h, h_min)
    G(y)      = arctan y + y (y² − 1) / (1 + y²)²

where ``u = θ1/Θp − n`` is the engagement (in base pitches) of tooth pair ``n`` (an integer),
which is in contact while ``0 ≤ u ≤ ε``.

Switching
---------
* **Contact** (``h₋ = 0`` or ``h₊ = 0``) is a jump of ``F_squeeze`` and a kink of ``F_mesh``:
  the solver runs in one of three regimes — gap, drive-flank contact, coast-flank contact — and
  each regime watches only the terminal, direction-aware events that leave it. Within a regime
  the right-hand side is the smooth extension of that regime's law. To make the restart
  unambiguous the switches carry a hysteresis of ``δ = 10⁻⁹·c`` (a regime is entered at
  ``h = −δ`` and left at ``h = +δ``), far below any physical length of the problem.
* **Mesh windows** (a tooth pair entering or leaving contact) are jumps of ``K`` in *time*
  only, and matter only in contact. They are not state events: inside a contact regime each
  piece of integration ends at the next window switch, found in advance from θ1(t) alone by
  conservative advancement (a root finder that cannot skip a crossing, using the bound on
  |θ̇1|), and the set of pairs in contact is held fixed within each piece. ``max_step`` is
  therefore not needed for accuracy (it is passed through if given).
* ``max(v, 0)`` and the saturation ``max(h, h_min)`` are kinks (continuous force), which the
  error control of the integrator handles; they are not made events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import ParameterError, SolverError

__all__ = ["ReferenceSolution", "simulate_reference"]

_GAP, _DRIVE, _COAST = 0, 1, 2
#: Relative hysteresis of the contact switches (fraction of half the backlash).
_HYSTERESIS = 1e-9


@dataclass(frozen=True)
class ReferenceSolution:
    """Output of :func:`simulate_reference`.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times ``k / sample_rate``, s.
    q : ndarray, shape (N,)
        Relative displacement on the pitch circle ``r2·θ2 − r1·θ1``, m.
    v : ndarray, shape (N,)
        Its rate ``q̇``, m/s.
    relative_motion : ndarray, shape (N,)
        Recorded relative motion ``Δθ* = −q / r1`` (eq. 6), rad.
    n_events : int
        Contact switches (onsets and exits) located, burn-in included.
    n_rhs : int
        Right-hand-side evaluations, burn-in included (for benchmarks).
    event_times : ndarray
        Times of those contact switches, s (burn-in ones are negative).
    """

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray
    relative_motion: np.ndarray
    n_events: int
    n_rhs: int
    event_times: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _scalar(name, value):
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 0:
        raise ParameterError(f"reference solver: {name} must be a scalar, got shape {arr.shape}")
    x = float(arr)
    if not math.isfinite(x):
        raise ParameterError(f"reference solver: {name} must be finite, got {x}")
    return x


def simulate_reference(
    geometry,
    drive,
    *,
    film_half_length,
    drag_torque,
    viscosity,
    backlash,
    min_film=2e-6,  # model.DEFAULT_MIN_FILM (this module stays free of JAX)
    stiffness_scale=1.0,
    duration=3.0,
    sample_rate=10_000.0,
    burn_in=0.5,
    method="DOP853",
    rtol=1e-8,
    atol=1e-11,
    max_step=None,
    initial_state=None,
) -> ReferenceSolution:
    """Integrate the sharp (unsmoothed) rattle model with event location at contact switches.

    Parameters
    ----------
    geometry : GearGeometry
        The gear pair; only its scalar attributes are read (m, r1, r2, k_p, C_a, ε, εα, Θp,
        R, Z).
    drive : Drive
        Primary-shaft motion θ1(t) (one unbatched drive); its coefficients are read as numpy.
    film_half_length : float
        a of eq. (5), m (0 disables the squeeze film).
    drag_torque : float
        T_b, bearing drag torque on the driven gear, N m.
    viscosity : float
        μ, oil viscosity between the flanks, Pa s.
    backlash : float
        Total circumferential backlash on the pitch circle, m (the flank gap is half of it).
    min_film : float, optional
        h_min, film thickness at which the squeeze damping saturates, m.
    stiffness_scale : float, optional
        s_k, factor on the mesh stiffness, dimensionless.
    duration : float, optional
        Recorded duration, s; samples are taken at ``k / sample_rate``, ``k = 0 … N−1`` with
        ``N = round(duration · sample_rate)``.
    sample_rate : float, optional
        Hz.
    burn_in : float, optional
        The integration starts at ``t0 = −burn_in``, s (≥ 0).
    method : str, optional
        :func:`scipy.integrate.solve_ivp` method (explicit ones are fastest here).
    rtol, atol : float, optional
        Integrator tolerances (``atol`` applies to q in m and v in m/s alike).
    max_step : float, optional
        Largest integrator step, s (default unbounded; see the module notes on mesh windows).
    initial_state : (float, float), optional
        ``(q0, v0)`` at ``t0`` in m and m/s. Default: resting on the drive flank, statically
        deflected by the drag, ``q0 = −c − (T_b / r2) / K(θ1(t0))``, ``v0 = 0``.

    Returns
    -------
    ReferenceSolution

    Raises
    ------
    ParameterError
        On non-physical inputs.
    SolverError
        If ``solve_ivp`` fails or the switching loop stops making progress.
    """
    g = geometry
    m = float(g.equivalent_mass)
    r1 = float(g.pitch_radius_driving)
    r2 = float(g.pitch_radius_driven)
    eps = float(g.total_contact_ratio)
    eps_a = float(g.transverse_contact_ratio)
    theta_p = float(g.base_pitch_angle)
    c_a = float(g.stiffness_shape)
    radius = float(g.curvature_radius)
    width = float(g.axial_width)

    a = _scalar("film_half_length", film_half_length)
    t_b = _scalar("drag_torque", drag_torque)
    mu = _scalar("viscosity", viscosity)
    b = _scalar("backlash", backlash)
    h_min = _scalar("min_film", min_film)
    s_k = _scalar("stiffness_scale", stiffness_scale)
    duration = _scalar("duration", duration)
    sample_rate = _scalar("sample_rate", sample_rate)
    burn_in = _scalar("burn_in", burn_in)
    checks = {
        "film_half_length": a >= 0,
        "viscosity": mu >= 0,
        "backlash": b > 0,
        "min_film": h_min > 0,
        "stiffness_scale": s_k > 0,
        "duration": duration > 0,
        "sample_rate": sample_rate > 0,
        "burn_in": burn_in >= 0,
        "rtol": rtol > 0,
        "atol": atol > 0,
    }
    for name, ok in checks.items():
        if not ok:
            raise ParameterError(f"reference solver: {name} is out of range")
    n_samples = round(duration * sample_rate)
    if n_samples < 1:
        raise ParameterError("reference solver: duration · sample_rate must be at least 1")

    c = 0.5 * b
    drag = t_b / r2
    k_scale = s_k * float(g.pitch_point_stiffness)
    shape_den = 1.125 * eps_a
    s_pref = 3.0 * mu * width * radius**1.5
    has_squeeze = a > 0.0 and mu > 0.0
    delta = _HYSTERESIS * c

    # -- drive: θ1(t) = θ0 + Ω t + Σ A_k cos(ω_k t) + B_k sin(ω_k t) ----------------------
    omega = _scalar("drive.mean_speed", drive.mean_speed)
    freq = _scalar("drive.frequency", drive.frequency)
    theta0 = _scalar("drive.offset", drive.offset)
    cos_c = np.asarray(drive.cos_coeffs, dtype=float)
    sin_c = np.asarray(drive.sin_coeffs, dtype=float)
    if cos_c.ndim != 1 or cos_c.shape != sin_c.shape:
        raise ParameterError("reference solver: the drive must be a single (unbatched) drive")
    harmonics = [
        (2.0 * math.pi * freq * k, 4.0 * math.pi**2 * freq**2 * k**2, float(ak), float(bk))
        for k, (ak, bk) in enumerate(zip(cos_c, sin_c, strict=True), start=1)
        if ak != 0.0 or bk != 0.0
    ]
    # Bound on |dθ1/dt| / Θp, for the conservative search of mesh-window switches.
    speed_bound = abs(omega) + sum(w * (abs(ak) + abs(bk)) for w, _, ak, bk in harmonics)
    pitch_rate_bound = speed_bound / theta_p

    def angle_and_accel(t):
        th = theta0 + omega * t
        acc = 0.0
        for w, w2, ak, bk in harmonics:
            ph = w * t
            x = ak * math.cos(ph) + bk * math.sin(ph)
            th += x
            acc -= w2 * x
        return th, acc

    def pitch_and_rate(t):
        th = theta0 + omega * t
        rate = omega
        for w, _, ak, bk in harmonics:
            ph = w * t
            cs, sn = math.cos(ph), math.sin(ph)
            th += ak * cs + bk * sn
            rate += w * (bk * cs - ak * sn)
        return th / theta_p, rate / theta_p

    # -- constitutive laws (pure Python floats) ------------------------------------------
    def stiffness(theta1, n_lo, n_hi):
        """K of eq. (4) with the pairs n_lo … n_hi in contact, N/m."""
        p = theta1 / theta_p
        total = 0.0
        for n in range(n_lo, n_hi + 1):
            z = abs((p - n - 0.5 * eps) / shape_den)
            total += math.exp(c_a * z * z * z)
        return k_scale * total

    def squeeze(h):
        """S(max(h, h_min)) of eq. (5), N s/m."""
        if h < h_min:
            h = h_min
        y = a / math.sqrt(radius * h)
        y2 = y * y
        if y < 1e-2:
            gy = (8.0 / 3.0) * y2 * y * (1.0 - 1.8 * y2 + (18.0 / 7.0) * y2 * y2)
        else:
            gy = math.atan(y) + y * (y2 - 1.0) / (1.0 + y2) ** 2
        return s_pref * gy / (h * math.sqrt(h))

    # -- mesh windows ------------------------------------------------------------------
    def window(t, t_limit):
        """Pairs in contact just after t, and the next time (≤ t_limit, else inf) they change."""
        p, rate = pitch_and_rate(t)
        tol = max(1e-11, 64.0 * np.finfo(float).eps * abs(p))
        nudge = 10.0 * tol
        pe = p + math.copysign(nudge, rate) if rate != 0.0 else p
        n_hi = math.floor(pe)
        n_lo = math.ceil(pe - eps)
        lo, hi = max(n_hi, n_lo - 1 + eps), min(n_hi + 1, n_lo + eps)
        if pitch_rate_bound == 0.0:
            return n_lo, n_hi, math.inf
        s = t
        if rate != 0.0 and min(p - lo, hi - p) < nudge:  # just crossed into this window
            s = t + 2.0 * nudge / abs(rate)
        for _ in range(200):
            if s >= t_limit:
                return n_lo, n_hi, math.inf
            p = pitch_and_rate(s)[0]
            d = min(p - lo, hi - p)
            if d <= tol:
                return n_lo, n_hi, s
            s += d / pitch_rate_bound
        return n_lo, n_hi, s  # an early (spurious) breakpoint is harmless

    # -- right-hand sides of the three regimes --------------------------------------------
    def rhs_gap(t, y):
        q, v = y.tolist()
        _, acc1 = angle_and_accel(t)
        f = -drag
        if has_squeeze:
            if v > 0.0:
                f -= squeeze(c - q) * v
            elif v < 0.0:
                f -= squeeze(c + q) * v
        return [v, f / m - r1 * acc1]

    def make_contact_rhs(regime, n_lo, n_hi):
        if regime == _DRIVE:

            def rhs(t, y):
                q, v = y.tolist()
                th, acc1 = angle_and_accel(t)
                f = -stiffness(th, n_lo, n_hi) * (c + q) - drag
                if has_squeeze and v > 0.0:
                    f -= squeeze(c - q) * v
                return [v, f / m - r1 * acc1]

        else:

            def rhs(t, y):
                q, v = y.tolist()
                th, acc1 = angle_and_accel(t)
                f = stiffness(th, n_lo, n_hi) * (c - q) - drag
                if has_squeeze and v < 0.0:
                    f -= squeeze(c + q) * v
                return [v, f / m - r1 * acc1]

        return rhs

    # -- events: each regime watches only the switches that leave it ------------------------
    def _event(fun, direction):
        fun.terminal = True
        fun.direction = direction
        return fun

    gap_events = [
        _event(lambda t, y: (c - y[0]) + delta, -1.0),  # → coast contact (h₊ falls to −δ)
        _event(lambda t, y: (c + y[0]) + delta, -1.0),  # → drive contact (h₋ falls to −δ)
    ]
    gap_targets = [_COAST, _DRIVE]
    leave_drive = [_event(lambda t, y: (c + y[0]) - delta, 1.0)]  # h₋ rises to +δ
    leave_coast = [_event(lambda t, y: (c - y[0]) - delta, 1.0)]  # h₊ rises to +δ

    # -- initial state -----------------------------------------------------------------
    t0 = -burn_in
    if initial_state is None:
        n_lo, n_hi, _ = window(t0, t0)
        k0 = stiffness(angle_and_accel(t0)[0], n_lo, n_hi)
        y = np.array([-c - drag / k0, 0.0])
    else:
        q0, v0 = initial_state
        y = np.array([_scalar("initial q", q0), _scalar("initial v", v0)])
    if c + y[0] <= 0.0:
        regime = _DRIVE
    elif c - y[0] <= 0.0:
        regime = _COAST
    else:
        regime = _GAP

    # -- piecewise integration -----------------------------------------------------------
    times = np.arange(n_samples) / sample_rate
    t_end = duration
    out = np.empty((2, n_samples))
    filled = 0
    n_rhs = 0
    event_times: list[float] = []
    step_limit = np.inf if max_step is None else float(max_step)
    t = t0
    stalled = 0
    while t < t_end:
        if regime == _GAP:
            fun, events, bound = rhs_gap, gap_events, t_end
        else:
            n_lo, n_hi, t_switch = window(t, t_end)
            fun = make_contact_rhs(regime, n_lo, n_hi)
            events = leave_drive if regime == _DRIVE else leave_coast
            bound = min(t_end, t_switch)
        if bound <= t:  # a window switch closer than the time resolution
            bound = min(t_end, math.nextafter(t, math.inf))
        sol = solve_ivp(
            fun,
            (t, bound),
            y,
            method=method,
            rtol=rtol,
            atol=atol,
            max_step=step_limit,
            events=events,
            dense_output=True,
        )
        if sol.status == -1:
            raise SolverError(f"reference solver failed at t = {t:.9g} s: {sol.message}")
        n_rhs += int(sol.nfev)
        t_new = float(sol.t[-1])
        i1 = int(np.searchsorted(times, t_new, side="right"))
        if i1 > filled:
            out[:, filled:i1] = sol.sol(times[filled:i1]) if sol.sol is not None else sol.y[:, -1:]
            filled = i1
        if sol.status == 1:  # a contact switch
            hits = [(float(te[0]), i) for i, te in enumerate(sol.t_events) if te.size]
            t_new, i = min(hits)
            y = np.asarray(sol.y_events[i][0], dtype=float)
            regime = gap_targets[i] if regime == _GAP else _GAP
            event_times.append(t_new)
        else:
            y = sol.y[:, -1].copy()
        stalled = stalled + 1 if t_new <= t else 0
        if stalled > 100:
            raise SolverError(f"reference solver stalled at t = {t:.9g} s (Zeno switching?)")
        t = t_new
    if filled < n_samples:  # only possible through rounding at the very end
        out[:, filled:] = y[:, None]

    q, v = out
    return ReferenceSolution(
        time=times,
        q=q,
        v=v,
        relative_motion=-q / r1,
        n_events=len(event_times),
        n_rhs=n_rhs,
        event_times=np.asarray(event_times),
    )

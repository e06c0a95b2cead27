"""The one-dof rattle model of the seed paper, eqs. (1)–(5), with smoothed contact switching.

Coordinate and sign convention
------------------------------
The state is ``y = (q, v)``: ``q = r2·θ2 − r1·θ1`` (m) is the paper's ``r2·Δθ`` of eq. (1),
the driven gear's lead over the driving gear on the pitch circle, and ``v = q̇`` (m/s). The
recorded relative motion of eq. (6) is ``Δθ* = −q / r1``. With ``c`` half the circumferential
backlash the flanks touch at ``q = −c`` (drive side: the driving gear pushes) and ``q = +c``
(coast side). The equation of motion, eq. (2) divided by r2, is

    m q̈ = F_mesh + F_squeeze − T_b / r2 − m r1 θ̈1(t),        m = I2 / r2²

* mesh contact (eq. 3, first line): ``F_mesh = −K(θ1)·[P(q − c) − P(−q − c)]``, P the
  penetration (``max(0, ·)``, smoothed by a softplus of width ``contact_width``);
* mesh stiffness (eq. 4): ``K(θ1)`` is the sum over the tooth pairs in contact of
  ``k_p·exp(C_a·|(φ − εΘp/2)/(1.125 εα Θp)|³)``, φ ∈ [0, εΘp] the engagement angle of the pair
  (pair windows smoothed over ``mesh_width`` base pitches; periodic in θ1 with Θp, so
  tabulated over one pitch), scaled by ``stiffness_scale``;
* squeeze film (eq. 3, second and third lines; eq. 5): the film ahead of the motion resists the
  approach, ``F_squeeze = −S(h₊)·max(v, 0)·g(h₊) + S(h₋)·max(−v, 0)·g(h₋)`` with the gaps
  ``h± = c ∓ q``, ``g`` the gap indicator (1 while the flanks are apart) and S evaluated at
  ``max(h, h_min)`` (saturation at S_max = S(h_min));
* drag: the constant bearing drag torque T_b opposes the driven gear's (always forward)
  rotation.

Eq. (3) writes the elastic force as ``K·r2Δθ``; rattlefit uses the penetration ``K·(|q| − c)``
so that the force is continuous at first touch, as every contact model does.

Extra physical effects (flank friction, run-out, ...) plug in through :class:`Effect`: each is a
self-contained module that may add a force and/or a kinematic error to the flank gap.
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int
from scipy import special

from ..config import require_x64
from ..errors import ParameterError
from ..quantities import QUANTITIES
from ..util import array_namespace, concrete
from .drive import Drive
from .elementary import arctan
from .geometry import GearGeometry

Scalar = Float[Array, "*batch"]

#: Default h_min, m. The paper gives no value; the sample recordings of ../shared pin it: in mild
#: rattle (pair II, 65.0 mm, 10 % at 8 Hz) the model at the true a, T_b and μ reproduces the
#: recorded motion cycle for cycle with h_min = 2 µm (band-feature rms deviation 0.07, against
#: 0.18 at 1.5 µm, 0.24 at 2.5 µm and 0.21 at 10 µm). The fit treats it as a nuisance with a prior.
DEFAULT_MIN_FILM = 2e-6

#: Upper bound on tooth pairs in contact at once (ε < 3 for automotive helical pairs; +1 margin).
MAX_PAIRS_IN_CONTACT = 4

#: K(θ1) is tabulated over one base pitch with at least this many nodes per ``mesh_width``
#: (cubic Hermite between nodes: relative error ≈ 1e-8 at 32), …
TABLE_NODES_PER_WIDTH = 32
#: … and at most this many nodes; a narrower window (a convergence study's) is summed exactly.
TABLE_MAX_NODES = 1 << 16


def _stiffness_shape(u, eps, eps_a, shape, width, xp=np):
    """K/k_p of eq. (4) at ``u`` = θ1/Θp (mod 1) and its derivative in u: the sum over the
    tooth pairs at engagement positions u + j, each inside its smoothed window [0, ε].

    The positions run from u − 1 so that a pair entering at a base-pitch boundary has both
    halves of its smoothed step (summing from u alone cut the step at u = 0 and made K jump by
    half a pair's stiffness there at every base pitch); the shape is then periodic in u.
    ``xp`` is numpy (tables) or jax.numpy (the exact sum in the vector field).
    """
    sigmoid = jax.nn.sigmoid if xp is jnp else special.expit
    pos = u[..., None] + xp.arange(-1, MAX_PAIRS_IN_CONTACT)
    enter, leave = sigmoid(pos / width), sigmoid((eps - pos) / width)
    d = (pos - eps / 2) / (1.125 * eps_a)
    pair = enter * leave * xp.exp(shape * xp.abs(d) ** 3)
    slope = (1 - enter) / width - (1 - leave) / width + 3 * shape * d * xp.abs(d) / (1.125 * eps_a)
    return pair.sum(-1), (pair * slope).sum(-1)


def _hermite(table, u, row=None):
    """Periodic cubic Hermite interpolation on u ∈ [0, 1) of a table of values and slopes
    (2, n), or of row ``row`` of a stack of them (T, 2, n). C¹: K and dK/dθ1 are continuous, as
    the adaptive solver's error control assumes."""
    n = table.shape[-1]
    s = u * n
    i = jnp.clip(jnp.floor(s).astype(int), 0, n - 1)
    f = s - i
    j = jnp.where(i + 1 == n, 0, i + 1)
    at = (lambda k, m: table[k, m]) if row is None else (lambda k, m: table[row, k, m])
    f2, f3 = f * f, f * f * f
    return (
        (2 * f3 - 3 * f2 + 1) * at(0, i)
        + (f3 - 2 * f2 + f) * at(1, i) / n
        + (3 * f2 - 2 * f3) * at(0, j)
        + (f3 - f2) * at(1, j) / n
    )


def _positive_field(name, value, *, allow_zero=False):
    arr = concrete(value)
    if arr is None:
        return
    ok = np.isfinite(arr) & ((arr >= 0) if allow_zero else (arr > 0))
    if not np.all(ok):
        bound = "≥ 0" if allow_zero else "> 0"
        raise ParameterError(f"parameter {name} must be finite and {bound}, got {arr}")


class RattleParams(eqx.Module):
    """The identifiable physical parameters (a pytree: batch it by giving leading axes).

    Attributes
    ----------
    film_half_length : a of eq. (5), semi-length of the oil film along the flanks, m (≥ 0;
        0 means dry).
    drag_torque : T_b, bearing drag torque on the driven gear, N m (≥ 0).
    viscosity : μ, effective dynamic viscosity of the oil between the flanks, Pa s (> 0).
    min_film : h_min, adsorbed film thickness at which squeeze damping saturates, m (> 0).
    stiffness_scale : factor on the default (ISO 6336) mesh stiffness, dimensionless (> 0).
    backlash : total circumferential backlash on the pitch circle, m (> 0).
    """

    film_half_length: Scalar
    drag_torque: Scalar
    viscosity: Scalar
    min_film: Scalar
    stiffness_scale: Scalar
    backlash: Scalar

    def __init__(
        self,
        film_half_length,
        drag_torque,
        viscosity,
        backlash,
        *,
        min_film=DEFAULT_MIN_FILM,
        stiffness_scale=1.0,
    ):
        self.film_half_length = jnp.asarray(film_half_length, dtype=float)
        self.drag_torque = jnp.asarray(drag_torque, dtype=float)
        self.viscosity = jnp.asarray(viscosity, dtype=float)
        self.backlash = jnp.asarray(backlash, dtype=float)
        self.min_film = jnp.asarray(min_film, dtype=float)
        self.stiffness_scale = jnp.asarray(stiffness_scale, dtype=float)

    def __check_init__(self):
        _positive_field("film_half_length", self.film_half_length, allow_zero=True)
        _positive_field("drag_torque", self.drag_torque, allow_zero=True)
        _positive_field("viscosity", self.viscosity)
        _positive_field("backlash", self.backlash)
        _positive_field("min_film", self.min_film)
        _positive_field("stiffness_scale", self.stiffness_scale)
        b, h = concrete(self.backlash), concrete(self.min_film)
        if b is not None and h is not None and np.any(2 * h >= b):
            raise ParameterError(
                f"parameter min_film ({h} m) must be well below half the backlash ({b / 2} m)"
            )

    def as_dict(self) -> dict[str, np.ndarray]:
        """Field name → numpy value (SI units)."""
        return {k: np.asarray(getattr(self, k)) for k in PARAM_UNITS}

    @classmethod
    def from_dict(cls, values) -> RattleParams:
        """The inverse of :meth:`as_dict`: field name → value (SI); ``min_film`` and
        ``stiffness_scale`` may be left out (their defaults), other names are ignored."""
        optional = {k: values[k] for k in ("min_film", "stiffness_scale") if k in values}
        return cls(
            values["film_half_length"],
            values["drag_torque"],
            values["viscosity"],
            values["backlash"],
            **optional,
        )


#: Parameter names with their SI units (:data:`rattlefit.quantities.QUANTITIES`' units).
PARAM_UNITS = {
    name: QUANTITIES[name].unit
    for name in (
        "film_half_length",
        "drag_torque",
        "viscosity",
        "min_film",
        "stiffness_scale",
        "backlash",
    )
}


class Smoothing(eqx.Module):
    """Widths over which the sharp switches of the model are smoothed.

    ``contact_width`` (m) smooths contact onset and the film-saturation kink (softplus and
    logistic of that width); ``mesh_width`` (in base pitches) smooths the entry and exit of a
    tooth pair in eq. (4). Both → 0 recovers the sharp model.
    """

    contact_width: float = eqx.field(static=True, default=0.1e-6)
    mesh_width: float = eqx.field(static=True, default=0.01)

    def __check_init__(self):
        if not (self.contact_width > 0 and self.mesh_width > 0):
            raise ParameterError("smoothing widths must be positive")

    def scaled(self, factor: float) -> Smoothing:
        """Both widths multiplied by ``factor``."""
        return Smoothing(self.contact_width * factor, self.mesh_width * factor)


def squeeze_coefficient(h, a, viscosity, radius, width):
    """Squeeze-film damping coefficient S(h) of eq. (5), N s/m (magnitude).

    Written as ``S = 3 μ Z R^{3/2} h^{-3/2} G(a/√(R h))`` with
    ``G(y) = arctan y + y (y² − 1)/(1 + y²)²``, which is eq. (5) exactly; ``G → π/2`` for a long
    film (a ≫ √(Rh)) and ``G ≈ (8/3) y³`` for a short one, where S → 8 μ Z a³ / h³ (parallel
    plates). The short-film series (8/3) y³ (1 − 9y²/5 + 18y⁴/7) is used below y = 10⁻², where
    the closed form loses digits to cancellation.
    """
    # one square root serves y and R^{3/2} h^{-3/2} = R³ / (R h)^{3/2}: the power h^{-1.5} (a log
    # and an exp) would dominate the squeeze force's cost. Outside a trace (a fit's host side:
    # equivalent_viscosity) it is numpy.
    xp = array_namespace(h, a, viscosity, radius, width)
    atan = arctan if xp is jnp else np.arctan
    root = xp.sqrt(radius * h)
    y = a / root
    small = y < 1e-2
    ys = xp.where(small, 0.5, y)  # keep the unused branch finite (and its gradient)
    g_full = atan(ys) + ys * (ys**2 - 1.0) / (1.0 + ys**2) ** 2
    g_series = (8.0 / 3.0) * y**3 * (1.0 - 1.8 * y**2 + (18.0 / 7.0) * y**4)
    g = xp.where(small, g_series, g_full)
    return 3.0 * viscosity * width * radius**3 * g / (root * root * root)


def equivalent_viscosity(h, a, viscosity, a_new, radius):
    """The viscosity (Pa s, or a factor on it) with which film half-length ``a_new`` (m)
    gives the squeeze coefficient that ``a`` and ``viscosity`` give at gap ``h`` (m).

    S is proportional to μ (eq. 5), so this is ``viscosity · S(h; a) / S(h; a_new)``; the
    flank width cancels. Where the film saturates (a ≫ √(R h)) the ratio tends to one, and a
    long film trades against the viscosity only through the gaps where it does not: the
    valley that a fit under oil jet follows in (a, μ) (:func:`rattlefit.inference.fit.identify`).
    """
    return (
        viscosity
        * squeeze_coefficient(h, a, 1.0, radius, 1.0)
        / squeeze_coefficient(h, a_new, 1.0, radius, 1.0)
    )


def film_saturation(y):
    """ψ(y) = arctan y − y/(1 + y²) of :func:`squeeze_momentum`, y = a/√(R h_min): (2/3) y³
    for a short film (the series below y = 10⁻², where the closed form cancels), π/2 for a
    saturated one; increasing."""
    xp = array_namespace(y)
    atan = arctan if xp is jnp else np.arctan
    ys = xp.where(y < 1e-2, 0.5, y)  # keep the unused branch finite
    return xp.where(
        y < 1e-2, (2.0 / 3.0) * y**3 * (1.0 - 1.8 * y**2), atan(ys) - ys / (1.0 + ys**2)
    )


def squeeze_momentum(a, viscosity, min_film, radius, width):
    """The momentum the squeeze film takes from one approach of the flanks down to h_min:
    ``M = ∫_{h_min}^∞ S(h) dh`` (N s) of eq. (5)'s coefficient S, the impulse ``∫ F dt`` of
    the squeeze force ``F = S(h) ḣ`` whatever the approach speed.

    In closed form ``M = 6 μ Z R^{3/2} h_min^{-1/2} ψ(a/√(R h_min))``
    (:func:`film_saturation`): ``M → 4 μ Z a³/h_min²`` for a short film and
    ``3π μ Z R^{3/2} h_min^{-1/2}`` for a long one, saturated in ``a``.
    """
    xp = array_namespace(a, viscosity, min_film, radius, width)
    root = xp.sqrt(radius * min_film)
    return 6.0 * viscosity * width * radius * root / min_film * film_saturation(a / root)


#: Bisection steps of :func:`film_for_squeeze_momentum` on ln y over ±ln 10⁶: 2⁻⁶⁴ of that
#: span, below a float's resolution.
MOMENTUM_BISECTIONS = 64
#: ln of the largest y = a/√(R h_min) :func:`film_for_squeeze_momentum` returns.
LN_Y_END = 6.0 * math.log(10.0)


def film_for_squeeze_momentum(momentum, viscosity, min_film, radius, width):
    """The film half-length ``a`` (m) whose :func:`squeeze_momentum` is ``momentum`` (N s),
    by bisection on ln y (ψ is increasing). Beyond the saturated film's momentum no ``a``
    reaches it, and ``a`` is that of y = 10⁶, a film far longer than any flank."""
    xp = array_namespace(momentum, viscosity, min_film, radius, width)
    root = xp.sqrt(radius * min_film)
    target = momentum * min_film / (6.0 * viscosity * width * radius * root)  # ψ(y)
    lo = xp.full_like(target, -LN_Y_END)
    hi = xp.full_like(target, LN_Y_END)
    for _ in range(MOMENTUM_BISECTIONS):
        mid = 0.5 * (lo + hi)
        above = film_saturation(xp.exp(mid)) > target
        lo, hi = xp.where(above, lo, mid), xp.where(above, mid, hi)
    return root * xp.exp(0.5 * (lo + hi))


class Effect(eqx.Module):
    """An extra physical effect outside the seed paper's model (the plug-in contract).

    An effect is a small immutable module; its array fields are its parameters (SI units).
    Subclasses override any of three hooks; each must be a pure JAX function of its inputs:

    * :meth:`gap_error` — a kinematic error (m) that shifts the flank positions, e.g. wheel
      run-out or tooth errors: the contact and squeeze laws see ``q − gap_error``.
    * :meth:`force` — an extra force on the pitch circle (N), e.g. flank friction or a
      speed-dependent drag; it is given the contact force ``f_mesh`` already computed.
    * :meth:`adjust` — the parameters in force at time ``t``, e.g. a viscosity that drifts.

    An effect may also carry state of its own (another degree of freedom, e.g. a shaft with
    inertia): ``states`` components appended to the model's ``(q, v)``, in the units
    ``state_units`` (``"m"`` or ``"m/s"``, which pick the solver's absolute tolerance), and
    the hooks

    * :meth:`coupled` — given its state and the net force on the driven gear from everything
      else, the force it adds on the pitch circle and its state's time derivative;
    * :meth:`initial_state` — its state at the start, given the model's ``(q, v)`` there
      (zero by default).

    Four class attributes let :mod:`rattlefit.diagnosis.diagnose` fit and judge the effect:
    ``name`` (its short name), ``ranges`` (fitted field → (unit, lower, upper)),
    ``shape_fields`` (the fields that shape the effect without sizing it, e.g. a frequency)
    and ``mechanism`` (the physics it stands for, shared by candidates that are other forms
    of one mechanism, e.g. ``"dissipation in contact"``; default: its name). The lower ends
    of the other fields' ranges stand for the effect being absent, whatever the shape fields
    are. A fifth, ``typical``, is the physical reference a fitted size is stated against:
    (typical value of the first ranged field in its unit, where that value comes from); a
    diagnosis names an effect from the band spectrum only when the lower end of its size's
    interval reaches a share of it (:data:`rattlefit.diagnosis.size.RELEVANT_SHARE`), and
    None leaves the size unreferenced. ``tried_by_default`` (default True) False keeps the
    effect out of a diagnosis' default candidates (it is tried on request).

    What a recording shows of the effect without any model: ``evidence``, the family of the
    model-free test that finds it (:mod:`rattlefit.diagnosis.evidence`: ``"runout"``,
    ``"mesh_order"``, ``"tooth"``, ``"drift"``, ``"drive_order"``; None: no such test);
    ``encoder_visible`` (default False), True for an effect the encoders see directly (a
    kinematic error or a drive ripple), which is named only when its test finds it and left
    out of the diagnosis' program when not; ``named_only_when_found`` (default False), True
    for another effect named only when its test finds it; ``relevant_size`` (m), the smallest
    flank pattern worth naming as a gap error on the pitch circle (None: no floor).
    :mod:`rattlefit.diagnosis.policy` reads these. :mod:`rattlefit.physics.effects` holds the
    catalogue.
    """

    name: ClassVar[str] = "effect"
    mechanism: ClassVar[str | None] = None
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {}
    shape_fields: ClassVar[tuple[str, ...]] = ()
    typical: ClassVar[tuple[float, str] | None] = None
    tried_by_default: ClassVar[bool] = True
    evidence: ClassVar[str | None] = None
    encoder_visible: ClassVar[bool] = False
    named_only_when_found: ClassVar[bool] = False
    relevant_size: ClassVar[float | None] = None
    states: ClassVar[int] = 0
    state_units: ClassVar[tuple[str, ...]] = ()

    def gap_error(self, t, theta1, model: RattleModel, params: RattleParams, drive: Drive):
        return jnp.zeros(())

    def force(self, t, q, v, f_mesh, model: RattleModel, params: RattleParams, drive: Drive):
        return jnp.zeros(())

    def adjust(self, t, params: RattleParams, model: RattleModel, drive: Drive) -> RattleParams:
        return params

    def coupled(self, t, q, v, state, f_gear, model: RattleModel, params, drive: Drive):
        """(force on the pitch circle, N; d state/dt) for an effect with ``states`` > 0;
        ``f_gear`` is the net force on the driven gear from everything else (N)."""
        return jnp.zeros(()), jnp.zeros((self.states,))

    def initial_state(self, q, v):
        """The effect's own state (…, ``states``) at the start, where the model's state is
        ``(q, v)`` (arrays of one shape): zero."""
        return jnp.zeros((*jnp.shape(q), self.states))

    def replace(self, **values) -> Effect:
        """The same effect with the named fields replaced (values as arrays)."""
        names = tuple(values)
        return eqx.tree_at(
            lambda e: tuple(getattr(e, n) for n in names),
            self,
            tuple(jnp.asarray(values[n], dtype=float) for n in names),
        )


class RattleModel(eqx.Module):
    """The gear pair's constants, the smoothing and the extra effects: the vector field.

    Build with :meth:`from_geometry`. Geometry constants are arrays (not static), so one
    compiled simulator serves every pair and centre distance.
    """

    mass: Float[Array, ""]  #: I2/r2², kg
    r1: Float[Array, ""]  #: m
    r2: Float[Array, ""]  #: m
    pitch_stiffness: Float[Array, ""]  #: k_p, N/m
    stiffness_shape: Float[Array, ""]  #: C_a
    contact_ratio: Float[Array, ""]  #: ε
    transverse_contact_ratio: Float[Array, ""]  #: εα
    base_pitch_angle: Float[Array, ""]  #: Θp, rad
    curvature_radius: Float[Array, ""]  #: R, m
    axial_width: Float[Array, ""]  #: Z, m
    smoothing: Smoothing
    effects: tuple[Effect, ...]
    #: K/k_p and its u-derivative at ``n`` nodes over one base pitch (see :meth:`mesh_stiffness`),
    #: or None where ``mesh_width`` is too narrow to tabulate (then summed exactly); (T, 2, n)
    #: when a batch of models shares a stack of tables (see :func:`share_stiffness_tables`)
    stiffness_table: Float[Array, "2 n"] | Float[Array, "T 2 n"] | None = None
    #: this model's row of a shared stack of tables, or None for a table of its own
    table_row: Int[Array, ""] | None = None

    @classmethod
    def from_geometry(
        cls,
        geometry: GearGeometry,
        *,
        smoothing: Smoothing | None = None,
        effects: tuple[Effect, ...] = (),
    ) -> RattleModel:
        """The model of the gear pair ``geometry``, its contact smoothed by ``smoothing``
        (default :class:`Smoothing`), with ``effects`` added. Raises
        :class:`~rattlefit.RattlefitError` when JAX's 64-bit mode is off
        (:func:`rattlefit.configure`)."""
        require_x64("RattleModel.from_geometry")
        g = geometry
        f = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
        smoothing = smoothing or Smoothing()
        nodes = 1 << max(10, math.ceil(math.log2(TABLE_NODES_PER_WIDTH / smoothing.mesh_width)))
        table = None
        if nodes <= TABLE_MAX_NODES:
            table = f(
                _stiffness_shape(
                    np.arange(nodes) / nodes,
                    g.total_contact_ratio,
                    g.transverse_contact_ratio,
                    g.stiffness_shape,
                    smoothing.mesh_width,
                )
            )
        return cls(
            mass=f(g.equivalent_mass),
            r1=f(g.pitch_radius_driving),
            r2=f(g.pitch_radius_driven),
            pitch_stiffness=f(g.pitch_point_stiffness),
            stiffness_shape=f(g.stiffness_shape),
            contact_ratio=f(g.total_contact_ratio),
            transverse_contact_ratio=f(g.transverse_contact_ratio),
            base_pitch_angle=f(g.base_pitch_angle),
            curvature_radius=f(g.curvature_radius),
            axial_width=f(g.axial_width),
            smoothing=smoothing,
            effects=tuple(effects),
            stiffness_table=table,
        )

    def with_effects(self, *effects: Effect) -> RattleModel:
        """The same model with extra effects appended."""
        return eqx.tree_at(lambda m: m.effects, self, self.effects + tuple(effects))

    # -- the state ----------------------------------------------------------------------
    @property
    def state_size(self) -> int:
        """Components of the state: ``(q, v)`` and every effect's own (:attr:`Effect.states`)."""
        return 2 + sum(e.states for e in self.effects)

    def full_state(self, y0):
        """``y0`` (…, 2) or (…, :attr:`state_size`) as the full state: the effects' own
        components appended where :meth:`Effect.initial_state` puts them."""
        y0 = jnp.asarray(y0, dtype=float)
        if y0.shape[-1] == self.state_size:
            return y0
        q, v = y0[..., 0], y0[..., 1]
        own = [e.initial_state(q, v) for e in self.effects if e.states]
        return jnp.concatenate([y0, *own], axis=-1)

    def state_atol(self, atol):
        """The solver's absolute tolerance per state component from ``atol``: one number for
        all, or ``(atol of q in m, atol of v in m/s)``, extended to the effects' components by
        their units (a tuple of floats, or the one number)."""
        if isinstance(atol, float) or np.ndim(atol) == 0:
            return atol
        atol_q, atol_v = atol
        units = [u for e in self.effects for u in e.state_units]
        return (atol_q, atol_v, *(atol_q if u == "m" else atol_v for u in units))

    # -- the constitutive laws ------------------------------------------------------------
    def mesh_stiffness(self, theta1, stiffness_scale=1.0):
        """K(θ1) of eq. (4), N/m: the sum over the tooth pairs in contact.

        The sum is periodic in θ1 with the base pitch Θp, so it is tabulated over one pitch
        (:attr:`stiffness_table`, at least :data:`TABLE_NODES_PER_WIDTH` nodes per window
        width) and read by cubic Hermite interpolation: the twenty transcendentals of the sum
        were half the cost of a vector-field call. Windows too narrow to tabulate are summed.
        """
        u = jnp.mod(theta1 / self.base_pitch_angle, 1.0)
        if self.stiffness_table is None:
            shape, _ = _stiffness_shape(
                u,
                self.contact_ratio,
                self.transverse_contact_ratio,
                self.stiffness_shape,
                self.smoothing.mesh_width,
                xp=jnp,
            )
        else:
            shape = _hermite(self.stiffness_table, u, self.table_row)
        return stiffness_scale * self.pitch_stiffness * shape

    def squeeze(self, h, params: RattleParams):
        """Squeeze damping S(max(h, h_min)) of eq. (5), N s/m, smoothly saturated."""
        w = self.smoothing.contact_width
        h_eff = params.min_film + w * jax.nn.softplus((h - params.min_film) / w)
        return squeeze_coefficient(
            h_eff,
            params.film_half_length,
            params.viscosity,
            self.curvature_radius,
            self.axial_width,
        )

    def forces(self, t, q, v, params: RattleParams, drive: Drive, *, theta1=None):
        """Contact and squeeze forces on the pitch circle, N, as (F_mesh, F_squeeze).

        ``theta1`` is θ1(t) if already known (else ``drive.angle(t)``). Only the film ahead
        of the motion resists it, so one squeeze coefficient is evaluated: that of the gap
        ``h₊`` while ``v > 0`` and ``h₋`` otherwise (at ``v = 0`` the force is zero either way).
        """
        w = self.smoothing.contact_width
        if theta1 is None:
            theta1 = drive.angle(t)
        qe = q - sum((e.gap_error(t, theta1, self, params, drive) for e in self.effects), 0.0)
        c = 0.5 * params.backlash
        h_plus, h_minus = c - qe, c + qe  # gaps to the coast and drive flanks
        k = self.mesh_stiffness(theta1, params.stiffness_scale)
        # only the nearer flank can touch (the other is a backlash away, and its softplus
        # underflows to zero): one softplus, signed by the side
        coast = h_plus < h_minus
        f_mesh = -k * w * jnp.where(coast, 1.0, -1.0)
        f_mesh = f_mesh * jax.nn.softplus(-jnp.minimum(h_plus, h_minus) / w)
        ahead = jnp.where(v > 0, h_plus, h_minus)  # the gap the motion closes
        f_squeeze = -self.squeeze(ahead, params) * v * jax.nn.sigmoid(ahead / w)
        return f_mesh, f_squeeze

    def vector_field(self, t, y, args):
        """dy/dt for diffrax: ``args = (params, drive)``."""
        params, drive = args
        for e in self.effects:
            params = e.adjust(t, params, self, drive)
        q, v = y[0], y[1]
        theta1, acc1 = drive.angle_and_acceleration(t)
        f_mesh, f_squeeze = self.forces(t, q, v, params, drive, theta1=theta1)
        f_extra = sum((e.force(t, q, v, f_mesh, self, params, drive) for e in self.effects), 0.0)
        f_gear = f_mesh + f_squeeze + f_extra - params.drag_torque / self.r2
        derivatives, at = [], 2
        for e in (e for e in self.effects if e.states):
            f, d = e.coupled(t, q, v, y[at : at + e.states], f_gear, self, params, drive)
            f_gear, at = f_gear + f, at + e.states
            derivatives.append(d)
        acc = f_gear / self.mass - self.r1 * acc1
        return jnp.concatenate([jnp.stack([v, acc]), *derivatives])

    # -- closed-form facts ---------------------------------------------------------------
    def rattle_threshold(self, params: RattleParams, drive: Drive) -> bool:
        """Singh et al. (1989): no rattle while I2 (r1/r2) max|θ̈1| < T_b.

        In the model's terms: the inertial forcing m r1 max|θ̈1| stays below the drag T_b/r2,
        so the driven gear never leaves the drive flank. Returns True when rattle is expected.
        """
        forcing = float(self.mass * self.r1) * drive.max_acceleration()
        return bool(forcing > float(params.drag_torque / self.r2))


def share_stiffness_tables(models: RattleModel) -> tuple[RattleModel, Array | None]:
    """Models stacked on a leading axis (T of them) → the same models with their stiffness
    tables taken out and ``table_row`` set to their index, and the tables stacked (T, 2, n).

    A batch of simulations indexes each row's model out of such a stack. Indexing the tables
    along with the rest would give every row a copy of its table (the shared file's: 64 KB a
    row, 1.5 MB for a device's 24 rows), and the interpolation would read it from memory at
    every vector-field call; :func:`~rattlefit.simulation.solve.solve_rows` given the stack
    instead reads each row's table out of the T shared ones, which stay in cache. Models whose
    K is summed exactly (no table) are returned unchanged, with None.
    """
    if models.stiffness_table is None:
        return models, None
    rows = jnp.arange(models.stiffness_table.shape[0])
    untabled = eqx.tree_at(
        lambda m: (m.stiffness_table, m.table_row),
        models,
        (None, rows),
        is_leaf=lambda x: x is None,
    )
    return untabled, models.stiffness_table


def with_stiffness_tables(model: RattleModel, tables: Array | None) -> RattleModel:
    """One row's model of :func:`share_stiffness_tables` reading its table out of the shared
    stack ``tables`` (T, 2, n) again; unchanged when ``tables`` is None."""
    if tables is None:
        return model
    return eqx.tree_at(lambda m: m.stiffness_table, model, tables, is_leaf=lambda x: x is None)

"""Physical effects outside the seed paper's one-dof model, each a self-contained plug-in.

Every effect is an :class:`~rattlefit.physics.model.Effect`: an immutable module whose array fields
are its parameters (SI units) and which changes the model through its hooks — a kinematic
error of the flank gap, an extra force on the pitch circle, parameters that change in time,
or a force coupled to a state of its own. Add one to a model with
``model.with_effects(Runout(...))``; nothing else in the simulator knows about it.
:func:`rattlefit.diagnosis.diagnose.diagnose` fits each effect in :data:`EFFECTS` on top of
an identification and reports how much of the misfit it removes.

Each class declares ``ranges``: its fitted fields with (unit, lower, upper). The lower end
stands for the effect being absent: there it changes the model's acceleration by less than
a thousandth of the drag's plus 10⁻⁴ of the acceleration itself, anywhere along a rattle
trajectory (tests/test_effects.py); the upper end is generous for a production gearbox.

Each effect lives in its own module of this package; to add one, write a module like
:mod:`.flank_friction` and list its class in :data:`EFFECTS`.

An effect may carry state of its own: :class:`ShaftInertia`, a secondary shaft with its own
inertia behind the driven gear, adds its two components to the model's ``(q, v)``;
:class:`ShaftCompliance` is the quasi-static limit of a shaft without inertia.
"""

from __future__ import annotations

from ...errors import RattlefitError
from ..model import Effect
from .drive_ripple import DriveRipple
from .flank_friction import FlankFriction
from .mesh_damping import MeshDamping
from .pitch_point_friction import PitchPointFriction
from .runout import Runout
from .shaft_compliance import ShaftCompliance
from .shaft_inertia import ShaftInertia
from .speed_dependent_drag import SpeedDependentDrag
from .tooth_defect import ToothDefect
from .tooth_errors import ToothErrors
from .viscosity_drift import ViscosityDrift

__all__ = [
    "DEFAULT_EFFECTS",
    "EFFECTS",
    "DriveRipple",
    "FlankFriction",
    "MeshDamping",
    "PitchPointFriction",
    "Runout",
    "ShaftCompliance",
    "ShaftInertia",
    "SpeedDependentDrag",
    "ToothDefect",
    "ToothErrors",
    "ViscosityDrift",
    "absent",
    "effect_class",
    "mechanism_of",
]


#: The catalogue, by name.
EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        Runout,
        ToothErrors,
        FlankFriction,
        SpeedDependentDrag,
        DriveRipple,
        ViscosityDrift,
        ShaftCompliance,
        MeshDamping,
        PitchPointFriction,
        ToothDefect,
        ShaftInertia,
    )
}
#: The effects a diagnosis tries unless told otherwise: every one but those that declare
#: ``tried_by_default = False`` (another form of a mechanism the others cover, and costlier).
DEFAULT_EFFECTS: tuple[str, ...] = tuple(n for n, c in EFFECTS.items() if c.tried_by_default)


def absent(name: str, **static) -> Effect:
    """The effect ``name`` with every fitted field at the absent end of its range, and its
    static fields (e.g. a drive ripple's ``order``) as given."""
    cls = effect_class(name)
    return cls(**{k: lo for k, (_, lo, _) in cls.ranges.items()}, **static)


def effect_class(name: str) -> type[Effect]:
    """The effect class called ``name`` (see :data:`EFFECTS`)."""
    try:
        return EFFECTS[name]
    except KeyError:
        known = ", ".join(sorted(EFFECTS))
        raise RattlefitError(f"unknown effect {name!r}; known effects: {known}") from None


def mechanism_of(name: str) -> str:
    """The physics the effect ``name`` stands for (its class's ``mechanism``, else its name):
    candidates of one mechanism are other forms of the same thing."""
    cls = effect_class(name)
    return cls.mechanism or cls.name

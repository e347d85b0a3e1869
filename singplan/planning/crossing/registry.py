"""Crossing method names -> method objects: the one home of the names, read by the task check, the
planner, auto, ``singplan info`` and the CLI.

``auto`` is not a method but a choice among the pose-keeping ones (:mod:`singplan.planning.orchestration.select`).
A user adds a method with :func:`register`; tasks may then name it (``singularity.method``), or
the object is passed to :func:`singplan.plan` directly (see docs/architecture.md). The table is
private: :func:`register` is the only way in, and it refuses a name that is taken.

Which methods an arm can use follows from what its kinematics offer
(:attr:`singplan.kinematics.families.Recognition.capabilities`): :func:`refusals` says which
methods cannot serve an arm and why, :func:`notes` how the others serve where it differs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from singplan.errors import InputError
from singplan.kinematics.families import Recognition
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import Average, Axis, Dls, Exact, Ptp, Stop, WristJoint
from singplan.planning.crossing.nullspace import NullSpace
from singplan.task.schema import AUTO_METHOD, Move, check_choice

WRIST_JOINT_WINDOWS = (1.0, 1.5, 2.5)  # blend spans, as multiples of the detected zone
Target = str | None  # the configuration a move asks for, None for auto / keep
_Factory = Callable[[Target], list[CrossingMethod]]

# every method under its own name: the built-in ones, then those users registered (register())
_METHODS: dict[str, _Factory] = {
    # wrist-joint is tried with a few blend windows: a wider one spreads the wrist's change of branch
    # over more path (less acceleration) at the price of more orientation deviation; the fastest wins
    WristJoint.name: lambda target: [WristJoint(target, w) for w in WRIST_JOINT_WINDOWS],
    Axis.name: lambda target: [Axis(target)],
    NullSpace.name: lambda target: [NullSpace()],
    Exact.name: lambda target: [Exact()],
    Dls.name: lambda target: [Dls()],
    Average.name: lambda target: [Average()],
    Ptp.name: lambda target: [Ptp()],
    Stop.name: lambda target: [Stop()],
}
BUILT_IN = (AUTO_METHOD, *_METHODS)  # the names every singplan knows, auto first
AUTO_CANDIDATES = (Exact.name, WristJoint.name, Axis.name, NullSpace.name)  # what auto compares, in order
# the methods whose crossing may wait on the singular point (CrossingFigures.pause_s): null-space,
# only where exact's way on would leave a joint limit
PAUSING = frozenset({NullSpace.name})
# under auto, null-space serves only where exact's own crossing would leave a joint limit
_AUTO_FORM: dict[str, _Factory] = {NullSpace.name: lambda target: [NullSpace(only_when_needed=True)]}


def names() -> tuple[str, ...]:
    """Every name a task or ``--method`` may give: auto, the built-in methods, the registered ones."""
    return (AUTO_METHOD, *_METHODS)


def check_name(where: str, value: Any) -> str:
    """A crossing method name (:func:`names`); else bad input naming ``where`` (the task's field,
    a command-line option or an argument), with the valid names and the closest one.

    Raises:
        TaskError: not one of :func:`names` (exit code 2).
    """
    return check_choice(where, value, names())


def register(method: CrossingMethod) -> None:
    """Make ``method`` available by its name (``method.name``) to tasks and to ``plan(task, method=name)``."""
    if method.name in names():
        raise InputError(f"crossing method {method.name!r} is already registered; taken: {', '.join(names())}")
    _METHODS[method.name] = lambda target: [method]


def candidates(name: str, move: Move) -> list[CrossingMethod]:
    """The method objects to try on a move: one method's (several wrist-joint windows), or auto's set."""
    target = move.config if move.config not in ("auto", "keep") else None
    if name == AUTO_METHOD:
        return [m for candidate in AUTO_CANDIDATES for m in _AUTO_FORM.get(candidate, _METHODS[candidate])(target)]
    return _METHODS[name](target)


_NO_CLOSED_FORM = "needs a closed form (opw or ur), which this arm does not have"
_NO_SPHERICAL_WRIST = ("needs a spherical wrist (three wrist axes meeting in a point); a five-axis arm has a "
                       "two-axis wrist")
_NO_SQUARE_JACOBIAN = ("moves the joints in the null space of a square (6 x 6) Jacobian at a singular "
                       "configuration; this arm's Jacobian is not square")
_REDUNDANT = (f"{_NO_SQUARE_JACOBIAN} (6 x 7); with `redundancy` holding one joint, the six-axis chain left "
              f"can use it")
_TOOL_AXIS_ONLY = {  # an arm that keeps position and tool axis only (five axes)
    WristJoint.name: _NO_SPHERICAL_WRIST, NullSpace.name: _NO_SQUARE_JACOBIAN,
    Axis.name: "interpolates one axis while three others keep a full pose component; a five-axis arm keeps "
               "position and tool axis only, with no closed form to re-solve them",
    AUTO_METHOD: "compares exact only: wrist-joint and axis need a six-axis arm's closed form"}
_NOT_SQUARE = {  # a full pose on more joints than six (seven axes)
    WristJoint.name: _NO_CLOSED_FORM, Axis.name: _NO_CLOSED_FORM, NullSpace.name: _REDUNDANT,
    AUTO_METHOD: "compares exact only: wrist-joint and axis need a closed form"}


def refusals(arm: Recognition) -> dict[str, str]:
    """The crossing methods that cannot serve an arm, each with why (a method not named serves).

    A six-axis arm without a closed form (general 6R) gets wrist-joint with a numeric position
    solve (joints 1-3 by Newton on Pinocchio's Jacobian) and axis (Gauss-Newton, as on every arm),
    both with exits from the all-branch numeric IK; wrist-joint needs a wrist singularity to cross.
    """
    capabilities = arm.capabilities
    if "full pose" not in capabilities:
        return dict(_TOOL_AXIS_ONLY)
    if "square jacobian" not in capabilities:
        return dict(_NOT_SQUARE)
    if "wrist singularity" not in capabilities:
        return {WristJoint.name: f"needs a wrist singularity to cross, and {arm.no_wrist} (none)"}
    return {}


def notes(arm: Recognition) -> dict[str, str]:
    """How the crossing methods that differ by arm serve this one (for ``singplan info``)."""
    if "closed form" in arm.capabilities or "square jacobian" not in arm.capabilities:
        return {}
    return {WristJoint.name: "joints 1-3 by Newton on the TCP position (no closed form); exit from the numeric IK",
            Axis.name: "Gauss-Newton as on every arm; exit from the numeric IK"}

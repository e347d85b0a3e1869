"""Crossing method names -> method objects: the one list the planner, auto and the CLI read.

``auto`` is not a method but a choice among the pose-keeping ones (:mod:`singplan.planning.orchestration.select`).
A user adds a method with :func:`register`; tasks may then name it (``singularity.method``), or
the object is passed to :func:`singplan.plan` directly (see docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Callable

from singplan.errors import InputError
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import Average, Axis, Dls, Exact, Ptp, Stop, WristJoint
from singplan.planning.crossing.nullspace import NullSpace
from singplan.task.schema import AUTO_METHOD, Move, accept_method_name, method_names

WRIST_JOINT_WINDOWS = (1.0, 1.5, 2.5)  # blend spans, as multiples of the detected zone
Target = str | None  # the configuration a move asks for, None for auto / keep
_Factory = Callable[[Target], list[CrossingMethod]]

# each built-in method under its own name (task.schema.METHODS lists the names a task may give)
_BUILT_IN: dict[str, _Factory] = {
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
AUTO_CANDIDATES = (Exact.name, WristJoint.name, Axis.name, NullSpace.name)  # what auto compares, in order
# under auto, null-space serves only where exact's own crossing would leave a joint limit
_AUTO_FORM: dict[str, _Factory] = {NullSpace.name: lambda target: [NullSpace(only_when_needed=True)]}
_registered: dict[str, CrossingMethod] = {}


def names() -> tuple[str, ...]:
    """Every name a task or ``--method`` may give: auto, the built-in methods, the registered ones."""
    return method_names()


def register(method: CrossingMethod) -> None:
    """Make ``method`` available by its name (``method.name``) to tasks and to ``plan(task, method=name)``."""
    if method.name in names():
        raise InputError(f"crossing method {method.name!r} is already registered; taken: {', '.join(names())}")
    _registered[method.name] = method
    accept_method_name(method.name)


def candidates(name: str, move: Move) -> list[CrossingMethod]:
    """The method objects to try on a move: one method's (several wrist-joint windows), or auto's set."""
    target = move.config if move.config not in ("auto", "keep") else None
    if name == AUTO_METHOD:
        return [m for candidate in AUTO_CANDIDATES for m in _AUTO_FORM.get(candidate, _BUILT_IN[candidate])(target)]
    if name in _registered:
        return [_registered[name]]
    return _BUILT_IN[name](target)


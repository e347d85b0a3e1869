"""The SingplanError tree.

Every expected failure raises a subclass of :class:`SingplanError`. Each carries the numbers
that explain it (which field, move, sample or joint; the value and the limit) as attributes,
and a message a user can act on. The CLI maps :class:`InputError` to exit code 2 and
:class:`PlanningError` to exit code 3.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence


class SingplanError(Exception):
    """Base class of every error singplan raises on purpose."""

    exit_code: int = 1


class InputError(SingplanError):
    """The input is malformed or contradicts the robot (exit code 2)."""

    exit_code = 2


class UnknownNameError(InputError):
    """A name (robot, frame, method, ...) is not one of the valid choices."""

    def __init__(self, what: str, name: str, choices: Sequence[str], where: str = "") -> None:
        self.what = what
        self.name = name
        self.choices = tuple(choices)
        prefix = f"{where}: " if where else ""
        shown = ", ".join(self.choices[:40]) + (" ..." if len(self.choices) > 40 else "")
        near = nearest(name, self.choices)
        hint = f" (did you mean {near!r}?)" if near is not None else ""
        super().__init__(f"{prefix}unknown {what} {name!r}{hint}; valid: {shown}")


def nearest(name: str, choices: Sequence[str]) -> str | None:
    """The choice ``name`` most likely meant: the same but for case, else the closest by difflib's ratio
    (0.6 or more), else None."""
    same = [c for c in choices if c.lower() == name.lower()]
    if same:
        return same[0]
    found = difflib.get_close_matches(name.lower(), [c.lower() for c in choices], n=1)
    return next((c for c in choices if found and c.lower() == found[0]), None)


class RobotModelError(InputError):
    """A URDF could not be read or does not have what singplan needs."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}")


class OutputPathError(InputError):
    """An output path singplan cannot write: ``path`` as given, ``reason`` what is wrong with it."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"output {path!r}: {reason}")


class TaskError(InputError):
    """A task field is invalid; ``field`` is its path, e.g. ``moves[2].lin.to.xyz``."""

    def __init__(self, field: str, reason: str) -> None:
        self.field = field
        self.reason = reason
        super().__init__(f"{field}: {reason}" if field else reason)


class BudgetError(TaskError):
    """A task (or one of its moves) would exceed the sample caps or the memory budget (exit code 2).

    Attributes:
        move: index of the move at which the running total crosses the cap.
        value: the figure that crosses it (samples, or MB for memory).
        cap: the cap it crosses, in the same unit.
    """

    def __init__(self, field: str, reason: str, move: int, value: float, cap: float) -> None:
        self.move = move
        self.value = value
        self.cap = cap
        super().__init__(field, reason)


class PlanningError(SingplanError):
    """A well-formed task cannot be executed within the limits and tolerances (exit code 3)."""

    exit_code = 3


class UnreachableError(PlanningError):
    """A pose has no inverse-kinematics solution (inside the joint limits)."""

    def __init__(self, message: str, move: int | None = None, sample: int | None = None) -> None:
        self.move = move
        self.sample = sample
        super().__init__(message)


class JointLimitError(PlanningError):
    """A joint would leave its position range."""

    def __init__(self, message: str, joint: str, value_rad: float, lower_rad: float, upper_rad: float,
                 move: int | None = None) -> None:
        self.joint = joint
        self.value_rad = value_rad
        self.lower_rad = lower_rad
        self.upper_rad = upper_rad
        self.move = move
        super().__init__(message)


class SingularityError(PlanningError):
    """A singular zone that the chosen method refuses or cannot cross within tolerance."""

    def __init__(self, message: str, move: int, kind: str, s_m: float) -> None:
        self.move = move
        self.kind = kind
        self.s_m = s_m
        super().__init__(message)


class CollisionError(PlanningError):
    """Two bodies (robot links, the tool, cell shapes) come closer than the clearance.

    Attributes:
        move: the move where it happens.
        sample: the output sample (between samples: the one before).
        t_s: the time [s].
        bodies: the two bodies.
        distance_m: their distance there [m] (negative: penetration depth; -inf: meshes intersect).
        clearance_m: the clearance asked for [m].
    """

    def __init__(self, message: str, move: int, sample: int, t_s: float, bodies: tuple[str, str], distance_m: float,
                 clearance_m: float) -> None:
        self.move = move
        self.sample = sample
        self.t_s = t_s
        self.bodies = bodies
        self.distance_m = distance_m
        self.clearance_m = clearance_m
        super().__init__(message)


class MethodError(PlanningError):
    """A crossing method failed inside its own computation on a move (a solver that did not
    converge, a numerical error): that method cannot plan the move. Under auto the other methods
    go on and this one is listed as infeasible with the reason."""

    def __init__(self, message: str, move: int, method: str, cause: str) -> None:
        self.move = move
        self.method = method
        self.cause = cause  # the failure's type and message, e.g. "LinAlgError: SVD did not converge"
        super().__init__(message)

"""Random valid tasks (YAML v1 mappings) over every bundled arm, for property tests and soaks.

A task is built by :func:`build_task` from a :class:`Draws` source, so the same generator serves
hypothesis (:func:`valid_tasks`, shrinkable draws) and plain seeded runs (:func:`seeded_task`,
``random.Random``) such as ``bench/reliability.py``.

What "valid" means here: start joints inside the limits (some with joint 5 near or exactly at
zero, a wrist singularity on the 6-axis arms), LIN / CIRC / PTP targets from forward kinematics
of joints a short step from the previous target (so one task plans in seconds), CIRC via points
from FK of joints part-way between (kept off the chord), PTP targets sometimes as joints, and
random speeds, tolerances, limits, periods, methods and tool offsets. Every such task is
well-formed and consistent with its robot: singplan may refuse it only with exit 3 (no plan).
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence
from functools import cache
from typing import Any, Protocol, TypeVar

import numpy as np
import pinocchio as pin
from hypothesis import strategies as st

from singplan import bundled_robots, load_robot
from singplan.kinematics.robot import Robot
from singplan.planning.crossing.registry import BUILT_IN as METHODS

T = TypeVar("T")

ROBOT_NAMES = tuple(sorted(bundled_robots()))
MAX_STEP_DEG = 25.0  # joint step between consecutive targets: keeps a task to a few seconds of planning
TINY_STEP_DEG = 1e-3  # an occasional tiny move (micrometres at the TCP): it must plan too
SPEED_RANGE_M_S = (0.01, 2.0)
PERIOD_RANGE_S = (0.001, 0.02)
LIMIT_MARGIN_DEG = 1e-6  # keeps degrees -> radians round-off inside the joint limits
MIN_VIA_OFFSET_M = 2e-3  # a CIRC via at least this far from the chord: a well-defined circle
WRIST_JOINT = 4  # joint 5: q5 = 0 is the wrist singularity of the 6-axis arms


class Draws(Protocol):
    """The random choices a task is built from."""

    def uniform(self, low: float, high: float) -> float: ...
    def integer(self, low: int, high: int) -> int: ...
    def choice(self, options: Sequence[T]) -> T: ...
    def chance(self, p: float) -> bool: ...


class RandomDraws:
    """Draws from a seeded ``random.Random``."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng

    def uniform(self, low: float, high: float) -> float:
        return self.rng.uniform(low, high)

    def integer(self, low: int, high: int) -> int:
        return self.rng.randint(low, high)

    def choice(self, options: Sequence[T]) -> T:
        return self.rng.choice(list(options))

    def chance(self, p: float) -> bool:
        return self.rng.random() < p


class HypothesisDraws:
    """Draws through hypothesis' ``draw``, so failing tasks shrink."""

    def __init__(self, draw: Callable[[st.SearchStrategy[Any]], Any]) -> None:
        self.draw = draw

    def uniform(self, low: float, high: float) -> float:
        return float(self.draw(st.floats(low, high, allow_nan=False, allow_infinity=False)))

    def integer(self, low: int, high: int) -> int:
        return int(self.draw(st.integers(low, high)))

    def choice(self, options: Sequence[T]) -> T:
        return self.draw(st.sampled_from(list(options)))

    def chance(self, p: float) -> bool:
        # an integer draw shrinks towards 0, i.e. towards "no" for the optional features
        return self.draw(st.integers(0, 999)) >= round(1000 * (1.0 - p))


@cache
def robot_for(name: str) -> Robot:
    return load_robot(name)


def _log_uniform(d: Draws, low: float, high: float) -> float:
    return math.exp(d.uniform(math.log(low), math.log(high)))


def _limits_deg(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    lo = np.degrees(robot.lower_rad) + LIMIT_MARGIN_DEG
    hi = np.degrees(robot.upper_rad) - LIMIT_MARGIN_DEG
    return lo, hi


def _wrist_near_zero(d: Draws, q_deg: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """Sometimes put joint 5 exactly at 0 or within 2 deg of it (when the limits allow)."""
    if q_deg.size <= WRIST_JOINT or not lo[WRIST_JOINT] < 0.0 < hi[WRIST_JOINT]:
        return
    if d.chance(0.15):
        q_deg[WRIST_JOINT] = 0.0
    elif d.chance(0.2):
        q_deg[WRIST_JOINT] = d.uniform(-2.0, 2.0)


def _start_joints(d: Draws, robot: Robot) -> np.ndarray:
    limit_lo, limit_hi = _limits_deg(robot)
    # mostly the middle 60 % of each range (so most tasks plan and reach the checker), sometimes
    # all of it; capped at +-270 deg: arms with +-360 deg joints need not start a whole turn away
    lo, hi = np.maximum(limit_lo, -270.0), np.minimum(limit_hi, 270.0)
    if d.chance(0.8):
        lo, hi = lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo)
    q = np.array([d.uniform(lo[j], hi[j]) for j in range(robot.n_joints)])
    _wrist_near_zero(d, q, limit_lo, limit_hi)
    return q


def _step(d: Draws, robot: Robot, q_deg: np.ndarray) -> np.ndarray:
    """Joints a short random step from ``q_deg``, inside the limits."""
    lo, hi = _limits_deg(robot)
    size = TINY_STEP_DEG if d.chance(0.04) else d.uniform(1.0, MAX_STEP_DEG)
    q = np.array([float(np.clip(q_deg[j] + d.uniform(-size, size), lo[j], hi[j])) for j in range(q_deg.size)])
    _wrist_near_zero(d, q, lo, hi)
    return q


def _pose(robot: Robot, q_deg: np.ndarray, with_rpy: bool = True) -> dict[str, list[float]]:
    """The TCP pose of ``q_deg`` as task YAML: xyz [m] and URDF rpy_deg (R = Rz Ry Rx)."""
    T = robot.fk(np.radians(q_deg))
    pose = {"xyz": [float(v) for v in T.translation]}
    if with_rpy:
        pose["rpy_deg"] = [float(v) for v in np.degrees(pin.rpy.matrixToRpy(T.rotation))]
    return pose


def _via(d: Draws, robot: Robot, q_from: np.ndarray, q_to: np.ndarray) -> list[float] | None:
    """A CIRC via point from FK of joints between the two ends, or None if it is too near the chord."""
    f = d.uniform(0.3, 0.7)
    q_mid = q_from + f * (q_to - q_from) + np.array([d.uniform(-3.0, 3.0) for _ in q_from])
    lo, hi = _limits_deg(robot)
    q_mid = np.clip(q_mid, lo, hi)
    pa = robot.fk(np.radians(q_from)).translation
    pb = robot.fk(np.radians(q_to)).translation
    pv = robot.fk(np.radians(q_mid)).translation
    chord = pb - pa
    if np.linalg.norm(chord) < MIN_VIA_OFFSET_M or min(np.linalg.norm(pv - pa), np.linalg.norm(pv - pb)) < 1e-3:
        return None
    off = np.linalg.norm(np.cross(pv - pa, chord)) / np.linalg.norm(chord)
    return [float(v) for v in pv] if off >= MIN_VIA_OFFSET_M else None


def _move(d: Draws, robot: Robot, q_from: np.ndarray, q_to: np.ndarray) -> dict[str, Any]:
    kind = d.choice(("lin", "circ", "ptp"))
    if kind == "ptp":
        spec: dict[str, Any] = {"to": ({"joints_deg": [float(v) for v in q_to]} if d.chance(0.5)
                                       else _pose(robot, q_to))}
        if d.chance(0.6):
            spec["velocity_scale"] = d.uniform(0.05, 1.0)
        return {"ptp": spec}
    spec = {"to": _pose(robot, q_to, with_rpy=not d.chance(0.1))}
    if d.chance(0.8):
        spec["speed"] = _log_uniform(d, *SPEED_RANGE_M_S)
    via = _via(d, robot, q_from, q_to) if kind == "circ" else None
    if via is None:
        return {"lin": spec}
    return {"circ": {"via": {"xyz": via}, **spec}}


def _tool(d: Draws) -> dict[str, list[float]] | None:
    if not d.chance(0.3):
        return None
    xyz = [d.uniform(-0.05, 0.05), d.uniform(-0.05, 0.05), d.uniform(0.0, 0.2)]
    return {"xyz": xyz, "rpy_deg": [d.uniform(-30.0, 30.0) for _ in range(3)]}


def _singularity(d: Draws) -> dict[str, Any]:
    sing: dict[str, Any] = {"method": d.choice(METHODS)}
    if d.chance(0.5):
        sing["orientation_tolerance_deg"] = d.uniform(0.5, 20.0)
    if d.chance(0.5):
        sing["position_tolerance_mm"] = _log_uniform(d, 0.01, 5.0)
    if d.chance(0.2):
        sing["zone"] = {"wrist_deg": d.uniform(1.0, 15.0), "shoulder_mm": d.uniform(5.0, 100.0),
                        "elbow_deg": d.uniform(1.0, 15.0)}
    return sing


def _limits(d: Draws, n_joints: int) -> dict[str, Any]:
    limits: dict[str, Any] = {}
    if d.chance(0.5):
        limits["velocity_scale"] = d.uniform(0.1, 1.0)
    if d.chance(0.3):
        limits["acceleration"] = [d.uniform(1.0, 50.0) for _ in range(n_joints)]
    elif d.chance(0.5):
        limits["acceleration"] = d.uniform(1.0, 50.0)
    return limits


def build_task(d: Draws) -> dict[str, Any]:
    """One random valid task as a YAML-v1 mapping."""
    name = d.choice(ROBOT_NAMES)
    tool = _tool(d)
    robot = robot_for(name)
    if tool is not None:
        rot = pin.rpy.rpyToMatrix(*np.radians(tool["rpy_deg"]))
        robot = robot.with_tool(pin.SE3(rot, np.array(tool["xyz"])))
    q = _start_joints(d, robot)
    task: dict[str, Any] = {"robot": name, "start": {"joints_deg": [float(v) for v in q]}}
    if tool is not None:
        task["tool"] = tool
    moves = []
    for _ in range(d.integer(1, 4)):
        q_next = _step(d, robot, q)
        moves.append(_move(d, robot, q, q_next))
        q = q_next
    for move in moves[:-1]:  # fly-by corners between some moves
        if d.chance(0.3):
            next(iter(move.values()))["blend_mm"] = _log_uniform(d, 1.0, 100.0)
    task["moves"] = moves
    task["singularity"] = _singularity(d)
    limits = _limits(d, robot.n_joints)
    if limits:
        task["limits"] = limits
    task["output"] = {"period": d.uniform(*PERIOD_RANGE_S)}
    return task


@st.composite
def valid_tasks(draw: Callable[[st.SearchStrategy[Any]], Any]) -> dict[str, Any]:
    """Hypothesis strategy: random valid task mappings (see the module docstring)."""
    return build_task(HypothesisDraws(draw))


def seeded_task(seed: int) -> dict[str, Any]:
    """The random valid task number ``seed``: the same mapping on every run."""
    return build_task(RandomDraws(random.Random(seed)))

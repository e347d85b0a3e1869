"""Tasks through singularities, written from outside singplan: a seeded battery for ``check`` against ``plan``.

Each task is one LIN or CIRC whose path passes exactly through a singular configuration (a hit)
or through one a small joint offset away from it (a near miss), on a bundled arm or an
example-robot-data UR. Nothing here asks singplan where its singularities are, or solves its IK:

- the singular configuration is a root of ``det J(q)`` (the 6 x 6 TCP Jacobian of Pinocchio's
  own model of the URDF) along one joint of random joints: joint 5 for the wrist, joint 3 for the
  elbow, joint 2 for the shoulder (found by a scan of the joint's range and bisection);
- the path is built around that configuration's TCP pose ``T_mid``: a LIN from ``T_mid`` moved
  back by half a displacement and rotation to ``T_mid`` moved forward by the other half (position
  linear and orientation slerped with one parameter, it passes through ``T_mid`` at its middle),
  or a CIRC on a random circle through ``T_mid`` with ``via`` there and the ends symmetric about
  it (orientation slerped by arc fraction: ``T_mid`` at the middle too). The displacement and
  rotation are a twist the Jacobian at the singular joints can make (``J v``, random v);
- the start joints are a Levenberg-Marquardt solve (Pinocchio only) of the start pose from the
  singular joints, and must lie inside the limits.

A draw that cannot meet these (no root in range, an end pose out of reach or out of limits)
is drawn again; :func:`battery` returns the tasks in a fixed order for a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from singplan.kinematics.robot import Robot, load_robot

from .conftest import erd_urdf

Kind = Literal["wrist", "shoulder", "elbow"]
SCAN_JOINT = {"wrist": 4, "elbow": 2, "shoulder": 1}  # the joint whose scan finds each kind's root
ARMS = ("abb_irb2400", "kuka_kr6_r900_2", "fanuc_lrmate200id", "erd:ur5", "erd:ur10")


@dataclass(frozen=True)
class SingularTask:
    """One battery task: its YAML mapping and how it was made."""

    name: str  # e.g. "erd:ur5-wrist-hit-lin-3"
    arm: str
    kind: Kind
    miss_deg: float  # 0 for a hit: the joint offset from the singular configuration at the middle
    move: Literal["lin", "circ"]
    mapping: dict[str, Any]


def arm_robot(arm: str) -> Robot:
    return load_robot(erd_urdf(arm.removeprefix("erd:"))) if arm.startswith("erd:") else load_robot(arm)


def _determinant(robot: Robot, q: np.ndarray) -> float:
    model, data = robot.model, robot.model.createData()
    J = pin.computeFrameJacobian(model, data, q, robot.tip_frame_id, pin.LOCAL)
    return float(np.linalg.det(J))


def singular_root(robot: Robot, q: np.ndarray, joint: int) -> np.ndarray | None:
    """q with ``joint`` moved to a root of det J nearest its value (scan of the range, bisection), or None."""
    lo = max(float(robot.lower_rad[joint]), -math.pi) + 1e-3
    hi = min(float(robot.upper_rad[joint]), math.pi) - 1e-3
    grid = np.linspace(lo, hi, 181)
    trial = np.repeat(q[None], len(grid), axis=0)
    trial[:, joint] = grid
    det = np.array([_determinant(robot, row) for row in trial])
    flips = np.flatnonzero(np.sign(det[:-1]) != np.sign(det[1:]))
    if not flips.size:
        return None
    k = int(flips[np.argmin(np.abs(grid[flips] - q[joint]))])
    a, b, fa = grid[k], grid[k + 1], det[k]
    for _ in range(80):
        mid = 0.5 * (a + b)
        row = q.copy()
        row[joint] = mid
        fm = _determinant(robot, row)
        a, b, fa = (mid, b, fm) if np.sign(fm) == np.sign(fa) else (a, mid, fa)
    out = q.copy()
    out[joint] = 0.5 * (a + b)
    return out


def solve_lm(robot: Robot, T_tcp: pin.SE3, q: np.ndarray, iterations: int = 300) -> np.ndarray | None:
    """Levenberg-Marquardt on the SE(3) log error from q, with Pinocchio's FK and Jacobian only."""
    model, data = robot.model, robot.model.createData()
    frame = robot.tip_frame_id
    target = T_tcp * robot.T_tip_tcp.inverse()
    for _ in range(iterations):
        pin.forwardKinematics(model, data, q)
        current = pin.updateFramePlacement(model, data, frame)
        err = pin.log6(current.actInv(target)).vector
        if np.linalg.norm(err) < 1e-12:
            return q
        J = pin.Jlog6(current.actInv(target)) @ pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-9 * np.eye(6), err)
    return None


def _pose(T: pin.SE3) -> dict[str, list[float]]:
    return {"xyz": [float(v) for v in T.translation],
            "rpy_deg": [float(v) for v in np.degrees(pin.rpy.matrixToRpy(T.rotation))]}


def _ends(robot: Robot, q_mid: np.ndarray, move: str, rng: np.random.Generator, held: bool = False
          ) -> tuple[pin.SE3, pin.SE3, np.ndarray | None]:
    """Start and end poses around ``T_mid = fk(q_mid)`` (and a CIRC's via point), T_mid at the path's middle.

    The path leaves T_mid along ``J(q_mid) v`` for random joint speeds v: a direction the arm can
    move in there, so a path through the boundary of the workspace (the stretched elbow, a UR's
    shoulder) starts along it instead of across it.
    """
    model, data = robot.model, robot.model.createData()
    T_mid = robot.fk(q_mid)
    J = pin.computeFrameJacobian(model, data, q_mid, robot.tip_frame_id, pin.LOCAL_WORLD_ALIGNED)
    twist = J @ rng.normal(size=robot.n_joints)
    length = rng.uniform(0.06, 0.25)
    scale = length / max(float(np.linalg.norm(twist[:3])), 1e-9)
    scale = min(scale, math.radians(30.0) / max(float(np.linalg.norm(twist[3:])), 1e-9))  # at most 30 deg
    direction, turn = twist[:3] * scale, T_mid.rotation.T @ twist[3:] * scale * (not held)  # body axis x angle
    half_turn = pin.exp3(0.5 * turn)
    R0, R1 = T_mid.rotation @ half_turn.T, T_mid.rotation @ half_turn
    if move == "lin":
        return pin.SE3(R0, T_mid.translation - 0.5 * direction), pin.SE3(R1, T_mid.translation + 0.5 * direction), None
    tangent = direction / np.linalg.norm(direction)
    side = np.cross(tangent, rng.normal(size=3))
    side /= np.linalg.norm(side)
    radius = rng.uniform(0.6, 2.0) * np.linalg.norm(direction)
    phi = 0.5 * np.linalg.norm(direction) / radius  # the arc is as long as the LIN would be
    centre = T_mid.translation - radius * side
    p0 = centre + radius * (-math.sin(phi) * tangent + math.cos(phi) * side)
    p1 = centre + radius * (math.sin(phi) * tangent + math.cos(phi) * side)
    return pin.SE3(R0, p0), pin.SE3(R1, p1), T_mid.translation.copy()


def draw_task(arm: str, robot: Robot, kind: Kind, miss_deg: float, move: Literal["lin", "circ"],
              rng: np.random.Generator, held: bool = False, tries: int = 200) -> dict[str, Any] | None:
    """One task's mapping (see the module's docstring), or None when ``tries`` draws all fail."""
    lo, hi = np.maximum(robot.lower_rad, -math.pi) + 0.3, np.minimum(robot.upper_rad, math.pi) - 0.3
    joint = SCAN_JOINT[kind]
    for _ in range(tries):
        q = singular_root(robot, rng.uniform(lo, hi), joint)
        if q is None:
            continue
        q[joint] += math.radians(miss_deg) * rng.choice([-1.0, 1.0])
        if not robot.within_limits(q):
            continue
        T_start, T_end, via = _ends(robot, q, move, rng, held)
        q_start = solve_lm(robot, T_start, q.copy())
        q_end = solve_lm(robot, T_end, q.copy())
        if q_start is None or q_end is None or not (robot.within_limits(q_start) and robot.within_limits(q_end)):
            continue
        if max(np.max(np.abs(q_start - q)), np.max(np.abs(q_end - q))) > 1.2:  # another branch: draw again
            continue
        target = _pose(T_end)
        spec: dict[str, Any] = ({"to": target} if via is None else {"via": {"xyz": [float(v) for v in via]},
                                                                    "to": target})
        spec["speed"] = float(rng.uniform(0.05, 0.5))
        return {"robot": erd_urdf(arm.removeprefix("erd:")) if arm.startswith("erd:") else arm,
                "start": {"joints_deg": [float(v) for v in np.degrees(q_start)]},
                "moves": [{move: spec}],
                "singularity": {"method": "auto", "orientation_tolerance_deg": float(rng.choice([1.0, 3.0, 5.0]))},
                "limits": {"acceleration": float(rng.uniform(5.0, 20.0))}}
    return None


def battery(seed: int, arms: tuple[str, ...] = ARMS, kinds: tuple[Kind, ...] = ("wrist", "shoulder", "elbow"),
            misses_deg: tuple[float, ...] = (0.0, 0.5), moves: tuple[Literal["lin", "circ"], ...] = ("lin", "circ"),
            per_case: int = 1, held: bool = False) -> list[SingularTask]:
    """Tasks for every (arm, kind, miss, move), ``per_case`` each, from ``seed``; ``held``: every path
    keeps its orientation."""
    out = []
    for a, arm in enumerate(arms):
        robot = arm_robot(arm)
        for k, kind in enumerate(kinds):
            for m, miss in enumerate(misses_deg):
                for v, move in enumerate(moves):
                    for n in range(per_case):
                        rng = np.random.default_rng([seed, a, k, m, v, n])
                        mapping = draw_task(arm, robot, kind, miss, move, rng, held)
                        if mapping is not None:
                            label = "hit" if miss == 0 else f"miss{miss:g}"
                            name = f"{arm}-{kind}-{label}-{move}{'-held' if held else ''}-{n}"
                            out.append(SingularTask(name, arm, kind, miss, move, mapping))
    return out

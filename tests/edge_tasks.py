"""Tasks "written from outside": LINs and CIRCs through wrist, shoulder and elbow singularities.

Each task is generated, not written by hand, from a seed: a configuration at a chosen signed
distance from one singularity (``hit``: 0, ``near``: a small miss) is found from random joints
(the distances singplan reports, :func:`singplan.kinematics.configuration.distances_batch`), and
a LIN or a CIRC at constant orientation is laid through its TCP along the direction in which
that distance does not change to first order (``tangent``: the path touches the singular surface
at the miss), or across it (``across``: the path passes through the surface transversally).
The path is followed by damped Newton IK from its middle to both ends, in small steps, inside the
joint limits; a task whose path cannot be followed continuously, or that passes another kind of
singularity, is drawn again. The start is the followed branch's joints at the path's start, so
the task can be planned as written.

Arms: bundled OPW arms of several vendors and the example-robot-data UR5 and UR10 (by the path of
their URDF, as a user would give it); no tool, a straight one, or one offset and tilted.

    from tests.edge_tasks import edge_tasks
    for case in edge_tasks(seed=0, count=12):
        ...  # case.name, case.task (a YAML v1 mapping), case.closest (the miss along the path)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from singplan import load_robot
from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.robot import Robot

from .conftest import erd_urdf

BUNDLED = ("abb_irb2400", "kuka_kr6_r900_2", "fanuc_lrmate200id", "staubli_tx2_60", "kuka_kr120_r2500_pro")
ERD = ("ur5", "ur10")
ARMS = BUNDLED + tuple(f"erd:{name}" for name in ERD)
KINDS = ("wrist", "shoulder", "elbow")
KIND_INDEX = {"wrist": 0, "shoulder": 1, "elbow": 2}
TUNE_JOINT = {"wrist": 4, "shoulder": 1, "elbow": 2}  # the joint moved to set the distance
PHASE_JOINT = {"wrist": 3, "shoulder": 0, "elbow": 1}  # the joint that turns fast through the near miss
NEAR_MISS = {"wrist": (math.radians(0.1), math.radians(2.0)), "shoulder": (0.0005, 0.005),
             "elbow": (math.radians(0.2), math.radians(2.0))}
# a hit: within what exact goes through (0.01 deg, the default position tolerance 0.01 mm)
HIT = {"wrist": math.radians(0.003), "shoulder": 2e-6, "elbow": math.radians(0.003)}
OTHER_CLEAR = {"wrist": math.radians(8.0), "shoulder": 0.05, "elbow": math.radians(8.0)}
NEWTON_STEP_M = 0.001
MAX_JOINT_STEP_RAD = 0.05
LOOSE = {"position_tolerance_mm": 50.0, "orientation_tolerance_deg": 45.0}  # issue 22's loose tolerances
METHODS = ("auto", "wrist-joint", "axis", "null-space", "exact", "dls", "average", "ptp", "stop")


@dataclass(frozen=True)
class EdgeTask:
    """One generated task and what it was generated to be."""

    name: str
    task: dict[str, Any]  # YAML v1 mapping
    arm: str
    kind: str  # the singularity it meets: wrist | shoulder | elbow
    move: str  # lin | circ
    shape: str  # hit | near (the miss at the generated point) and tangent | across
    closest: float  # the smallest |distance| of that kind along the followed path [rad | m]


@cache
def arm_robot(arm: str) -> tuple[str, Robot]:
    """The task's ``robot`` value and the loaded robot for an arm label (``erd:NAME``: example-robot-data)."""
    if arm.startswith("erd:"):  # test-only: the UR arms as a user's URDF files
        path = str(Path(erd_urdf(arm[4:])).resolve())
        return path, load_robot(path)
    return arm, load_robot(arm)


def edge_tasks(seed: int, count: int, arms: tuple[str, ...] = ARMS) -> Iterator[EdgeTask]:
    """``count`` tasks cycling through arms x kinds x (LIN, CIRC) x shapes, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    combos = [(arm, kind, move, shape) for kind in KINDS for move in ("lin", "circ")
              for shape in ("near-tangent", "hit-tangent", "hit-across") for arm in arms
              if not (shape == "hit-across" and kind == "elbow")]  # across the stretched arm: out of reach
    order = rng.permutation(len(combos))
    made = 0
    for k in order:
        if made >= count:
            return
        arm, kind, move, shape = combos[int(k)]
        case = generate(arm, kind, move, shape, rng)
        if case is not None:
            made += 1
            yield case


def generate(arm: str, kind: str, move: str, shape: str, rng: np.random.Generator,
             tries: int = 60) -> EdgeTask | None:
    """One task of the kind asked for, or None when ``tries`` random starts found none."""
    robot_value, bare = arm_robot(arm)
    tool = _tool(rng)
    robot = bare if tool is None else bare.with_tool(
        pin.SE3(pin.rpy.rpyToMatrix(*np.radians(tool["rpy_deg"])), np.array(tool["xyz"])))
    lo, hi = robot.lower_rad, robot.upper_rad
    lo, hi = np.maximum(lo, -math.pi), np.minimum(hi, math.pi)  # UR arms: one turn either way is enough
    margin = 0.15 * (hi - lo)
    for _ in range(tries):
        miss = HIT[kind] if shape.startswith("hit") else float(rng.uniform(*NEAR_MISS[kind]))
        q = rng.uniform(lo + margin, hi - margin)
        q_mid = _at_distance(robot, q, kind, miss * float(rng.choice([-1.0, 1.0])), TUNE_JOINT[kind])
        if q_mid is None:
            continue
        frame = _directions(robot, q_mid, kind)
        if frame is None:
            continue
        length = float(rng.uniform(0.08, 0.3))
        path, u_mid = _path_function(robot.fk(q_mid), frame, kind, move, shape, length, rng)
        followed = _follow(robot, q_mid, path, u_mid)
        if followed is None:
            continue
        dist = distances_batch(robot, followed)
        if any(np.min(np.abs(dist[:, KIND_INDEX[k]])) < OTHER_CLEAR[k] for k in KINDS if k != kind):
            continue
        closest = float(np.min(np.abs(dist[:, KIND_INDEX[kind]])))
        task = _task(robot_value, robot, followed[0], path, move, rng)
        if tool is not None:
            task = {"robot": task["robot"], "tool": tool, **{k: v for k, v in task.items() if k != "robot"}}
        name = f"{arm.replace(':', '-')}__{kind}_{move}_{shape}_{int(rng.integers(1_000_000)):06d}"
        return EdgeTask(name, task, arm, kind, move, shape, closest)
    return None


def with_method(case: EdgeTask, method: str, loose: bool = False) -> dict[str, Any]:
    """The case's task with ``singularity.method`` set (and issue 22's loose tolerances)."""
    task = {**case.task, "singularity": {**case.task["singularity"], "method": method}}
    if loose:
        task["singularity"].update(LOOSE)
    return task


# -- geometry -----------------------------------------------------------------------------------


def _at_distance(robot: Robot, q: np.ndarray, kind: str, target: float, joint: int) -> np.ndarray | None:
    """q with ``joint`` moved (bisection on a grid of its range) so the signed distance is ``target``."""
    lo, hi = robot.lower_rad[joint], robot.upper_rad[joint]
    grid = np.linspace(max(lo, -math.pi), min(hi, math.pi), 721)
    qs = np.repeat(q[None], grid.size, axis=0)
    qs[:, joint] = grid
    f = distances_batch(robot, qs)[:, KIND_INDEX[kind]] - target
    roots = np.nonzero((np.sign(f[:-1]) != np.sign(f[1:])) & (np.abs(f[:-1] - f[1:]) < 0.5))[0]
    if roots.size == 0:
        return None
    a, b = grid[roots[0]], grid[roots[0] + 1]
    sign_a = np.sign(f[roots[0]])
    for _ in range(60):
        m = 0.5 * (a + b)
        qm = q.copy()
        qm[joint] = m
        fm = distances_batch(robot, qm[None])[0, KIND_INDEX[kind]] - target
        a, b = (m, b) if np.sign(fm) == sign_a else (a, m)
    out = q.copy()
    out[joint] = 0.5 * (a + b)
    return out


def _directions(robot: Robot, q: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Two unit TCP directions at q: along the singular surface, turning the phase joint fastest
    (the distance stationary to first order), and the distance's gradient (away from the surface)."""
    J = robot.jacobian(q)
    if np.linalg.svd(J, compute_uv=False)[-1] < 1e-9:
        return None
    jinv_xyz = np.linalg.inv(J)[:, :3]  # joint rates of a unit TCP velocity at fixed orientation
    h = 1e-6
    qs = np.repeat(q[None], 2 * len(q), axis=0)
    for j in range(len(q)):
        qs[2 * j, j] += h
        qs[2 * j + 1, j] -= h
    d = distances_batch(robot, qs)[:, KIND_INDEX[kind]]
    g = ((d[0::2] - d[1::2]) / (2 * h)) @ jinv_xyz  # the signed distance's gradient in TCP position
    g_norm = float(np.linalg.norm(g))
    if g_norm < 1e-9:
        return None
    g_unit = g / g_norm * (1.0 if distances_batch(robot, q[None])[0, KIND_INDEX[kind]] >= 0 else -1.0)
    v = jinv_xyz[PHASE_JOINT[kind]]
    tangent = v - (v @ g_unit) * g_unit
    if float(np.linalg.norm(tangent)) < 1e-9:
        return None
    return tangent / np.linalg.norm(tangent), g_unit


PathFunction = Callable[[float], np.ndarray]  # u in [0, 1] -> TCP position (3,)


def _path_function(T_mid: pin.SE3, frame: tuple[np.ndarray, np.ndarray], kind: str, move: str, shape: str,
                   length: float, rng: np.random.Generator) -> tuple[PathFunction, float]:
    """The path's positions as a function of u in [0, 1], and the u of the generated point.

    Wrist and shoulder: through the point along the surface (``tangent``) or at 30-60 deg to it
    (``across``), the point in the middle. Elbow (the stretched arm, the edge of the workspace): a
    LIN ends at the point coming from inside; a CIRC touches the edge from inside at its middle,
    bending more than the workspace's edge does.
    """
    p_mid = T_mid.translation.copy()
    tangent, away = frame  # ``away``: the |distance| grows (into the workspace, for the elbow)
    if kind == "elbow" and move == "lin":
        return (lambda u: p_mid + (1.0 - u) * length * away), 1.0
    direction = tangent
    if shape.endswith("across"):
        angle = math.radians(float(rng.uniform(30.0, 60.0)))
        direction = math.cos(angle) * tangent + math.sin(angle) * away
    if move == "lin":
        return (lambda u: p_mid + (u - 0.5) * length * direction), 0.5
    if kind == "elbow":
        normal, radius = away, float(rng.uniform(0.15, 0.4))  # more curved than any arm's reach: inside
    else:
        normal = np.cross(direction, rng.normal(size=3))
        normal /= np.linalg.norm(normal)
        radius = float(rng.uniform(0.6, 2.0)) * length  # an arc of 30-95 deg
    half = 0.5 * length / radius
    centre = p_mid + radius * normal

    def arc(u: float) -> np.ndarray:
        phi = (2.0 * u - 1.0) * half
        return centre + radius * (-normal * math.cos(phi) + direction * math.sin(phi))

    return arc, 0.5


def _newton(robot: Robot, q: np.ndarray, target: pin.SE3) -> np.ndarray | None:
    lo, hi = robot.lower_rad, robot.upper_rad
    for _ in range(30):
        T = robot.fk(q)
        err = np.concatenate([target.translation - T.translation, pin.log3(target.rotation @ T.rotation.T)])
        if np.linalg.norm(err) < 1e-11:
            return q if np.all(q >= lo) and np.all(q <= hi) else None
        J = robot.jacobian(q)
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-12 * np.eye(6), err)
    return None


def _follow(robot: Robot, q_mid: np.ndarray, path: PathFunction, u_mid: float) -> np.ndarray | None:
    """Joint samples (N, 6) along the path from u = 0 to 1 through q_mid at ``u_mid``, or None."""
    rotation = robot.fk(q_mid).rotation
    length = float(np.linalg.norm(path(1.0) - path(0.0))) + 1e-9
    sides: list[list[np.ndarray]] = []
    for end in (0.0, 1.0):
        q, side = q_mid.copy(), []
        steps = math.ceil(abs(end - u_mid) * length / NEWTON_STEP_M)
        for k in range(1, steps + 1):
            q_next = _step(robot, q, rotation, path, u_mid + (end - u_mid) * (k - 1) / steps,
                           u_mid + (end - u_mid) * k / steps)
            if q_next is None:
                return None
            q = q_next
            side.append(q)
        sides.append(side)
    return np.array(sides[0][::-1] + [q_mid] + sides[1])


def _step(robot: Robot, q: np.ndarray, rotation: np.ndarray, path: PathFunction, u0: float, u1: float,
          depth: int = 0) -> np.ndarray | None:
    """Newton from u0 to u1, halving the step where the joints jump (near the singularity)."""
    q_next = _newton(robot, q, pin.SE3(rotation, path(u1)))
    if q_next is not None and np.max(np.abs(q_next - q)) <= MAX_JOINT_STEP_RAD:
        return q_next
    if depth >= 18:
        return None
    half = _step(robot, q, rotation, path, u0, 0.5 * (u0 + u1), depth + 1)
    return None if half is None else _step(robot, half, rotation, path, 0.5 * (u0 + u1), u1, depth + 1)


def _tool(rng: np.random.Generator) -> dict[str, list[float]] | None:
    """No tool (the flange), a straight one along the flange's z axis, or one offset and tilted."""
    kind = int(rng.integers(3))
    if kind == 0:
        return None
    if kind == 1:
        return {"xyz": [0.0, 0.0, round(float(rng.uniform(0.05, 0.25)), 4)], "rpy_deg": [0.0, 0.0, 0.0]}
    return {"xyz": [round(float(v), 4) for v in rng.uniform([-0.05, -0.05, 0.05], [0.05, 0.05, 0.25])],
            "rpy_deg": [round(float(v), 2) for v in rng.uniform(-30.0, 30.0, 3)]}


def _task(robot_value: str, robot: Robot, q_start: np.ndarray, path: PathFunction, move: str,
          rng: np.random.Generator) -> dict[str, Any]:
    rpy = [math.degrees(float(v)) for v in pin.rpy.matrixToRpy(robot.fk(q_start).rotation)]
    target = {"xyz": [round(float(v), 9) for v in path(1.0)], "rpy_deg": rpy}
    spec: dict[str, Any] = {"to": target, "speed": round(float(rng.uniform(0.05, 0.5)), 3)}
    if move == "circ":
        spec = {"via": {"xyz": [round(float(v), 9) for v in path(float(rng.uniform(0.25, 0.75)))]}, **spec}
    return {"robot": robot_value,
            "start": {"joints_deg": [round(math.degrees(float(v)), 9) for v in q_start]},
            "moves": [{move: spec}],
            "singularity": {"method": "auto",
                            "orientation_tolerance_deg": float(rng.choice([2.0, 5.0, 10.0])),
                            "position_tolerance_mm": float(rng.choice([0.01, 0.1, 1.0, 2.0]))},
            "limits": {"acceleration": 10.0},
            "output": {"period": 0.004}}

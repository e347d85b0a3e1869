"""Five-joint arms (SEEDS 002, reduced order): the TCP position and the tool's z axis are kept,
the rotation about that axis is free.

Five joints cannot hold a full pose; they can hold five numbers. singplan keeps the TCP
position (3) and the direction of the tool's z axis (2), and ignores the rotation about it,
as DESIGN.md's "Task YAML" says. Everything that measures or solves a pose for such an arm
goes through this module:

* the error ``[p* - p, r_x, r_y]`` [m, rad]: ``r`` is the rotation vector, in the TCP frame,
  that turns the current z axis onto the wanted one (no z component: no roll);
* its Jacobian: the TCP's linear rows (base frame) and the x, y rows of its angular velocity
  in the TCP frame (exact at the solution, which is all the damped Newton needs);
* the orientation error of a sample: the angle between the two z axes.

A joint whose axis is the tool's z axis through the TCP (the wrist roll of the common
base / shoulder / elbow / pitch / roll layout) does not move either kept quantity: its column
of the reduced Jacobian is zero, and the IK leaves it where the seed had it (nearest the seed,
0 without one), so it never wanders along a path.

Singular zones and labels: a five-axis arm has no wrist flip (a pitch-roll wrist cannot reach
the same tool axis with the pitch mirrored), so the wrist distance is reported as 180 deg,
never singular, and the wrist letter of the label is always ``N``. The shoulder distance is
the signed distance [m] of the wrist point (the origin of joint 4, the pitch axis the arm
positions) from axis 1, measured along ``forward``, the horizontal direction normal to axis 2
that points to the arm at q = 0 (``F`` when positive). The elbow distance is the signed angle
[rad] about ``up x forward`` from the upper arm (origin 2 -> origin 3) to the forearm
(origin 3 -> wrist point), 0 when the arm is stretched (``U`` when positive: the forearm
turned down from the upper arm, as the six-axis labels read). Both zones are where the
reduced Jacobian of such an arm loses rank.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pinocchio as pin

from singplan.kinematics.robot import Robot

NO_WRIST_RAD = math.pi  # a five-axis arm's wrist distance: as far from a wrist flip as can be
_FREE_COLUMN_TOL = 1e-9  # a reduced-Jacobian column this small [m, rad per rad] at every sample is free
_FREE_SAMPLES = 8
_FREE_SEED = 20261123
ANGLE_WEIGHT_M = 0.01  # [m/rad] the tool axis's rows count 1 rad as 1 cm: a residual goes to the axis, not the position


def is_reduced(robot: Robot) -> bool:
    """True for a five-joint arm (position and tool z axis only)."""
    return robot.n_joints == 5


def error(T_target_tcp: pin.SE3, T_tcp: pin.SE3) -> np.ndarray:
    """The reduced error (5,): position [m] in the base frame, then the z-axis rotation about
    the TCP's own x and y axes [rad] times ANGLE_WEIGHT_M.

    A five-axis arm reaches a four-dimensional set of (position, axis) pairs when a joint turns
    about the tool axis (a pitch-roll wrist keeps the axis in the arm plane), so a target given
    to a few digits is slightly out of reach; the weight makes the least-squares solution keep
    the position and leave that residual in the axis, where it is reported."""
    v = T_tcp.rotation.T @ T_target_tcp.rotation[:, 2]  # the wanted z axis in the TCP frame
    sin = math.hypot(float(v[0]), float(v[1]))
    angle = math.atan2(sin, float(v[2]))
    r = np.zeros(2) if sin < 1e-300 else angle / sin * np.array([-v[1], v[0]])
    if sin < 1e-300 and v[2] < 0:  # exactly opposite: any perpendicular axis turns it over
        r = np.array([math.pi, 0.0])
    return np.concatenate([T_target_tcp.translation - T_tcp.translation, ANGLE_WEIGHT_M * r])


def jacobian(robot: Robot, q: np.ndarray, R_tcp: np.ndarray) -> np.ndarray:
    """d(-error)/dq (5, n): the TCP's linear rows and the weighted x, y rows of its angular
    velocity in the TCP frame; the free joints' columns are zero (they never move)."""
    J = _jacobian(robot, q, R_tcp)
    J[:, list(free_joints(robot))] = 0.0
    return J


def _jacobian(robot: Robot, q: np.ndarray, R_tcp: np.ndarray) -> np.ndarray:
    J = robot.jacobian(q)
    return np.vstack([J[:3], ANGLE_WEIGHT_M * (R_tcp.T @ J[3:])[:2]])


def z_angles(R: np.ndarray, R_want: np.ndarray) -> np.ndarray:
    """Angles [rad] between the z axes of rotations R and R_want, (N, 3, 3) each -> (N,)."""
    dots = np.einsum("ni,ni->n", R[:, :, 2], R_want[:, :, 2])
    cross = np.linalg.norm(np.cross(R[:, :, 2], R_want[:, :, 2]), axis=1)
    return np.arctan2(cross, dots)  # atan2 keeps 1e-9 rad visible where acos of the dot would lose it


@lru_cache(maxsize=64)
def free_joints(robot: Robot) -> tuple[int, ...]:
    """Joints that move neither the TCP position nor the tool's z axis (their column is zero)."""
    rng = np.random.default_rng(_FREE_SEED)
    lower, upper = np.maximum(robot.lower_rad, -math.pi), np.minimum(robot.upper_rad, math.pi)
    worst = np.zeros(robot.n_joints)
    for q in rng.uniform(lower, upper, size=(_FREE_SAMPLES, robot.n_joints)):
        R = robot.fk(q).rotation
        worst = np.maximum(worst, np.abs(_jacobian(robot, q, R)).max(axis=0) / ANGLE_WEIGHT_M)
    return tuple(int(j) for j in np.nonzero(worst < _FREE_COLUMN_TOL)[0])


def settle_free(robot: Robot, q: np.ndarray, seed: np.ndarray | None) -> np.ndarray:
    """``q`` with its free joints at the seed's values (0 without a seed), inside the limits."""
    free = list(free_joints(robot))
    if not free:
        return q
    out = np.array(q, dtype=float)
    out[free] = 0.0 if seed is None else np.asarray(seed, dtype=float)[free]
    out[free] = np.clip(out[free], robot.lower_rad[free], robot.upper_rad[free])
    return out


def _frames(robot: Robot, q: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Joint origins and unit axes (base frame) at ``q``."""
    model, data = robot.model, robot.data
    J = pin.computeJointJacobians(model, data, q)  # WORLD frame: the angular rows are the joint axes
    origins = [np.array(data.oMi[i].translation) for i in range(1, model.njoints)]
    axes = [np.array(J[3:, model.joints[i].idx_v]) for i in range(1, model.njoints)]
    return origins, axes


@lru_cache(maxsize=64)
def _reference(robot: Robot) -> tuple[np.ndarray, float]:
    """Axis 1 oriented from the base towards the shoulder, and the sign that makes ``z2 x up``
    point from axis 1 to the wrist point (else the TCP) at q = 0, whatever the URDF's axis signs."""
    q0 = np.clip(np.zeros(robot.n_joints), robot.lower_rad, robot.upper_rad)
    o, z = _frames(robot, q0)
    up = z[0] if float(z[0] @ (o[1] - o[0])) >= 0 else -z[0]
    side = np.cross(z[1], up)
    reach = float((o[3] - o[0]) @ side)
    if abs(reach) < 1e-6:  # the wrist point over axis 1 at zero: the TCP tells the front
        reach = float((robot.fk(q0).translation - o[0]) @ side)
    return up, 1.0 if reach >= 0 else -1.0


def distances(robot: Robot, q: np.ndarray) -> tuple[float, float, float]:
    """(wrist [rad] = 180 deg, shoulder [m], elbow [rad]) signed distances of joints ``q`` (see the module)."""
    up, sign = _reference(robot)
    o, z = _frames(robot, np.asarray(q, dtype=float))
    forward = sign * np.cross(z[1], up)
    forward /= np.linalg.norm(forward)
    normal = np.cross(up, forward)
    wrist = o[3]
    shoulder = float((wrist - o[0]) @ forward)
    upper, fore = o[2] - o[1], wrist - o[2]
    upper = upper - float(upper @ normal) * normal
    fore = fore - float(fore @ normal) * normal
    elbow = math.atan2(float(np.cross(upper, fore) @ normal), float(upper @ fore))
    return NO_WRIST_RAD, shoulder, elbow


def distances_batch(robot: Robot, q: np.ndarray) -> np.ndarray:
    """:func:`distances` of many samples (N, 5) -> (N, 3)."""
    return np.array([distances(robot, qk) for qk in np.atleast_2d(q)]).reshape(-1, 3)


def sigma_min(robot: Robot, q: np.ndarray) -> float:
    """Smallest singular value of the reduced Jacobian without its free joints' (zero) columns."""
    q = np.asarray(q, dtype=float)
    J = _jacobian(robot, q, robot.fk(q).rotation)
    J[3:] /= ANGLE_WEIGHT_M
    kept = [j for j in range(robot.n_joints) if j not in free_joints(robot)]
    return float(np.linalg.svd(J[:, kept], compute_uv=False)[-1])

"""Closed-form inverse kinematics of Universal Robots arms (UR3/UR5/UR10 URDF layout).

Geometry of the ur_description URDF (joint frames, base frame ``0``, link-1 frame ``1``):
axis 1 is z; axes 2, 3, 4 are parallel to the lateral axis ``y1``; the arm lies in a plane at
the lateral offset ``d4`` (sum of the y offsets of joints 2, 3 and 5); axis 5 is
perpendicular to ``y1``; axis 6 (the tool z axis) is ``y`` of link 5.

1. Wrist point ``P = p - d6 z_tool``, where axes 5 and 6 meet. Its lateral coordinate in
   frame 1 must equal ``d4``: ``r sin(phi - q1) = d4`` gives two q1 (front / back).
2. Axis 6 seen from frame 1: ``y1 . z_tool = cos q5`` gives +-q5 (the two wrist branches).
3. ``R_1_tool Rx(pi/2) = Ry(a) Rz(q5) Ry(q6)`` with ``a = q2 + q3 + q4 + pi``: a YZY
   decomposition with a known middle angle gives ``a`` and ``q6``; at q5 = 0 ``a`` keeps
   the seed's value and q6 takes the rest.
4. The wrist-1 point ``o4 = P - d5 z5 - w y1`` is placed by the planar two-link arm
   (lengths L2, L3) in the x1-z1 plane: two elbow solutions q3 = +-acos(...), then q2, q4.

Eight branches in all, the same (N, 8, 6) layout as the OPW solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from singplan.robot import Robot


@dataclass(frozen=True)
class UrParameters:
    """Lengths [m] read from the URDF joint placements."""

    d1: float  # height of the shoulder pan frame
    shoulder_y: float  # lateral offset of the shoulder lift joint
    lateral: float  # d4: lateral offset of the wrist point from axis 1
    l2: float  # upper arm
    l3: float  # forearm
    wrist_y: float  # lateral offset of wrist 2 from wrist 1
    d5: float  # wrist 2 -> wrist 3 along axis 5
    d6: float  # wrist 3 -> tool0 along axis 6

    @classmethod
    def from_robot(cls, robot: Robot) -> UrParameters:
        jp = [robot.model.jointPlacements[i].translation for i in range(1, 7)]
        tip = robot.model.frames[robot.tip_frame_id].placement.translation
        return cls(d1=float(jp[0][2]), shoulder_y=float(jp[1][1]), lateral=float(jp[1][1] + jp[2][1] + jp[4][1]),
                   l2=float(jp[2][2]), l3=float(jp[3][2]), wrist_y=float(jp[4][1]), d5=float(jp[5][2]),
                   d6=float(tip[1]))


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


_RX_HALF_PI = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def ur_solutions(p: UrParameters, T_base_tool: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
    """All eight branches for one tool0 pose (4, 4); (8, 6) [rad], NaN rows where unreachable.

    Branch index bits: 4 = back shoulder, 2 = negative q5, 1 = second elbow solution.
    """
    R, pos = T_base_tool[:3, :3], T_base_tool[:3, 3]
    z_tool = R[:, 2]
    wrist = pos - p.d6 * z_tool
    r = math.hypot(wrist[0], wrist[1])
    phi = math.atan2(wrist[1], wrist[0])
    out = np.full((8, 6), np.nan)
    if r < abs(p.lateral):
        return out
    delta = math.asin(p.lateral / r)
    seed_q = np.zeros(6) if seed is None else np.asarray(seed, dtype=float)
    for shoulder, q1 in enumerate((phi - delta, phi - math.pi + delta)):
        R1 = _rz(q1)
        y1 = R1[:, 1]
        M = R1.T @ R @ _RX_HALF_PI
        cos5 = float(np.clip(y1 @ z_tool, -1.0, 1.0))
        for wrist_branch, q5 in enumerate((math.acos(cos5), -math.acos(cos5))):
            a, q6 = _wrist_yzy(M, q5, float(seed_q[1] + seed_q[2] + seed_q[3] + math.pi))
            z5 = R1 @ np.array([math.sin(a), 0.0, math.cos(a)])
            o4 = wrist - p.d5 * z5 - p.wrist_y * y1
            for elbow, arm in enumerate(_planar(p, R1.T @ o4)):
                if arm is None:
                    continue
                q2, q3 = arm
                k = 4 * shoulder + 2 * wrist_branch + elbow
                out[k] = (q1, q2, q3, a - math.pi - q2 - q3, q5, q6)
    return math.pi - np.mod(math.pi - out, 2.0 * math.pi)


def _wrist_yzy(M: np.ndarray, q5: float, a_seed: float) -> tuple[float, float]:
    """(a, q6) with Ry(a) Rz(q5) Ry(q6) = M; a = a_seed where q5 = 0 leaves it free."""
    s5 = math.sin(q5)
    a = math.atan2(M[2, 1] * s5, -M[0, 1] * s5) if abs(s5) > 1e-12 else a_seed
    N = _rz(-q5) @ _ry(-a) @ M
    return a, math.atan2(N[0, 2], N[0, 0])


def _planar(p: UrParameters, o4_in_1: np.ndarray) -> list[tuple[float, float] | None]:
    """Both (q2, q3) placing the wrist-1 point; None for an unreachable one."""
    x = float(o4_in_1[0])
    z = float(o4_in_1[2] - p.d1)
    cos3 = (x * x + z * z - p.l2**2 - p.l3**2) / (2.0 * p.l2 * p.l3)
    if abs(cos3) > 1.0 + 1e-12:
        return [None, None]
    out: list[tuple[float, float] | None] = []
    for q3 in (math.acos(min(1.0, max(-1.0, cos3))), -math.acos(min(1.0, max(-1.0, cos3)))):
        alpha = math.atan2(z, x) - math.atan2(-p.l3 * math.sin(q3), p.l2 + p.l3 * math.cos(q3))
        out.append((-alpha, q3))
    return out

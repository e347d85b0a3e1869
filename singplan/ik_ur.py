"""Closed-form inverse kinematics of Universal Robots arms (UR3/UR5/UR10 URDF layout).

Geometry of the ur_description URDF (joint frames, base frame ``0``, link-1 frame ``1``):
axis 1 is z; axes 2, 3, 4 are parallel to the lateral axis ``y1``; the arm lies in a plane at
the lateral offset ``d4`` (sum of the y offsets of joints 2, 3 and 5); axis 5 is
perpendicular to ``y1``; axis 6 (the tool z axis) is ``y`` of link 5.

1. Wrist point ``P = p - d6 z_tool``, where axes 5 and 6 meet. Its lateral coordinate in
   frame 1 must equal ``d4``: ``r sin(phi - q1) = d4`` gives two q1 (front / back).
2. Axis 6 seen from frame 1: ``y1 . z_tool = cos q5`` (and ``|y1 x z_tool| = |sin q5|``) gives
   +-q5 (the two wrist branches).
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

from singplan.compiled import jit
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
    elbow_y: float = 0.0  # lateral offset of the elbow joint from the shoulder lift joint
    shoulder_turn: float = 0.0  # the shoulder lift joint's placement: a turn about its axis y [rad]

    @classmethod
    def from_robot(cls, robot: Robot) -> UrParameters:
        jp = [robot.model.jointPlacements[i].translation for i in range(1, 7)]
        tip = robot.model.frames[robot.tip_frame_id].placement.translation
        R2 = robot.model.jointPlacements[2].rotation
        return cls(d1=float(jp[0][2]), shoulder_y=float(jp[1][1]), lateral=float(jp[1][1] + jp[2][1] + jp[4][1]),
                   l2=float(jp[2][2]), l3=float(jp[3][2]), wrist_y=float(jp[4][1]), d5=float(jp[5][2]),
                   d6=float(tip[1]), elbow_y=float(jp[2][1]), shoulder_turn=math.atan2(R2[0, 2], R2[0, 0]))


_RX_HALF_PI = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_SINGULAR_Q5 = 1e-9  # |sin q5| under which a (= q2 + q3 + q4 + pi) keeps the seed's value [rad]


def ur_solutions(p: UrParameters, T_base_tool: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
    """All eight branches for one tool0 pose (4, 4); (8, 6) [rad], NaN rows where unreachable."""
    return ur_batch(p, np.asarray(T_base_tool, dtype=float)[None], None if seed is None else np.asarray(seed)[None])[0]


def ur_batch(p: UrParameters, T_base_tool: np.ndarray, seeds: np.ndarray | None = None) -> np.ndarray:
    """All eight branches for N tool0 poses (N, 4, 4), vectorised; (N, 8, 6) [rad], NaN rows unreachable.

    Branch index bits: 4 = back shoulder, 2 = negative q5, 1 = second elbow solution.
    ``seeds`` (N, 6) give q2 + q3 + q4 where q5 = 0 leaves it free (default 0).
    Shapes below: S shoulder, W wrist and E elbow solutions, 2 each.
    """
    T = np.asarray(T_base_tool, dtype=float).reshape(-1, 4, 4)
    n = T.shape[0]
    R, z_tool = T[:, :3, :3], T[:, :3, 2]
    wrist = T[:, :3, 3] - p.d6 * z_tool  # (N, 3)
    r = np.hypot(wrist[:, 0], wrist[:, 1])
    phi = np.arctan2(wrist[:, 1], wrist[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = np.arcsin(p.lateral / r)  # NaN where the wrist point is inside the lateral offset
    q1 = np.stack([phi - delta, phi - math.pi + delta], axis=1)  # (N, S)
    c1, s1 = np.cos(q1), np.sin(q1)
    x1 = np.stack([c1, s1, np.zeros_like(c1)], axis=-1)  # (N, S, 3): axes of frame 1 in the base
    y1 = np.stack([-s1, c1, np.zeros_like(c1)], axis=-1)
    z1 = np.broadcast_to(np.array([0.0, 0.0, 1.0]), x1.shape)
    R1T = np.stack([x1, y1, z1], axis=-2)  # (N, S, 3, 3) = Rz(q1)^T
    M = R1T @ (R @ _RX_HALF_PI)[:, None]  # (N, S, 3, 3)
    # |q5| from both its cosine and sine: acos alone loses half the digits near q5 = 0
    angle5 = np.arctan2(np.linalg.norm(np.cross(y1, z_tool[:, None]), axis=-1), np.einsum("nsi,ni->ns", y1, z_tool))
    q5 = np.stack([angle5, -angle5], axis=2)  # (N, S, W)
    a_seed = (np.zeros(n) if seeds is None else np.asarray(seeds, dtype=float)[:, 1:4].sum(axis=1)) + math.pi
    a, q6 = _wrist_yzy(M[:, :, None], q5, a_seed[:, None, None])  # (N, S, W)
    z5 = np.sin(a)[..., None] * x1[:, :, None] + np.cos(a)[..., None] * z1[:, :, None]  # (N, S, W, 3)
    o4 = wrist[:, None, None] - p.d5 * z5 - p.wrist_y * y1[:, :, None]
    x = np.einsum("nswi,nsi->nsw", o4, x1)
    z = o4[..., 2] - p.d1
    q2, q3 = _planar(p, x, z)  # (N, S, W, E)
    q4 = a[..., None] - math.pi - q2 - q3
    wide = np.broadcast_to
    out = np.stack([wide(q1[:, :, None, None], q2.shape), q2, q3, q4, wide(q5[..., None], q2.shape),
                    wide(q6[..., None], q2.shape)], axis=-1).reshape(n, 8, 6)
    out[np.any(np.isnan(out), axis=2)] = np.nan
    return math.pi - np.mod(math.pi - out, 2.0 * math.pi)


def _wrist_yzy(M: np.ndarray, q5: np.ndarray, a_seed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, q6) with Ry(a) Rz(q5) Ry(q6) = M; a = a_seed where q5 = 0 leaves it free.

    Only the first row of ``Rz(-q5) Ry(-a) M = Ry(q6)`` is formed for q6.
    """
    s5, c5 = np.sin(q5), np.cos(q5)
    regular = np.abs(s5) > _SINGULAR_Q5  # below it, a from M's tiny entries is noise
    a = np.where(regular, np.arctan2(M[..., 2, 1] * s5, -M[..., 0, 1] * s5), a_seed)
    ca, sa = np.cos(a), np.sin(a)
    row = [c5 * (ca * M[..., 0, j] - sa * M[..., 2, j]) + s5 * M[..., 1, j] for j in (0, 2)]
    return a, np.arctan2(row[1], row[0])


def _planar(p: UrParameters, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both (q2, q3) of the planar two-link arm placing the wrist-1 point at (x, z) in frame 1;
    each (..., E), NaN where unreachable."""
    cos3 = (x * x + z * z - p.l2**2 - p.l3**2) / (2.0 * p.l2 * p.l3)
    cos3 = np.where(np.abs(cos3) <= 1.0 + 1e-12, np.clip(cos3, -1.0, 1.0), np.nan)
    q3 = np.stack([np.arccos(cos3), -np.arccos(cos3)], axis=-1)
    alpha = np.arctan2(z, x)[..., None] - np.arctan2(-p.l3 * np.sin(q3), p.l2 + p.l3 * np.cos(q3))
    return -alpha, q3


def ur_arm_for_point(robot: Robot, q: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """Joints 1-3 that put the TCP at ``targets_m`` (N, 3) [m], joints 4-6 of ``q`` (N, 6) held.

    With q4..q6 fixed, the TCP is a fixed point ``x`` of the elbow link (joint 3's frame,
    found with Pinocchio at ``q``). Axes 2 and 3 are parallel to y of frame 1, so ``x``'s
    lateral coordinate in frame 1 is fixed: as for the wrist point of :func:`ur_batch`, it gives
    two q1. In frame 1's x-z plane the upper arm (0, l2) and the elbow link's (x_x, x_z) form
    a two-link arm: ``|A + Ry(t3) X| = |P|`` gives two ``t3``, then ``t2`` turns the sum onto P.
    Of the four solutions the one nearest ``q``'s joints 1-3 is kept; NaN rows are out of reach.
    """
    from singplan.ik import nearest_shifted  # ik imports this module

    p = UrParameters.from_robot(robot)
    point = np.array([_tcp_in_joint3(robot, qk) for qk in q]).reshape(-1, 3)
    arms = _arm_for_point(point, np.ascontiguousarray(targets_m, dtype=float), p.d1, p.shoulder_y + p.elbow_y,
                          p.l2, p.shoulder_turn)
    out = np.array(q, dtype=float)
    out[:, :3] = nearest_shifted(arms, out[:, :3])[0]
    return out


def _tcp_in_joint3(robot: Robot, q: np.ndarray) -> np.ndarray:
    T_base_tcp = robot.fk(q)  # also places joint 3 in robot.data
    return np.asarray(robot.data.oMi[3].actInv(T_base_tcp.translation))


@jit
def _arm_for_point(point: np.ndarray, targets: np.ndarray, d1: float, lateral: float, l2: float,
                   shoulder_turn: float) -> np.ndarray:
    """(q1, q2, q3) (N, 4, 3) placing ``point`` (N, 3, in joint 3's frame) at ``targets`` (N, 3)."""
    out = np.full((point.shape[0], 4, 3), np.nan)
    for i in range(point.shape[0]):
        tx, ty, tz = targets[i, 0], targets[i, 1], targets[i, 2] - d1
        xx, xz = point[i, 0], point[i, 2]
        r = math.hypot(tx, ty)
        side = lateral + point[i, 1]
        if not abs(side) <= r:
            continue  # the point's lateral offset cannot reach the target
        phi, delta = math.atan2(ty, tx), math.asin(side / r)
        # |A + Ry(t3) X|^2 = |P|^2, A = (0, l2): A.(Ry(t3) X) = l2 (xz cos t3 - xx sin t3) = k
        reach = math.hypot(xx, xz) * l2
        psi = math.atan2(-xx, xz)
        for s in range(2):
            q1 = phi - delta if s == 0 else phi - math.pi + delta
            px, pz = math.cos(q1) * tx + math.sin(q1) * ty, tz
            k = 0.5 * (px * px + pz * pz - l2 * l2 - xx * xx - xz * xz)
            if not abs(k) <= reach * (1.0 + 1e-12) or reach == 0.0:
                continue
            swing = math.acos(min(1.0, max(-1.0, k / reach)))
            for e in range(2):
                t3 = psi + swing if e == 0 else psi - swing
                vx = xx * math.cos(t3) + xz * math.sin(t3)
                vz = l2 - xx * math.sin(t3) + xz * math.cos(t3)
                out[i, 2 * s + e, 0] = q1
                out[i, 2 * s + e, 1] = math.atan2(vz, vx) - math.atan2(pz, px) - shoulder_turn
                out[i, 2 * s + e, 2] = t3
    return out

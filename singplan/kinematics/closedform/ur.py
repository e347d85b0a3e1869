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
import pinocchio as pin

from singplan.kinematics.angles import wrap
from singplan.kinematics.compiled import jit


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
    def from_model(cls, model: pin.Model, tip_frame_id: int) -> UrParameters:
        """Read from the joint placements of a chain in the ur_description layout (not checked here:
        :mod:`singplan.kinematics.families` verifies the closed form against the chain's FK)."""
        jp = [model.jointPlacements[i].translation for i in range(1, 7)]
        tip = model.frames[tip_frame_id].placement.translation
        R2 = model.jointPlacements[2].rotation
        return cls(d1=float(jp[0][2]), shoulder_y=float(jp[1][1]), lateral=float(jp[1][1] + jp[2][1] + jp[4][1]),
                   l2=float(jp[2][2]), l3=float(jp[3][2]), wrist_y=float(jp[4][1]), d5=float(jp[5][2]),
                   d6=float(tip[1]), elbow_y=float(jp[2][1]), shoulder_turn=math.atan2(R2[0, 2], R2[0, 0]))


# |sin q5| under which a (= q2 + q3 + q4 + pi) keeps the seed's value [rad]: the pose then
# differs by at most |sin q5| * |a - a_true|, under 1e-9 m / rad even a half turn from the seed
_SINGULAR_Q5 = 1e-10
_WRIST_SHIFT_RAD = 1e-10  # the most pose error a shift of a into the arm's reach may cost


def ur_solutions(p: UrParameters, T_base_tool: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
    """All eight branches for one tool0 pose (4, 4); (8, 6) [rad], NaN rows where unreachable."""
    return ur_batch(p, np.asarray(T_base_tool, dtype=float)[None], None if seed is None else np.asarray(seed)[None])[0]


def ur_batch(p: UrParameters, T_base_tool: np.ndarray, seeds: np.ndarray | None = None) -> np.ndarray:
    """All eight branches for N tool0 poses (N, 4, 4); (N, 8, 6) [rad] in (-pi, pi], NaN rows unreachable.

    Branch index bits: 4 = back shoulder, 2 = negative q5, 1 = second elbow solution.
    ``seeds`` (N, 6) give q2 + q3 + q4 where q5 = 0 leaves it free (default 0).
    """
    T = np.ascontiguousarray(T_base_tool, dtype=float).reshape(-1, 4, 4)
    a_seed = (np.zeros(len(T)) if seeds is None else np.asarray(seeds, dtype=float)[:, 1:4].sum(axis=1)) + math.pi
    return _branches(T, a_seed, p.d1, p.lateral, p.l2, p.l3, p.wrist_y, p.d5, p.d6, _tolerance_m(p))


def _tolerance_m(p: UrParameters) -> float:
    """How far [m] beyond a reach boundary a point still counts as on it (REACH_REL_TOL of the arm)."""
    size = abs(p.d1) + abs(p.lateral) + abs(p.l2) + abs(p.l3) + abs(p.d5) + abs(p.d6)
    return REACH_REL_TOL * size


# A point this much [m per m of the arm's size] beyond a reach boundary (the stretched or folded
# elbow, the shoulder's lateral offset) is taken as on it: the URDF's placements are rounded
# (e.g. pi/2 to 11 digits), which moves the boundary by ~1e-12 of the lengths, and a pose made
# by FK exactly on the boundary must keep its solution.
REACH_REL_TOL = 1e-9


@jit
def _shoulder(x: float, y: float, lateral: float, tol_m: float) -> tuple[float, float]:
    """The two q1 (front, back) that put a point at (x, y) in the base at ``lateral`` on y1:
    ``r sin(phi - q1) = lateral``; NaN when the point lies inside that offset by more than tol_m."""
    r = math.hypot(x, y)
    if not abs(lateral) <= r + tol_m:
        return math.nan, math.nan
    phi = math.atan2(y, x)
    delta = math.copysign(0.5 * math.pi, lateral) if abs(lateral) >= r else math.asin(lateral / r)
    return phi - delta, phi - math.pi + delta


@jit
def _branches(T: np.ndarray, a_seed: np.ndarray, d1: float, lateral: float, l2: float, l3: float, wrist_y: float,
              d5: float, d6: float, tol_m: float) -> np.ndarray:
    """The four steps of the module docstring, pose by pose; (N, 8, 6)."""
    out = np.full((T.shape[0], 8, 6), np.nan)
    # |cos q3| slack for a wrist-1 point tol_m beyond the stretched (or folded) elbow
    cos_tol = tol_m * (abs(l2) + abs(l3)) / abs(l2 * l3)
    m = np.empty((3, 3))
    for i in range(T.shape[0]):
        zx, zy, zz = T[i, 0, 2], T[i, 1, 2], T[i, 2, 2]
        px, py, pz = T[i, 0, 3] - d6 * zx, T[i, 1, 3] - d6 * zy, T[i, 2, 3] - d6 * zz  # wrist point
        front, back = _shoulder(px, py, lateral, tol_m)
        if math.isnan(front):
            continue  # the wrist point is inside the lateral offset
        for s in range(2):
            q1 = front if s == 0 else back
            c1, s1 = math.cos(q1), math.sin(q1)
            for col in range(3):  # M = Rz(q1)^T R Rx(pi/2): rows x1, y1, z1 against R's columns 0, 2, -1
                k, sign = (0, 1.0) if col == 0 else ((2, 1.0) if col == 1 else (1, -1.0))
                m[0, col] = sign * (c1 * T[i, 0, k] + s1 * T[i, 1, k])
                m[1, col] = sign * (-s1 * T[i, 0, k] + c1 * T[i, 1, k])
                m[2, col] = sign * T[i, 2, k]
            # |q5| from both its cosine and sine: acos alone loses half the digits near q5 = 0
            cross = math.sqrt((c1 * zz) ** 2 + (s1 * zz) ** 2 + (-s1 * zy - c1 * zx) ** 2)
            angle5 = math.atan2(cross, -s1 * zx + c1 * zy)
            for w in range(2):
                q5 = angle5 if w == 0 else -angle5
                s5, c5 = math.sin(q5), math.cos(q5)
                x0, z0 = c1 * px + s1 * py, pz - d1
                if abs(s5) > _SINGULAR_Q5:
                    a = math.atan2(m[2, 1] * s5, -m[0, 1] * s5)
                    # near q5 = 0, a carries an error of (rotation round-off) / |sin q5| that can
                    # put the wrist-1 point out of reach; moving a by d costs only |sin q5| d of pose
                    reach_a = _free_wrist_angle(a, x0, z0, d5, l2, l3)
                    if abs(s5) * abs(math.sin(0.5 * (reach_a - a))) * 2.0 <= _WRIST_SHIFT_RAD:
                        a = reach_a
                else:
                    a = _free_wrist_angle(a_seed[i], x0, z0, d5, l2, l3)
                ca, sa = math.cos(a), math.sin(a)
                row0 = c5 * (ca * m[0, 0] - sa * m[2, 0]) + s5 * m[1, 0]
                row2 = c5 * (ca * m[0, 2] - sa * m[2, 2]) + s5 * m[1, 2]
                q6 = math.atan2(row2, row0)
                # wrist-1 point o4 = P - d5 z5 - wrist_y y1, z5 = sin(a) x1 + cos(a) z1, in frame 1's x-z plane
                x = x0 - d5 * sa
                z = z0 - d5 * ca
                cos3 = (x * x + z * z - l2 * l2 - l3 * l3) / (2.0 * l2 * l3)
                if not abs(cos3) <= 1.0 + cos_tol:
                    continue
                for e in range(2):
                    q3 = math.acos(min(1.0, max(-1.0, cos3))) * (1.0 if e == 0 else -1.0)
                    q2 = math.atan2(-l3 * math.sin(q3), l2 + l3 * math.cos(q3)) - math.atan2(z, x)
                    row = out[i, 4 * s + 2 * w + e]
                    row[0], row[1], row[2] = q1, q2, q3
                    row[3], row[4], row[5] = a - math.pi - q2 - q3, q5, q6
                    for j in range(6):
                        row[j] = wrap(row[j])
    return out


@jit
def _free_wrist_angle(a_seed: float, x: float, z: float, d5: float, l2: float, l3: float) -> float:
    """``a`` at q5 = 0, where the pose leaves it free: the seed's, or the nearest the arm reaches.

    The wrist-1 point ``(x - d5 sin a, z - d5 cos a)`` (frame 1's x-z plane, wrist point at
    (x, z)) runs round a circle as ``a`` turns; its distance rho from the shoulder must lie in
    [|l2 - l3|, l2 + l3]. With ``theta = atan2(x, z)`` that is ``cos(a - theta)`` between
    ``(R^2 + d5^2 - (l2 + l3)^2) / (2 d5 R)`` and the same with |l2 - l3|. A seed outside is
    moved to the nearest end of that range, so a pose reachable with some ``a`` is solved.
    """
    radius = math.hypot(x, z)
    if radius * d5 == 0.0:
        return a_seed
    theta = math.atan2(x, z)
    delta = wrap(a_seed - theta)
    c_far = (radius * radius + d5 * d5 - (l2 + l3) ** 2) / (2.0 * d5 * radius)
    c_near = (radius * radius + d5 * d5 - (l2 - l3) ** 2) / (2.0 * d5 * radius)
    c = math.cos(delta)
    if c_far > 1.0 or c_near < -1.0 or c_far <= c <= c_near:
        return a_seed  # out of reach for every a, or the seed's reaches
    bound = c_far if c < c_far else c_near
    return theta + math.copysign(math.acos(min(1.0, max(-1.0, bound))), delta)


def arm_for_point(p: UrParameters, point: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """(q1, q2, q3) (N, 4, 3) of the four arm solutions placing ``point`` (N, 3) [m], fixed in the
    closed form's joint-3 frame, at ``targets_m`` (N, 3) [m]; NaN where out of reach.

    With q4..q6 fixed, the TCP is a fixed point ``x`` of the elbow link. Axes 2 and 3 are parallel
    to y of frame 1, so ``x``'s lateral coordinate in frame 1 is fixed: as for the wrist point of
    :func:`ur_batch`, it gives two q1. In frame 1's x-z plane the upper arm (0, l2) and the elbow
    link's (x_x, x_z) form a two-link arm: ``|A + Ry(t3) X| = |P|`` gives two ``t3``, then ``t2``
    turns the sum onto P.
    """
    return _arm_for_point(np.ascontiguousarray(point, dtype=float), np.ascontiguousarray(targets_m, dtype=float),
                          p.d1, p.shoulder_y + p.elbow_y, p.l2, p.shoulder_turn, _tolerance_m(p))


@jit
def _arm_for_point(point: np.ndarray, targets: np.ndarray, d1: float, lateral: float, l2: float,
                   shoulder_turn: float, tol_m: float) -> np.ndarray:
    """(q1, q2, q3) (N, 4, 3) placing ``point`` (N, 3, in joint 3's frame) at ``targets`` (N, 3)."""
    out = np.full((point.shape[0], 4, 3), np.nan)
    for i in range(point.shape[0]):
        tx, ty, tz = targets[i, 0], targets[i, 1], targets[i, 2] - d1
        xx, xz = point[i, 0], point[i, 2]
        front, back = _shoulder(tx, ty, lateral + point[i, 1], tol_m)
        if math.isnan(front):
            continue  # the point's lateral offset cannot reach the target
        # |A + Ry(t3) X|^2 = |P|^2, A = (0, l2): A.(Ry(t3) X) = l2 (xz cos t3 - xx sin t3) = k
        reach = math.hypot(xx, xz) * l2
        psi = math.atan2(-xx, xz)
        for s in range(2):
            q1 = front if s == 0 else back
            px, pz = math.cos(q1) * tx + math.sin(q1) * ty, tz
            k = 0.5 * (px * px + pz * pz - l2 * l2 - xx * xx - xz * xz)
            # k changes by |P| per metre of |P|: the same slack as the wrist point's elbow
            if not abs(k) <= reach + tol_m * (l2 + math.hypot(xx, xz)) or reach == 0.0:
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

"""Compiled OPW closed form: the per-pose arithmetic of :func:`singplan.kinematics.ik.solve.opw_batch`.

The formulas are those of Brandstoetter, Angerer and Hofbaur (2014), written as scalar loops
over the poses and compiled (:mod:`singplan.kinematics.compiled`): as vectorised numpy the solver was
~150 array operations, about 0.3 ms per call whatever the number of poses.

All angles here are in OPW coordinates; :mod:`singplan.kinematics.ik.solve` converts to robot joints.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from singplan.kinematics.angles import wrap
from singplan.kinematics.compiled import jit

# A wrist centre this much [m per m of the arm's size] beyond a reach boundary (the stretched or
# folded elbow, the offset cylinder round axis 1) is taken as on it: a pose made by FK exactly
# on the boundary must keep its solution, whatever the round-off of the URDF's placements.
REACH_REL_TOL = 1e-9
AXIS_EPS = 1e-12  # wrist centre this close to axis 1: q1 undefined, keep the seed's
WRIST_EPS = 1e-12  # sin q5 under this: q4 undefined, keep the seed's


@jit
def _safe_acos(x: float, slack: float) -> float:
    """acos that clips an overshoot of up to ``slack`` at a stretched arm, NaN when really out of reach."""
    if not abs(x) <= 1.0 + slack:  # also NaN
        return math.nan
    return math.acos(min(1.0, max(-1.0, x)))


@jit
def _arm(cx: float, cy: float, cz: float, a1: float, a2: float, b: float, c1: float, c2: float, c3: float,
         q1_seed: float, out: np.ndarray) -> None:
    """The four (theta1, theta2, theta3) of the arm for one wrist centre, into ``out`` (4, 3).

    theta3 comes from the distance of the wrist centre (law of cosines), theta2 from theta3 by
    turning the elbow triangle onto the wrist centre's direction: at a stretched elbow, where
    acos loses half the digits, the pair still places the wrist centre to round-off.
    """
    kappa = math.hypot(a2, c3)
    tol_m = REACH_REL_TOL * (abs(a1) + abs(a2) + abs(b) + abs(c1) + abs(c2) + abs(c3))
    r2 = cx * cx + cy * cy
    lateral2 = r2 - b * b
    if lateral2 < 0.0 and lateral2 > -2.0 * tol_m * (abs(b) + tol_m):
        lateral2 = 0.0  # on the offset cylinder to round-off
    nx1 = np.sqrt(lateral2) - a1  # NaN inside the offset cylinder
    tmp1 = q1_seed if r2 < AXIS_EPS * AXIS_EPS else math.atan2(cy, cx)
    tmp2 = math.atan2(b, nx1 + a1)
    tmp3 = cz - c1
    tmp4 = nx1 + 2.0 * a1
    # |cos| slack for a distance tol_m beyond the elbow's reach: d(cos)/d(distance) <= (c2 + kappa) / (c2 kappa)
    slack = tol_m * (c2 + kappa) / (c2 * kappa)
    k = 2.0 * c2 * kappa
    acos_c = _safe_acos((nx1 * nx1 + tmp3 * tmp3 - c2 * c2 - kappa * kappa) / k, slack)
    acos_d = _safe_acos((tmp4 * tmp4 + tmp3 * tmp3 - c2 * c2 - kappa * kappa) / k, slack)
    phi = math.atan2(a2, c3)
    front, back = math.atan2(nx1, tmp3), math.atan2(tmp4, tmp3)
    out[0, 0] = out[1, 0] = tmp1 - tmp2
    out[2, 0] = out[3, 0] = tmp1 + tmp2 - math.pi
    for j in range(4):
        elbow = acos_c if j == 0 else (-acos_c if j == 1 else (acos_d if j == 2 else -acos_d))
        # theta2: the wrist centre's direction (from the vertical) less the elbow triangle's angle
        towards = front if j < 2 else -back
        out[j, 1] = towards - math.atan2(kappa * math.sin(elbow), c2 + kappa * math.cos(elbow))
        out[j, 2] = elbow - phi


@jit
def _wrist(R: np.ndarray, t1: float, t23: float, q4_seed: float) -> tuple[float, float, float]:
    """(theta4, theta5, theta6) of the non-flipped wrist: ``R_ce = (Rz(t1) Ry(t23))^T R`` as ZYZ.

    Only the entries of ``R_ce`` the angles need are formed. q6 comes from
    ``M = Ry(-t5) Rz(-t4) R_ce = Rz(t6)``, which stays well conditioned where sin q5 -> 0.
    """
    s1, c1, s23, c23 = math.sin(t1), math.cos(t1), math.sin(t23), math.cos(t23)
    xy0_0 = c1 * R[0, 0] + s1 * R[1, 0]
    xy0_2 = c1 * R[0, 2] + s1 * R[1, 2]
    e00 = c23 * xy0_0 - s23 * R[2, 0]
    e02 = c23 * xy0_2 - s23 * R[2, 2]
    e10 = -s1 * R[0, 0] + c1 * R[1, 0]
    e12 = -s1 * R[0, 2] + c1 * R[1, 2]
    e20 = s23 * xy0_0 + c23 * R[2, 0]
    e22 = s23 * xy0_2 + c23 * R[2, 2]
    sin5 = math.hypot(e02, e12)
    if sin5 > WRIST_EPS:
        t4, s4, c4 = math.atan2(e12, e02), e12 / sin5, e02 / sin5
    else:
        t4 = q4_seed
        s4, c4 = math.sin(t4), math.cos(t4)
    t5 = math.atan2(sin5, e22)
    m00 = (e22 * (c4 * e00 + s4 * e10) - sin5 * e20) / math.hypot(sin5, e22)
    m10 = -s4 * e00 + c4 * e10
    return t4, t5, math.atan2(m10, m00)


@jit
def branches(T: np.ndarray, a1: float, a2: float, b: float, c1: float, c2: float, c3: float, c4: float,
             offsets: np.ndarray, signs: np.ndarray, q4_seed: np.ndarray, q1_seed: np.ndarray) -> np.ndarray:
    """All eight branches (N, 8, 6) of flange poses T (N, 4, 4), in robot joint coordinates.

    Branches 0-3 are the four arm solutions with the non-flipped wrist, 4-7 the same arms with
    the flipped wrist (q4 + pi, -q5, q6 + pi). NaN rows: the arm cannot reach the wrist centre.
    """
    n = T.shape[0]
    out = np.full((n, 8, 6), np.nan)
    arms = np.empty((4, 3))
    for i in range(n):
        R = T[i, :3, :3]
        _arm(T[i, 0, 3] - c4 * R[0, 2], T[i, 1, 3] - c4 * R[1, 2], T[i, 2, 3] - c4 * R[2, 2],
             a1, a2, b, c1, c2, c3, q1_seed[i], arms)
        for j in range(4):
            t1, t2, t3 = arms[j, 0], arms[j, 1], arms[j, 2]
            if math.isnan(t1) or math.isnan(t2) or math.isnan(t3):
                continue  # both wrists of this arm stay NaN
            t4, t5, t6 = _wrist(R, t1, t2 + t3, q4_seed[i])
            row, flip = out[i, j], out[i, j + 4]
            row[0] = flip[0] = wrap((t1 + offsets[0]) * signs[0])
            row[1] = flip[1] = wrap((t2 + offsets[1]) * signs[1])
            row[2] = flip[2] = wrap((t3 + offsets[2]) * signs[2])
            row[3] = wrap((t4 + offsets[3]) * signs[3])
            row[4] = wrap((t5 + offsets[4]) * signs[4])
            row[5] = wrap((t6 + offsets[5]) * signs[5])
            flip[3] = wrap(row[3] + math.pi)
            flip[4] = wrap((offsets[4] - t5) * signs[4])
            flip[5] = wrap(row[5] + math.pi)
    return out


@jit
def arm_for_point(q_opw: np.ndarray, point: np.ndarray, targets: np.ndarray, a1: float, a2: float, b: float,
                  c1: float, c2: float, c3: float) -> np.ndarray:
    """The four arm solutions (N, 4, 3) that put ``point`` (3,), fixed in the frame ``e`` of the
    wrist, at ``targets`` (N, 3), wrist angles q_opw[:, 3:] held
    (see :func:`singplan.kinematics.ik.solve.opw_arm_for_point`).

    ``w = Rz(t4) Ry(t5) Rz(t6) point`` is the point in the forearm frame ``c``; the arm then
    places it as the wrist centre of an arm with a2 + w_x, b + w_y, c3 + w_z.
    """
    out = np.empty((q_opw.shape[0], 4, 3))
    for i in range(q_opw.shape[0]):
        s4, c4 = math.sin(q_opw[i, 3]), math.cos(q_opw[i, 3])
        s5, c5 = math.sin(q_opw[i, 4]), math.cos(q_opw[i, 4])
        s6, c6 = math.sin(q_opw[i, 5]), math.cos(q_opw[i, 5])
        x6 = c6 * point[0] - s6 * point[1]  # Rz(t6) point
        y6 = s6 * point[0] + c6 * point[1]
        x5, z5 = c5 * x6 + s5 * point[2], -s5 * x6 + c5 * point[2]  # Ry(t5)
        wx, wy = c4 * x5 - s4 * y6, s4 * x5 + c4 * y6  # Rz(t4)
        _arm(targets[i, 0], targets[i, 1], targets[i, 2], a1, a2 + wx, b + wy, c1, c2, c3 + z5, q_opw[i, 0], out[i])
    return out


def kernels_cached() -> bool:
    """Whether numba's disk cache already holds singplan's kernels (judged by this module's)."""
    folder = branches.stats.cache_path  # None when numba found no writable cache folder
    return folder is not None and any(Path(folder).glob(f"opw.{branches.py_func.__qualname__}-*.nbi"))

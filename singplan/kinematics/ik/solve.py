"""Inverse kinematics: all branches of a TCP pose.

Three solvers share one API (:func:`solve_all`, :func:`closed_form_branches`):

* **OPW closed form** for ortho-parallel arms with a spherical wrist, after Brandstoetter,
  Angerer and Hofbaur, "An analytical solution of the inverse kinematics problem of
  industrial serial manipulators with an ortho-parallel basis and a spherical wrist" (2014).
  The arm part gives four (q1, q2, q3) solutions from the wrist centre
  ``c = p - c4 * z_flange``; for each, the wrist rotation ``R_ce = R_0c^T R`` is a ZYZ
  rotation ``Rz(q4) Ry(q5) Rz(q6)`` whose two decompositions (q5 and -q5) give eight
  branches. :func:`opw_batch` evaluates all eight for N poses at once (a compiled loop,
  :mod:`singplan.kinematics.closedform.opw`).
* **UR closed form** (:mod:`singplan.kinematics.closedform.ur`) for the ur_description layout, eight branches.
* **Numeric** (:mod:`singplan.kinematics.ik.numeric`: Levenberg-Marquardt on the SE(3) log error from
  quasi-random and branch-flipped seeds, inside the joint limits) for any other chain.

Which applies is :attr:`Robot.family`, recognised and verified from the chain (:mod:`singplan.kinematics.families`).

At an exactly wrist-singular pose (q5 = 0) only q4 + q6 is determined. singplan keeps q4
at the seed's value (0 without a seed) and gives the rest to q6, so no branch is lost and
no NaN is returned. q6 is always recovered from the full wrist rotation (not from the row
that vanishes at the singularity), which keeps the pose exact to round-off near it too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from singplan.kinematics.angles import nearest_shifted, wrap_to_pi
from singplan.kinematics.closedform import opw
from singplan.kinematics.closedform.ur import arm_for_point as ur_arm_kernel
from singplan.kinematics.closedform.ur import ur_batch
from singplan.kinematics.configuration import LABEL_ZERO, classify, labels_batch, labels_of_variants
from singplan.kinematics.ik import numeric as ik_numeric
from singplan.kinematics.ik import turns
from singplan.kinematics.robot import OpwParameters, Robot


@dataclass(frozen=True)
class IkSolutions:
    """Every solution of one pose.

    Attributes:
        q: joint values [rad], shape (M, n); each row reproduces the pose.
        labels: configuration label of each row ("F U N"), length M.
        branches: solver branch of each row (0..7 for OPW, seed index for numeric), shape (M,).
    """

    q: np.ndarray  # (M, n)
    labels: tuple[str, ...]
    branches: np.ndarray  # (M,)

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def nearest(self, q_ref: np.ndarray) -> np.ndarray:
        """The solution closest to ``q_ref`` (max-norm joint distance)."""
        k = int(np.argmin(np.max(np.abs(self.q - q_ref), axis=1)))
        return np.array(self.q[k])


def opw_batch(params: OpwParameters, T_base_flange: np.ndarray, q4_seed_opw: np.ndarray | None = None,
              q1_seed_opw: np.ndarray | None = None) -> np.ndarray:
    """All eight OPW branches for N flange poses, in robot joint coordinates.

    Args:
        params: the arm's OPW parameters.
        T_base_flange: homogeneous flange poses (N, 4, 4) [m].
        q4_seed_opw, q1_seed_opw: (N,) OPW-coordinate angles kept where q4 (wrist singular) or
            q1 (wrist centre on axis 1) is free; default 0.

    Returns:
        (N, 8, 6) joint values [rad] wrapped to (-pi, pi]; NaN rows for unreachable branches.
        Branches 0-3 are the four arm solutions with the OPW wrist, 4-7 the same arms flipped.
    """
    T = np.ascontiguousarray(T_base_flange, dtype=float).reshape(-1, 4, 4)
    n = T.shape[0]
    q4s = np.zeros(n) if q4_seed_opw is None else np.ascontiguousarray(q4_seed_opw, dtype=float)
    q1s = np.zeros(n) if q1_seed_opw is None else np.ascontiguousarray(q1_seed_opw, dtype=float)
    p = params
    return opw.branches(T, p.a1, p.a2, p.b, p.c1, p.c2, p.c3, p.c4, p.offsets, p.signs, q4s, q1s)


def ur_arm_for_point(robot: Robot, q: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """Joints 1-3 that put the TCP at ``targets_m`` (N, 3) [m], joints 4-6 of ``q`` (N, 6) held, on a
    UR-type arm (:func:`singplan.kinematics.closedform.ur.arm_for_point`: with q4..q6 fixed the TCP is a
    fixed point of the elbow link, found with Pinocchio at ``q``). Of the four solutions the one
    nearest ``q``'s joints 1-3 is kept; NaN rows are out of reach.
    """
    p = robot.ur
    if p is None:
        raise ValueError(f"{robot.name} is not a UR-type arm (family {robot.family})")
    point = np.array([_tcp_in_joint3(robot, qk) for qk in q]).reshape(-1, 3)
    arms = ur_arm_kernel(p, point, targets_m)
    out = np.array(q, dtype=float)
    out[:, :3] = nearest_shifted(arms, out[:, :3])[0]
    return out


def _tcp_in_joint3(robot: Robot, q: np.ndarray) -> np.ndarray:
    """The TCP in the closed form's joint-3 frame (the URDF's, or its layout's: T_joint3_closed)."""
    T_tcp, joint3 = robot.fk_and_joint(q, 3)
    return np.asarray((joint3 * pin.SE3(robot.recognition.T_joint3_closed)).actInv(T_tcp.translation))


def opw_arm_for_point(params: OpwParameters, q_robot: np.ndarray, point_flange_m: np.ndarray,
                      targets_m: np.ndarray) -> np.ndarray:
    """Joints 1-3 that put a point fixed to the flange at ``targets_m``, joints 4-6 held (SEEDS 001).

    With the wrist angles fixed, the point sits at ``w = R_ce (c4 e_z + point_flange)`` in the
    frame ``c`` of the OPW arm (``R_0c = Rz(t1) Ry(t2 + t3)``). Because ``Ry(t2 + t3)`` turns
    ``w`` with the forearm and leaves its y part alone, the point is the wrist centre of an
    OPW arm with ``a2 + w_x``, ``b + w_y`` and ``c3 + w_z``: the arm closed form then gives
    all four (q1, q2, q3), and the one nearest ``q_robot``'s is kept.

    Args:
        params: the arm's OPW parameters.
        q_robot: joint values [rad] (N, 6); joints 4-6 are kept, joints 1-3 seed the choice.
        point_flange_m: the point in the flange (tip) frame [m], (3,).
        targets_m: where the point must be, in the base frame [m], (N, 3).

    Returns:
        (N, 6) joint values; rows whose point is out of reach are NaN.
    """
    p = params
    point = np.array([0.0, 0.0, p.c4]) + point_flange_m
    arms_opw = opw.arm_for_point(np.ascontiguousarray(_to_opw(p, q_robot)), point,
                                 np.ascontiguousarray(targets_m, dtype=float), p.a1, p.a2, p.b, p.c1, p.c2, p.c3)
    arms = (arms_opw + p.offsets[:3]) * p.signs[:3]  # robot coordinates
    out = np.array(q_robot, dtype=float)
    out[:, :3] = nearest_shifted(arms, out[:, :3])[0]
    return out


def _to_opw(params: OpwParameters, q_robot: np.ndarray) -> np.ndarray:
    return q_robot * params.signs - params.offsets


def solve_all(robot: Robot, T_base_tcp: pin.SE3, seed: np.ndarray | None = None) -> IkSolutions:
    """Every IK solution of a TCP pose inside the joint limits.

    Without a seed, every 2*pi-shifted variant inside the limits is listed (joints whose
    range exceeds +-180 deg have several; an unlimited joint's angle is given in (-pi, pi]). With
    a seed, each branch gives the variant nearest the seed (the shortest turn), and at a wrist
    singularity the seed's q4 is kept; solutions equal up to whole
    turns are one solution, listed once (branches meet on a singular pose: the UR5 at q = 0 has
    two solver branches 360 deg apart in q2 and q4), as the variant nearest the seed.
    """
    if robot.family in ("opw", "ur"):  # the branches are the closed form's rows 0..7
        rows = closed_form_branches(robot, T_base_tcp.homogeneous[None], None if seed is None else seed[None])[0]
        q_all, branch = turns.variants_inside(rows, robot.lower_rad, robot.upper_rad, seed, LABEL_ZERO)
        return IkSolutions(q=q_all, labels=tuple(labels_of_variants(robot, rows, branch, q_all)), branches=branch)
    rows, branches = _numeric_candidates(robot, T_base_tcp, seed)
    q_all, branch = turns.inside_limits(rows, branches, robot.lower_rad, robot.upper_rad, seed, LABEL_ZERO)
    return IkSolutions(q=q_all, labels=tuple(labels_batch(robot, q_all)), branches=branch)


def closed_form_branches(robot: Robot, T_base_tcp: np.ndarray, seeds: np.ndarray | None = None) -> np.ndarray:
    """Every closed-form branch of N TCP poses (N, 4, 4): (N, B, n) joint values, NaN rows unreachable.

    B = 8 for OPW and UR arms, 0 for chains with no closed form. ``seeds`` (N, n) give the
    free joints at a singularity (the seed's q4 at q5 = 0, its q1 on axis 1).
    """
    T_tip = np.asarray(T_base_tcp, dtype=float).reshape(-1, 4, 4) @ robot.T_tcp_tip_h
    T_flange = robot.recognition.to_closed_form(T_tip)  # a base or tip off the closed form's axes folded in
    if robot.opw is not None:
        p = robot.opw
        seeds_opw = None if seeds is None else _to_opw(p, np.asarray(seeds, dtype=float).reshape(len(T_flange), -1))
        return opw_batch(p, T_flange, None if seeds_opw is None else seeds_opw[:, 3],
                         None if seeds_opw is None else seeds_opw[:, 0])
    if robot.ur is not None:
        return ur_batch(robot.ur, T_flange, seeds)
    return np.full((len(T_flange), 0, robot.n_joints), np.nan)


def _numeric_candidates(robot: Robot, T_base_tcp: pin.SE3,
                        seed: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    rows, origins = ik_numeric.all_branches(robot, T_base_tcp, seed, label=lambda q: classify(robot, q).label)
    return np.array([wrap_to_pi(q) for q in rows]).reshape(-1, robot.n_joints), np.array(origins, dtype=int)


solve_newton = ik_numeric.newton  # the seeded per-sample solve (tracking, joint maps)

"""A move's map from path parameter ``u`` in [0, 1] to joint values.

The map is what the planner hands to the timing: dense reference samples for TOPP-RA, and
:meth:`JointMap.evaluate` to compute the joint values of any ``u`` exactly, so that every
output sample lies on the path. It is stitched from parts:

* ``track``: exact IK; the branch and the 2*pi turn are those nearest the tracked reference
  samples, interpolated at ``u``.
* ``blend``: a crossing's joint interpolation (cubic Hermite between the entry and exit
  joint values and slopes), with joints 1-3 re-solved so that the TCP *position* is exact.
* ``axis``: one joint follows the blend; the others keep one pose component exact and
  minimise the error of the other (SEEDS 000, :func:`axis_solve`).
* ``ptp``: piecewise-linear in joint space (PTP moves, and the ``ptp`` baseline's jump, which
  starts and ends at rest: :mod:`singplan.planning.orchestration.stops`).
* ``spline``: a C2 cubic spline through the samples of a baseline (``average``, ``dls``), its end
  slopes the neighbouring path's, so the joints move smoothly through them and on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline

from singplan.kinematics.angles import nearest_shifted
from singplan.kinematics.compiled import jit
from singplan.kinematics.geometry import relative_rotations, rotation_log_jacobians, rotation_logs
from singplan.kinematics.ik.numeric import damped_solve_rows
from singplan.kinematics.ik.solve import closed_form_branches, opw_arm_for_point, solve_newton, ur_arm_for_point
from singplan.kinematics.robot import Robot
from singplan.planning.path.spline import not_a_knot
from singplan.planning.path.tracking import PoseFunction

_DAMPING = 1e-6  # Levenberg-Marquardt lambda^2 of the position re-solve [m^2]
_CHUNK = 65_536  # samples evaluated at once: the IK's temporaries take ~0.8 kB a sample


@dataclass(frozen=True)
class JointPart:
    """One part of a joint map over [u0, u1].

    Attributes:
        kind: "track" | "blend" | "axis" | "ptp" | "spline".
        u: reference parameters inside [u0, u1], increasing, shape (K,).
        q: reference joint values [rad], shape (K, n).
        dq_du: joint slopes at u0 and u1 (blend, axis and spline parts), shape (2, n).
    """

    kind: str
    u: np.ndarray  # (K,)
    q: np.ndarray  # (K, n)
    dq_du: np.ndarray | None = None  # (2, n)
    axis: int = -1  # "axis" parts: the interpolated joint
    exact: str = "position"  # "axis" parts: the pose component kept exact

    @property
    def u0(self) -> float:
        return float(self.u[0])

    @property
    def u1(self) -> float:
        return float(self.u[-1])


def hermite(part: JointPart, u: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of a blend part's end values and slopes, (N, n)."""
    assert part.dq_du is not None
    return _hermite(part.u0, part.u1, np.ascontiguousarray(part.q[0]), np.ascontiguousarray(part.q[-1]),
                    np.ascontiguousarray(part.dq_du), np.ascontiguousarray(u, dtype=float))


@jit
def _hermite(u0: float, u1: float, q0: np.ndarray, q1: np.ndarray, dq_du: np.ndarray, u: np.ndarray) -> np.ndarray:
    h = u1 - u0
    out = np.empty((u.shape[0], q0.shape[0]))
    for i in range(u.shape[0]):
        t = (u[i] - u0) / h
        h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
        h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
        for j in range(q0.shape[0]):
            out[i, j] = h00 * q0[j] + h10 * h * dq_du[0, j] + h01 * q1[j] + h11 * h * dq_du[1, j]
    return out


def interpolate(part: JointPart, u: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation of the part's reference samples, (N, n); constant outside."""
    return _interpolate_rows(part.u, np.ascontiguousarray(part.q), np.ascontiguousarray(u, dtype=float))


@jit
def _interpolate_rows(u_ref: np.ndarray, q_ref: np.ndarray, u: np.ndarray) -> np.ndarray:
    out = np.empty((u.shape[0], q_ref.shape[1]))
    last = u_ref.shape[0] - 1
    for i in range(u.shape[0]):
        k = min(max(np.searchsorted(u_ref, u[i], side="right") - 1, 0), max(last - 1, 0))
        t = 0.0 if last == 0 else min(1.0, max(0.0, (u[i] - u_ref[k]) / (u_ref[k + 1] - u_ref[k])))
        for j in range(q_ref.shape[1]):
            out[i, j] = (1.0 - t) * q_ref[k, j] + t * q_ref[min(k + 1, last), j]
    return out


class JointMap:
    """Map u -> q of one move, built from consecutive parts that share their end samples."""

    def __init__(self, robot: Robot, poses: PoseFunction | None, parts: list[JointPart]) -> None:
        self.robot = robot
        self.poses = poses
        self.parts = parts
        # an axis part's spline through its solutions, a spline part's curve, by the part's id (the
        # part is kept: its id stays its own)
        self._starts: dict[int, tuple[JointPart, CubicSpline]] = {}

    def release(self) -> None:
        """Drop the splines made for evaluating it (made again, the same, if it is evaluated later): a
        long program keeps every move's joint map, and these are a quarter of what a move keeps."""
        self._starts.clear()

    @property
    def straight(self) -> bool:
        """A straight line in joint space (a PTP): a few reference points describe it."""
        return all(part.kind == "ptp" for part in self.parts)

    @property
    def off_path_parts(self) -> list[JointPart]:
        """The parts whose TCP may leave a LIN / CIRC's path in position (joint lines and splines,
        axis parts that keep the orientation); none for a PTP move."""
        if self.poses is None:
            return []
        return [p for p in self.parts if p.kind in ("ptp", "spline") or (p.kind == "axis" and p.exact != "position")]

    def reference(self) -> tuple[np.ndarray, np.ndarray]:
        """All reference samples (u (K,), q (K, n)), without repeated part ends."""
        us, qs = [self.parts[0].u[:1]], [self.parts[0].q[:1]]
        for part in self.parts:
            us.append(part.u[1:])
            qs.append(part.q[1:])
        return np.concatenate(us), np.concatenate(qs)

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        """Joint values (N, n) at parameters u (N,), each exactly on the map's definition."""
        u = np.minimum(np.maximum(np.asarray(u, dtype=float), 0.0), 1.0)  # np.clip costs several times more
        if len(u) == 0:
            return np.empty((0, self.robot.n_joints))
        if not self.parts:  # given up once timed (PlannedMove.without_joint_map): nothing may evaluate it
            raise ValueError("a joint map without parts (given up once its move was timed) was evaluated")
        if len(u) > _CHUNK:
            out = np.empty((len(u), self.robot.n_joints))
            for k in range(0, len(u), _CHUNK):
                out[k:k + _CHUNK] = self.evaluate(u[k:k + _CHUNK])
            return out
        if len(self.parts) == 1:
            return self._evaluate_part(self.parts[0], u)
        q = np.empty((len(u), self.robot.n_joints))
        done = np.zeros(len(u), dtype=bool)
        for part in self.parts:
            mask = ~done & (u <= part.u1 + 1e-15)
            if not mask.any():
                continue
            q[mask] = self._evaluate_part(part, u[mask])
            done |= mask
        return q

    def _evaluate_part(self, part: JointPart, u: np.ndarray) -> np.ndarray:
        if part.kind == "ptp":
            return interpolate(part, u)
        if part.kind == "spline":
            return np.asarray(self._spline(part)(u))
        if part.kind == "blend":
            return self.fix_position(hermite(part, u), u)
        if part.kind == "axis":
            return self.solve_axis(part, u)
        return self._exact_near(interpolate(part, u), u)

    def solve_axis(self, part: JointPart, u: np.ndarray) -> np.ndarray:
        """The axis method's joints at u: part.axis on the blend, the rest by :func:`axis_solve`.

        On a densely sampled part (the crossing's reference samples, each a solution) each solve
        starts from a spline through them: it converges in a few iterations to the same solution
        (to the solve's tolerance) as from the blend.
        """
        assert self.poses is not None
        start = hermite(part, u)
        if len(part.u) > 3:
            free = np.arange(start.shape[1]) != part.axis
            start[:, free] = self._start(part, free)(u)
        return axis_solve(self.robot, start, self.poses(u), part.axis, part.exact)

    def _start(self, part: JointPart, free: np.ndarray) -> CubicSpline:
        """The spline through an axis part's solutions (its free joints), made once per part of this map."""
        if id(part) not in self._starts:
            self._starts[id(part)] = (part, not_a_knot(part.u, part.q[:, free]))
        return self._starts[id(part)][1]

    def _spline(self, part: JointPart) -> CubicSpline:
        """A spline part's curve: through its samples, with its end slopes where it has them (made once)."""
        if id(part) not in self._starts:
            ends = "not-a-knot" if part.dq_du is None else ((1, part.dq_du[0]), (1, part.dq_du[1]))
            self._starts[id(part)] = (part, CubicSpline(part.u, part.q, axis=0, bc_type=ends))
        return self._starts[id(part)][1]

    def _exact_near(self, q_ref: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Exact IK at each u: the branch and turn nearest the reference joint values."""
        assert self.poses is not None
        T_tcp = self.poses(u)
        cands = closed_form_branches(self.robot, T_tcp, q_ref)
        if cands.shape[1] == 0:
            return np.array([self._newton(T, s) for T, s in zip(T_tcp, q_ref, strict=True)])
        return nearest_shifted(cands, q_ref)[0]

    def _newton(self, T: np.ndarray, seed: np.ndarray) -> np.ndarray:
        q = solve_newton(self.robot, pin.SE3(T[:3, :3], T[:3, 3]), seed)
        return seed if q is None else q

    def fix_position(self, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Re-solve joints 1-3 of q (N, n) so the TCP position is exactly the path's at u (N,)."""
        assert self.poses is not None
        return exact_position(self.robot, q, self.poses(u)[:, :3, 3])


def exact_position(robot: Robot, q: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """Joints (N, n): q with joints 1-3 re-solved so the TCP reaches targets_m (N, 3) [m].

    OPW and UR arms: the closed forms of :func:`singplan.kinematics.ik.solve.opw_arm_for_point` and
    :func:`singplan.kinematics.ik.solve.ur_arm_for_point` (the solution nearest ``q``); other chains, or
    where the point is out of the arm's reach: damped Newton from ``q``.
    """
    rec = robot.recognition  # the closed forms work in their own base and flange frames
    if robot.opw is not None:
        out = opw_arm_for_point(robot.opw, q, rec.flange_point(robot.T_tip_tcp.translation),
                                rec.closed_points(targets_m))
        lost = np.isnan(out[:, 0])  # the point is out of the arm's reach: the nearest Newton can do
    elif robot.family == "ur":
        out = ur_arm_for_point(robot, q, rec.closed_points(targets_m))
        lost = np.isnan(out[:, 0])
    else:
        out, lost = np.array(q, dtype=float), np.ones(len(q), dtype=bool)
    out[lost] = position_solve(robot, np.asarray(q)[lost], targets_m[lost])
    return out


def position_solve(robot: Robot, q: np.ndarray, targets_m: np.ndarray, joints: int = 3,
                   tol_m: float = 1e-12, iterations: int = 30) -> np.ndarray:
    """Joints (N, n): q (N, n) with the first ``joints`` joints moved so the TCP reaches targets_m
    (N, 3) [m]; the others stay.

    Damped Newton on the TCP position (:func:`~singplan.kinematics.ik.numeric.damped_solve_rows`,
    the batched kinematics of :class:`~singplan.kinematics.robot.Robot`); each row's last iterate.
    """
    def residual(rows: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        position, _, J = robot.tcp_kinematics(rows, 3)
        return targets_m[at] - position, J[:, :, :joints]

    # constant damping: directions the joints barely move (a shoulder singularity) stay put
    return damped_solve_rows(residual, np.reshape(q, (-1, robot.n_joints)), np.arange(joints), damping=_DAMPING,
                             tol=tol_m, iterations=iterations)


_EXACT_WEIGHT = 1e4  # weight of the kept component against the minimised one (per m / per rad)


def axis_solve(robot: Robot, q: np.ndarray, T_target: np.ndarray, fixed: int, exact: str,
               iterations: int = 25) -> np.ndarray:
    """Joints (N, n) from starts ``q`` (N, n) with ``q[:, fixed]`` held, for the poses ``T_target``
    (N, 4, 4): one pose component exact, the other's error minimised.

    Gauss-Newton on the weighted residual ``[w_p (p - p*), w_o log3(R*^T R)]`` over the free
    joints (batched kinematics, :func:`~singplan.kinematics.geometry.rotation_log_jacobians` for
    ``Jlog3``), each sample until its step is under 1e-13 (the samples' least-squares steps are
    solved together); then the kept component is made
    exact by the three joints that control it (arm joints for the position, wrist joints for
    the orientation). SEEDS 000: wrist zone -> A4 held, position exact; shoulder -> A1 held,
    orientation exact; elbow -> A2 held, orientation exact.
    """
    q = np.array(q, dtype=float).reshape(-1, robot.n_joints)
    T_target = np.asarray(T_target, dtype=float).reshape(-1, 4, 4)
    free = np.arange(robot.n_joints) != fixed
    w = np.array([_EXACT_WEIGHT] * 3 + [1.0] * 3) if exact == "position" else np.array([1.0] * 3 + [_EXACT_WEIGHT] * 3)

    def residual(rows: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, Jr = _weighted_residuals(robot, rows, T_target[at], free, w)
        return -r, Jr

    q = damped_solve_rows(residual, q, np.flatnonzero(free), step_tol=1e-13, iterations=iterations)  # least squares
    if exact == "position":
        return exact_position(robot, q, T_target[:, :3, 3])
    return exact_orientation(robot, q, T_target[:, :3, :3])


def _weighted_residuals(robot: Robot, q: np.ndarray, T_target: np.ndarray, free: np.ndarray,
                        w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """axis_solve's residuals (N, 6) and their Jacobians over the free joints (N, 6, n - 1)."""
    position, rotation, J = robot.tcp_kinematics(q)  # (N, 3), (N, 3, 3), (N, 6, n)
    M = relative_rotations(T_target[:, :3, :3], rotation)  # R*^T R
    r = np.empty((len(q), 6))
    r[:, :3] = position - T_target[:, :3, 3]
    r[:, 3:] = rotation_logs(M)
    J[:, 3:] = rotation_log_jacobians(r[:, 3:]) @ rotation.transpose(0, 2, 1) @ J[:, 3:]
    return r * w, J[:, :, free] * w[:, None]


def exact_orientation(robot: Robot, q: np.ndarray, R_target: np.ndarray, tol_rad: float = 1e-13,
                      iterations: int = 30) -> np.ndarray:
    """Joints (N, n): q with the wrist joints (the last three) moved so the TCP orientation is
    R_target (N, 3, 3).

    Damped Gauss-Newton (:func:`~singplan.kinematics.ik.numeric.damped_solve_rows`) on the
    body-frame error log3(R^T R*), every sample at once with the batched kinematics of
    :class:`~singplan.kinematics.robot.Robot`, each until its error is under ``tol_rad``.
    """
    wrist = np.arange(robot.n_joints - 3, robot.n_joints)

    def residual(rows: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _, R, J = robot.tcp_kinematics(rows)
        err = rotation_logs(relative_rotations(R, R_target[at]))
        return err, np.einsum("nji,njk->nik", R, J[:, 3:][:, :, wrist])  # in the tool's frame: R^T J (M, 3, 3)

    return damped_solve_rows(residual, np.reshape(q, (-1, robot.n_joints)), wrist, damping=_DAMPING, tol=tol_rad,
                             iterations=iterations)

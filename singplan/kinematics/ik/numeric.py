"""Numeric inverse kinematics for any serial chain: every branch inside the joint limits.

A general 6R arm (no closed form, e.g. a wrist whose axes do not meet) has up to 16 solutions
per pose; a 7R arm has one-parameter families of them. :func:`all_branches` finds them with
Levenberg-Marquardt (Pinocchio Jacobians, SE(3) log error, :func:`damped_step`)
run from a deterministic seed set:

1. the caller's seed, if any;
2. every solution found so far, flipped at the shoulder, elbow and wrist (6R arms): a flip of
   a general arm is not a solution, but it lies in the basin of the neighbouring branch;
3. quasi-random (Halton) points over the joint box, spread evenly whatever the arm.

Each iterate is kept inside the joint limits (whole turns first, then clamping), so a run
never ends on a solution the limits forbid and a redundant arm settles on an allowed point of
its family. The search stops when ``patience`` quasi-random seeds in a row found nothing new
(at least ``min_seeds`` tried, at most ``max_seeds``). Solutions are the same branch when
they agree modulo whole turns (6R) or carry the same configuration label (7R: one per
configuration found, the one nearest the seed).

:func:`newton` is the fast seeded solve the per-sample tracking uses (no limits, no search).
:func:`damped_step`, :func:`damped_solve` and :func:`damped_solve_rows` are the package's one
damped least-squares step and its loop, for one joint vector or a batch: the planner's re-solves
(position, orientation, axis, null-space) call them with their own residual, joints and damping.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from singplan.kinematics import reduced
from singplan.kinematics.angles import shifted_toward, wrap_to_pi
from singplan.kinematics.compiled import jit
from singplan.kinematics.robot import Robot

_HALTON_PRIMES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37)
_SAME_BRANCH_RAD = 1e-6  # two converged solutions closer than this (mod 2*pi) are one branch
_FAR_COST = 1e-4  # squared log error [m^2, rad^2] of a run given up half way
# a five-joint arm's residual accepted where the iteration stalls: 0.1 um and 0.6 mdeg, far
# inside the 0.01 mm / 0.01 deg the path is held to
REDUCED_RESIDUAL_M = 1e-7
REDUCED_RESIDUAL_RAD = 1e-5
_ROUND_OFF = 1e-15  # [m, rad] an error at round-off: no step can improve it
_REACHABLE_TOL = 1e-14  # [m, rad]: the reachable part of such a residual is converged
_SLIDE_ITERATIONS = 60  # null-space steps of a redundant arm toward the seed (each halves the gap)


@dataclass(frozen=True)
class NumericIkOptions:
    """Tuning of the all-branch search (defaults measured in docs/kinematics.md).

    Attributes:
        min_seeds: quasi-random seeds always tried.
        patience: stop after this many quasi-random seeds in a row gave no new branch.
        max_seeds: quasi-random seeds at most.
        max_iterations: Levenberg-Marquardt iterations per seed.
        tol: norm of the SE(3) log error at convergence [m, rad].
    """

    min_seeds: int = 24
    patience: int = 24
    max_seeds: int = 200
    max_iterations: int = 100
    tol: float = 1e-12


Residual = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # q -> (error (m,), its Jacobian (m, n))


def damped_step(J: np.ndarray, err: np.ndarray, damping: float, rcond: float | None = None,
                stacked: bool = False) -> np.ndarray:
    """The step ``dq`` minimising ``|J dq - err|^2 + damping |dq|^2``; J of shape (m, n), or a batch
    (N, m, n) with err (N, m) solved row by row (each its own step, no stacking).

    ``damping`` 0 gives the minimum-norm least-squares step, singular values under ``rcond``
    times the largest dropped. ``stacked`` solves ``[J; sqrt(damping) I] dq = [err; 0]`` by
    least squares instead of the normal equations: for a Jacobian that lacks rank everywhere (a
    five-joint arm's reduced rows: a roll about the tool axis moves nothing they keep), where
    the normal equations would divide round-off by a vanishing damping.
    """
    if J.ndim == 3:
        if stacked:
            raise ValueError("damped_step: stacked solves one row; a batch takes the normal equations")
        return _damped_steps(J, err, damping, rcond)
    if damping == 0.0:
        return np.linalg.lstsq(J, err, rcond=rcond)[0]
    if stacked:
        lifted = np.vstack([J, math.sqrt(damping) * np.eye(J.shape[1])])
        return np.linalg.lstsq(lifted, np.concatenate([err, np.zeros(J.shape[1])]), rcond=rcond)[0]
    return J.T @ np.linalg.solve(J @ J.T + damping * np.eye(J.shape[0]), err)


def _damped_steps(J: np.ndarray, err: np.ndarray, damping: float, rcond: float | None) -> np.ndarray:
    """damped_step of a batch: J (N, m, n), err (N, m) -> steps (N, n) (numpy has no batched lstsq:
    the minimum-norm step is the pseudo-inverse's, with lstsq's default cut-off, eps * max(m, n)).

    A tall J of full rank has one least-squares step: Householder QR (compiled, a fraction of a
    microsecond a row against numpy's few for an SVD); rows whose R is near rank-deficient (its
    diagonal spans more than :data:`_QR_SPAN`), wide J and a caller's own ``rcond`` take the
    pseudo-inverse as before."""
    if damping == 0.0:
        cut = np.finfo(float).eps * max(J.shape[1:]) if rcond is None else rcond
        m, n = J.shape[1:]
        if m < n or len(J) == 0 or rcond is not None:  # a cut-off of the caller's: the SVD applies it
            return np.einsum("kij,kj->ki", np.linalg.pinv(J, rcond=cut), err)
        steps, sound = _qr_steps(np.ascontiguousarray(J, dtype=float), np.ascontiguousarray(err, dtype=float),
                                 _QR_SPAN)
        if not sound.all():
            rest = ~sound
            steps[rest] = np.einsum("kij,kj->ki", np.linalg.pinv(J[rest], rcond=cut), err[rest])
        return steps
    JJt = J @ J.transpose(0, 2, 1) + damping * np.eye(J.shape[1])
    return np.einsum("kji,kj->ki", J, np.linalg.solve(JJt, err[:, :, None])[:, :, 0])


_QR_SPAN = 1e8  # a row whose |R_jj| range over this much (condition ~1e8 and up) takes the SVD


@jit
def _qr_steps(J: np.ndarray, err: np.ndarray, span: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares steps (N, n) of tall J (N, m, n), err (N, m) by Householder QR (Golub and Van
    Loan, Matrix Computations, 5.3.3), and whether each row's R is sound: its diagonal within
    ``span`` of its largest, so the step is the pseudo-inverse's (to round-off)."""
    rows, m, n = J.shape
    steps = np.zeros((rows, n))
    sound = np.ones(rows, dtype=np.bool_)
    A = np.empty((m, n))
    b = np.empty(m)
    for k in range(rows):
        A[:, :] = J[k]
        b[:] = err[k]
        for j in range(n):
            norm = 0.0
            for i in range(j, m):
                norm += A[i, j] * A[i, j]
            norm = math.sqrt(norm)
            if norm == 0.0:
                continue
            alpha = -norm if A[j, j] >= 0.0 else norm
            v0 = A[j, j] - alpha
            vv = 2.0 * norm * (norm + abs(A[j, j]))  # |v|^2 of v = x - alpha e_j (alpha opposite x_j)
            A[j, j] = v0
            for c in range(j + 1, n):
                dot = 0.0
                for i in range(j, m):
                    dot += A[i, j] * A[i, c]
                f = 2.0 * dot / vv
                for i in range(j, m):
                    A[i, c] -= f * A[i, j]
            dot = 0.0
            for i in range(j, m):
                dot += A[i, j] * b[i]
            f = 2.0 * dot / vv
            for i in range(j, m):
                b[i] -= f * A[i, j]
            A[j, j] = alpha  # R's diagonal
        largest = 0.0
        least = math.inf
        for j in range(n):
            largest = max(largest, abs(A[j, j]))
            least = min(least, abs(A[j, j]))
        if not least * span > largest:
            sound[k] = False
            continue
        for j in range(n - 1, -1, -1):
            total = b[j]
            for c in range(j + 1, n):
                total -= A[j, c] * steps[k, c]
            steps[k, j] = total / A[j, j]
    return steps, sound


def damped_solve(residual: Residual, q: np.ndarray, joints: slice | list[int] | np.ndarray, damping: float = 0.0,
                 rcond: float | None = None, tol: float = 0.0, step_tol: float = 0.0,
                 max_step: float = math.inf, iterations: int = 30) -> np.ndarray:
    """Joints ``q`` with ``joints`` moved by damped Gauss-Newton until the residual vanishes; the best found.

    ``residual(q)`` gives the error a step should remove and its Jacobian (``J dq = err``
    removes it to first order); each step is :func:`damped_step` on the ``joints`` columns,
    scaled down to ``max_step`` [rad] (max norm) when longer. The loop ends when the error is
    under ``tol`` (max norm, before a step), the step under ``step_tol``, or after ``iterations``.
    """
    q = np.array(q, dtype=float)
    sized = step_tol > 0.0 or max_step < math.inf  # its size costs ~2 us an iteration: only for a stop or a cap
    for _ in range(iterations):
        err, J = residual(q)
        if tol > 0.0 and float(np.max(np.abs(err))) < tol:
            break
        step = damped_step(J[:, joints], err, damping, rcond)
        size = float(np.max(np.abs(step))) if sized else 0.0
        q[joints] += step if size <= max_step else step * (max_step / size)
        if size < step_tol:
            break
    return q


RowsResidual = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
# (q rows (M, n), their row numbers (M,)) -> (errors (M, m), their Jacobians over the moved joints (M, m, k))


def damped_solve_rows(residual: RowsResidual, q: np.ndarray, joints: np.ndarray, damping: float = 0.0,
                      tol: float = 0.0, step_tol: float = 0.0, iterations: int = 30) -> np.ndarray:
    """:func:`damped_solve` of many joint vectors q (N, n) at once, ``joints`` (k,) moved: each
    row's steps (:func:`damped_step` of the batch) until its own error is under ``tol`` (max norm,
    before a step) or its step under ``step_tol``; the rows that are done leave the batch.

    ``residual`` is asked for the rows still moving only, with their row numbers (a row's target).
    """
    q = np.array(q, dtype=float)
    active = np.arange(len(q))
    for _ in range(iterations):
        if active.size == 0:
            break
        err, J = residual(q[active], active)
        if tol > 0.0:
            moving = np.max(np.abs(err), axis=1) >= tol
            active, err, J = active[moving], err[moving], J[moving]
            if active.size == 0:
                break
        step = damped_step(J, err, damping)
        q[np.ix_(active, joints)] += step
        if step_tol > 0.0:
            active = active[np.abs(step).max(axis=1) >= step_tol]
    return q


def pose_error(robot: Robot, q: np.ndarray, T_target: np.ndarray) -> np.ndarray:
    """(6,) position [m] and orientation [rad] error of the TCP at ``q`` to T_target (4, 4), in base
    coordinates (the frame of :meth:`Robot.jacobian`), so that ``J dq = error`` removes it to first order."""
    T = robot.fk(q)
    return np.concatenate([T_target[:3, 3] - T.translation,
                           T.rotation @ pin.log3(T.rotation.T @ T_target[:3, :3])])


def _tip_target(robot: Robot, T_base_tcp: pin.SE3) -> pin.SE3:
    return T_base_tcp * robot.T_tip_tcp.inverse()


def _error(robot: Robot, T_target_tip: pin.SE3, q: np.ndarray) -> tuple[np.ndarray, pin.SE3]:
    """``log6(T(q)^-1 T_target)`` (tip frame) and the tip pose T(q); for a five-joint arm the
    reduced error of :func:`singplan.kinematics.reduced.error` (position and tool z axis, 5 rows)."""
    pin.forwardKinematics(robot.model, robot.data, q)
    T = pin.updateFramePlacement(robot.model, robot.data, robot.tip_frame_id)
    if reduced.is_reduced(robot):
        return reduced.error(T_target_tip * robot.T_tip_tcp, T * robot.T_tip_tcp), T
    return pin.log6(T.actInv(T_target_tip)).vector, T


def _error_jacobian(robot: Robot, T_target_tip: pin.SE3, q: np.ndarray, T: pin.SE3) -> np.ndarray:
    """d(-error)/dq: the Jacobian of ``log6(T_target^-1 T(q))`` (6, n), or the reduced one (5, n)."""
    if reduced.is_reduced(robot):
        return reduced.jacobian(robot, q, T.rotation @ robot.T_tip_tcp.rotation)
    J_local = pin.computeFrameJacobian(robot.model, robot.data, q, robot.tip_frame_id, pin.LOCAL)
    return pin.Jlog6(T_target_tip.actInv(T)) @ J_local


def newton(robot: Robot, T_base_tcp: pin.SE3, seed: np.ndarray, tol: float = 1e-12,
           max_iterations: int = 60) -> np.ndarray | None:
    """Damped Newton on the pose error from ``seed``; the converged joints [rad] or None.

    The damping vanishes with the error, so convergence is quadratic away from singularities.
    No limits and no step control: the tracking calls it with the previous sample as seed.
    """
    q = np.array(seed, dtype=float)
    T_target_tip = _tip_target(robot, T_base_tcp)
    # a five-joint arm takes one step even under tol: the reference samples a few 1e-9 of the
    # path apart must agree to round-off, or their slopes differ by 1e-4 (TOPP-RA's spline)
    floor = _ROUND_OFF if reduced.is_reduced(robot) else tol
    for iteration in range(max_iterations):
        err, T = _error(robot, T_target_tip, q)
        norm = float(np.linalg.norm(err))
        if norm < floor or (norm < tol and iteration > 0):
            return q
        J = _error_jacobian(robot, T_target_tip, q, T)
        if _stalled(robot, err, J):
            return q
        q = q + damped_step(J, err, min(1e-2, norm) ** 2, stacked=reduced.is_reduced(robot))
    return None


def _stalled(robot: Robot, err: np.ndarray, J: np.ndarray) -> bool:
    """A five-joint arm at the least-squares solution of an error it cannot cancel: what is left
    is outside the Jacobian's range (no joint motion reduces it to first order), with the
    position within REDUCED_RESIDUAL_M and the tool axis within REDUCED_RESIDUAL_RAD. (The
    SO-100's URDF tilts axis 1 by 6e-6 rad: a vertical tool axis is that far out of its arm
    plane away from q1 = 0.)"""
    if not (reduced.is_reduced(robot) and float(np.linalg.norm(err[:3])) < REDUCED_RESIDUAL_M
            and float(np.linalg.norm(err[3:])) < REDUCED_RESIDUAL_RAD * reduced.ANGLE_WEIGHT_M):
        return False
    reachable = J @ np.linalg.lstsq(J, err, rcond=1e-10)[0]  # the part joint motion can cancel
    return float(np.linalg.norm(reachable)) < _REACHABLE_TOL


def into_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Each joint moved by whole turns next to the middle of its range, then clamped to it (an
    unlimited joint left as it is).

    The variant nearest the middle is the one inside the range whenever one exists.
    """
    limited = np.isfinite(lower) & np.isfinite(upper)
    middle = np.where(limited, 0.5 * (np.where(limited, lower, 0.0) + np.where(limited, upper, 0.0)), q)
    return np.clip(shifted_toward(q, middle), lower, upper)


def solve_lm(robot: Robot, T_base_tcp: pin.SE3, seed: np.ndarray,
             options: NumericIkOptions = NumericIkOptions()) -> np.ndarray | None:
    """Levenberg-Marquardt inside the joint limits from ``seed``; the solution [rad] or None.

    The damping follows Nielsen's rule (K. Madsen, H. B. Nielsen, O. Tingleff, "Methods for
    non-linear least squares problems", 2004): it shrinks by how well the linear model
    predicted the step's gain, and doubles its growth after each refused step, which keeps
    the iteration moving through the ill-conditioned region near a singular pose. A run still
    far from any solution half way through its iterations is given up.
    """
    lower, upper = robot.lower_rad, robot.upper_rad
    T_target_tip = _tip_target(robot, T_base_tcp)
    q = into_limits(np.asarray(seed, dtype=float), lower, upper)
    err, T = _error(robot, T_target_tip, q)
    cost, damping, growth = float(err @ err), 1e-2, 2.0
    J = _error_jacobian(robot, T_target_tip, q, T)
    for iteration in range(options.max_iterations):
        if cost < options.tol ** 2 or _stalled(robot, err, J):
            return q
        if iteration == options.max_iterations // 2 and cost > _FAR_COST:
            return None
        step = damped_step(J, err, damping, stacked=reduced.is_reduced(robot))
        q_new = into_limits(q + step, lower, upper)
        err_new, T_new = _error(robot, T_target_tip, q_new)
        cost_new = float(err_new @ err_new)
        predicted = cost - float(np.sum((err - J @ step) ** 2))
        gain = (cost - cost_new) / predicted if predicted > 0.0 else -1.0
        if gain > 0.0:
            q, err, cost = q_new, err_new, cost_new
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
            J = _error_jacobian(robot, T_target_tip, q, T_new)
        else:
            damping *= growth
            growth *= 2.0
            if damping > 1e12:
                break
    return q if cost < options.tol ** 2 or _stalled(robot, err, J) else None


def halton(count: int, dim: int, skip: int = 1) -> np.ndarray:
    """The Halton points ``skip .. skip + count - 1`` in [0, 1)^dim (count, dim), deterministic."""
    out = np.empty((count, dim))
    for j in range(dim):
        base = _HALTON_PRIMES[j]
        for i in range(count):
            k, f, x = i + skip, 1.0, 0.0
            while k > 0:
                f /= base
                x += f * (k % base)
                k //= base
            out[i, j] = x
    return out


def flips(q: np.ndarray) -> list[np.ndarray]:
    """Seeds near the other branches of a 6R solution: shoulder, elbow and wrist flipped alone
    and together (exact flips of an ortho-parallel arm with zero offsets; near ones otherwise)."""
    out = []
    for shoulder in (False, True):
        for elbow in (False, True):
            for wrist in (False, True):
                if not (shoulder or elbow or wrist):
                    continue
                s = np.array(q, dtype=float)
                if shoulder:
                    s[0], s[1], s[2] = s[0] + math.pi, -s[1], math.pi - s[2]
                if elbow:
                    s[1], s[2] = s[1] + s[2], -s[2]
                if wrist:
                    s[3], s[4], s[5] = s[3] + math.pi, -s[4], s[5] + math.pi
                out.append(s)
    return out


@dataclass
class _Found:
    """Solutions found so far, one per branch, and the key that tells branches apart."""

    key: Callable[[np.ndarray], str] | None  # configuration label (redundant arms) or None (6R)
    seed: np.ndarray | None
    rows: list[np.ndarray]
    origins: list[int]
    keys: list[str]

    def add(self, q: np.ndarray, origin: int) -> bool:
        """Keep ``q``; True when it is a new branch (a redundant arm's nearer point replaces the old)."""
        if self.key is None:
            if any(np.all(np.abs(wrap_to_pi(q - r)) < _SAME_BRANCH_RAD) for r in self.rows):
                return False
            self.rows.append(q)
            self.origins.append(origin)
            return True
        key = self.key(q)
        if key in self.keys:
            k = self.keys.index(key)
            if self.seed is not None and _distance(q, self.seed) < _distance(self.rows[k], self.seed):
                self.rows[k], self.origins[k] = q, origin
            return False
        self.rows.append(q)
        self.origins.append(origin)
        self.keys.append(key)
        return True


def _distance(q: np.ndarray, seed: np.ndarray) -> float:
    return float(np.linalg.norm(q - seed))  # Euclidean: what the null-space pull minimises


def _box_seeds(robot: Robot, options: NumericIkOptions) -> Iterator[np.ndarray]:
    # a joint wider than a turn is sampled over one turn around its middle (an unlimited one's: 0)
    middle = np.where(robot.unlimited, 0.0, 0.5 * (np.where(robot.unlimited, 0.0, robot.lower_rad)
                                                   + np.where(robot.unlimited, 0.0, robot.upper_rad)))
    half = np.minimum(0.5 * (robot.upper_rad - robot.lower_rad), math.pi)
    for u in halton(options.max_seeds, robot.n_joints):
        yield middle + (2.0 * u - 1.0) * half


def all_branches(robot: Robot, T_base_tcp: pin.SE3, seed: np.ndarray | None = None,
                 label: Callable[[np.ndarray], str] | None = None,
                 options: NumericIkOptions = NumericIkOptions()) -> tuple[list[np.ndarray], list[int]]:
    """Every IK branch of a TCP pose inside the joint limits, by seeded Levenberg-Marquardt.

    Args:
        robot: any serial arm with n >= 5 joints (five: position and tool z axis only).
        T_base_tcp: the target TCP pose.
        seed: tried first; with a redundant arm, each configuration keeps its point nearest it.
        label: configuration label of a joint vector; a redundant arm (n > 6) gives one
            solution per label (one in all without it); a 6R arm's branches are told apart
            by their joints.
        options: seed counts and convergence.

    Returns:
        The solutions (each inside the limits, pose error below ``options.tol``) and, for
        each, the index of the seed it came from (0 = the caller's seed when given).
    """
    redundant = robot.n_joints > 6
    key = (label or _one_configuration) if redundant else None
    found = _Found(key=key, seed=seed, rows=[], origins=[], keys=[])
    pending: list[np.ndarray] = [] if seed is None else [np.asarray(seed, dtype=float)]
    tried, box_tried, quiet = 0, 0, 0
    box = _box_seeds(robot, options)
    while box_tried < options.max_seeds and (box_tried < options.min_seeds or quiet < options.patience):
        is_box = not pending
        q = solve_lm(robot, T_base_tcp, next(box) if is_box else pending.pop(0), options)
        if q is not None and reduced.is_reduced(robot):
            q = reduced.settle_free(robot, q, seed)  # a roll about the tool axis stays at the seed's
        new = q is not None and found.add(q, tried)
        tried += 1
        if new and robot.n_joints == 6:
            pending.extend(flips(found.rows[-1]))
        if is_box:
            box_tried += 1
            quiet = 0 if new else quiet + 1
    if key is not None and seed is not None:
        return _nearest_per_label(robot, T_base_tcp, found, np.asarray(seed, dtype=float), key, options)
    return found.rows, found.origins


def _one_configuration(q: np.ndarray) -> str:
    return ""  # a redundant arm searched without labels: one solution


def _nearest_per_label(robot: Robot, T_base_tcp: pin.SE3, found: _Found, seed: np.ndarray,
                       label: Callable[[np.ndarray], str],
                       options: NumericIkOptions) -> tuple[list[np.ndarray], list[int]]:
    """A redundant arm's solutions slid toward the seed; per label the nearest point found, nearest first.

    A slide may cross into another label (the labels of a 7R arm are not its self-motion's
    boundaries), so the slid and the unslid points compete for their own labels.
    """
    best: dict[str, tuple[float, np.ndarray, int]] = {}
    for q, origin in zip(found.rows, found.origins, strict=True):
        slid = _slide_toward(robot, T_base_tcp, q, seed, options)
        for candidate in (q,) if slid is None else (q, slid):
            key, d = label(candidate), _distance(candidate, seed)
            if key not in best or d < best[key][0]:
                best[key] = (d, candidate, origin)
    rows: list[np.ndarray] = []
    origins: list[int] = []
    for _, q, origin in sorted(best.values(), key=lambda item: item[0]):
        # on a label boundary one point carries both labels: keep it once
        if not any(np.all(np.abs(wrap_to_pi(q - r)) < _SAME_BRANCH_RAD) for r in rows):
            rows.append(q)
            origins.append(origin)
    return rows, origins


def _slide_toward(robot: Robot, T_base_tcp: pin.SE3, q: np.ndarray, target: np.ndarray,
                  options: NumericIkOptions) -> np.ndarray | None:
    """A redundant arm's solution moved along its self-motion toward ``target``, same pose; None if lost.

    Each step pulls halfway to the target inside the Jacobian's null space and corrects the
    pose error; a final Levenberg-Marquardt run restores the pose exactly where the limits
    clamped a step.
    """
    T_target_tip = _tip_target(robot, T_base_tcp)
    moved = np.array(q)
    for _ in range(_SLIDE_ITERATIONS):
        err, T = _error(robot, T_target_tip, moved)
        J = _error_jacobian(robot, T_target_tip, moved, T)
        J_pinv = np.linalg.pinv(J, rcond=1e-6)
        pull = 0.5 * (target - moved)
        null_step = pull - J_pinv @ (J @ pull)
        moved = into_limits(moved + J_pinv @ err + null_step, robot.lower_rad, robot.upper_rad)
        if np.max(np.abs(null_step)) < _SAME_BRANCH_RAD:
            break
    return solve_lm(robot, T_base_tcp, moved, options)

"""Inverse kinematics along a sampled path, following one continuous solution.

At every sample all IK branches are computed (closed form for OPW and UR arms); each
candidate is moved to the 2*pi variant nearest the previous sample and the nearest is kept.
Where a step still moves some joint more than ``max_joint_step_rad`` the interval is
subdivided, so that the fast wrist (or axis 1) swing of a near miss is resolved sample by
sample instead of being jumped over. A step that stays large on an interval shorter than
``min_du`` is a real discontinuity of the inverse kinematics and is reported. Inside singular
zones (``hold``) the refinement waits: a crossing method usually replaces that stretch, and
the planner tracks it in full only when the method keeps it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from singplan.kinematics.angles import nearest_row, nearest_shifted, row_step, shift_row_into
from singplan.kinematics.compiled import jit
from singplan.kinematics.ik import numeric as ik_numeric
from singplan.kinematics.ik.solve import closed_form_branches, solve_newton
from singplan.kinematics.robot import Robot

_MAX_SAMPLES = 200_000  # refinement stops here: beyond it the IK is discontinuous, not just fast
PoseFunction = Callable[[np.ndarray], np.ndarray]  # u (N,) -> TCP poses (N, 4, 4)


@dataclass(frozen=True)
class TrackedPath:
    """Joint values along a path.

    Attributes:
        u: path parameters, increasing, shape (N,).
        q: joint values [rad], shape (N, n), continuous from sample to sample.
        max_step_rad: largest joint change between neighbouring samples.
        gap_index: first interval k (u[k] -> u[k+1]) where no continuous solution was found, or -1.
        coarse_from_u: where the first large step left unrefined inside a held (singular)
            interval starts; inf when there is none.
    """

    u: np.ndarray  # (N,)
    q: np.ndarray  # (N, n)
    max_step_rad: float
    gap_index: int
    coarse_from_u: float = math.inf


_CONTINUE_DU = 1e-3  # a pose this near (in u) one whose branches were searched continues them by Newton
# full all-branch searches a move's tracking makes where a branch ends (~0.5 s each); past them the
# branches of the nearest searched pose are carried on, which bounds the time a fold or the
# workspace's edge costs on an arm without a closed form (a valid task spent 75 s there)
_SEARCHES = 8


class BranchCandidates:
    """All IK branches of the poses at given parameters, computed once per parameter."""

    def __init__(self, robot: Robot, poses: PoseFunction) -> None:
        self.robot = robot
        self.poses = poses
        self.u = np.empty(0)  # (M,) sorted parameters solved so far
        self.sols = np.empty((0, 0, robot.n_joints))  # (M, B, n)
        self.free = np.empty(0, dtype=bool)  # (M,) a branch sits on a singularity: some joints are free
        self._all: dict[float, np.ndarray] = {}  # every branch of a parameter's pose, where one was searched for
        self._searches = 0  # full all-branch searches made

    def fill(self, u: np.ndarray) -> None:
        """Solve the parameters of ``u`` (sorted, distinct) not solved yet."""
        todo = u[self.u[np.minimum(np.searchsorted(self.u, u), len(self.u) - 1)] != u] if len(self.u) else u
        if todo.size == 0:
            return
        sols = closed_form_branches(self.robot, self.poses(todo))
        order = np.argsort(np.concatenate([self.u, todo]), kind="stable")
        self.sols = np.concatenate([self.sols, sols])[order] if len(self.u) else sols
        self.u = np.concatenate([self.u, todo])[order]
        self.free = np.concatenate([self.free, self._has_free_joints(sols)])[order]

    def at(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Branches (N, B, n) and free-joint flags (N,) of already solved parameters."""
        k = np.searchsorted(self.u, u)
        return self.sols[k], self.free[k]

    def _has_free_joints(self, sols: np.ndarray) -> np.ndarray:
        """(N,) True where a branch is (numerically) wrist-singular, or no closed form is known."""
        if sols.shape[1] == 0:
            return np.ones(len(sols), dtype=bool)  # no closed form: every sample is solved from its predecessor
        q5 = sols[:, :, 4]
        if self.robot.opw is not None:
            p = self.robot.opw
            q5 = q5 * p.sign_corrections[4] - p.offsets_rad[4]
        return np.any(np.abs(np.sin(q5)) < 1e-9, axis=1)  # NaN rows compare False

    def exact(self, u: float, seed: np.ndarray) -> np.ndarray:
        """Branches of one pose, solved with ``seed`` for the free joints at a singularity."""
        T = self.poses(np.array([u]))[0]
        sols = closed_form_branches(self.robot, T[None], seed[None])[0]
        if sols.shape[0]:
            return sols
        pose = pin.SE3(T[:3, :3], T[:3, 3])
        q = solve_newton(self.robot, pose, seed)
        if q is not None:
            return q[None]
        # the seeded branch ends here (it folds back at a singularity of an arm without a closed
        # form): every other branch, so the path goes on in the nearest one (a jump in a zone). The
        # search is the costly part of tracking such an arm (~1 s a pose; a path leaving the
        # workspace asks again for each sample it refines toward the edge): once per parameter
        if u not in self._all:
            carried = self._continued(u, pose)
            if carried is not None and (len(carried) == self._near_count(u) or self._searches >= _SEARCHES):
                rows = carried
            else:
                self._searches += 1
                found, _ = ik_numeric.all_branches(self.robot, pose, seed)
                rows = np.array(found) if found else np.full((1, self.robot.n_joints), np.nan)
            self._all[u] = rows
        return self._all[u]

    def _near_count(self, u: float) -> int:
        near = min(self._all, key=lambda v: abs(v - u))
        return int(np.count_nonzero(np.all(np.isfinite(self._all[near]), axis=1)))

    def _continued(self, u: float, pose: pin.SE3) -> np.ndarray | None:
        """The branches of the nearest pose searched (within ``_CONTINUE_DU`` in u: a refinement's new
        samples lie between searched ones) carried to the pose at ``u`` by Newton, distinct (one that
        ends there is left out; a NaN row where none carries on); None where no pose is that near."""
        near = min(self._all, key=lambda v: abs(v - u), default=None)
        if near is None or abs(near - u) > _CONTINUE_DU:
            return None
        rows = [solve_newton(self.robot, pose, r) for r in self._all[near] if np.all(np.isfinite(r))]
        kept = list({tuple(np.round(r, 9)): r for r in rows if r is not None}.values())
        return np.array(kept) if kept else np.full((1, self.robot.n_joints), np.nan)


def nearest_candidate(candidates: np.ndarray, q_prev: np.ndarray) -> tuple[np.ndarray, float]:
    """The candidate (shifted by whole turns) nearest ``q_prev``, and its max-norm distance."""
    best, dist, _ = _nearest(candidates, q_prev)
    return best, dist


def _nearest(candidates: np.ndarray, q_prev: np.ndarray) -> tuple[np.ndarray, float, int]:
    """As :func:`nearest_candidate`, plus the candidate's row index (-1 when none)."""
    if candidates.shape[0] == 0:
        return np.full_like(q_prev, np.nan), math.inf, -1
    best, dist, k = nearest_shifted(candidates, q_prev)
    if not np.isfinite(dist):
        return np.full_like(q_prev, np.nan), math.inf, -1
    return best, float(dist), int(k)


def _select(cands: BranchCandidates, u: np.ndarray, q0: np.ndarray, max_step: float,
            min_du: float) -> tuple[np.ndarray, np.ndarray]:
    """Follow the nearest candidate from q0; returns q (N, n) and the step before each sample.

    :func:`_follow` does the work; it hands back the samples with free joints whose rows all
    step too far, where the pose is solved again with the previous joints as the seed.
    """
    C, free = cands.at(u)  # (N, B, n), (N,)
    q = np.empty((len(u), len(q0)))
    steps = np.zeros(len(u))
    du = np.diff(u, prepend=u[0])  # (N,) interval before each sample
    k, row = 0, -1
    while True:
        k = int(_follow(C, free, du, np.ascontiguousarray(q0, dtype=float), row, k, max_step, min_du, q, steps))
        if k >= len(u):
            return q, steps
        q_prev = q[k - 1] if k > 0 else q0
        best, dist, row = _nearest(C[k], q_prev)
        best2, dist2, _ = _nearest(cands.exact(float(u[k]), q_prev), q_prev)
        if dist2 < dist:
            best, dist, row = best2, dist2, -1
        q[k], steps[k] = best, dist
        if not np.all(np.isfinite(best)):
            q[k + 1:], steps[k + 1:] = np.nan, np.inf
            return q, steps
        k += 1


@jit
def _follow(C: np.ndarray, free: np.ndarray, du: np.ndarray, q0: np.ndarray, row: int, start: int,
            max_step: float, min_du: float, q: np.ndarray, steps: np.ndarray) -> int:
    """Fill q[start:] and steps[start:] from candidates C (N, B, n), each moved by whole turns next to
    the previous sample (``q0`` before sample 0); ``row`` is the candidate row q[start - 1] came
    from (-1: none); ``du`` (N,) the parameter interval before each sample.

    The current row is followed while its step is small. A finite row that steps too far on an
    interval still wider than ``min_du`` is followed too, its large step left for the caller to
    refine: where two branches approach each other (the UR arm's q1, q3 and q5 pairs near the
    shoulder, elbow and wrist) the other row may be nearer on a coarse grid although it is not
    the continuation. Elsewhere the nearest row is searched again (it may be the same row).
    Returns the first sample whose joints are free (a singular pose, where the rows hold one
    arbitrary split of the free joints: the caller keeps the nearer of that and a solve seeded
    with the previous joints, so a move that starts on a singularity starts at its own joints),
    or N. A sample with no finite row ends the path: it and the rest become NaN, their steps inf.
    (Chains without a closed form have no rows and free joints everywhere: every sample goes to
    the caller.)
    """
    n_samples = C.shape[0]
    for k in range(start, n_samples):
        prev = q[k - 1] if k > 0 else q0
        if row >= 0 and not free[k]:
            step = row_step(C[k, row], prev)
            if step <= max_step or (math.isfinite(step) and du[k] > min_du):
                shift_row_into(C[k, row], prev, q[k])
                steps[k] = step
                continue
        row, step = nearest_row(C[k], prev)
        if free[k]:
            return k
        if not math.isfinite(step):
            q[k:] = np.nan
            steps[k:] = np.inf
            return n_samples
        shift_row_into(C[k, row], prev, q[k])
        steps[k] = step
    return n_samples


def track(robot: Robot, poses: PoseFunction, u0: np.ndarray, q_start: np.ndarray,
          max_joint_step_rad: float = math.radians(1.0), min_du: float = 1e-10,
          max_passes: int = 48, cands: BranchCandidates | None = None,
          hold: Callable[[np.ndarray], np.ndarray] | None = None) -> TrackedPath:
    """Follow one continuous IK solution along ``poses(u)``, starting at ``q_start`` (u0[0]).

    ``u0`` is the initial grid; it is refined where joints move more than
    ``max_joint_step_rad`` between samples. ``cands`` (of the same ``poses``) carries the
    branches already solved by an earlier call. ``hold(q) -> (N,) bool`` marks samples whose
    intervals stay coarse (inside a singular zone that a crossing may replace): their large
    steps are neither refined nor reported as gaps, only located in ``coarse_from_u``.
    """
    cands = BranchCandidates(robot, poses) if cands is None else cands
    u = np.asarray(u0, dtype=float)
    q, steps = _select_all(cands, u, q_start, max_joint_step_rad, min_du)
    held: np.ndarray | None = None  # (N - 1,) of the current samples, once computed
    for _ in range(max_passes):
        lost = np.nonzero(~np.isfinite(steps))[0]
        if lost.size:  # the path leaves the workspace: nothing to refine past that sample
            u, q, steps = u[:lost[0] + 1], q[:lost[0] + 1], steps[:lost[0] + 1]
        held = _held_intervals(hold, q)
        # the step into a lost sample is not refined: where the path leaves the workspace is told to
        # the grid, and on an arm without a closed form each sample past the edge costs an
        # all-branch search (a valid task spent 75 s locating an edge that way)
        big = np.nonzero(np.isfinite(steps[1:]) & (steps[1:] > max_joint_step_rad) & (np.diff(u) > min_du)
                         & ~held)[0]
        if big.size == 0 or len(u) > _MAX_SAMPLES:
            break
        u = np.sort(np.concatenate([u, _subdivide(u, big, steps[big + 1] / max_joint_step_rad)]))
        q, steps = _select_all(cands, u, q_start, max_joint_step_rad, min_du)
        held = None
    large = ~np.isfinite(steps[1:]) | (steps[1:] > max_joint_step_rad)
    held = _held_intervals(hold, q) if held is None else held
    gaps, coarse = np.nonzero(large & ~held)[0], np.nonzero(large & held)[0]
    return TrackedPath(u=u, q=q, max_step_rad=float(np.max(steps[1:])) if len(u) > 1 else 0.0,
                       gap_index=int(gaps[0]) if gaps.size else -1,
                       coarse_from_u=float(u[coarse[0]]) if coarse.size else math.inf)


def _held_intervals(hold: Callable[[np.ndarray], np.ndarray] | None, q: np.ndarray) -> np.ndarray:
    """(N - 1,) True for intervals whose both ends are held."""
    if hold is None or len(q) < 2:
        return np.zeros(max(len(q) - 1, 0), dtype=bool)
    inside = hold(q)
    return inside[:-1] & inside[1:]


def _subdivide(u: np.ndarray, big: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """New parameters inside the intervals u[big] -> u[big + 1]: a step ``ratio`` times too large
    gets that many pieces (2 to 8); a jump that stays large is thus narrowed 8x per pass."""
    pieces = np.clip(np.ceil(ratio), 2, 8).astype(int)
    t = np.concatenate([np.arange(1, m) / m for m in pieces])
    k = np.repeat(big, pieces - 1)
    return u[k] + t * (u[k + 1] - u[k])


def _select_all(cands: BranchCandidates, u: np.ndarray, q_start: np.ndarray,
                max_step: float, min_du: float) -> tuple[np.ndarray, np.ndarray]:
    cands.fill(u)
    return _select(cands, u, q_start, max_step, min_du)

"""One LIN / CIRC / PTP move's joint map with a crossing method: the path tracked by continuous IK
(shared by auto's candidates through :class:`MoveTracking`), each singular zone handed to the
method, the joint map stitched and its limits checked."""


from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.robot import Robot
from singplan.planning.crossing.base import Crossing, CrossingMethod, MoveContext
from singplan.planning.orchestration.checks import check_limits, check_tracked
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.orchestration.targets import move_limits, ptp_target
from singplan.planning.path.cartesian import STEP_M, STEP_RAD
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.path.pieces import move_piece
from singplan.planning.path.tracking import BranchCandidates, track
from singplan.planning.path.zones import DistanceFunction, Zone, find_zones
from singplan.planning.timing.trace import tcp_trace
from singplan.task.schema import Move, Task


def plan_move(robot: Robot, task: Task, i: int, move: Move, T_start: pin.SE3, q_start: np.ndarray,
               method: CrossingMethod, tracking: MoveTracking | None = None,
               q_target: np.ndarray | None = None) -> PlannedMove:
    """One move's joint map with ``method``; ``tracking`` shares the tracked stretches among candidates;
    ``q_target``: a PTP's target joints (default :func:`~singplan.planning.targets.ptp_target`'s)."""
    if move.kind == "ptp":
        q_target = q_target if q_target is not None else ptp_target(robot, i, move, q_start)
        part = JointPart("ptp", np.array([0.0, 1.0]), np.array([q_start, q_target]))
        return PlannedMove(i, "ptp", JointMap(robot, None, [part]), move_limits(robot, task, move, 0.0))
    tracking = tracking if tracking is not None else MoveTracking(robot, task, i, move, T_start)
    return plan_cartesian(robot, task, i, move, tracking, q_start, method)


def plan_cartesian(robot: Robot, task: Task, i: int, move: Move, tracking: MoveTracking, q_start: np.ndarray,
                    method: CrossingMethod) -> PlannedMove:
    """Track the path, let the method handle each zone, and stitch the joint map."""
    piece = tracking.piece
    grid = tracking.grid
    parts: list[JointPart] = []
    zones: list[Zone] = []
    crossings: list[Crossing] = []
    u_from, q_from = 0.0, q_start
    full = False  # track singular zones in full (a method kept one that was left coarse)
    while True:
        stage = tracking.stage(grid, u_from, q_from, full, crossings[-1].zone.kind if crossings else None)
        tracked = stage.ctx.tracked
        # the grid as refined: a re-track after a crossing starts from it (tracked.u starts at u_from)
        grid = np.concatenate([grid[grid < u_from], tracked.u])
        zones_before = list(zones)
        result = _first_crossing(method, stage.ctx, stage.found, zones, u_from)
        if tracked.coarse_from_u < (result.blend.u0 if result is not None else math.inf):
            zones[:], full = zones_before, True  # a kept zone was left coarse: track it in full
            continue
        full = False
        if result is None:
            parts.append(JointPart("track", tracked.u, tracked.q))
            check_limits(robot, i, move, piece, tracked.u, tracked.q, zones)
            break
        k_a = int(np.searchsorted(tracked.u, result.blend.u0))
        parts.append(JointPart("track", tracked.u[:k_a + 1], tracked.q[:k_a + 1]))
        check_limits(robot, i, move, piece, tracked.u[:k_a + 1], tracked.q[:k_a + 1], zones)
        for part in result.parts:
            parts.append(part)
            check_limits(robot, i, move, piece, part.u, part.q, zones)  # every method's crossing
        crossings.append(result)
        u_from, q_from = result.parts[-1].u1, result.q_exit
    jmap = JointMap(robot, piece.poses, parts)
    limits = move_limits(robot, task, move, piece.length_m)
    if move.weave is None:  # a weave's programmed speed is along its base path, which u measures
        limits = replace(limits, trace=tcp_trace(jmap, piece.length_m))
    return PlannedMove(i, move.kind, jmap, limits, piece, tuple(zones), tuple(crossings))


@dataclass(frozen=True)
class _Stage:
    """One tracked stretch of a move, from where it starts to the move's end, and the zones along it."""

    ctx: MoveContext  # what a method sees: the tracked joints and their singular distances
    found: tuple[Zone, ...]


class MoveTracking:
    """The tracking of one LIN / CIRC move, shared by the candidate methods that plan it.

    A stretch (IK tracked from a start to the move's end, its singular distances and zones)
    depends only on where it starts, the grid ahead of it, whether held zones are tracked in
    full and which zone kind it continues, never on the method: every candidate starts with the
    same stretch, and candidates whose crossings end alike share the stretch after them too.
    """

    def __init__(self, robot: Robot, task: Task, i: int, move: Move, T_start: pin.SE3) -> None:
        self.robot, self.task, self.index, self.move = robot, task, i, move
        self.piece = move_piece(i, move, T_start)
        self.grid = self.piece.grid(STEP_M, STEP_RAD)
        self.thresholds = task.singularity.zone.si()
        self._cands = BranchCandidates(robot, self.piece.poses)  # IK branches per path parameter, solved once
        self._in_zone = _ZoneTest(robot, self.thresholds)
        self._stages: dict[tuple[float, bytes, bool, str | None, bytes], _Stage] = {}

    def stage(self, grid: np.ndarray, u_from: float, q_from: np.ndarray, full: bool,
              continued: str | None) -> _Stage:
        """The stretch from ``q_from`` at ``u_from`` over ``grid``'s points after it (computed once)."""
        ahead = grid[grid > u_from + 1e-12]
        key = (u_from, np.asarray(q_from, dtype=float).tobytes(), full, continued, ahead.tobytes())
        if key not in self._stages:
            self._stages[key] = self._track(np.concatenate([[u_from], ahead]), q_from, full, continued)
        return self._stages[key]

    def _track(self, u: np.ndarray, q_from: np.ndarray, full: bool, continued: str | None) -> _Stage:
        robot, piece, task = self.robot, self.piece, self.task
        # inside singular zones the in-branch swing is resolved only if the method keeps it
        tracked = track(robot, piece.poses, u, q_from, cands=self._cands, hold=None if full else self._in_zone)
        check_tracked(robot, self.index, self.move, piece, tracked)
        dist = self._in_zone.distances(tracked.q)
        ref = JointMap(robot, piece.poses, [JointPart("track", tracked.u, tracked.q)])
        found = find_zones(tracked.u, dist, self.thresholds, refiner(robot, ref), continued=continued)
        ctx = MoveContext(robot, self.index, self.move.kind, piece, tracked, dist,
                          task.singularity.position_tolerance_mm / 1e3,
                          math.radians(task.singularity.orientation_tolerance_deg), self.thresholds, self._cands)
        return _Stage(ctx, tuple(found))


def _first_crossing(method: CrossingMethod, ctx: MoveContext, found: tuple[Zone, ...], zones: list[Zone],
                    u_from: float) -> Crossing | None:
    """Ask the method about each new zone; record zones; return the first crossing it makes."""
    for zone in found:
        if zones and zone.u_entry <= u_from + 1e-12 and zones[-1].kind == zone.kind and u_from > 0:
            crossed = zones[-1]  # the rest of a crossed zone: it and its segment end where this exits
            zones[-1] = replace(crossed, u_exit=zone.u_exit, window=(crossed.span[0], zone.u_exit))
            continue
        zones.append(zone)
        crossing = method.cross(ctx, zone)
        if crossing is not None:
            zones[-1] = _spanning(zone, crossing)
            return crossing
    return None


def _spanning(zone: Zone, crossing: Crossing) -> Zone:
    """The crossing's zone with the window of the joint-map part it replaced.

    A method may start its part before the detected entry (at the tracked sample below it) or end
    it after the exit, or cross a zone it widened (wrist-joint's blend window); every sample of
    that part is the crossing's, so its segment covers the window. The entry and exit stay the
    detected ``zone``'s, where the path itself is inside: the zone events report those.
    """
    z, u0, u1 = crossing.zone, crossing.parts[0].u0, crossing.parts[-1].u1
    window = (min(z.u_entry, zone.u_entry, u0), max(z.u_exit, zone.u_exit, u1))
    return replace(z, u_entry=zone.u_entry, u_exit=zone.u_exit, window=window)


class _ZoneTest:
    """Which joint samples lie in a singular zone of any kind (the tracker's ``hold``).

    Keeps the signed distances of the last samples it was asked about, so the planner reads
    the distances of the tracked path without computing them again (per sample on arms
    without a closed form).
    """

    def __init__(self, robot: Robot, thresholds: np.ndarray) -> None:
        self.robot = robot
        self.thresholds = thresholds
        self._q: np.ndarray | None = None
        self._d = np.empty((0, 3))

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Signed (wrist, shoulder, elbow) distances (N, 3) of joint samples q (N, n)."""
        if q is not self._q:
            self._q, self._d = q, distances_batch(self.robot, q)
        return self._d

    def __call__(self, q: np.ndarray) -> np.ndarray:
        return np.any(np.abs(self.distances(q)) < self.thresholds, axis=1)  # NaN rows compare False


def refiner(robot: Robot, ref: JointMap) -> DistanceFunction:
    def abs_distance(u: np.ndarray, index: int) -> np.ndarray:
        return np.abs(distances_batch(robot, ref.evaluate(u))[:, index])

    return abs_distance

"""planning.crossing.methods on their own, on the stretch the planner hands them (the demo's KUKA LIN
straight through a wrist singularity, tracked once): the exact path's joint slope against finite
differences of the exact IK, every exit candidate against solve_all's branches (brute force), and each
pose-keeping method's crossing against geometry (position on the path sample by sample, the seams
continuous in value and slope, the exit a full solution of the path pose in the other wrist branch)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot
from singplan.planning.crossing.base import Crossing, MoveContext
from singplan.planning.crossing.methods import Axis, Exact, WristJoint, exit_candidates, path_slope
from singplan.planning.orchestration.move_plan import MoveTracking
from singplan.planning.orchestration.targets import load_task_robot, start_joints
from singplan.planning.path.cartesian import CartesianPiece, make_circ
from singplan.planning.path.jointmap import JointMap, JointPart, hermite
from singplan.planning.path.tracking import track
from singplan.planning.path.zones import Zone, distances_along
from singplan.task.load import load_task

DEMO = Path(__file__).resolve().parents[1] / "singplan" / "demo_task.yaml"
TURN = 2.0 * math.pi


@pytest.fixture(scope="module")
def stretch() -> tuple[MoveContext, Zone]:
    task = load_task(DEMO)
    robot = load_task_robot(task)
    q0 = start_joints(task, robot)
    tracking = MoveTracking(robot, task, 0, task.moves[0], robot.fk(q0))
    stage = tracking.stage(tracking.grid, 0.0, q0, False, None)
    (zone,) = stage.found
    assert zone.kind == "wrist" and zone.min_distance < 1e-5  # straight through the singularity
    return stage.ctx, zone


def _exact_slope_fd(robot: Robot, piece: CartesianPiece, u: np.ndarray, q: np.ndarray, at: float) -> np.ndarray:
    """dq/du of the exact IK branch through the tracked samples, by central differences (h = 1e-6)."""
    exact = JointMap(robot, piece.poses, [JointPart("track", u, q)])
    h = 1e-6
    ahead, behind = exact.evaluate(np.array([at + h, at - h]))
    return (ahead - behind) / (2.0 * h)


@pytest.mark.parametrize("at", [0.05, 0.2, 0.8, 0.95])
def test_the_path_slope_is_the_derivative_of_the_exact_ik_along_a_lin(stretch: tuple[MoveContext, Zone],
                                                                      at: float) -> None:
    ctx, _ = stretch
    q = JointMap(ctx.robot, ctx.piece.poses, [JointPart("track", ctx.tracked.u, ctx.tracked.q)]).evaluate(
        np.array([at]))[0]
    fd = _exact_slope_fd(ctx.robot, ctx.piece, ctx.tracked.u, ctx.tracked.q, at)
    np.testing.assert_allclose(path_slope(ctx.robot, ctx.piece, at, q), fd, rtol=1e-5, atol=1e-6)


def test_the_path_slope_is_the_derivative_of_the_exact_ik_along_a_circ() -> None:
    robot = load_robot("abb_irb2400")
    q0 = np.radians([10, 20, 15, 40, 50, -30])
    T0 = robot.fk(q0)
    T1 = pin.SE3(T0.rotation @ pin.exp3(np.array([0.1, 0.2, -0.1])), T0.translation + np.array([0.0, -0.3, 0.1]))
    piece = make_circ(T0, T0.translation + np.array([0.1, -0.15, 0.1]), T1, "m")
    tracked = track(robot, piece.poses, piece.grid(0.005, math.radians(2.0)), q0)
    assert tracked.gap_index == -1
    exact = JointMap(robot, piece.poses, [JointPart("track", tracked.u, tracked.q)])
    for at in (0.1, 0.5, 0.9):
        q = exact.evaluate(np.array([at]))[0]
        fd = _exact_slope_fd(robot, piece, tracked.u, tracked.q, at)
        np.testing.assert_allclose(path_slope(robot, piece, at, q), fd, rtol=1e-5, atol=1e-6)


def test_every_exit_candidate_solves_the_path_pose_and_covers_every_branch(stretch: tuple[MoveContext, Zone]) -> None:
    ctx, zone = stretch
    u = zone.u_exit
    T = ctx.piece.poses(np.array([u]))[0]
    options = exit_candidates(ctx, u)
    assert len(options) == 8  # the OPW closed form's branches, none singular here
    for q in options:
        reached = ctx.robot.fk(q)
        assert np.linalg.norm(reached.translation - T[:3, 3]) < 1e-9
        assert np.linalg.norm(pin.log3(reached.rotation.T @ T[:3, :3])) < 1e-9
    # brute force: every solution solve_all lists (inside the limits) is a candidate up to whole turns
    for q in solve_all(ctx.robot, pin.SE3(T[:3, :3], T[:3, 3])).q:
        assert any(np.allclose(np.round((q - c) / TURN) * TURN, q - c, atol=1e-7) for c in options)


def _crossings(ctx: MoveContext, zone: Zone) -> dict[str, Crossing]:
    out = {}
    for method in (Exact(), WristJoint(None, 1.0), Axis(None)):
        crossing = method.cross(ctx, zone)
        assert crossing is not None, method.name
        out[method.name] = crossing
    return out


@pytest.mark.parametrize("name", ["exact", "wrist-joint", "axis"])
def test_a_wrist_crossing_keeps_the_position_joins_its_seams_and_exits_in_the_other_branch(
        stretch: tuple[MoveContext, Zone], name: str) -> None:
    ctx, zone = stretch
    crossing = _crossings(ctx, zone)[name]
    blend, robot = crossing.blend, ctx.robot
    assert blend.u0 <= zone.u_closest <= blend.u1 and not crossing.at_rest
    # the entry seam: a tracked sample, its joints
    k = int(np.searchsorted(ctx.tracked.u, blend.u0))
    assert ctx.tracked.u[k] == blend.u0
    np.testing.assert_allclose(blend.q[0], ctx.tracked.q[k], atol=1e-9)
    np.testing.assert_allclose(blend.q[-1], crossing.q_exit, atol=1e-12)  # re-solved there: to round-off
    # the position on the path at every sample of the crossing (what these methods keep)
    want = ctx.piece.poses(blend.u)
    for u_k, q_k, T in zip(blend.u, blend.q, want, strict=True):
        assert np.linalg.norm(robot.fk(q_k).translation - T[:3, 3]) < 1e-9, (name, u_k)
    # the exit: the whole path pose, in the other wrist branch than the entry
    T_exit = robot.fk(crossing.q_exit)
    assert np.linalg.norm(pin.log3(T_exit.rotation.T @ want[-1][:3, :3])) < 1e-9
    wrist = distances_along(robot, np.array([blend.q[0], crossing.q_exit]))[0][:, 0]
    assert wrist[0] * wrist[1] < 0.0
    # the seams' slopes: the exact path's own through each end (joint velocities continuous)
    if blend.dq_du is not None:
        np.testing.assert_allclose(blend.dq_du[0], path_slope(robot, ctx.piece, blend.u0, blend.q[0]), rtol=1e-9)
        np.testing.assert_allclose(blend.dq_du[1], path_slope(robot, ctx.piece, blend.u1, crossing.q_exit),
                                   rtol=1e-9)


def test_the_axis_crossing_drives_a4_on_the_blend_and_the_wrist_joint_one_all_three(
        stretch: tuple[MoveContext, Zone]) -> None:
    ctx, zone = stretch
    crossings = _crossings(ctx, zone)
    axis = crossings["axis"].blend
    assert axis.kind == "axis" and axis.axis == 3 and axis.exact == "position"
    np.testing.assert_allclose(axis.q[:, 3], hermite(axis, axis.u)[:, 3], atol=1e-12)  # A4 on its blend
    wrist = crossings["wrist-joint"].blend
    # the wrist joints are the Hermite blend's; the arm joints are re-solved for the position (not the blend's)
    np.testing.assert_allclose(wrist.q[:, 3:], hermite(wrist, wrist.u)[:, 3:], atol=1e-12)
    assert np.max(np.abs(wrist.q[:, :3] - hermite(wrist, wrist.u)[:, :3])) > 1e-6

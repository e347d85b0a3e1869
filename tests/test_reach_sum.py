"""The link-length reach sum has one home (``Robot.link_lengths_m`` / ``Robot.offsets_m``); its three
users (the out-of-reach bound, the stopping reach bounds, the collision bodies' reach and arms) give
the same numbers, bit for bit, as their own sums did before (the references below are those sums,
as they were written in each module at fbbe553)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics import collision
from singplan.kinematics.robot import Robot, bundled_robots, load_robot
from singplan.kinematics.stopping import reach_bounds

# every arm of robots/urdf and example-robot-data's UR5 and Panda
URDFS = Path(__file__).resolve().parents[1] / "robots" / "urdf"
ARMS = [*sorted(p.stem for p in URDFS.glob("*.urdf")), "ur5", "panda"]
TOOLS = {"no tool": pin.SE3.Identity(),
         "tilted tool": pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.1), np.array([0.013, -0.021, 0.187]))}


def _offsets_before(robot: Robot) -> float:
    placements = robot.model.jointPlacements
    lengths = [np.linalg.norm(placements[i].translation) for i in range(2, robot.model.njoints)]
    return float(sum(lengths) + np.linalg.norm(robot.model.frames[robot.tip_frame_id].placement.translation))


def _reach_bounds_before(robot: Robot) -> np.ndarray:
    model = robot.model
    tool = (model.frames[robot.tip_frame_id].placement * robot.T_tip_tcp).translation
    links = [np.asarray(model.jointPlacements[k].translation) for k in range(2, model.njoints)] + [tool]
    lengths = np.array([float(np.linalg.norm(v)) for v in links])
    after = np.concatenate([np.cumsum(lengths[::-1])[::-1][1:], [0.0]])
    across = [float(np.linalg.norm(v - np.dot(v, a) * a)) for v, a in zip(links, robot.joint_axes, strict=True)]
    return np.array(across) + after


def _arms_before(robot: Robot, joint: int, extent: float) -> np.ndarray:
    arm = np.zeros(robot.n_joints)
    offsets = [float(np.linalg.norm(robot.model.jointPlacements[i].translation)) for i in range(joint + 1)]
    for j in range(1, joint + 1):
        arm[robot.model.joints[j].idx_q] = sum(offsets[j + 1:joint + 1]) + extent
    return arm


def test_the_arms_are_the_ones_asked_for() -> None:
    assert len(ARMS) == 12 and {"kuka_kr6_r900_2", "abb_irb2400", "staubli_tx2_60"} <= set(ARMS)
    assert all(name in bundled_robots() for name in ARMS)


@pytest.mark.parametrize("tool", TOOLS)
@pytest.mark.parametrize("name", ARMS)
def test_the_three_reach_sums_are_unchanged(name: str, tool: str) -> None:
    robot = load_robot(name, tool=TOOLS[tool])
    assert robot._offsets_m() == _offsets_before(robot)
    assert robot.link_lengths_m[0] == 0.0 and robot.offsets_m(3, 2) == 0.0
    assert np.array_equal(reach_bounds(robot), _reach_bounds_before(robot))
    bodies = collision.collision_model(robot).bodies
    assert bodies
    for body in bodies:
        assert body.joint is not None and body.arm_m is not None
        assert np.array_equal(body.arm_m, _arms_before(robot, body.joint, body.extent_m)), body.name
        own = robot.model.joints[body.joint].idx_q if body.joint else None
        others = [j for j in range(robot.n_joints) if j != own]
        assert np.array_equal(body.reach_m[others], body.arm_m[others])
    geoms = [g for b in bodies for g in b.geoms][:3]
    for joint in range(robot.model.njoints):  # every joint as the carrying one, as the tool body can be
        _, extent, arm = collision._reach(robot, joint, geoms)
        assert np.array_equal(arm, _arms_before(robot, joint, extent) if joint else np.zeros(robot.n_joints))

"""The compiled chain composition (singplan.kinematics.chain) gives numpy's numbers bit for bit, or is not used."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics import chain
from singplan.kinematics.robot import load_robot

TOOL = pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), np.array([0.01, 0.02, 0.1]))


def _pair(name: str):
    """The robot composed as it is here, and the same robot composed by numpy."""
    compiled = load_robot(name, tool=TOOL)
    plain = load_robot(name, tool=TOOL)
    plain.__dict__["_compiled_chain"] = None  # the cached property, set: numpy's composition
    return compiled, plain


@pytest.mark.parametrize("name", ["kuka_kr6_r900_2", "ur5", "panda", "so100", "staubli_tx2_60"])
def test_compiled_chain_is_numpy_bit_for_bit(name: str) -> None:
    compiled, plain = _pair(name)
    if not chain.faithful():
        assert compiled._compiled_chain is None  # this BLAS sums otherwise: numpy composes the chain
        return
    rng = np.random.default_rng(7)
    for count in (2, 5, 300):
        q = rng.uniform(-3.0, 3.0, size=(count, compiled.n_joints))
        for rows in (0, 3, 6):
            for a, b in zip(compiled.tcp_kinematics(q, rows), plain.tcp_kinematics(q, rows), strict=True):
                assert np.array_equal(a, b)
        for a, b in zip(compiled.joint_frames(q), plain.joint_frames(q), strict=True):
            assert np.array_equal(a, b)
        assert np.array_equal(compiled.tcp_positions(q), plain.tcp_positions(q))


def test_compiled_chain_agrees_with_pinocchio() -> None:
    """An independent reference: Pinocchio's own forward kinematics and Jacobian."""
    robot = load_robot("kuka_kr6_r900_2", tool=TOOL)
    q = np.random.default_rng(3).uniform(-2.0, 2.0, size=(20, 6))
    position, rotation, jacobian = robot.tcp_kinematics(q, 6)
    for k in range(len(q)):
        T = robot.fk(q[k])
        assert np.allclose(position[k], T.translation, atol=1e-12)
        assert np.allclose(rotation[k], T.rotation, atol=1e-12)
        assert np.allclose(jacobian[k], robot.jacobian(q[k]), atol=1e-12)


def test_placement_is_numpy_bit_for_bit() -> None:
    """A collision shape placed for coal: the frame times the shape's placement (C and Fortran order)."""
    if not chain.faithful():
        pytest.skip("this BLAS sums otherwise: numpy places the shapes (chain.faithful() is False)")
    rng = np.random.default_rng(11)
    for _ in range(500):
        R, origin, t = rng.normal(size=(3, 3)), rng.normal(size=3), rng.normal(size=3)
        for rotation in (rng.normal(size=(3, 3)), np.asfortranarray(rng.normal(size=(3, 3)))):
            out_R, out_t = chain.placed(R, origin, rotation, t)
            assert np.array_equal(out_R, R @ rotation)
            assert np.array_equal(out_t, origin + R @ t)

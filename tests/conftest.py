"""Shared fixtures: robots are loaded once per session (Pinocchio parsing is the slow part)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from singplan.kinematics.robot import Robot, bundled_robots, load_robot

OPW_NAMES = [name for name, entry in bundled_robots().items() if entry.family == "opw"]


@pytest.fixture(scope="session")
def robots() -> dict[str, Robot]:
    return {name: load_robot(name) for name in [*OPW_NAMES, "ur5"]}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def erd_urdf(name: str) -> str:
    """The URDF path ``example_robot_data.load(name).urdf`` gives, without building the model: load()
    also parses every mesh (2.6 s for so101, 1 s for z1). tests/test_robot.py checks the two agree."""
    import example_robot_data.robots_loader as loaders

    loader = loaders.ROBOTS[name]
    return os.path.join(loaders.getModelPath(loader.path), loader.path, loader.urdf_subpath, loader.urdf_filename)


def random_q(robot: Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """n joint vectors inside the limits (finite ranges, capped at +-2*pi), shape (n, dof)."""
    lo = np.maximum(robot.lower_rad, -2 * np.pi)
    hi = np.minimum(robot.upper_rad, 2 * np.pi)
    return rng.uniform(lo, hi, size=(n, robot.n_joints))


# the public scenarios sit next to the project in development and CI (as in tests/test_scenarios.py)
_SHARED_SCENARIOS = Path(__file__).resolve().parents[2] / "shared" / "scenarios"
SCENARIOS = _SHARED_SCENARIOS if _SHARED_SCENARIOS.is_dir() else None


@pytest.fixture(scope="session")
def planned_kuka(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An output folder of a small plan (a KUKA LIN through a wrist near miss), planned once per session."""
    from singplan.results.plan import plan
    from singplan.results.trajectory import save
    from singplan.task.load import load_task

    task = Path(__file__).resolve().parent.parent / "singplan" / "demo_task.yaml"
    return save(plan(load_task(task)), tmp_path_factory.mktemp("planned_kuka"))

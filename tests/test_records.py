"""The trajectory's records: typed all through, written explicitly, read back the same.

The task a trajectory carries is the validated ``Task`` (not its mapping), a file's task is parsed
once when it is read, and the programmed path the pages and programs draw is the planner's own
pieces, made in one place (:mod:`singplan.results.path`) for a trajectory planned or read back.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest

from singplan.kinematics.robot import Robot
from singplan.outputs.timeline import robot_of
from singplan.planning.orchestration.planner import PlannedTask, plan_moves
from singplan.results.metrics import CrossingFigures, JerkFigures, Metrics, TorqueFigures
from singplan.results.path import programmed_path, woven_moves
from singplan.results.plan import trajectory_of
from singplan.results.trajectory import Trajectory, load, save
from singplan.task.load import load_task
from singplan.task.schema import Task

ROOT = Path(__file__).resolve().parents[1]
PROGRAM = ROOT / "examples" / "kuka_program.yaml"  # LIN, CIRC, PTP
U = np.linspace(0.0, 1.0, 101)


@pytest.fixture(scope="module")
def planned() -> tuple[PlannedTask, Trajectory]:
    moves = plan_moves(load_task(PROGRAM))
    return moves, trajectory_of(moves)


@pytest.fixture(scope="module")
def back(planned: tuple[PlannedTask, Trajectory], tmp_path_factory: pytest.TempPathFactory) -> Trajectory:
    return load(save(planned[1], tmp_path_factory.mktemp("records")))


@pytest.fixture(scope="module")
def robot(planned: tuple[PlannedTask, Trajectory]) -> Robot:
    return robot_of(planned[1])


def test_the_trajectory_carries_the_typed_task_and_reads_it_back_equal(planned: tuple[PlannedTask, Trajectory],
                                                                        back: Trajectory) -> None:
    traj = planned[1]
    assert isinstance(traj.task, Task) and isinstance(back.task, Task)
    assert back.task == traj.task == planned[0].task
    assert [m.kind for m in traj.task.moves] == ["lin", "circ", "ptp"]
    assert traj.to_json()["task"] == traj.task.to_mapping() == json.loads(json.dumps(back.task.to_mapping()))


def test_the_programmed_path_is_the_planners_pieces(planned: tuple[PlannedTask, Trajectory], robot: Robot) -> None:
    moves, traj = planned
    path = programmed_path(traj.task, robot, traj.q[0])
    assert [p.kind for p in path] == ["lin", "circ", "ptp"] and path[2].piece is None
    for programmed, pm in zip(path[:2], moves.moves[:2], strict=True):
        assert programmed.piece is not None and pm.piece is not None
        # the planner starts a move where the one before it was programmed to end, as the record does
        np.testing.assert_allclose(programmed.piece.poses(U), pm.piece.poses(U), rtol=0, atol=1e-9)
        assert programmed.weave_slope == 0.0


def test_a_trajectory_read_back_gives_the_same_programmed_path(planned: tuple[PlannedTask, Trajectory],
                                                               back: Trajectory, robot: Robot) -> None:
    traj = planned[1]
    for a, b in zip(programmed_path(traj.task, robot, traj.q[0]), programmed_path(back.task, robot_of(back),
                                                                                  back.q[0]), strict=True):
        assert a.move == b.move
        assert (a.piece is None) == (b.piece is None)
        if a.piece is not None and b.piece is not None:
            assert np.array_equal(a.piece.poses(U), b.piece.poses(U))  # bit for bit: the pages' bytes rely on it


def test_the_metrics_are_records_written_explicitly_and_read_back_equal(planned: tuple[PlannedTask, Trajectory],
                                                                         back: Trajectory) -> None:
    metrics = planned[1].metrics
    assert not isinstance(metrics, Mapping) and not isinstance(metrics.crossings[0], Mapping)
    document = json.loads(json.dumps(metrics.to_json()))
    assert Metrics.from_json(document) == metrics
    assert back.metrics == metrics
    ratios = {k: v for k, v in document.items() if k.startswith("max_") and k.endswith("_ratio")}
    assert metrics.limit_ratios() == ratios  # the file's every max_*_ratio, torque and jerk ones included
    crossing = next(s for s in back.segments if s.kind == "crossing")
    assert isinstance(crossing.details, CrossingFigures) and crossing.details.alternatives
    assert crossing.pause_s is None and "pause_s" not in crossing.to_json()


def test_woven_moves_are_read_from_the_typed_task() -> None:
    task = load_task(ROOT / "examples" / "weave_seam.yaml")
    assert woven_moves(task) == {0, 1}


def test_limit_ratios_list_the_torque_and_jerk_ratios_the_file_writes_flat() -> None:
    metrics = Metrics(0.001, 0.01, 0.9, 0.8, 1.0, 0.1, 251, "auto", (),
                      TorqueFigures(0.7, 0.5, "joint_2", {"joint_2": 70.0}, {"joint_2": 100.0}), 12.0, 0.4,
                      JerkFigures(0.9, 0.1, 0.95), max_tcp_speed_ratio=1.0)
    document = metrics.to_json()
    ratios = {k: v for k, v in document.items() if k.startswith("max_") and k.endswith("_ratio")}
    assert metrics.limit_ratios() == ratios
    assert list(metrics.limit_ratios()) == ["max_joint_speed_ratio", "max_joint_accel_ratio", "max_tcp_speed_ratio",
                                            "max_torque_ratio", "max_joint_jerk_ratio"]
    quintic = Metrics(0.0, 0.0, 0.5, 0.5, 1.0, 0.1, 251, "auto", (), "not computed: no dynamics", 0.0, 0.0,
                      JerkFigures(0.9, 0.1))  # the quintic PTP law alone: no jerk ratio
    assert "max_joint_jerk_ratio" not in quintic.limit_ratios() and "max_torque_ratio" not in quintic.limit_ratios()
    assert Metrics.from_json(json.loads(json.dumps(document))) == metrics

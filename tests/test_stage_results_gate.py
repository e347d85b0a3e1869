"""The record's last gate (results/plan.py), a stretch of samples at a time: it finds the sample a
whole-trajectory mask would, and names it."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from singplan.errors import JointLimitError, PlanningError
from singplan.planning.orchestration.planner import PlannedTask, plan_moves
from singplan.results import plan as plan_module
from singplan.results.plan import _check_metrics, trajectory_of
from singplan.results.trajectory import Trajectory
from singplan.task.load import load_task

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def planned() -> tuple[PlannedTask, Trajectory]:
    moves = plan_moves(load_task(ROOT / "examples" / "kuka_long_program.yaml"))  # wrist crossings and paths
    return moves, trajectory_of(moves)


def _gate(planned: PlannedTask, traj: Trajectory) -> None:
    _check_metrics(planned.full, planned.task, list(planned.moves), list(planned.timed), traj)


def test_the_first_sample_outside_a_joint_limit_is_named_whatever_the_chunks(
        planned: tuple[PlannedTask, Trajectory], monkeypatch: pytest.MonkeyPatch) -> None:
    moves, traj = planned
    monkeypatch.setattr(plan_module, "_CHUNK", 97)  # the samples below sit in different chunks
    q = traj.q.copy()
    q[1500, 4] = moves.full.upper_rad[4] + 0.01  # the first outside, row by row ...
    q[3000, 0] = moves.full.lower_rad[0] - 0.5
    with pytest.raises(JointLimitError, match=r"sample 1500 .* puts joint_5") as caught:
        _gate(moves, replace(traj, q=q.copy()))
    assert caught.value.move == int(np.searchsorted(np.cumsum([len(tm.q) - 1 for tm in moves.timed]), 1500))
    q[1500, 2] = np.nan  # ... an earlier joint of the same sample not a number: that one is named
    with pytest.raises(JointLimitError, match=r"sample 1500 .* puts joint_3"):
        _gate(moves, replace(traj, q=q.copy()))


def test_the_worst_turn_outside_the_crossings_is_named_and_a_crossing_may_turn(
        planned: tuple[PlannedTask, Trajectory]) -> None:
    moves, traj = planned
    _gate(moves, traj)  # the real samples pass
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    inside = round(crossing.t0 / traj.period) + 1
    path = next(s for s in traj.segments if s.kind in ("pre", "post", "path") and s.t1 - s.t0 > 0.1)
    outside = round(path.t0 / traj.period) + 5
    ori = traj.samples["orientation_error_rad"].copy()
    ori[inside] = math.radians(5.0)  # a crossing may trade orientation: not named
    _gate(moves, _with_turns(traj, ori))
    ori[outside], ori[outside + 3] = math.radians(0.02), math.radians(0.03)
    with pytest.raises(PlanningError, match=rf"sample {outside + 3} .* turns the tool 0\.0300 deg"):
        _gate(moves, _with_turns(traj, ori))
    ori[outside] = np.nan  # not a number is a turn too, and the worst
    with pytest.raises(PlanningError, match=rf"sample {outside} .* turns the tool nan deg"):
        _gate(moves, _with_turns(traj, ori))


def _with_turns(traj: Trajectory, ori: np.ndarray) -> Trajectory:
    return replace(traj, samples={**traj.samples, "orientation_error_rad": ori.copy()})


def test_a_sample_that_is_not_a_number_is_refused_by_name_not_by_a_crash() -> None:
    planned = plan_moves(load_task(ROOT / "examples" / "kuka_program.yaml"))
    planned.q[100, 2] = np.nan  # the stopping distances skip it; the gate names it
    with pytest.raises(JointLimitError, match=r"move 0 \(lin\): sample 100 .* puts joint_3 at nan deg"):
        trajectory_of(planned)

"""Zone events mark where the path enters and leaves a singular zone, not the crossing segment's
ends: a method's window (wrist-joint's blend) may be wider than the zone.

The task is a user's: an ABB IRB 2400 LIN exactly through a wrist-singular pose (zone at s
135.6-358.0 mm of 482 mm). The events are checked against independent geometry: the wrist angle
|q5| of the programmed pose at each sample's place on the line, solved by IK.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot
from singplan.outputs.report import report_html
from singplan.outputs.summary import summary
from singplan.planning.crossing.methods import WristJoint
from singplan.results.detect import detect
from singplan.results.plan import plan
from singplan.results.trajectory import Segment, Trajectory
from singplan.task.load import parse_task
from singplan.task.schema import Task

START_DEG = [-10, 15, 5, 20, 12, -15]
TARGET = {"xyz": [1.177437, 0.186894, 0.828224], "rpy_deg": [-167.600682, 59.869559, -160.423716]}
WRIST_THRESHOLD = math.radians(5.0)  # the default singularity.zone.wrist_deg


def _task(start_deg: list[float], target: dict[str, Any], method: str = "auto") -> Task:
    return parse_task({"robot": "abb_irb2400", "start": {"joints_deg": start_deg},
                       "moves": [{"lin": {"to": target, "speed": 0.3}}],
                       "singularity": {"method": method, "orientation_tolerance_deg": 2.0}})


@pytest.fixture(scope="module")
def task() -> Task:
    return _task(START_DEG, TARGET)


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot("abb_irb2400")


@pytest.fixture(scope="module")
def wide(task: Task) -> Trajectory:
    """The wrist-joint crossing with the x2.5 window auto picks: it spans the whole move."""
    return plan(task, method=WristJoint(None, 2.5))


@pytest.fixture(scope="module")
def exact(task: Task) -> Trajectory:
    return plan(task, method="exact")


def _zone_samples(traj: Trajectory) -> tuple[int, int]:
    """The samples of the one zone_entry and zone_exit event."""
    times = {e.type: e.t for e in traj.events if e.type != "config_change"}
    assert len([e for e in traj.events if e.type != "config_change"]) == 2
    return round(times["zone_entry"] / traj.period), round(times["zone_exit"] / traj.period)


def _crossing(traj: Trajectory) -> Segment:
    (crossing,) = [s for s in traj.segments if s.kind == "crossing"]
    return crossing


class _Line:
    """The programmed LIN: u of a TCP position, and |q5| of the programmed pose there (IK)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.T0 = robot.fk(np.radians(START_DEG))
        self.p1 = np.array(TARGET["xyz"])
        self.R1 = pin.rpy.rpyToMatrix(*np.radians(TARGET["rpy_deg"]))
        self.length_m = float(np.linalg.norm(self.p1 - self.T0.translation))
        self.turn = pin.log3(self.T0.rotation.T @ self.R1)

    def u(self, q: np.ndarray) -> float:
        p = self.robot.fk(q).translation
        return float((p - self.T0.translation) @ (self.p1 - self.T0.translation)) / self.length_m ** 2

    def wrist_rad(self, q: np.ndarray) -> float:
        """|q5| of the programmed pose at q's place on the line, in q's arm branch (q1..q3 nearest)."""
        u = self.u(q)
        T = pin.SE3(self.T0.rotation @ pin.exp3(u * self.turn), self.robot.fk(q).translation)
        solutions = solve_all(self.robot, T).q
        return abs(float(solutions[np.argmin(np.linalg.norm(solutions[:, :3] - q[:3], axis=1)), 4]))


def test_the_wide_window_spans_the_move_and_the_events_lie_inside_it(wide: Trajectory) -> None:
    crossing = _crossing(wide)
    assert (crossing.method, crossing.t0, crossing.t1) == ("wrist-joint", 0.0, wide.duration_s)  # segment as before
    entry, exit_ = _zone_samples(wide)
    assert crossing.t0 < entry * wide.period < exit_ * wide.period < crossing.t1
    assert wide.zone_times(crossing) == (entry * wide.period, exit_ * wide.period)


def test_wide_window_events_are_where_the_line_enters_and_leaves_the_zone(task: Task, wide: Trajectory,
                                                                          robot: Robot) -> None:
    (zone,) = detect(task)[0].zones
    line = _Line(robot)
    np.testing.assert_allclose(robot.fk(wide.q[-1]).translation, line.p1, atol=1e-9)  # the line's end as read
    entry, exit_ = _zone_samples(wide)
    # the zone's u range on the samples: the first sample at or past the entry, the first at or past the exit
    assert line.u(wide.q[entry - 1]) < zone.u_entry <= line.u(wide.q[entry]) + 1e-9
    assert line.u(wide.q[exit_ - 1]) < zone.u_exit <= line.u(wide.q[exit_]) + 1e-9
    # independent: the programmed pose's wrist angle is under the threshold from the entry event
    # up to the exit event and over it just outside (within a sample)
    wrist = np.array([line.wrist_rad(q) for q in wide.q])
    inside = np.nonzero(wrist < WRIST_THRESHOLD)[0]
    assert (inside[0], inside[-1] + 1) == (entry, exit_)
    assert np.all(wrist[entry:exit_] < WRIST_THRESHOLD)
    # the crossing's own joints are not the measure: the blend has |q5| over the threshold at the entry
    assert abs(wide.q[entry, 4]) > WRIST_THRESHOLD


def test_exact_events_are_the_crossing_segment_as_before(exact: Trajectory) -> None:
    crossing = _crossing(exact)
    entry, exit_ = _zone_samples(exact)
    assert (entry * exact.period, exit_ * exact.period) == (crossing.t0, crossing.t1)
    assert [s.kind for s in exact.segments] == ["pre", "crossing", "post"]
    # exact follows the programmed pose: its own |q5| is under the threshold exactly between the events
    inside = np.nonzero(np.abs(exact.q[:, 4]) < WRIST_THRESHOLD)[0]
    assert (inside[0], inside[-1] + 1) == (entry, exit_)


def test_the_summary_gives_the_crossing_and_the_zone(task: Task, wide: Trajectory, exact: Trajectory) -> None:
    crossing = _crossing(wide)
    a, b = wide.zone_times(crossing) or (math.nan, math.nan)
    assert (f"wrist crossing 0.000 .. {crossing.t1:.3f} s (zone {a:.3f} .. {b:.3f} s): closest "
            in summary(wide, task))
    crossing = _crossing(exact)
    assert f"wrist zone {crossing.t0:.3f} .. {crossing.t1:.3f} s: closest " in summary(exact, task)


def test_the_report_gives_the_crossing_and_the_zone(wide: Trajectory, robot: Robot) -> None:
    crossing = _crossing(wide)
    a, b = wide.zone_times(crossing) or (math.nan, math.nan)
    page = report_html(wide, robot)
    assert "<th>time [s]</th><th>zone [s]</th>" in page
    assert f"<td>0.000 .. {crossing.t1:.3f}</td><td>{a:.3f} .. {b:.3f}</td>" in page


def test_a_zone_at_the_move_start_is_entered_at_the_start(robot: Robot) -> None:
    T1 = robot.fk(np.radians([-5, 20, 10, 20, 25, -15]))
    target = {"xyz": T1.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T1.rotation)).tolist()}
    traj = plan(_task([-10, 15, 5, 20, 2, -15], target, "exact"))  # q5 = 2 deg: inside the zone at the start
    crossing = _crossing(traj)
    entry, exit_ = _zone_samples(traj)
    assert entry == 0 and crossing.t0 == 0.0 and exit_ * traj.period == crossing.t1
    assert abs(traj.q[exit_ - 1, 4]) < WRIST_THRESHOLD <= abs(traj.q[exit_, 4])


def test_a_null_space_crossing_without_a_pause_says_it_went_as_exact(task: Task, exact: Trajectory) -> None:
    """null-space pauses only where exact's way on leaves a joint limit; here it does not, so the
    plan is exact's and the summary says so instead of implying a null-space motion."""
    traj = plan(task, method="null-space")
    np.testing.assert_array_equal(traj.q, exact.q)
    assert "method null-space changing branch as exact does (no pause needed)" in summary(traj, task)
    assert "as exact does" not in summary(exact, task)

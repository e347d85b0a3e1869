"""Correct at the edges (issue 10, item 4): seams, reach boundaries, tiny moves, the final gate,
and exit-3 messages that name the move and the point."""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest

from singplan.errors import PlanningError
from singplan.kinematics.robot import load_robot
from singplan.planning.orchestration import planner
from singplan.planning.timing.records import TimedMove
from singplan.results.plan import plan
from singplan.task.load import parse_task

DEMO_START = [34.466047735, -69.193961827, 100.109975431, 68.691762951, -14.064499937, -11.872434380]
DEMO_TO = {"xyz": [0.703837, -0.107362, 0.658022], "rpy_deg": [-121.329770, 35.631042, -129.525465]}


def _pose(robot_name: str, q: np.ndarray) -> dict:
    T = load_robot(robot_name).fk(q)
    return {"xyz": T.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T.rotation)).tolist()}


def _at_rest_everywhere_it_should(traj, amax: float) -> None:
    """Every move boundary at rest: adjacent steps within amax dt^2 (the checker's rule)."""
    for t in sorted({s.t0 for s in traj.segments if s.kind in ("path", "pre", "ptp")} | {traj.t[-1]}):
        k = round(t / traj.period)
        for a, b in ((k - 1, k), (k, k + 1)):
            if a >= 0 and b < len(traj.q):
                assert np.all(np.abs(traj.q[b] - traj.q[a]) <= amax * traj.period**2 * (1 + 1e-9))


def test_a_seam_between_two_moves_stays_within_the_acceleration_limit() -> None:
    # a LIN through an elbow zone and back: on main its seam reached x1.22 of the limit and exited 0
    q1 = np.radians([108.4394909672286, -31.879570340686037, -14.748323930099344, -81.69897881878425,
                     45.28664295022643, -91.47042407495059])
    to = {"xyz": [-0.24734205310513402, -0.7614441882650282, 0.9626770134041593],
          "rpy_deg": [16.437440253879867, -59.830845017173154, 78.56866094270666]}
    accel = 19.955916517058462
    task = {"robot": "kuka_kr6_r900_2", "start": {"joints_deg": np.degrees(q1).tolist()},
            "moves": [{"lin": {"to": to, "speed": 1.363765544507002}},
                      {"lin": {"to": _pose("kuka_kr6_r900_2", q1), "speed": 1.363765544507002}}],
            "singularity": {"method": "auto", "orientation_tolerance_deg": 5},
            "limits": {"acceleration": accel}, "output": {"period": 0.004}}
    traj = plan(parse_task(task))
    qdd = np.diff(traj.q, n=2, axis=0) / traj.period**2
    assert np.abs(qdd).max() <= accel * (1 + 1e-9)
    assert traj.metrics.max_joint_accel_ratio <= 1 + 1e-9
    _at_rest_everywhere_it_should(traj, accel)


def test_a_ur5_lin_ending_at_full_reach_stops_there() -> None:
    q_end = np.array([0.3, -0.6, 0.0, -0.9, 1.2, 0.4])  # elbow straight: the reach boundary
    q_start = np.array([0.3, -0.9, 0.6, -1.2, 1.2, 0.4])
    task = {"robot": "ur5", "start": {"joints_deg": np.degrees(q_start).tolist()},
            "moves": [{"lin": {"to": _pose("ur5", q_end), "speed": 0.25}},
                      {"ptp": {"to": {"joints_deg": np.degrees(q_start).tolist()}}}]}
    traj = plan(parse_task(task))
    _at_rest_everywhere_it_should(traj, 10.0)
    assert traj.metrics.max_joint_accel_ratio <= 1 + 1e-9


@pytest.mark.parametrize("move", [
    {"lin": {"to": {"xyz": 1e-5}, "speed": 0.25}},
    {"lin": {"to": {"xyz": 1e-9}, "speed": 0.25}},
    {"ptp": {"to": {"joints_deg": [1e-4, 10, 20, 0, 30, 0]}}},
    {"ptp": {"to": {"joints_deg": [0, 10, 20, 0, 30, 0]}}},  # changes nothing: rest samples
], ids=["lin-10um", "lin-1nm", "ptp-1e-4deg", "ptp-nothing"])
def test_tiny_moves_plan(move) -> None:
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    if "lin" in move:
        shift = np.array([move["lin"]["to"]["xyz"], 0.0, 0.0])
        move = {"lin": {"to": {"xyz": (load_robot("abb_irb2400").fk(q0).translation + shift).tolist()}, "speed": 0.25}}
    traj = plan(parse_task({"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
                            "moves": [move]}))
    assert traj.metrics.max_joint_accel_ratio <= 1 + 1e-9
    _at_rest_everywhere_it_should(traj, 10.0)


def test_the_final_gate_refuses_samples_over_a_limit(monkeypatch) -> None:
    real = planner.time_move

    def broken(*args, **kwargs) -> TimedMove:  # a future regression: one sample off the profile
        tm = real(*args, **kwargs)
        q = tm.q.copy()
        q[len(q) // 2, 2] += 0.05
        return TimedMove(tm.u, q, tm.duration_s, tm.speed_ratio, tm.accel_ratio)

    monkeypatch.setattr(planner, "time_move", broken)
    task = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
            "moves": [{"ptp": {"to": {"joints_deg": [20, 10, 20, 0, 30, 0]}}}]}
    with pytest.raises(PlanningError, match=r"move 0 \(ptp\): the planned samples break a limit .* near sample \d+"):
        plan(parse_task(task))


POINT = r"(s = -?[\d.]+ mm along the path \(xyz|of the joint motion \(joints_deg|xyz \[)"
EXIT3_TASKS = {
    "unreachable-lin": {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
                        "moves": [{"lin": {"to": {"xyz": [2.5, 0, 1.0]}}}]},
    "stop-at-wrist": {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]},
                      "start": {"joints_deg": DEMO_START}, "moves": [{"lin": {"to": DEMO_TO}}],
                      "singularity": {"method": "stop"}},
    "keep-config": {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]},
                    "start": {"joints_deg": DEMO_START}, "moves": [{"lin": {"to": DEMO_TO, "config": "keep"}}],
                    "singularity": {"method": "exact"}},
    "ptp-unreachable": {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
                        "moves": [{"ptp": {"to": {"xyz": [3.0, 0, 1.0]}}}]},
    "ur5-from-zero": {"robot": "ur5", "start": {"joints_deg": [0, 0, 0, 0, 0, 0]},
                      "moves": [{"lin": {"to": {"xyz": [0.6, 0.2, 0.4]}, "speed": 0.2}}]},
}


@pytest.mark.parametrize("name", sorted(EXIT3_TASKS))
def test_every_exit_3_message_names_the_move_and_the_point(name: str) -> None:
    with pytest.raises(PlanningError) as info:
        plan(parse_task(EXIT3_TASKS[name]))
    message = str(info.value)
    assert re.search(r"move \d+", message), message
    assert re.search(POINT, message), message


@pytest.mark.parametrize("offset_m", [0.0, 0.05])
@pytest.mark.parametrize("q4_deg", [1.0, 0.4, -30.0])
def test_a_move_starting_on_the_wrist_singularity_starts_at_its_own_joints(offset_m: float, q4_deg: float) -> None:
    """At q5 = 0 only q4 + q6 is fixed by the pose; the tracker's branches hold one split of it. A
    LIN from there (or to its own start) begins at the start joints, not at that split (found by the
    soak: q4 = 1 deg, within the tracker's 1 deg step, began at q4 = 0, q6 = 1 deg)."""
    robot = load_robot("abb_irb2400")
    start = np.radians([0.0, 0.0, 0.0, q4_deg, 0.0, 0.0])
    T = robot.fk(start)
    target = {"xyz": list(T.translation + np.array([0.0, offset_m, 0.0])),
              "rpy_deg": list(np.degrees(pin.rpy.matrixToRpy(T.rotation)))}
    traj = plan(parse_task({"robot": "abb_irb2400", "start": {"joints_deg": list(np.degrees(start))},
                            "moves": [{"lin": {"to": target}}], "singularity": {"method": "auto"},
                            "output": {"period": 0.015625}}))
    np.testing.assert_allclose(traj.q[0], start, atol=1e-12)
    if offset_m == 0.0:  # nothing to do: the joints stay where they are
        assert np.max(np.abs(traj.q - start)) < 1e-12

"""Crossing methods: exact positions, honest deviations, C1 seams, baselines that fail loudly."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.errors import PlanningError, SingularityError
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import load_robot
from singplan.planning.crossing.registry import candidates
from singplan.planning.orchestration.targets import load_task_robot
from singplan.results.plan import plan
from singplan.task.load import load_task, parse_task

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NEAR_MISS = EXAMPLES / "abb_near_miss_auto.yaml"


def _independent_deviation(traj, task_path: Path | dict, move: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each sample of a single-LIN task from its line [m] and its tilt from the
    (constant) programmed orientation [rad], recomputed from the task and the samples."""
    task = load_task(task_path) if isinstance(task_path, Path) else parse_task(task_path)
    robot = load_task_robot(task)
    a = robot.fk(np.radians(task.start_joints_deg))
    b = np.array(task.moves[move].to.xyz)
    d = b - a.translation
    pos, ori = [], []
    for q in traj.q:
        T = robot.fk(q)
        s = float(np.clip((T.translation - a.translation) @ d / (d @ d), 0.0, 1.0))
        pos.append(np.linalg.norm(T.translation - a.translation - s * d))
        ori.append(np.linalg.norm(pin.log3(a.rotation.T @ T.rotation)))
    return np.array(pos), np.array(ori)


@pytest.mark.parametrize("method", ["wrist-joint", "axis"])
def test_wrist_crossings_keep_the_position_exact_and_report_the_true_deviation(method: str) -> None:
    traj = plan(NEAR_MISS, method=method)
    pos, ori = _independent_deviation(traj, NEAR_MISS)
    assert pos.max() < 1e-9  # TCP on the line everywhere, crossing included
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    assert crossing.method == method and crossing.config_before != crossing.config_after
    assert 0.01 < math.degrees(ori.max()) < 2.0  # it did deviate, within the task's tolerance
    assert crossing.details.max_orientation_error_deg == pytest.approx(math.degrees(ori.max()), abs=1e-6)
    assert traj.metrics.max_orientation_error_deg == pytest.approx(math.degrees(ori.max()), abs=1e-6)


@pytest.mark.parametrize("method", ["wrist-joint", "axis"])
def test_crossing_seams_are_c1(method: str) -> None:
    from singplan.planning.orchestration.move_plan import plan_move as _plan_move  # the joint map before timing

    task = load_task(NEAR_MISS).with_method(method)
    robot = load_task_robot(task)
    q0 = np.radians(task.start_joints_deg)
    pm = _plan_move(robot, task, 0, task.moves[0], robot.fk(q0), q0, candidates(method, task.moves[0])[0])
    _assert_c1(pm.jmap, next(p for p in pm.jmap.parts if p.kind in ("blend", "axis")))


def _assert_c1(jmap, part) -> None:  # type: ignore[no-untyped-def]
    """One-sided slopes of the joint map agree at both seams of a crossing part (to 0.5 %)."""
    h = 1e-6
    for u in (part.u0, part.u1):
        if u in (0.0, 1.0):
            continue
        q = jmap.evaluate(np.array([u - h, u, u + h]))
        left, right = (q[1] - q[0]) / h, (q[2] - q[1]) / h
        assert np.max(np.abs(left - right)) <= 0.005 * max(1.0, float(np.max(np.abs(left)))), (u, left, right)


def test_auto_prefers_a_crossing_and_reports_the_runner_up() -> None:
    traj = plan(NEAR_MISS)
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    alternatives = crossing.details.alternatives
    assert crossing.method in ("wrist-joint", "axis")
    feasible = [a for a in alternatives if a.feasible]
    assert feasible[0].method == crossing.method
    assert feasible[0].duration_s == pytest.approx(traj.duration_s)
    exact = next(a for a in alternatives if a.method == "exact")
    # the swing costs exact tracking time: its duration, or the bound that spared timing it, is longer
    assert (exact.duration_s if exact.feasible else exact.at_least_s) > traj.duration_s


def _shoulder_near_miss(miss_m: float) -> dict:
    """An IRB 2400 LIN passing ``miss_m`` beside axis 1 (wrist centre over the base)."""
    robot = load_robot("abb_irb2400", tool=pin.SE3(np.eye(3), np.array([0, 0, 0.1])))

    def wrist_x(q2: float) -> float:
        return float(robot.wrist_center(np.array([0.0, q2, 0.3, 0.5, 0.6, 0.2]))[0])

    lo, hi = -1.7, 0.0  # bisect q2 so the wrist centre sits on axis 1
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if (wrist_x(lo) > 0) == (wrist_x(mid) > 0) else (lo, mid)
    q_mid = np.array([0.0, 0.5 * (lo + hi), 0.3, 0.5, 0.6, 0.2])
    T = robot.fk(q_mid)
    side = np.array([0.0, miss_m, 0.0])
    start = pin.SE3(T.rotation, T.translation - np.array([0.1, 0, 0]) + side)
    sols = solve_all(robot, start, seed=q_mid)
    q0 = sols.nearest(q_mid)
    return {"robot": "abb_irb2400", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": list(np.degrees(q0))},
            "moves": [{"lin": {"to": {"xyz": list(T.translation + np.array([0.1, 0, 0]) + side),
                                      "rpy_deg": list(np.degrees(pin.rpy.matrixToRpy(T.rotation)))}}}],
            "singularity": {"method": "axis", "position_tolerance_mm": 2.0}}


@pytest.mark.parametrize("miss_m", [0.0002, 0.001])
def test_axis_at_the_shoulder_keeps_the_orientation_and_leaves_the_path_by_about_the_miss(miss_m: float) -> None:
    doc = _shoulder_near_miss(miss_m)
    traj = plan(parse_task(doc))
    crossing = [s for s in traj.segments if s.kind == "crossing"]
    assert [(s.singularity, s.method) for s in crossing] == [("shoulder", "axis")]
    assert crossing[0].config_before[0] != crossing[0].config_after[0]  # front <-> back
    pos, ori = _independent_deviation(traj, doc)
    assert math.degrees(ori.max()) < 1e-6  # the kept component
    assert pos.max() * 1e3 == pytest.approx(miss_m * 1e3, rel=0.1)  # the minimised one: about the miss
    assert crossing[0].details.max_position_error_mm == pytest.approx(pos.max() * 1e3, abs=1e-6)
    assert traj.metrics.max_position_error_mm == pytest.approx(pos.max() * 1e3, abs=1e-6)
    assert traj.metrics.max_joint_speed_ratio <= 1.0 + 1e-9


def test_axis_seams_at_the_shoulder_are_c1() -> None:
    from singplan.planning.crossing.methods import Axis
    from singplan.planning.orchestration.move_plan import plan_move as _plan_move

    task = parse_task(_shoulder_near_miss(0.001))
    robot = load_task_robot(task)
    q0 = np.radians(task.start_joints_deg)
    pm = _plan_move(robot, task, 0, task.moves[0], robot.fk(q0), q0, Axis())
    part = next(p for p in pm.jmap.parts if p.kind == "axis")
    _assert_c1(pm.jmap, part)


def test_auto_keeps_exact_tracking_when_the_tolerance_is_tight() -> None:
    doc = _shoulder_near_miss(0.0002)
    doc["singularity"] = {"method": "auto", "position_tolerance_mm": 0.01}
    with pytest.raises(PlanningError, match="no method could plan it") as info:
        plan(parse_task(doc))
    # exact breaks a joint limit here and axis breaks the tolerance: each says so with its figures
    text = str(info.value)
    assert re.search(r"exact[^:]*: following the path with the full pose drives joint_5 to 120\.\d+ deg "
                     r".*outside its limits \[-120\.0, 120\.0\] deg", text), text
    assert re.search(r"axis: the crossing in the shoulder zone deviates 0\.2\d* mm / \d\.\d+ deg .*"
                     r"over the tolerance 0\.01 mm / 5 deg", text), text


@pytest.mark.parametrize("method", ["dls", "average"])
def test_baselines_leave_the_path_and_say_so(method: str) -> None:
    """Refused for the deviation itself: an acceleration limit the baselines' abrupt joints can keep
    leaves the tolerance (0.01 mm / 2 deg) as the only thing they break."""
    doc = yaml.safe_load(NEAR_MISS.read_text())
    doc["limits"]["acceleration"] = 1000.0
    with pytest.raises(SingularityError) as info:
        plan(parse_task(doc), method=method)
    found = re.search(r"move 0 \(lin\): the crossing in the wrist zone deviates (\d+\.\d+) mm / (\d+\.\d+) deg "
                      r"at s = [\d.]+ mm along the path .*, over the tolerance 0\.01 mm / 2 deg", str(info.value))
    assert found, str(info.value)
    assert float(found.group(1)) > 0.01  # [mm]: over the tolerance (up to 11 mm)
    assert (info.value.move, info.value.kind) == (0, "wrist") and info.value.s_m > 0.0


def test_ptp_jumps_only_the_span_the_tracking_cannot_follow() -> None:
    """A near miss is tracked in full before ptp jumps: its jump spans two neighbouring tracked
    samples around the closest point, so it keeps even a 0.01 mm tolerance, and still stops at rest
    on both sides (the time a controller's PTP loses)."""
    doc = yaml.safe_load(NEAR_MISS.read_text())
    doc["limits"]["acceleration"] = 1000.0
    (crossing,) = plan(parse_task(doc), method="ptp").metrics.crossings
    assert crossing.method == "ptp" and crossing.figures.changes_branch
    assert crossing.figures.max_position_error_mm < 0.01  # [mm], the tolerance
    assert crossing.figures.time_lost_s > 0.1  # [s]: two stops


def test_summary_tabulates_what_auto_compared() -> None:
    """One row per candidate: its move time (or the least it can have, not timed), the deviation of
    its crossings, and why it was not chosen; the rule named with its setting."""
    from singplan.outputs.summary import summary

    task = load_task(NEAR_MISS)
    text = summary(plan(task), task)
    assert "auto chose axis (a crossing that uses its whole tolerance counts 3 % slower, " \
           "singularity.deviation_cost_percent):" in text, text
    rows = {line.split()[0]: line for line in text.splitlines()[4:] if line.startswith("          ")}
    assert re.search(r"axis +1\.032 s +0\.000 mm / 0\.122 deg +chosen", rows["axis"]), text
    assert re.search(r"exact +>= 1\.748 s +0\.000 mm / 0\.000 deg +not timed: cannot win", rows["exact"]), text
    assert re.search(r"null-space +- +- +infeasible: null-space acts only where", rows["null-space"]), text


def test_a_method_comparing_its_own_variants_is_not_called_auto() -> None:
    """Asked for wrist-joint, the table is wrist-joint's choice among its windows (auto chose nothing)."""
    from singplan.outputs.summary import summary

    task = load_task(EXAMPLES / "kuka_program.yaml")
    text = summary(plan(task, method="wrist-joint"), task)
    assert "wrist-joint (its variants) chose wrist-joint window x" in text and "auto chose" not in text, text

"""auto's shared work: one tracking per move, one timing per distinct joint map, deviations measured once,
and the axis method's warm-started solves equal to cold ones; the choices stay those of each method alone."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from singplan.errors import PlanningError
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import load_robot
from singplan.planning.crossing.methods import Axis
from singplan.planning.crossing.registry import candidates
from singplan.planning.orchestration import checks, move_plan, planner, targets
from singplan.planning.path.cartesian import sample_deviations
from singplan.planning.path.jointmap import axis_solve, hermite
from singplan.results import build
from singplan.results.plan import plan
from singplan.task.load import load_task, parse_task

NEAR_MISS = Path(__file__).resolve().parents[1] / "examples" / "abb_near_miss_auto.yaml"


def _shoulder_near_miss() -> dict[str, Any]:
    """An IRB 2400 LIN passing 5 mm beside axis 1 (built as in tests/test_crossing.py), under auto: exact
    plans it (the wrist swings within its limits), so every candidate gets timed."""
    robot = load_robot("abb_irb2400", tool=pin.SE3(np.eye(3), np.array([0, 0, 0.1])))
    wrist = [0.3, -0.8, 0.1]
    lo, hi = -1.7, 0.0  # bisect q2 so the wrist centre sits on axis 1
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        x_lo, x_mid = (float(robot.wrist_center(np.array([0.0, v, 0.3, *wrist]))[0]) for v in (lo, mid))
        lo, hi = (mid, hi) if (x_lo > 0) == (x_mid > 0) else (lo, mid)
    q_mid = np.array([0.0, 0.5 * (lo + hi), 0.3, *wrist])
    T = robot.fk(q_mid)
    side = np.array([0.0, 0.005, 0.0])
    q0 = solve_all(robot, pin.SE3(T.rotation, T.translation - np.array([0.1, 0, 0]) + side), seed=q_mid).nearest(q_mid)
    return {"robot": "abb_irb2400", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": list(np.degrees(q0))},
            "moves": [{"lin": {"to": {"xyz": list(T.translation + np.array([0.1, 0, 0]) + side),
                                      "rpy_deg": list(np.degrees(pin.rpy.matrixToRpy(T.rotation)))}}}],
            "singularity": {"method": "auto", "position_tolerance_mm": 2.0}}


def test_auto_tracks_each_stretch_of_the_move_once(monkeypatch: pytest.MonkeyPatch) -> None:
    stretches: list[tuple[float, bytes, bool, int]] = []
    real_track = move_plan.track

    def counting_track(*args: Any, **kwargs: Any) -> Any:
        # a stretch: where it starts (the grid's first point) and from which joints, held zones coarse or in full
        stretches.append((float(args[2][0]), args[3].tobytes(), kwargs.get("hold") is None, len(args[2])))
        return real_track(*args, **kwargs)

    monkeypatch.setattr(move_plan, "track", counting_track)
    task = load_task(NEAR_MISS)
    traj = plan(task)
    assert len(candidates("auto", task.moves[0])) >= 5
    assert stretches.count(stretches[0]) == 1 and stretches[0][0] == 0.0  # the move's start: once, not per candidate
    assert len(set(stretches)) == len(stretches)
    assert any(s.kind == "crossing" for s in traj.segments)


def test_auto_picks_and_reports_what_each_candidate_gives_alone() -> None:
    """Every candidate is listed: a timed one with the very duration it gives planned alone, one
    not timed with a bound that it does not beat alone and that the chosen one already meets,
    an infeasible one with a reason it also fails with alone."""
    task = load_task(NEAR_MISS)
    traj = plan(task)
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    listed = {(a.method, a.variant): a for a in crossing.details.alternatives}
    methods = candidates("auto", task.moves[0])
    assert set(listed) == {(m.name, m.variant) for m in methods}
    kinds = {"timed": 0, "untimed": 0, "infeasible": 0}
    for method in methods:
        entry = listed[(method.name, method.variant)]
        try:
            alone: float | None = plan(task, method=method).duration_s
        except PlanningError:
            alone = None
        if entry.feasible:
            kinds["timed"] += 1
            assert alone == entry.duration_s, (method.name, method.variant)
        elif entry.feasible is None:
            kinds["untimed"] += 1
            assert entry.at_least_s >= traj.duration_s
            assert alone is None or alone >= entry.at_least_s, (method.name, method.variant)
        else:
            kinds["infeasible"] += 1
            assert alone is None, (method.name, method.variant, entry.reason)
    assert crossing.method == crossing.details.alternatives[0].method
    assert kinds["timed"] >= 1 and kinds["untimed"] >= 1, kinds  # the bound spared some timing here


def test_a_candidate_with_an_earlier_ones_joint_map_is_not_timed_again(monkeypatch: pytest.MonkeyPatch) -> None:
    timed: list[int] = []
    real_timed = planner._timed

    def counting_timed(*args: Any, **kwargs: Any) -> Any:
        timed.append(1)
        return real_timed(*args, **kwargs)

    monkeypatch.setattr(planner, "_timed", counting_timed)
    task = parse_task(_shoulder_near_miss())
    crossing = next(s for s in plan(task).segments if s.kind == "crossing")
    assert crossing.singularity == "shoulder"
    durations = {(a.method, a.variant): a.duration_s for a in crossing.details.alternatives}
    windows = [key for key in durations if key[0] == "wrist-joint"]
    assert len(windows) == 3 and all(durations[key] == durations[("exact", "")] for key in windows)
    # at a shoulder zone wrist-joint hands the zone to exact: its three windows take exact's timing
    assert len(timed) <= len(candidates("auto", task.moves[0])) - 3


def test_the_trajectory_reuses_the_deviations_measured_when_the_move_was_checked(
        monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[np.ndarray] = []  # the path parameters of the samples measured
    real = sample_deviations

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(np.array(args[2]))
        return real(*args, **kwargs)

    monkeypatch.setattr(checks, "sample_deviations", counting)
    monkeypatch.setattr(build, "sample_deviations", counting)
    planned = planner.plan_moves(load_task(NEAR_MISS), "axis")
    traj = plan(load_task(NEAR_MISS), method="axis")
    pm, tm = planned.moves[0], planned.timed[0]
    # the output samples once per plan: the check; the record reused it (the other calls measure
    # the crossing's own reference samples before timing: checks.refusal)
    assert sum(np.array_equal(u, tm.u) for u in calls) == 1 + 1
    crossing_u = np.concatenate([part.u for c in pm.crossings for part in c.parts])
    assert all(np.array_equal(u, crossing_u) for u in calls if not np.array_equal(u, tm.u))
    assert pm.deviations is not None
    pos, ori = real(planned.robot, pm.piece, tm.u, tm.q)
    assert traj.metrics.max_position_error_mm == pytest.approx(pos.max() * 1e3, rel=1e-12, abs=1e-15)
    assert traj.metrics.max_orientation_error_deg == pytest.approx(np.degrees(ori.max()), rel=1e-12)
    other = tm.q.copy()
    other[len(other) // 2] += 1e-3
    assert pm.deviations.of(tm.u, tm.q) is not None and pm.deviations.of(tm.u, other) is None


@pytest.mark.parametrize("dense", [True, False])
def test_axis_warm_started_solves_equal_cold_ones(dense: bool) -> None:
    task = load_task(NEAR_MISS).with_method("axis")
    robot = targets.load_task_robot(task)
    q0 = np.radians(task.start_joints_deg)
    pm = move_plan.plan_move(robot, task, 0, task.moves[0], robot.fk(q0), q0, Axis())
    part = next(p for p in pm.jmap.parts if p.kind == "axis")
    if not dense:  # the part as the method gives it before sampling: its two ends
        part = replace(part, u=part.u[[0, -1]], q=part.q[[0, -1]])
    rng = np.random.default_rng(7)
    u = np.sort(rng.uniform(part.u0, part.u1, 60))
    warm = pm.jmap.solve_axis(part, u)
    blend, T = hermite(part, u), pm.jmap.poses(u)
    cold = np.array([axis_solve(robot, blend[k], T[k], part.axis, part.exact)[0] for k in range(len(u))])  # one by one
    assert np.max(np.abs(warm - cold)) < 1e-11  # the same solutions, to the solve's own tolerance
    assert np.max(np.abs(warm - blend)) > 1e-4  # and not the blend itself: the solve moved the joints


def test_no_plan_names_each_variant_and_gives_each_reason_once() -> None:
    """The refusal of a move no method plans: a reason several methods (or wrist-joint windows) met is
    written once after their names, the move not repeated inside it (it was ~2 KB on an ABB wrist LIN)."""
    from singplan.planning.orchestration.select import Failure, no_plan

    wall = "move 0 (lin): following the path with the full pose drives joint_5 to -120.01 deg"
    failures = [Failure(0, "exact", "", PlanningError(wall)),
                *(Failure(k, "wrist-joint", f"window x{w:g}", PlanningError(wall))
                  for k, w in ((1, 1), (2, 1.5), (3, 2))),
                Failure(4, "axis", "", PlanningError(wall)),
                Failure(5, "null-space", "", PlanningError("move 0 (lin): null-space finds no joint motion"))]
    text = str(no_plan(0, "lin", failures))
    assert text == ("move 0 (lin): no method could plan it: exact, wrist-joint (window x1, window x1.5, window x2), "
                    "axis: following the path with the full pose drives joint_5 to -120.01 deg; "
                    "null-space: null-space finds no joint motion")
    apart = [Failure(0, "wrist-joint", "window x1", PlanningError(wall)),
             Failure(1, "wrist-joint", "window x1.5", PlanningError("move 0 (lin): over the tolerance"))]
    assert str(no_plan(0, "lin", apart)) == ("move 0 (lin): no method could plan it: wrist-joint (window x1): "
                                            "following the path with the full pose drives joint_5 to -120.01 deg; "
                                            "wrist-joint (window x1.5): over the tolerance")

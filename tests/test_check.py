"""``singplan check`` against ``singplan plan`` on tasks written from outside (tests/singular_battery.py).

Wherever some crossing method plans a task, check exits 0 and lists the zones; its stopping distance
is at or above every plan's, move by move. The battery's tasks pass exactly through (or a small
joint offset past) wrist, shoulder and elbow singularities found as roots of Pinocchio's Jacobian
determinant, on bundled arms and on example-robot-data's UR5 and UR10, as LINs and CIRCs.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.errors import SingplanError
from singplan.kinematics.robot import load_robot
from singplan.outputs import documents
from singplan.results.detect import MoveZones, detect
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory
from singplan.task.load import parse_task
from tests.cli_helpers import run_cli

from .singular_battery import SingularTask, battery

METHODS = ("auto", "exact", "wrist-joint", "axis", "null-space", "dls", "average", "ptp")


def _check(mapping: dict[str, Any], tmp_path: Path) -> tuple[int, str, str]:
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(mapping))
    return run_cli("check", path)


def _plans(mapping: dict[str, Any], methods: tuple[str, ...]) -> dict[str, Trajectory]:
    """The plans of the methods that plan the task."""
    out = {}
    for method in methods:
        try:
            out[method] = plan(parse_task(mapping), method=method)
        except SingplanError:
            continue
    return out


def _per_move_stopping_m(traj: Trajectory) -> list[float]:
    d = traj.samples["stopping_distance_m"]
    return [float(d[round(m.t0 / traj.period):round(m.t1 / traj.period) + 1].max()) for m in traj.moves]


def _holds(task: SingularTask, tmp_path: Path, methods: tuple[str, ...]) -> int:
    """check exits 0 when some method plans; each plan's per-move stopping distance is within the
    bound of that move. Returns how many methods planned."""
    code, out, err = _check(task.mapping, tmp_path)
    plans = _plans(task.mapping, methods)
    if plans:
        assert code == 0, f"{task.name}: check exits {code} ({err.strip()}) but {sorted(plans)} plan"
        found = detect(parse_task(task.mapping))
        assert f"{sum(len(m.zones) for m in found)} singular zone(s)" in out
        for method, traj in plans.items():
            for k, (planned, move) in enumerate(zip(_per_move_stopping_m(traj), found, strict=True)):
                assert planned <= move.stopping.bound_m, (
                    f"{task.name} {method} move {k}: planned {planned * 1e3:.3f} mm over the bound "
                    f"{move.stopping.bound_m * 1e3:.3f} mm")
    else:  # 3 where every method is refused before timing; a refusal only the timed samples show check cannot see
        assert code in (0, 3), err
        if code == 3 and out:  # (no text: a path no method can follow, refused before any report)
            assert "no bound" in out and "at most" not in out  # no plan: no figure (a bound of 0 mm was printed)
    return len(plans)


_QUICK = battery(3, arms=("abb_irb2400", "erd:ur5"), kinds=("wrist", "shoulder"), misses_deg=(0.0,))


@pytest.mark.parametrize("task", _QUICK, ids=[t.name for t in _QUICK])
def test_check_exits_0_wherever_a_method_plans_and_bounds_the_stopping_distance(task: SingularTask,
                                                                                 tmp_path: Path) -> None:
    # a method plans every one of these hits (auto or dls: 1 of the 2 each, measured), so check's exit 0
    # is what is tested, not only its refusals
    assert _holds(task, tmp_path, ("auto", "dls")) >= 1


_ISSUE = battery(1, arms=("abb_irb2400",), kinds=("shoulder",), misses_deg=(0.0,))


@pytest.mark.parametrize("task", _ISSUE, ids=[t.name for t in _ISSUE])
def test_abb_shoulder_hits_that_plan_are_checked(task: SingularTask, tmp_path: Path) -> None:
    """The issue's case: LINs and CIRCs through the ABB's shoulder singularity, which check refused
    ("no continuous joint motion ... the inverse kinematics jumps") while several methods plan them."""
    assert _holds(task, tmp_path, ("auto", "exact", "wrist-joint")) >= 2
    (move,) = detect(parse_task(task.mapping))
    assert [z.kind for z in move.zones] == ["shoulder"]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12])
def test_the_whole_battery_every_method(seed: int, tmp_path: Path) -> None:
    """Every arm, kind, hit and near miss, LIN and CIRC; every method's plan against the bound."""
    tasks = battery(seed)
    assert len(tasks) >= 50
    planned = sum(_holds(task, tmp_path, METHODS) > 0 for task in tasks)
    assert planned >= len(tasks) // 2  # the battery is not vacuous: most of its tasks plan


def test_check_lists_zones_in_the_branch_the_planner_tracks() -> None:
    """A move through a wrist hit lists one wrist zone around the hit, as the planner's first stretch
    finds it (the zone the crossing methods are asked about)."""
    (task,) = battery(2, arms=("kuka_kr6_r900_2",), kinds=("wrist",), misses_deg=(0.0,), moves=("lin",), held=True)
    (move,) = detect(parse_task(task.mapping))
    assert isinstance(move, MoveZones) and move.kind == "lin"
    (zone,) = move.zones
    assert zone.kind == "wrist" and zone.u_entry < 0.5 < zone.u_exit
    assert zone.min_distance < 1e-6 and zone.u_closest == pytest.approx(0.5, abs=1e-3)
    traj = plan(parse_task(task.mapping))
    (crossing,) = [s for s in traj.segments if s.kind == "crossing"]
    assert crossing.singularity == "wrist"


def test_a_path_out_of_reach_is_exit_3_for_check_and_plan(tmp_path: Path) -> None:
    (task,) = battery(4, arms=("abb_irb2400",), kinds=("wrist",), misses_deg=(0.0,), moves=("lin",))
    mapping = {**task.mapping, "moves": [{"lin": {"to": {"xyz": [3.0, 0.0, 1.0]}}}]}
    code, _, err = _check(mapping, tmp_path)
    assert code == 3 and "leaves the workspace" in err
    assert not _plans(mapping, METHODS)


def test_the_bound_holds_for_a_flown_program(tmp_path: Path) -> None:
    """Fly-by corners superpose two moves' motions: the corner's figure is bounded too."""
    example = Path(__file__).resolve().parents[1] / "examples" / "flyby_pick_place.yaml"
    found = detect(example)
    traj = plan(example)
    planned = _per_move_stopping_m(traj)
    assert all(p <= m.stopping.bound_m for p, m in zip(planned, found, strict=True))
    assert np.max(planned) > 0.05  # a real figure, not a trivial one


def _check_json(mapping: dict[str, Any], tmp_path: Path) -> tuple[int, dict[str, Any], str]:
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(mapping))
    code, out, err = run_cli("check", path, "--json")
    document = json.loads(out)
    jsonschema.validate(document, documents.schema("check"))
    return code, document, err


def _past_joint_5() -> dict[str, Any]:
    """An ABB LIN no method plans, without a singular zone: the tool tilts 20 deg about its y axis
    from joint_5 at 110 deg, so the full pose drives joint_5 past its 120 deg limit."""
    robot = load_robot("abb_irb2400")
    q = [0.0, 10.0, 20.0, 0.0, 110.0, 0.0]
    T = robot.fk(np.radians(q))
    R = T.rotation @ pin.exp3(np.array([0.0, np.radians(20.0), 0.0]))
    to = {"xyz": [float(v) for v in T.translation + np.array([0.0, 0.0, -0.05])],
          "rpy_deg": [float(v) for v in np.degrees(pin.rpy.matrixToRpy(R))]}
    return {"robot": "abb_irb2400", "start": {"joints_deg": q}, "moves": [{"lin": {"to": to}}]}


def test_a_move_no_method_plans_has_no_bound_and_is_exit_3(tmp_path: Path) -> None:
    """No joint path of any method stays in the limits: no plan, so no bound (0 mm was printed, exit 0)."""
    mapping = _past_joint_5()
    assert not _plans(mapping, ("auto",))
    code, out, err = _check(mapping, tmp_path)
    assert code == 3, out
    assert "stopping distance: no bound: move 0 (lin) has no plan" in out and "at most" not in out
    assert "drives joint_5 to 120." in err and "outside its limits" in err
    code, document, _ = _check_json(mapping, tmp_path)
    assert (code, document["ok"], document["exit_code"]) == (3, False, 3)
    (move,) = document["moves"]
    assert move["stopping_distance_bound_mm"] is None and "joint_5" in move["no_plan"]
    assert document["error"] == move["no_plan"]


def test_a_move_whose_every_path_collides_is_exit_3(tmp_path: Path) -> None:
    """A wall across an ABB LIN: plan refuses it (exit 3); check said ok with a bound."""
    mapping = {"robot": "abb_irb2400", "tool": {"xyz": [0, 0, 0.15]},
               "start": {"pose": {"xyz": [1.0, 0.2, 0.8], "rpy_deg": [180, 10, 0]}, "config": "F U N"},
               "moves": [{"lin": {"to": {"xyz": [1.0, -0.2, 0.8]}, "speed": 0.5}}],
               "cell": [{"name": "wall", "box": {"size": [0.1, 0.1, 0.6]}, "xyz": [1.0, 0.0, 0.8]}],
               "collision": {"clearance_mm": 5}}
    with pytest.raises(SingplanError, match="wall") as planned:
        plan(parse_task(mapping))
    assert planned.value.exit_code == 3
    code, out, err = _check(mapping, tmp_path)
    assert code == 3 and "collides: link_4 and wall" in out and "no bound" in out
    assert re.search(r"link_\d and wall are [\d.]+ mm into each other at s = [\d.]+ mm", err), err
    code, document, _ = _check_json(mapping, tmp_path)
    assert (code, document["ok"]) == (3, False) and "wall" in document["moves"][0]["no_plan"]


def test_a_wrist_lin_no_method_plans_has_no_bound(tmp_path: Path) -> None:
    """The trial's task (an ABB LIN through a wrist zone, every method past joint_5's limit near the end):
    check printed 'at most 0.000 mm' and exited 0 while plan exits 3."""
    mapping = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
               "moves": [{"lin": {"to": {"xyz": [1.2, 0, 1.0], "rpy_deg": [0, 0, 0]}}}]}
    code, out, err = _check(mapping, tmp_path)
    assert code == 3 and "1 singular zone(s)" in out and "move 0 (lin) wrist" in out
    assert "no bound" in out and "at most" not in out
    assert "no method could plan it" in err and "wrist-joint (window x1" in err and "joint_5" in err

"""Fly-by corners (``blend_mm``): task rules, the blend geometry, the chain's C1 seams, timing
through the corner, reporting of reduced radii, and the independent checker on several arms."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from singplan.cli import main
from singplan.errors import TaskError
from singplan.kinematics.robot import load_robot
from singplan.planning.orchestration import planner as planner_module
from singplan.planning.orchestration.blending import RAMPS, CrossingMemo, Ramp, corners, ramps, side_of
from singplan.planning.orchestration.chain import chain_map
from singplan.planning.orchestration.planner import plan_moves
from singplan.results.metrics import BlendFigures
from singplan.results.plan import plan, trajectory_of
from singplan.results.trajectory import Trajectory, save
from singplan.task.load import parse_task

from .shared import PROGRAMS, require, run_checker

UR5_START = [-41.296046003, -78.35196501, 113.017645809, -124.665680799, -90.0, -41.296046003]  # TCP 0.45 -0.25 0.28
DOWN = [-180.0, 0.0, -90.0]


def _polyline(points: list[list[float]], blend_mm: float | list[float], speed: float = 0.5,
              **limits: Any) -> dict[str, Any]:
    """A UR5 task of LINs at constant orientation through ``points`` [m], each corner blended."""
    radii = blend_mm if isinstance(blend_mm, list) else [blend_mm] * (len(points) - 1)
    moves = []
    for k, p in enumerate(points):
        spec: dict[str, Any] = {"to": {"xyz": p, "rpy_deg": DOWN}, "speed": speed}
        if k < len(points) - 1 and radii[k]:
            spec["blend_mm"] = radii[k]
        moves.append({"lin": spec})
    return {"robot": "ur5", "tool": {"xyz": [0, 0, 0.1], "rpy_deg": [0, 0, 0]}, "start": {"joints_deg": UR5_START},
            "moves": moves, "singularity": {"method": "auto"},
            "limits": {"velocity_scale": 1.0, "acceleration": 5.0, **limits}, "output": {"period": 0.004}}


def _corner(traj: Trajectory, move: int) -> np.ndarray:
    """The programmed end point of a LIN move [m]."""
    target = traj.task.moves[move].to
    assert target is not None
    return np.asarray(target.xyz, dtype=float)


def _tcp(traj: Trajectory, ks: range) -> np.ndarray:
    robot = load_robot(traj.robot, tool=pin.SE3(np.eye(3), np.asarray(traj.tool["xyz"], dtype=float)))
    return robot.tcp_positions(traj.q[ks.start:ks.stop])


def _stop_to_stop(doc: dict[str, Any]) -> dict[str, Any]:
    flat = copy.deepcopy(doc)
    for move in flat["moves"]:
        next(iter(move.values())).pop("blend_mm", None)
    return flat


# --- task rules ----------------------------------------------------------------------------------

def test_a_negative_radius_is_bad_input_naming_the_move() -> None:
    doc = _polyline([[0.45, -0.25, 0.20], [0.45, -0.15, 0.20], [0.40, -0.15, 0.20]], [10, -20])
    with pytest.raises(TaskError, match=r"moves\[1\]\.lin\.blend_mm: must be at least 0 mm, got -20"):
        parse_task(doc)


def test_a_radius_on_the_last_move_is_bad_input() -> None:
    doc = _polyline([[0.45, -0.25, 0.20], [0.45, -0.15, 0.20]], 10)
    doc["moves"][1]["lin"]["blend_mm"] = 5
    with pytest.raises(TaskError, match=r"moves\[1\]\.lin\.blend_mm: the last move ends the task at rest"):
        parse_task(doc)


def test_the_public_negative_blend_exits_2_naming_moves_2(capsys: pytest.CaptureFixture[str]) -> None:
    require(PROGRAMS)
    assert main(["plan", str(PROGRAMS / "bad__blend_negative.yaml"), "-o", "/nonexistent/never"]) == 2
    assert "moves[2].lin.blend_mm" in capsys.readouterr().err.strip().splitlines()[-1]


def test_blend_mm_round_trips_through_the_validated_mapping() -> None:
    doc = _polyline([[0.45, -0.25, 0.20], [0.45, -0.15, 0.20], [0.40, -0.15, 0.20]], [10, 0])
    task = parse_task(doc)
    assert [m.blend_mm for m in task.moves] == [10.0, 0.0, 0.0]
    assert parse_task(task.to_mapping()) == task


# --- geometry and seams --------------------------------------------------------------------------

@given(st.floats(0.0, 1.0), st.floats(0.0, math.pi), st.sampled_from(RAMPS))
def test_superposed_straight_lines_stay_inside_the_sphere(v: float, angle: float, ramp: Ramp) -> None:
    """|-(1 - alpha) a + beta b| <= r for unit a, b at any angle: the ramps sum to at most 1."""
    alpha, beta = ramps(np.array([v]), ramp)
    a, b = np.array([1.0, 0.0, 0.0]), np.array([math.cos(angle), math.sin(angle), 0.0])
    offset = -(1.0 - alpha[0]) * a + beta[0] * b  # from the corner, radius 1
    assert np.linalg.norm(offset) <= 1.0 + 1e-12


def test_the_chain_is_c1_across_every_seam() -> None:
    """Joint slopes dq/dw just before and just after each seam agree (finite differences)."""
    doc = _polyline([[0.45, -0.25, 0.20], [0.45, -0.17, 0.22], [0.40, -0.12, 0.22]], 20)
    planned = plan_moves(parse_task(doc))
    blends = {b.move: b for b in planned.blends}
    chain = chain_map(list(planned.moves), blends)
    h = 1e-7
    for piece in chain.pieces[:-1]:
        w = piece.w1
        before = (chain.evaluate(np.array([w - h]))[0] - chain.evaluate(np.array([w - 2 * h]))[0]) / h
        after = (chain.evaluate(np.array([w + 2 * h]))[0] - chain.evaluate(np.array([w + h]))[0]) / h
        scale = max(float(np.max(np.abs(before))), 1e-9)
        assert float(np.max(np.abs(after - before))) <= 1e-3 * scale, (w, before, after)


# --- planned fly-by ------------------------------------------------------------------------------

@pytest.mark.parametrize("turn_deg", [30.0, 90.0, 150.0])
def test_a_blended_corner_stays_in_its_sphere_keeps_moving_and_saves_time(turn_deg: float) -> None:
    a = np.array([0.45, -0.25, 0.20])
    corner = a + np.array([0.0, 0.08, 0.0])
    turn = math.radians(turn_deg)
    b = corner + 0.08 * np.array([-math.sin(turn), math.cos(turn), 0.0])
    doc = _polyline([corner.tolist(), b.tolist()], 20)
    doc["start"] = {"pose": {"xyz": a.tolist(), "rpy_deg": DOWN}}
    traj = plan(parse_task(doc))
    blend = [s for s in traj.segments if s.kind == "blend"]
    assert len(blend) == 1 and blend[0].move == 0 and blend[0].details.radius_mm == 20.0
    k0, k1 = round(blend[0].t0 / traj.period), round(blend[0].t1 / traj.period)
    assert k1 - k0 >= 2
    far = np.linalg.norm(_tcp(traj, range(k0 + 1, k1)) - corner, axis=1)
    assert float(far.max()) <= 0.020 + 1e-6
    # it flies by: no sample of the corner is at rest (a step within amax period^2, the checker's rest)
    steps = np.max(np.abs(np.diff(traj.q[k0:k1 + 1], axis=0)), axis=1)
    assert float(steps.min()) > 3 * 5.0 * traj.period**2
    flat = plan(parse_task(_stop_to_stop(doc)))
    assert traj.duration_s < flat.duration_s


def test_a_radius_too_large_for_its_moves_is_reduced_and_reported() -> None:
    doc = _polyline([[0.45, -0.19, 0.20], [0.40, -0.19, 0.20], [0.40, -0.09, 0.20]], 500)
    doc["start"] = {"pose": {"xyz": [0.45, -0.25, 0.20], "rpy_deg": DOWN}}
    traj = plan(parse_task(doc))
    first, second = traj.metrics.blends
    assert first.radius_mm == pytest.approx(25.0, abs=1e-6)  # half of move 1's 50 mm
    assert "half of move 1" in first.reduced and first.flown
    # move 1 keeps 5 % of itself between its two corners: 0.45 x 50 mm is left for the second
    assert second.radius_mm == pytest.approx(22.5 * 0.999, abs=1e-6) and "no more room" in second.reduced
    seg = next(s for s in traj.segments if s.kind == "blend" and s.move == 0)
    assert isinstance(seg.details, BlendFigures) and seg.details.requested_mm == 500 and seg.details.reduced


def test_fly_by_with_a_jerk_limit_keeps_every_jerk_and_passes_the_checker(tmp_path: Path) -> None:
    doc = _polyline([[0.45, -0.19, 0.25], [0.45, -0.09, 0.28], [0.44, 0.01, 0.28]], 10, jerk=500.0)
    doc["start"] = {"joints_deg": UR5_START}
    traj = plan(parse_task(doc))
    assert traj.metrics.jerk.max_joint_jerk_ratio <= 1.0
    assert [s.kind for s in traj.segments].count("blend") == 2
    _check(tmp_path, doc, traj)


@pytest.mark.parametrize("kinds", [("ptp", "lin"), ("lin", "ptp"), ("ptp", "ptp"), ("circ", "lin")])
def test_every_pair_of_move_kinds_flies_by(tmp_path: Path, kinds: tuple[str, str]) -> None:
    targets = [[0.45, -0.15, 0.22], [0.38, -0.10, 0.22]]
    moves = []
    for kind, xyz in zip(kinds, targets, strict=True):
        spec: dict[str, Any] = {"to": {"xyz": xyz, "rpy_deg": DOWN}}
        if kind == "circ":
            spec["via"] = {"xyz": [0.47, -0.20, 0.22]}
        if kind != "ptp":
            spec["speed"] = 0.5
        moves.append({kind: spec})
    next(iter(moves[0].values()))["blend_mm"] = 20
    doc = _polyline([[0, 0, 0]], 0)
    doc.update(moves=moves, start={"pose": {"xyz": [0.45, -0.25, 0.22], "rpy_deg": DOWN}})
    traj = plan(parse_task(doc))
    assert [s.kind for s in traj.segments if s.move == 0][-1] == "blend"
    flat = plan(parse_task(_stop_to_stop(doc)))
    assert traj.duration_s < flat.duration_s
    _check(tmp_path, doc, traj)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["abb_irb2400__flyby_pick_place", "fanuc_lrmate200id__flyby_seam_lin_circ_lin",
                                  "kuka_kr6_r900_2__flyby_corner_near_wrist", "ur5__flyby_palletise"])
def test_the_public_fly_by_programs_pass_and_beat_stop_to_stop_by_20_percent(tmp_path: Path, name: str) -> None:
    require(PROGRAMS)
    expect = yaml.safe_load((PROGRAMS / "expect.yaml").read_text())[name]
    task = PROGRAMS / f"{name}.yaml"
    assert main(["plan", str(task), "-o", str(tmp_path), "--no-report", "--no-replay", "--quiet"]) == 0
    run = run_checker(task, tmp_path)
    assert run.returncode == 0 and "PASS" in run.stdout, run.stdout + run.stderr
    duration = float(yaml.safe_load((tmp_path / "trajectory.json").read_text())["metrics"]["duration_s"])
    assert duration <= expect["max_duration_s"]


def test_a_corner_next_to_a_null_space_pause_is_stopped_at_with_the_reason() -> None:
    require(PROGRAMS)
    doc = yaml.safe_load((PROGRAMS / "kuka_kr6_r900_2__nullspace_wrist_exact_hit.yaml").read_text())
    last = doc["moves"][-1]
    back = copy.deepcopy(last)
    spec = next(iter(back.values()))
    spec["to"]["xyz"][2] += 0.05
    next(iter(last.values()))["blend_mm"] = 10
    doc["moves"].append(back)
    traj = plan(parse_task(doc))
    note = traj.metrics.blends[0]
    assert not note.flown and "pauses on its path" in note.reduced
    assert not any(s.kind == "blend" for s in traj.segments)
    assert any(s.pause_s is not None for s in traj.segments)


def test_the_example_pick_and_place_flies_by_and_saves_a_fifth(tmp_path: Path) -> None:
    example = Path(__file__).resolve().parents[1] / "examples" / "flyby_pick_place.yaml"
    doc = yaml.safe_load(example.read_text())
    planned = plan_moves(parse_task(doc))
    assert all(b.jmap is not None and b.radius_m == pytest.approx(0.050) for b in planned.blends)
    traj = trajectory_of(planned)
    flat = plan(parse_task(_stop_to_stop(doc)))
    assert traj.duration_s <= 0.8 * flat.duration_s
    _check(tmp_path, doc, traj)


@pytest.mark.soak
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.floats(-0.06, 0.06), st.floats(-0.06, 0.06), st.sampled_from([0, 5, 10, 30])),
                min_size=2, max_size=4))
def test_random_blended_polylines_plan_pass_and_never_lose_time(tmp_path: Path,
                                                                steps: list[tuple[float, float, int]]) -> None:
    p = np.array([0.45, -0.25, 0.28])
    points, radii = [], []
    for dx, dy, r in steps:
        p = p + np.array([dx, dy, 0.0]) + np.array([0.0, 0.0, 0.01])
        points.append(p.round(4).tolist())
        radii.append(r)
    doc = _polyline(points, [*radii[:-1], 0])
    traj = plan(parse_task(doc))
    flat = plan(parse_task(_stop_to_stop(doc)))
    assert traj.duration_s <= flat.duration_s + traj.period
    _check(tmp_path / str(abs(hash(str(steps)))), doc, traj)


def _check(tmp_path: Path, doc: dict[str, Any], traj: Trajectory) -> None:
    tmp_path.mkdir(parents=True, exist_ok=True)
    task_file = tmp_path / "task.yaml"
    task_file.write_text(yaml.safe_dump(doc))
    run = run_checker(task_file, save(traj, tmp_path / "out"))
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.slow
@pytest.mark.parametrize("example, hold", [("so100_lin", True), ("panda_redundancy", False),
                                           pytest.param("panda_redundancy", True, marks=pytest.mark.soak)])
def test_five_and_seven_axis_arms_fly_by(tmp_path: Path, example: str, hold: bool) -> None:
    """Reduced-order and redundant arms: the corners flown, checked, and no slower than stopping."""
    doc = yaml.safe_load((Path(__file__).resolve().parents[1] / "examples" / f"{example}.yaml").read_text())
    if not hold:
        doc.pop("redundancy")  # minimum-norm joint velocity: the corner ends on the next move's joints
    for move in doc["moves"][:-1]:
        next(iter(move.values()))["blend_mm"] = 10
    traj = plan(parse_task(doc))
    assert all(b.flown for b in traj.metrics.blends)
    assert traj.duration_s < plan(parse_task(_stop_to_stop(doc))).duration_s
    _check(tmp_path, doc, traj)


FANUC_START = [-19.983106522, 6.301262855, -37.800889182, 0.0, -45.897847963, 19.983106522]


def _fanuc(targets: list[list[float]], radii: list[float], **limits: Any) -> dict[str, Any]:
    moves = [{"lin": {"to": {"xyz": xyz, "rpy_deg": [180.0, 0.0, 0.0]}, "speed": 0.4,
                      **({"blend_mm": r} if r else {})}} for xyz, r in zip(targets, radii, strict=True)]
    return {"robot": "fanuc_lrmate200id", "tool": {"xyz": [0, 0, 0.12], "rpy_deg": [0, 0, 0]},
            "start": {"joints_deg": FANUC_START}, "moves": moves,
            "limits": {"velocity_scale": 1.0, "acceleration": 5.0, **limits}, "output": {"period": 0.004}}


def test_a_move_too_short_for_a_sample_between_two_corners_stops_its_first_corner(tmp_path: Path) -> None:
    """1 mm between two 20 mm corners at 0.4 m/s: the move's own path would get no output sample."""
    doc = _fanuc([[0.33, -0.04, 0.25], [0.33, -0.039, 0.25], [0.25, -0.039, 0.25]], [20, 20, 0])
    traj = plan(parse_task(doc))
    first = traj.metrics.blends[0]
    assert not first.flown and "move 1's own path between its corners is shorter than one period" in first.reduced
    assert all(s.t1 > s.t0 for s in traj.segments) and traj.metrics.max_position_error_mm < 0.01
    _check(tmp_path, doc, traj)


SOAK_CORNER = {  # found by the soak: a 1 mm corner after a PTP, crossed within one 13.7 ms period
    "robot": "abb_irb2400", "start": {"joints_deg": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]},
    "moves": [{"lin": {"to": {"xyz": [0.94, 0.0, 1.4549999999999998], "rpy_deg": [0.0, 89.99999999999999, 0.0]}}},
              {"ptp": {"to": {"xyz": [1.1478491872788357, 0.0, 1.1746535363232182],
                              "rpy_deg": [180.0, 73.10655959784906, 180.0]}, "blend_mm": 1.0}},
              {"circ": {"via": {"xyz": [1.1553517183996715, 0.0, 1.2671686703789016]},
                        "to": {"xyz": [1.1407296233821331, 0.0, 1.4481962086251337],
                               "rpy_deg": [0.0, 88.38508244232, 0.0]}}}],
    "singularity": {"method": "auto"}, "limits": {"acceleration": 20.16531570767569},
    "output": {"period": 0.013662499686820893}}


@pytest.mark.parametrize("ramp", RAMPS)
def test_a_flown_corner_has_a_sample_inside_its_sphere(tmp_path: Path, ramp: Ramp,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A corner crossed within one output period has no sample to show it kept inside its sphere
    (the checker then holds its two neighbours to the sphere, and they are on the paths outside
    it): such a corner is stopped at, with the reason; a flown one has samples inside, all within."""
    monkeypatch.setattr(planner_module, "RAMPS", (ramp,))  # each ramp alone must keep the rule
    traj = plan(parse_task(SOAK_CORNER))
    (corner,) = traj.metrics.blends
    segment = next((seg for seg in traj.segments if seg.kind == "blend"), None)
    if corner.flown:
        assert segment is not None
        k0, k1 = round(segment.t0 / traj.period), round(segment.t1 / traj.period)
        assert k1 - k0 >= 2
        inner = _tcp(traj, range(k0 + 1, k1)) - np.asarray(SOAK_CORNER["moves"][1]["ptp"]["to"]["xyz"])
        assert np.max(np.linalg.norm(inner, axis=1)) <= 1e-3 + 1e-9
    else:
        assert segment is None and "within one output period" in corner.reduced
    _check(tmp_path, SOAK_CORNER, traj)


def test_a_jerk_limited_chain_that_loses_time_is_split_and_never_slower_than_stopping() -> None:
    doc = _fanuc([[0.33, -0.04, 0.25], [0.29, 0.0, 0.25], [0.21, 0.0, 0.25]], [5, 5, 0], jerk=5.0)
    traj = plan(parse_task(doc))
    flat = plan(parse_task(_stop_to_stop(doc)))
    assert traj.duration_s <= flat.duration_s
    for b in traj.metrics.blends:
        assert b.flown or "stopped here and the parts timed apart" in b.reduced


@pytest.mark.parametrize("radius_mm, second, reason", [
    (0.001, [0.33, -0.03, 0.25], "at or below the least radius flown"),
    (20.0, [0.33, -0.04, 0.25], "move 1 has no TCP travel to fly by in")])
def test_a_corner_that_cannot_be_flown_says_why(radius_mm: float, second: list[float], reason: str) -> None:
    doc = _fanuc([[0.33, -0.04, 0.25], second, [0.25, -0.04, 0.25]], [radius_mm, 0, 0])
    traj = plan(parse_task(doc))
    assert not traj.metrics.blends[0].flown and reason in traj.metrics.blends[0].reduced


def test_both_ramps_are_tried_and_the_faster_program_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    example = Path(__file__).resolve().parents[1] / "examples" / "flyby_pick_place.yaml"
    task = parse_task(yaml.safe_load(example.read_text()))
    alone = {}
    for ramp in RAMPS:
        monkeypatch.setattr(planner_module, "RAMPS", (ramp,))
        alone[ramp] = plan(task).duration_s
    monkeypatch.undo()
    traj = plan(task)
    assert traj.duration_s == min(alone.values())
    kept = {s.details.ramp for s in traj.segments if s.kind == "blend"}
    assert kept == {min(alone, key=lambda r: alone[r])}


def test_the_corners_crossings_found_once_for_every_ramp_are_the_same() -> None:
    """The crossings of each corner's sphere do not depend on the ramp shape: found for the first ramp
    and reused for the next (``CrossingMemo``), every corner is what it is found afresh."""
    planned = plan_moves(Path(__file__).resolve().parents[1] / "examples" / "flyby_pick_place.yaml")
    robot = planned.robot
    sides = [side_of(robot, pm.jmap, pm.piece is not None, pm.limits.tcp_speed_m_s) for pm in planned.moves]
    at_rest = [planner_module._at_rest(pm) for pm in planned.moves]
    requested = [m.blend_mm / 1e3 for m in planned.task.moves]
    memo = CrossingMemo()
    found = []
    for ramp in RAMPS:
        shared = corners(robot, sides, at_rest, requested, ramp, memo)
        fresh = corners(robot, sides, at_rest, requested, ramp)
        assert shared.keys() == fresh.keys() and any(b.jmap is not None for b in fresh.values())
        for i, blend in fresh.items():
            assert (shared[i].radius_m, shared[i].u_leave, shared[i].u_join, shared[i].note) == \
                (blend.radius_m, blend.u_leave, blend.u_join, blend.note)
        found.append(len(memo._found))
    assert found[0] > 0 and found[-1] == found[0]  # the later ramps found every crossing in the memo

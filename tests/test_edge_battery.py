"""Honest at the edges (issue 22): tasks written from outside, planned with every method, judged by
the independent checker; and the mechanisms that make them pass (the final gate, the TCP's own
speed, isolated candidates, auto's rule, zones that need a crossing, bounded tracking).

The battery's tasks come from :mod:`tests.edge_tasks` (seeded: wrist, shoulder and elbow hits and
near misses, LIN and CIRC, bundled arms and the example-robot-data UR5 / UR10). Its criteria: no
exit 1 (or any other crash), every exit 0 passes the checker, and with loose tolerances (50 mm,
45 deg) ``average`` and ``ptp`` plan wherever ``exact`` does. A small subset runs in the default
suite, 24 tasks under ``-m slow``, ``SINGPLAN_SOAK_EXAMPLES`` (default 96) under ``-m soak``;
``bench/edge_battery.py`` runs it in worker processes and docs/reliability.md has the figures.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
import yaml

from singplan.cli import main
from singplan.errors import MethodError, PlanningError, UnreachableError
from singplan.outputs.summary import summary
from singplan.planning.crossing.methods import Axis
from singplan.results.plan import plan
from singplan.task.load import load_task, parse_task

from .edge_tasks import LOOSE, METHODS, EdgeTask, edge_tasks, with_method
from .shared import check_in_process, checker_module

DATA = Path(__file__).resolve().parent / "data"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
LOOSE_METHODS = ("exact", "average", "ptp")


class Outcome(NamedTuple):
    code: int
    text: str
    failures: list[str]  # the checker's, for exit 0


def _run(task: dict[str, Any], folder: Path) -> Outcome:
    """``singplan plan`` of the task through the CLI in this process, and the checker's verdict."""
    folder.mkdir(parents=True)
    path = folder / "task.yaml"
    path.write_text(yaml.safe_dump(task, sort_keys=False))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["plan", str(path), "-o", str(folder / "out"), "--quiet", "--no-report", "--no-replay"],
                    out=out, err=err)
    failures = check_in_process(path, folder / "out") if code == 0 else []
    return Outcome(code, out.getvalue() + err.getvalue(), failures)


def _battery(cases: list[EdgeTask], methods: tuple[str, ...], tmp_path: Path) -> None:
    """Every method on every case, and exact / average / ptp at the loose tolerances: the criteria hold."""
    checker_module()  # skip (a user's clone) before planning anything
    broken: list[str] = []
    for case in cases:
        loose: dict[str, Outcome] = {}
        for method in methods:
            got = _run(with_method(case, method), tmp_path / case.name / method)
            if got.code not in (0, 3) or got.failures or "Traceback" in got.text:
                broken.append(f"{case.name} {method}: exit {got.code} {got.failures} {got.text[-300:]}")
        for method in LOOSE_METHODS:
            loose[method] = got = _run(with_method(case, method, loose=True), tmp_path / case.name / f"{method}-loose")
            if got.code not in (0, 3) or got.failures:
                broken.append(f"{case.name} {method} (loose): exit {got.code} {got.failures} {got.text[-300:]}")
        for method in ("average", "ptp"):
            if loose["exact"].code == 0 and loose[method].code != 0:
                broken.append(f"{case.name} {method} (loose): exit {loose[method].code} where exact plans: "
                              f"{loose[method].text[-300:]}")
    assert not broken, "\n".join(broken)


def test_a_few_tasks_written_from_outside_keep_the_contract(tmp_path: Path) -> None:
    cases = list(edge_tasks(seed=7, count=2))
    assert len(cases) == 2
    _battery(cases, ("auto", "axis", "ptp"), tmp_path)


@pytest.mark.slow
def test_tasks_written_from_outside_keep_the_contract_with_every_method(tmp_path: Path) -> None:
    _battery(list(edge_tasks(seed=1, count=24)), METHODS, tmp_path)


@pytest.mark.soak
def test_many_tasks_written_from_outside_keep_the_contract_with_every_method(tmp_path: Path) -> None:
    count = int(os.environ.get("SINGPLAN_SOAK_EXAMPLES", "96"))
    _battery(list(edge_tasks(seed=2, count=count)), METHODS, tmp_path)


def test_the_generated_tasks_are_what_they_say() -> None:
    """Each generated case meets its singularity as named: a hit within what exact goes through
    (0.003 deg, 2 um), a near miss within its range; the same seed gives the same tasks."""
    cases = list(edge_tasks(seed=3, count=6))
    assert [c.task for c in cases] == [c.task for c in edge_tasks(seed=3, count=6)]
    for c in cases:
        hit = c.shape.startswith("hit")
        limit = {"wrist": math.radians(2.0), "shoulder": 0.005, "elbow": math.radians(2.0)}[c.kind]
        assert c.closest <= (limit if not hit else {"shoulder": 3e-6}.get(c.kind, math.radians(0.004))), c
        assert parse_task(c.task).moves[0].kind == c.move


# -- the final gate and the TCP's own speed ---------------------------------------------------------

AXIS_SHOULDER = DATA / "fanuc_shoulder_circ_axis.yaml"


def test_max_tcp_speed_ratio_is_measured_as_the_checker_measures_it(tmp_path: Path) -> None:
    """axis across a shoulder near miss leaves the path; the TCP's speed on the samples stays under the
    programmed speed, and the metric agrees with the independent checker's to 1e-6."""
    task = yaml.safe_load(AXIS_SHOULDER.read_text())
    got = _run(task, tmp_path / "axis")
    assert got.code == 0 and not got.failures, got
    traj = plan(load_task(AXIS_SHOULDER))
    verify = checker_module()
    out = tmp_path / "axis" / "out"
    result = verify.Checker(task, json.loads((out / "trajectory.json").read_text()), out).run()
    assert traj.metrics.max_tcp_speed_ratio <= 1.0 + 1e-6
    assert traj.metrics.max_tcp_speed_ratio == pytest.approx(result["metrics"]["max_tcp_speed_ratio"], rel=1e-6)
    assert traj.metrics.to_json()["max_tcp_speed_ratio"] == traj.metrics.max_tcp_speed_ratio  # as the file writes it
    assert traj.samples["tcp_speed_ratio"].shape == traj.t.shape


def test_without_the_tcp_trace_the_gate_refuses_the_overspeed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The timing held only the path's progress to the programmed speed before; with that back, the
    TCP runs over it where axis leaves the path, and the plan is refused naming move and samples."""
    from singplan.planning.orchestration import move_plan

    monkeypatch.setattr(move_plan, "tcp_trace", lambda *args, **kwargs: None)
    with pytest.raises(PlanningError, match=r"move 0 \(circ\): the TCP runs at x1\.00\d+ its programmed speed "
                                            r"\(0\.068 m/s\) between the move's samples \d+ and \d+ at s = [\d.]+ mm"):
        plan(load_task(AXIS_SHOULDER))


def test_null_space_pieces_that_do_not_meet_are_bridged(tmp_path: Path) -> None:
    """The turn at a shoulder singular point ends 2 um off the pose (its tolerance), the path after
    it re-solves the position: a rest-to-rest bridge joins them instead of a jump (x1.06 acceleration)."""
    got = _run(yaml.safe_load((DATA / "kuka_shoulder_circ_hit_nullspace.yaml").read_text()), tmp_path / "ns")
    assert got.code == 0 and not got.failures, got


def test_without_the_bridge_the_seam_is_refused_naming_the_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """The candidate check measures a move timed in pieces across its seams: the jump the bridge
    removes breaks the acceleration limit, and the method alone is refused naming move and sample."""
    from singplan.planning.orchestration import stops

    monkeypatch.setattr(stops, "_with_bridges", lambda jmap, pieces, limits: pieces)
    with pytest.raises(PlanningError, match=r"move 0 \(circ\): its samples break the joint limits \(acceleration "
                                            r"x1\.06\d+\) near its sample \d+ \(t = [\d.]+ s into the move\) at s = "):
        plan(load_task(DATA / "kuka_shoulder_circ_hit_nullspace.yaml"))


@pytest.mark.parametrize("name", ["ur5_wrist_lin_trace_knot", "kuka_shoulder_circ_ptp_near_miss"])
def test_the_baselines_plan_the_soaks_finds_where_exact_does(name: str, tmp_path: Path) -> None:
    """Two tasks of the 120-task soak (50 mm / 45 deg): ``average`` refused a UR5 wrist LIN as "not
    controllable" (a trace point a rounding from a map sample made a zero-width TOPP-RA stage) and
    ``ptp`` jumped 90 mm off a KUKA shoulder CIRC's near miss (its jump spanned the coarse grid)."""
    task = yaml.safe_load((DATA / f"{name}.yaml").read_text())
    for method in LOOSE_METHODS:
        got = _run({**task, "singularity": {**task["singularity"], "method": method}}, tmp_path / method)
        assert got.code == 0 and not got.failures, (method, got)


# -- isolated candidates ----------------------------------------------------------------------------


def _numerical_failure(self: Axis, ctx: Any, zone: Any) -> Any:
    raise np.linalg.LinAlgError("SVD did not converge")


def test_a_method_that_fails_in_its_own_computation_is_infeasible_under_auto(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(Axis, "cross", _numerical_failure)
    traj = plan(load_task(EXAMPLES / "abb_near_miss_auto.yaml"))
    alternatives = traj.metrics.crossings[0].figures.alternatives
    axis = [a for a in alternatives if a.method == "axis"]
    assert axis and axis[0].feasible is False
    assert axis[0].reason == ("move 0 (lin): method axis failed in its own computation "
                              "(LinAlgError: SVD did not converge)")
    assert traj.metrics.crossings[0].method == "wrist-joint"


def test_a_method_that_fails_in_its_own_computation_alone_is_exit_3(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(Axis, "cross", _numerical_failure)
    with pytest.raises(MethodError) as info:
        plan(load_task(EXAMPLES / "abb_near_miss_auto.yaml"), method="axis")
    assert info.value.exit_code == 3 and info.value.move == 0 and info.value.method == "axis"
    assert info.value.cause == "LinAlgError: SVD did not converge"


# -- auto's rule ------------------------------------------------------------------------------------


def _auto(example: str, cost_percent: float | None) -> tuple[str, str, float]:
    doc = yaml.safe_load((EXAMPLES / example).read_text())
    if cost_percent is not None:
        doc["singularity"]["deviation_cost_percent"] = cost_percent
    task = parse_task(doc, EXAMPLES)
    traj = plan(task)
    return traj.metrics.crossings[0].method or "", summary(traj, task), traj.duration_s


def test_a_deviation_must_buy_time() -> None:
    """ABB near miss: axis and wrist-joint take 1.032 s; with no cost the first listed (wrist-joint,
    0.20 deg) wins the tie, with the default the one that turns the tool less (axis, 0.12 deg). UR5:
    wrist-joint saves 47 % for 1.0 deg of a 1.5 deg tolerance; at 200 % a whole tolerance costs
    more than that and exact (1.596 s, no deviation) is kept without timing the others."""
    assert _auto("abb_near_miss_auto.yaml", 0.0)[0] == "wrist-joint"
    method, text, _ = _auto("abb_near_miss_auto.yaml", None)
    assert method == "axis" and "counts 3 % slower" in text
    assert _auto("ur5_wrist_auto.yaml", None)[0] == "wrist-joint"
    method, text, duration = _auto("ur5_wrist_auto.yaml", 200.0)
    assert method == "exact" and duration == pytest.approx(1.596)
    # its bound (0.844 s) counted at 200 % of its 67 % share of the tolerance cannot beat exact's 1.596 s
    row = r"wrist-joint window x1\.5 +>= 0\.844 s +0\.000 mm / 1\.001 deg +not timed: cannot win"
    assert re.search(row, text), text


def test_deviation_cost_percent_is_checked_as_a_task_field() -> None:
    doc = yaml.safe_load((EXAMPLES / "abb_near_miss_auto.yaml").read_text())
    doc["singularity"]["deviation_cost_percent"] = -1
    with pytest.raises(Exception, match=r"singularity\.deviation_cost_percent: must be at least 0 %, got -1"):
        parse_task(doc)


# -- zones that need a crossing; bounded tracking ---------------------------------------------------


def test_wide_thresholds_make_no_crossing_where_no_singularity_is_near(tmp_path: Path) -> None:
    """Zone thresholds at their documented maxima (90 deg, 1000 mm): a LIN that stays 30 deg and more
    from every singularity is tracked with the full pose, no crossing marked; one that nearly meets
    the wrist singularity is crossed, and the crossing segment passes near it."""
    far = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 40, 0]},
           "moves": [{"lin": {"to": {"xyz": [0.95, 0.1, 1.1]}, "speed": 0.2}}],
           "singularity": {"method": "wrist-joint", "zone": {"wrist_deg": 90, "shoulder_mm": 1000, "elbow_deg": 90}}}
    got = _run(far, tmp_path / "far")
    assert got.code == 0 and not got.failures, got
    traj = plan(parse_task(far))
    assert [s.kind for s in traj.segments] == ["path"] and traj.metrics.max_orientation_error_deg < 0.01
    near = yaml.safe_load((EXAMPLES / "abb_near_miss_auto.yaml").read_text())
    near["singularity"] = {"method": "wrist-joint", "orientation_tolerance_deg": 45.0,
                           "zone": {"wrist_deg": 90, "shoulder_mm": 1000, "elbow_deg": 90}}
    got = _run(near, tmp_path / "near")
    assert got.code in (0, 3) and not got.failures, got


def test_a_path_leaving_the_workspace_bounds_its_all_branch_searches(monkeypatch: pytest.MonkeyPatch) -> None:
    """Random valid task 219 (an SO-101, no closed form) spent 75 s locating where its CIRC leaves the
    workspace: each refined sample past the edge searched every branch. Now the step into a lost
    sample is not refined and a tracked stretch makes at most 8 full searches."""
    from singplan.planning.path import tracking

    from .task_strategies import seeded_task

    calls: list[float] = []
    search = tracking.ik_numeric.all_branches

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1.0)
        return search(*args, **kwargs)

    monkeypatch.setattr(tracking.ik_numeric, "all_branches", counted)
    task = parse_task(seeded_task(219))
    with pytest.raises(UnreachableError, match=r"move 3 \(circ\): the path leaves the workspace at s = "):
        plan(task)
    cartesian = sum(m.kind != "ptp" for m in task.moves)
    assert len(calls) <= 8 * cartesian * 2  # at most 8 per tracked stretch, a stretch or two a move


def test_loose_tolerances_are_issue_22s() -> None:
    assert LOOSE == {"position_tolerance_mm": 50.0, "orientation_tolerance_deg": 45.0}

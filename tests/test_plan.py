"""End-to-end planning on the bundled demo task, checked with independent geometry."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.robot import load_robot
from singplan.results.plan import plan
from singplan.task.load import parse_task

from .conftest import ReplayServer

DEMO = Path(__file__).resolve().parents[1] / "singplan" / "demo_task.yaml"


@pytest.fixture(scope="module")
def demo():
    calls: list[tuple[int, int]] = []
    traj = plan(DEMO, progress=lambda done, total: calls.append((done, total)))
    return traj, calls


@pytest.fixture(scope="module")
def demo_cli(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """`singplan plan DEMO -o OUT` with every default output, run once: the folder and the summary printed."""
    folder = tmp_path_factory.mktemp("demo_cli") / "out"
    out = io.StringIO()
    assert main(["plan", str(DEMO), "-o", str(folder)], out=out) == 0
    return folder, out.getvalue()


def _robot_for(traj):
    return load_robot(traj.robot, tool=pin.SE3(np.eye(3), np.array(traj.tool["xyz"])))


def test_samples_are_uniform_and_progress_is_reported(demo) -> None:
    traj, calls = demo
    assert traj.t[0] == 0.0
    np.testing.assert_allclose(np.diff(traj.t), traj.period, atol=1e-12)
    assert calls == [(1, 2), (2, 2)]


def test_every_lin_sample_is_on_the_line_and_keeps_the_pose_outside_crossings(demo) -> None:
    traj, _ = demo
    robot = _robot_for(traj)
    task = yaml.safe_load(DEMO.read_text())
    q0 = np.radians(task["start"]["joints_deg"])
    a = robot.fk(q0)
    b_xyz = np.array(task["moves"][0]["lin"]["to"]["xyz"])
    lin = [s for s in traj.segments if s.move == 0]
    k0, k1 = round(lin[0].t0 / traj.period), round(lin[-1].t1 / traj.period)
    crossing = [(round(s.t0 / traj.period), round(s.t1 / traj.period)) for s in lin if s.kind == "crossing"]
    d = b_xyz - a.translation
    for k in range(k0, k1 + 1):
        T = robot.fk(traj.q[k])
        u = float(np.clip((T.translation - a.translation) @ d / (d @ d), 0, 1))
        assert np.linalg.norm(T.translation - (a.translation + u * d)) < 1e-8  # 0.01 um
        R_path = a.rotation  # the demo LIN keeps the orientation
        err = math.degrees(np.linalg.norm(pin.log3(R_path.T @ T.rotation)))
        inside = any(c0 <= k <= c1 for c0, c1 in crossing)
        assert err < (0.01 if not inside else 1.0)


def test_limits_hold_on_the_output_samples(demo) -> None:
    traj, _ = demo
    robot = _robot_for(traj)
    qd = np.diff(traj.q, axis=0) / traj.period
    qdd = np.diff(qd, axis=0) / traj.period
    assert np.all(np.abs(qd) <= robot.velocity_rad_s * (1 + 1e-9))
    assert np.all(np.abs(qdd) <= 10.0 * (1 + 1e-9))
    assert np.all(traj.q >= robot.lower_rad) and np.all(traj.q <= robot.upper_rad)
    p = np.array([robot.fk(q).translation for q in traj.q])
    tcp_speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / traj.period
    lin_end = round(next(s.t1 for s in reversed(traj.segments) if s.move == 0) / traj.period)
    assert tcp_speed[:lin_end].max() <= 0.25 * (1 + 1e-9)


def test_moves_start_and_end_at_rest_on_samples(demo) -> None:
    traj, _ = demo
    for move in (0, 1):
        segs = [s for s in traj.segments if s.move == move]
        for t in (segs[0].t0, segs[-1].t1):
            k = round(t / traj.period)
            assert abs(k * traj.period - t) < 1e-12
            for a, b in ((k - 1, k), (k, k + 1)):
                if a >= 0 and b < len(traj.t):
                    assert np.all(np.abs(traj.q[b] - traj.q[a]) <= 10.0 * traj.period**2 * (1 + 1e-9))


def test_the_through_crossing_is_reported(demo) -> None:
    traj, _ = demo
    kinds = [(s.kind, s.singularity) for s in traj.segments]
    assert kinds == [("pre", None), ("crossing", "wrist"), ("post", None), ("ptp", None)]
    crossing = traj.segments[1]
    assert (crossing.config_before, crossing.config_after) == ("F U F", "F U N")
    assert crossing.details.changes_branch and crossing.details.min_distance < math.radians(0.01)
    changes = [e for e in traj.events if e.type == "config_change"]
    assert len(changes) == 1 and crossing.t0 <= changes[0].t <= crossing.t1
    assert traj.metrics.crossings[0].method == "exact"


def test_outputs_follow_the_contract(demo_cli: tuple[Path, str]) -> None:
    folder, summary = demo_cli
    doc = json.loads((folder / "trajectory.json").read_text())
    for key in ("format", "robot", "urdf", "tip", "tool", "task", "joint_names", "period", "t", "q", "qd", "qdd",
                "segments", "events", "metrics"):
        assert key in doc
    assert doc["format"] == "singplan.trajectory/1" and Path(doc["urdf"]).is_absolute()
    for key in ("max_position_error_mm", "max_orientation_error_deg", "max_joint_speed_ratio",
                "max_joint_accel_ratio", "duration_s", "planning_time_s", "crossings"):
        assert key in doc["metrics"]
    assert parse_task(doc["task"]).robot == "kuka_kr6_r900_2"
    csv = (folder / "trajectory.csv").read_text().splitlines()
    assert csv[0] == "t," + ",".join(doc["joint_names"]) and len(csv) == len(doc["t"]) + 1
    assert "wrist zone " in summary and "(zone " not in summary  # exact: the crossing is the zone


def _variant(tmp_path: Path, edit) -> Path:
    task = yaml.safe_load(DEMO.read_text())
    edit(task)
    path = tmp_path / "variant.yaml"
    path.write_text(yaml.safe_dump(task))
    return path


def test_failed_plan_exits_3_and_leaves_no_folder(tmp_path: Path) -> None:
    def far(task):
        task["moves"][0]["lin"]["to"]["xyz"] = [3.0, 0.0, 0.5]

    err = io.StringIO()
    out_dir = tmp_path / "never"
    assert main(["plan", str(_variant(tmp_path, far)), "-o", str(out_dir)], out=io.StringIO(), err=err) == 3
    assert "move 0 (lin)" in err.getvalue() and "leaves the workspace" in err.getvalue()
    assert not out_dir.exists()
    assert not list(tmp_path.glob(".never*"))


def test_keep_refuses_the_configuration_change_and_stop_refuses_the_zone(tmp_path: Path) -> None:
    def keep(task):
        task["moves"][0]["lin"]["config"] = "keep"

    err = io.StringIO()
    assert main(["plan", str(_variant(tmp_path, keep)), "-o", str(tmp_path / "o")], out=io.StringIO(), err=err) == 3
    assert "keep" in err.getvalue() and "F U F" in err.getvalue()
    err = io.StringIO()
    code = main(["plan", str(DEMO), "-o", str(tmp_path / "o"), "--method", "stop"], out=io.StringIO(), err=err)
    assert code == 3 and "move 0 (lin): wrist singular zone" in err.getvalue()


def test_check_lists_the_zone_and_demo_writes_its_folder(tmp_path: Path, monkeypatch) -> None:
    out = io.StringIO()
    assert main(["check", str(DEMO)], out=out) == 0
    assert "1 singular zone" in out.getvalue() and "wrist" in out.getvalue()
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    assert main(["demo"], out=out) == 0
    assert (tmp_path / "singplan-demo" / "trajectory.json").is_file()


def test_report_is_self_contained_with_every_plot(demo_cli: tuple[Path, str], tmp_path: Path) -> None:
    page = (demo_cli[0] / "report.html").read_text()
    for key in ("joints", "speed", "distances", "deviation", "tcp", "stopping", "clearance"):
        assert f'id="plot-{key}"' in page
    assert page.count("<svg") == 7
    assert "<script" not in page and "src=" not in page and "href=\"http" not in page  # nothing to fetch
    assert "Crossings" in page and "wrist" in page
    assert main(["plan", str(DEMO), "-o", str(tmp_path / "bare"), "--no-report", "--quiet"], out=io.StringIO()) == 0
    assert not (tmp_path / "bare" / "report.html").exists()


def test_replay_is_written_self_contained_and_can_be_rebuilt_from_the_saved_trajectory(demo, demo_cli: tuple[Path, str],
                                                                                     tmp_path: Path) -> None:
    import singplan
    from singplan.results.trajectory import load

    folder = demo_cli[0]
    page = (folder / "replay.html").read_text()
    assert len(page.encode()) < 5_000_000  # the demo's replay stays small enough to mail around
    assert 'src="http' not in page and 'href="http' not in page and "<link" not in page  # nothing fetched
    assert "new MeshCat.Viewer" in page and "window.singplan = " in page and "__DATA__" not in page
    saved = load(folder)
    again, _ = demo  # plan(DEMO) in this process
    np.testing.assert_allclose(saved.q, again.q, atol=1e-12)  # trajectory.json round-trips
    assert [s.kind for s in saved.segments] == [s.kind for s in again.segments]
    out = io.StringIO()
    assert main(["replay", str(folder), "--html", str(tmp_path / "again.html")], out=out) == 0
    assert (tmp_path / "again.html").stat().st_size > 100_000
    assert singplan.replay(saved, html=tmp_path / "api.html").is_file()
    err = io.StringIO()
    assert main(["replay", str(tmp_path / "nowhere"), "--html", str(tmp_path / "x.html")], err=err) == 2
    assert "nowhere: no such trajectory.json" in err.getvalue()
    err = io.StringIO()
    assert main(["replay", str(folder)], err=err) == 2  # neither --html nor --serve
    assert "--serve" in err.getvalue()


def test_replay_serve_runs_a_live_meshcat_server_on_loopback_until_stopped(replay_server: ReplayServer) -> None:
    import urllib.request

    line = replay_server.line  # the server replays the demo (tests/conftest.py: planned_kuka)
    assert line.startswith("replay served at http://127.0.0.1:"), line + replay_server.errors()
    url = line.split()[3]
    with urllib.request.urlopen(url, timeout=20) as response:
        assert response.status == 200
        assert "meshcat" in response.read().decode().lower()
    out = replay_server.stop()
    assert replay_server.proc.returncode == 0 and "stopped" in out
    with pytest.raises(OSError):  # the meshcat server went with it
        urllib.request.urlopen(url, timeout=5)


@pytest.mark.slow  # a cold compile of every kernel in a fresh cache: ~10 s whatever the test does
def test_the_first_run_says_it_compiles_and_later_runs_use_the_disk_cache(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}  # an empty cache, as after an install

    def plan_once(out: str) -> str:
        run = subprocess.run([sys.executable, "-m", "singplan", "plan", str(DEMO), "-o", str(tmp_path / out),
                              "--no-report", "--no-replay"], env=env, capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr
        return run.stderr

    assert "compiling the planner's kernels" in plan_once("first")
    assert any((tmp_path / "cache").rglob("*.nbi"))
    assert "compiling" not in plan_once("second")

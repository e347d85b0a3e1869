"""Inverse dynamics along trajectories, limits.torque_scale, and arms without published dynamics."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.errors import TaskError
from singplan.kinematics import dynamics
from singplan.kinematics.dynamics import (
    central_differences,
    effort_limits_nm,
    has_inertias,
    no_dynamics_reason,
    span_differences,
    trajectory_torques,
)
from singplan.kinematics.robot import bundled_robots, load_robot
from singplan.results.plan import plan
from singplan.task.load import parse_task
from tests.cli_helpers import run_cli

from .shared import run_checker

# A UR5 PTP (shoulder pan 90 deg, arm raised) then a LIN; at 40 rad/s^2 the unconstrained timing
# drives the shoulder to ~0.9 of its 150 N m effort, so torque_scale 0.45 binds.
UR5_TASK: dict[str, Any] = {
    "robot": "ur5",
    "start": {"joints_deg": [0, -90, 90, -90, -90, 0]},
    "moves": [{"ptp": {"to": {"joints_deg": [90, -30, 30, -90, -90, 0]}}},
              {"lin": {"to": {"xyz": [0.3, 0.3, 0.4], "rpy_deg": [180, 0, 0]}, "speed": 1.0}}],
    "limits": {"acceleration": 40.0},
}


def _with_scale(scale: float) -> dict[str, Any]:
    return {**UR5_TASK, "limits": {**UR5_TASK["limits"], "torque_scale": scale}}


def _sine_samples(robot, count: int, period_s: float) -> np.ndarray:
    """Joint samples q (count, n) of a smooth motion inside the limits (seeded phases)."""
    rng = np.random.default_rng(7)
    mid, half = (robot.lower_rad + robot.upper_rad) / 2, (robot.upper_rad - robot.lower_rad) / 4
    phase = rng.uniform(0, 2 * np.pi, robot.n_joints)
    t = np.arange(count)[:, None] * period_s
    return mid + 0.8 * np.minimum(half, 1.5) * np.sin(2.0 * t + phase)


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_rnea_torques_match_mass_matrix_and_nonlinear_effects_of_the_full_urdf(name: str) -> None:
    """tau = M(q) qdd + nle(q, qd) from CRBA on the URDF as written (fingers included, at rest)."""
    robot = load_robot(name)
    period = 0.004
    q = _sine_samples(robot, 200, period)
    peaks, ratios = trajectory_torques(robot, q, period, effort_limits_nm(robot), series=True)
    full = pin.buildModelFromUrdf(str(robot.urdf_path))
    data = full.createData()
    idx = [full.joints[full.getJointId(j)].idx_v for j in robot.joint_names]
    worst = 0.0
    for k in range(1, len(q) - 1):
        qf, vf, af = pin.neutral(full), np.zeros(full.nv), np.zeros(full.nv)
        qf[idx] = q[k]
        vf[idx] = (q[k + 1] - q[k - 1]) / (2 * period)
        af[idx] = (q[k + 1] - 2 * q[k] + q[k - 1]) / period**2
        mass = pin.crba(full, data, qf)
        mass = np.triu(mass) + np.triu(mass, 1).T  # CRBA fills the upper triangle
        tau = (mass @ af + pin.nonLinearEffects(full, data, qf, vf))[idx]
        expected = np.abs(tau) / effort_limits_nm(robot)
        assert ratios is not None
        worst = max(worst, float(np.max(np.abs(ratios[k] - expected) * effort_limits_nm(robot))))
    assert worst < 1e-3  # N m; the series is float32 (7 digits of a ~100 N m torque)
    # the two end samples are at rest: the torque holds the arm against gravity
    gravity = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), q[0])
    assert ratios is not None
    np.testing.assert_allclose(ratios[0], np.abs(gravity) / effort_limits_nm(robot), rtol=1e-5, atol=1e-7)
    assert peaks.ratio == pytest.approx(float(ratios.max()), rel=1e-6)


def test_peaks_do_not_depend_on_the_chunk_size(monkeypatch: pytest.MonkeyPatch) -> None:
    robot = load_robot("ur5")
    q = _sine_samples(robot, 301, 0.004)
    whole, _ = trajectory_torques(robot, q, 0.004, effort_limits_nm(robot))
    monkeypatch.setattr(dynamics, "_CHUNK", 64)
    chunked, _ = trajectory_torques(robot, q, 0.004, effort_limits_nm(robot))
    assert (chunked.sample, chunked.joint) == (whole.sample, whole.joint)
    np.testing.assert_allclose(chunked.peak_nm, whole.peak_nm, rtol=1e-12)


def _whole_array_differences(q: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The trajectory record's qd, qdd as results/trajectory.py formed them before the formula had
    one home (kept here as the reference the record must not drift from)."""
    qd = np.zeros_like(q)
    qdd = np.zeros_like(q)
    if len(q) > 2:
        qd[1:-1] = (q[2:] - q[:-2]) / (2 * period_s)
        qdd[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / period_s**2
    return qd, qdd


@pytest.mark.parametrize("chunk", [1, 2, 7, 65_536])
def test_central_differences_equal_the_record_formula_bit_for_bit(monkeypatch: pytest.MonkeyPatch,
                                                                   chunk: int) -> None:
    monkeypatch.setattr(dynamics, "_CHUNK", chunk)
    rng = np.random.default_rng(12)
    for count in (0, 1, 2, 3, 8, 9, 51):
        q = rng.normal(scale=3.0, size=(count, 7))
        for period_s in (0.004, 0.001, 0.0123):
            qd, qdd = central_differences(q, period_s)
            want_qd, want_qdd = _whole_array_differences(q, period_s)
            assert qd.dtype == want_qd.dtype and qd.shape == want_qd.shape
            assert np.array_equal(qd, want_qd) and np.array_equal(qdd, want_qdd), (chunk, count, period_s)


def test_span_differences_from_rest_set_only_the_end_accelerations() -> None:
    rng = np.random.default_rng(3)
    q, period_s = rng.normal(size=(9, 6)), 0.004
    qd, qdd = span_differences(q, period_s, 0, len(q), ends_from_rest=True)
    want_qd, want_qdd = _whole_array_differences(q, period_s)
    assert np.array_equal(qd, want_qd) and np.array_equal(qdd[1:-1], want_qdd[1:-1])
    assert np.array_equal(qdd[0], 2.0 * (q[1] - q[0]) / period_s**2)
    assert np.array_equal(qdd[-1], 2.0 * (q[-2] - q[-1]) / period_s**2)
    # a span inside the samples has no end sample of q: its rows are the whole array's
    inner_qd, inner_qdd = span_differences(q, period_s, 2, 6, ends_from_rest=True)
    assert np.array_equal(inner_qd, want_qd[2:6]) and np.array_equal(inner_qdd, want_qdd[2:6])


def test_the_records_velocities_and_accelerations_are_the_central_differences_of_its_samples() -> None:
    traj = plan(parse_task(UR5_TASK))
    want_qd, want_qdd = _whole_array_differences(traj.q, traj.period)
    assert np.array_equal(traj.qd, want_qd) and np.array_equal(traj.qdd, want_qdd)
    assert np.abs(traj.qdd).max() > 1.0  # not vacuous: the arm moves


def test_only_urdfs_with_real_inertias_have_dynamics(tmp_path: Path) -> None:
    assert has_inertias(load_robot("ur5")) and has_inertias(load_robot("panda"))
    industrial = [name for name, e in bundled_robots().items() if e.urdf_file is not None]
    assert len(industrial) == 10
    for name in industrial:
        robot = load_robot(name)
        assert "no published dynamics" in str(no_dynamics_reason(robot)), name
        # the same file by path, and a copy of it elsewhere, say the same
        copy = tmp_path / f"{name}.urdf"
        copy.write_text(robot.urdf_path.read_text())
        assert not has_inertias(load_robot(str(robot.urdf_path))) and not has_inertias(load_robot(str(copy)))
    # a URDF without the mark and without inertias: the reason names a joint
    text = load_robot("abb_irb2400").urdf_path.read_text()
    bare = "".join(part.split("</inertial>")[-1] for part in text.split("<inertial>"))
    bare = bare.replace("singplan: no published dynamics", "")
    (tmp_path / "bare.urdf").write_text(bare)
    assert "no mass for the link moved by joint_1" in str(no_dynamics_reason(load_robot(str(tmp_path / "bare.urdf"))))


def _plan_cli(task: dict[str, Any], folder: Path) -> tuple[int, str]:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "task.yaml").write_text(yaml.safe_dump(task, sort_keys=False))
    # no test reads the replay
    code, _, err = run_cli("plan", folder / "task.yaml", "-o", folder / "out", "--quiet", "--no-replay")
    return code, err


def _checker(folder: Path) -> subprocess.CompletedProcess[str]:
    return run_checker(folder / "task.yaml", folder / "out", "--quiet")


@pytest.mark.slow  # three UR5 plans and the independent checker
def test_torque_scale_binds_slows_the_plan_and_passes_the_checker(tmp_path: Path) -> None:
    free = plan(parse_task(UR5_TASK))
    bound = plan(parse_task(_with_scale(0.45)))
    # unconstrained, the shoulder would need more than 0.45 of its effort
    assert free.metrics.torques.max_torque_ratio > 0.45 * 1.5
    assert bound.metrics.torques.max_torque_ratio <= 1.0
    assert bound.duration_s > free.duration_s + 0.05
    limit = bound.metrics.torques.torque_limit_Nm["shoulder_lift_joint"]
    assert limit == pytest.approx(0.45 * 150.0)
    assert bound.metrics.torques.peak_torque_Nm["shoulder_lift_joint"] <= limit
    code, err = _plan_cli(_with_scale(0.45), tmp_path / "bound")
    assert code == 0, err
    result = _checker(tmp_path / "bound")
    assert result.returncode == 0, result.stdout


def test_without_torque_scale_torques_are_reported_not_enforced(tmp_path: Path) -> None:
    code, err = _plan_cli(UR5_TASK, tmp_path / "free")
    assert code == 0, err
    page = (tmp_path / "free" / "out" / "report.html").read_text()
    # with the stopping distance, and the least distance of the UR5's self-collision check (its meshes)
    assert 'id="plot-torque"' in page and page.count("<svg") == 8
    assert "not enforced" in page


def test_a_torque_limit_below_the_holding_torque_is_no_plan(tmp_path: Path) -> None:
    code, err = _plan_cli(_with_scale(0.3), tmp_path / "weak")
    assert code == 3
    assert "holding the arm against gravity" in err and "shoulder_lift_joint" in err and "move 0 (ptp)" in err


def test_torque_scale_on_an_arm_without_published_dynamics_is_bad_input(tmp_path: Path) -> None:
    task = {"robot": "kuka_kr6_r900_2", "start": {"joints_deg": [0, -90, 90, 0, 30, 0]},
            "moves": [{"ptp": {"to": {"joints_deg": [10, -90, 90, 0, 30, 0]}}}], "limits": {"torque_scale": 0.5}}
    code, err = _plan_cli(task, tmp_path / "kuka")
    assert code == 2
    assert "limits.torque_scale" in err and "no published dynamics" in err
    assert not (tmp_path / "kuka" / "out").exists()
    del task["limits"]
    code, err = _plan_cli(task, tmp_path / "kuka_free")
    assert code == 0, err
    assert "torque" not in " ".join(k for k in plan(parse_task(task)).metrics.to_json() if k.startswith("max_"))


@pytest.mark.parametrize("value", [0, -0.5, 1.5, "half", None, float("nan"), True])
def test_torque_scale_must_be_a_fraction(value: object) -> None:
    with pytest.raises(TaskError) as info:
        parse_task(_with_scale(value))  # type: ignore[arg-type]
    assert info.value.field == "limits.torque_scale"


def test_torque_scale_round_trips_through_the_mapping() -> None:
    task = parse_task(_with_scale(0.7))
    assert task.limits.torque_scale == 0.7
    assert parse_task(task.to_mapping()).limits.torque_scale == 0.7
    assert "torque_scale" not in parse_task(UR5_TASK).to_mapping()["limits"]

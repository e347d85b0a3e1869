"""singplan's crossing methods beside what an integrator can use today, on singular LINs.

    python bench/bench_crossing.py [--scenarios ../shared/scenarios] [--write docs/benchmarks.md]

Cases: the public ``*_near_lin`` and ``*_exact_lin`` scenarios, plus the UR5 cases S1 (a LIN
exactly through the wrist singularity of q = [0.3, -1.2, 1.5, -0.3, 0, 0.4]) and S2 (the
same LIN tilted 1 deg: the public ``ur5__wrist_near_lin``). For each case, in one run:

- singplan ``auto``, ``wrist-joint``, ``axis``, ``exact``;
- **newton+toppra**: Pinocchio damped-Newton IK from the previous sample every 2 mm, then
  TOPP-RA on a cubic joint spline through the samples, sampled at the period (what one
  assembles from an IK library and toppra);
- **dls**: a servo loop at the controller period, the target moving along the path at the
  programmed speed, ``qd = J^T (J J^T + 1e-4 I)^-1 (v + k e)`` with joint speed clipping;
- **pink**: pink's differential IK (FrameTask, position cost 1, orientation cost 0.1,
  configuration and velocity limits, quadprog) at the controller period, same target motion.

Every result is measured here by the same code, independently of the method: the largest
distance of a sample from the programmed line, the largest tilt from the programmed
(slerped) orientation at the nearest point, the largest joint speed over its limit, the
duration and the planning time per output sample. "ok" means position within the task's
tolerance, orientation within its tolerance, joint positions, speeds and accelerations within
limits, and the move ending at its target. "plan" is the whole planning time (for singplan:
IK, detection, crossing and timing; ``auto`` plans every candidate) per output sample.
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pinocchio as pin
import toppra as ta
import toppra.algorithm as ta_algo
import toppra.constraint as ta_constraint

from singplan.errors import SingplanError
from singplan.kinematics.ik.solve import solve_all, solve_newton
from singplan.kinematics.robot import Robot
from singplan.planning.orchestration.targets import load_task_robot
from singplan.results.plan import plan
from singplan.task.load import load_task, parse_task
from singplan.task.schema import Task

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_ik import machine, write_section  # noqa: E402 - the shared results-file helpers


@dataclass(frozen=True)
class Result:
    ok: bool
    pos_mm: float
    ori_deg: float
    speed_ratio: float
    accel_ratio: float
    duration_s: float
    us_per_sample: float
    note: str = ""


def ur5_case(tilt_deg: float, nudge_deg: float = 0.0) -> Task:
    """The issue's UR5 case: +-0.1 m through q_mid along normalise(tool z + 0.5 world z).

    ``nudge_deg`` is added to the start's joint 5: a change far below any tolerance, to show
    how much a method's result depends on the last digits where the path meets the singularity.
    """
    robot = load_task_robot(parse_task({"robot": "ur5", "start": {"joints_deg": [0, -60, 90, 0, 30, 0]},
                                        "moves": [{"ptp": {"to": {"joints_deg": [0, -60, 90, 0, 30, 0]}}}]}))
    q_mid = np.array([0.3, -1.2, 1.5, -0.3, 0.0, 0.4])
    T = robot.fk(q_mid)
    d = T.rotation[:, 2] + 0.5 * np.array([0.0, 0.0, 1.0])
    d /= np.linalg.norm(d)
    R = T.rotation
    if tilt_deg:  # about the horizontal axis perpendicular to the tool axis
        axis = np.cross(np.array([0.0, 0.0, 1.0]), R[:, 2])
        R = pin.AngleAxis(math.radians(tilt_deg), axis / np.linalg.norm(axis)).matrix() @ R
    start = pin.SE3(R, T.translation - 0.1 * d)
    q0 = np.degrees(solve_all(robot, start, seed=q_mid).nearest(q_mid)) + np.array([0, 0, 0, 0, nudge_deg, 0])
    return parse_task({"robot": "ur5", "tip": "tool0", "start": {"joints_deg": list(q0)},
                       "moves": [{"lin": {"to": {"xyz": list(T.translation + 0.1 * d),
                                                 "rpy_deg": list(np.degrees(pin.rpy.matrixToRpy(R)))},
                                          "speed": 0.25}}],
                       "singularity": {"orientation_tolerance_deg": 1.5}, "limits": {"acceleration": 10.0}})


# -- measuring ----------------------------------------------------------------------------------


def measure(robot: Robot, task: Task, q: np.ndarray, period: float, seconds: float) -> Result:
    """Deviation from the LIN, joint speed/accel ratios; independent of how q was made."""
    a = robot.fk(np.radians(task.start_joints_deg))
    move = task.moves[0]
    R_b = pin.rpy.rpyToMatrix(*np.radians(move.to.rpy_deg)) if move.to.rpy_deg else a.rotation
    p_b = np.asarray(move.to.xyz)
    d = p_b - a.translation
    omega = pin.log3(a.rotation.T @ R_b)
    pos = ori = 0.0
    for qk in q:
        T = robot.fk(qk)
        s = float(np.clip((T.translation - a.translation) @ d / (d @ d), 0.0, 1.0))
        pos = max(pos, float(np.linalg.norm(T.translation - a.translation - s * d)))
        R_path = a.rotation @ pin.exp3(s * omega)
        ori = max(ori, float(np.linalg.norm(pin.log3(R_path.T @ T.rotation))))
    vmax = robot.velocity_rad_s * task.limits.velocity_scale
    qd = np.diff(q, axis=0) / period
    qdd = np.diff(qd, axis=0) / period
    speed = float(np.max(np.abs(qd) / vmax))
    accel = float(np.max(np.abs(qdd) / task.limits.joint_accelerations(robot.n_joints)))
    end_err = float(np.linalg.norm(robot.fk(q[-1]).translation - p_b))
    inside = bool(np.all(q >= robot.lower_rad - 1e-9) and np.all(q <= robot.upper_rad + 1e-9))
    ok = inside and (pos * 1e3 <= task.singularity.position_tolerance_mm and
          math.degrees(ori) <= task.singularity.orientation_tolerance_deg + 1e-9 and
          speed <= 1.005 and accel <= 1.02 and end_err * 1e3 <= task.singularity.position_tolerance_mm)
    note = "outside joint limits" if not inside else ("" if end_err < 1e-4 else f"ends {end_err * 1e3:.1f} mm short")
    return Result(ok, pos * 1e3, math.degrees(ori), speed, accel, (len(q) - 1) * period, seconds / len(q) * 1e6, note)


def _path_pose(task: Task, a: pin.SE3, s: float) -> pin.SE3:
    move = task.moves[0]
    R_b = pin.rpy.rpyToMatrix(*np.radians(move.to.rpy_deg)) if move.to.rpy_deg else a.rotation
    p = a.translation + s * (np.asarray(move.to.xyz) - a.translation)
    return pin.SE3(a.rotation @ pin.exp3(s * pin.log3(a.rotation.T @ R_b)), p)


# -- peers ----------------------------------------------------------------------------------------


def newton_toppra(robot: Robot, task: Task) -> np.ndarray:
    a = robot.fk(np.radians(task.start_joints_deg))
    length = float(np.linalg.norm(np.asarray(task.moves[0].to.xyz) - a.translation))
    n = max(2, math.ceil(length / 0.002))
    q = [np.radians(task.start_joints_deg)]
    for s in np.linspace(0, 1, n + 1)[1:]:
        sol = solve_newton(robot, _path_pose(task, a, float(s)), q[-1])
        q.append(sol if sol is not None else q[-1])
    qs = np.array(q)
    u = np.linspace(0, 1, len(qs))
    path = ta.SplineInterpolator(u, np.hstack([qs, (u * length)[:, None]]))
    vmax = np.append(robot.velocity_rad_s * task.limits.velocity_scale, task.moves[0].speed_m_s)
    amax = np.append(task.limits.joint_accelerations(robot.n_joints), 1e9)
    inst = ta_algo.TOPPRA([ta_constraint.JointVelocityConstraint(np.stack([-vmax, vmax], 1)),
                           ta_constraint.JointAccelerationConstraint(np.stack([-amax, amax], 1))], path,
                          parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0, 0)
    t = np.arange(0.0, traj.duration + task.period_s, task.period_s)
    return np.asarray(traj(np.minimum(t, traj.duration)))[:, :-1]


ServoStep = Callable[[np.ndarray, pin.SE3, np.ndarray, float], np.ndarray]  # (q, target, twist, dt) -> q


def _servo(robot: Robot, task: Task, step: ServoStep) -> np.ndarray:
    a = robot.fk(np.radians(task.start_joints_deg))
    length = float(np.linalg.norm(np.asarray(task.moves[0].to.xyz) - a.translation))
    v, dt = task.moves[0].speed_m_s, task.period_s
    count = math.ceil(length / v / dt)
    q = [np.radians(task.start_joints_deg)]
    for k in range(1, count + 1):
        s0, s1 = (k - 1) / count, k / count
        target = _path_pose(task, a, s1)
        twist = pin.log6(_path_pose(task, a, s0).actInv(target)).vector / dt
        q.append(step(q[-1], target, twist, dt))
    return np.array(q)


def dls(robot: Robot, task: Task) -> np.ndarray:
    vmax = robot.velocity_rad_s * task.limits.velocity_scale

    def step(q: np.ndarray, target: pin.SE3, twist: np.ndarray, dt: float) -> np.ndarray:
        T = robot.fk(q)
        err = np.concatenate([target.translation - T.translation,
                              T.rotation @ pin.log3(T.rotation.T @ target.rotation)])
        J = robot.jacobian(q)
        qd = J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(6), err / dt)
        return q + np.clip(qd, -vmax, vmax) * dt

    return _servo(robot, task, step)


def pink_ik(robot: Robot, task: Task) -> np.ndarray:
    import pink
    from pink.limits import ConfigurationLimit, VelocityLimit
    from pink.tasks import FrameTask

    model = robot.model.copy()
    tip = model.frames[robot.tip_frame_id]
    model.addFrame(pin.Frame("bench_tcp", tip.parentJoint, tip.placement * robot.T_tip_tcp, pin.FrameType.OP_FRAME))
    data = model.createData()
    frame_task = FrameTask("bench_tcp", position_cost=1.0, orientation_cost=0.1)
    config = pink.Configuration(model, data, np.radians(task.start_joints_deg))
    limits = [ConfigurationLimit(model), VelocityLimit(model)]

    def step(q: np.ndarray, target: pin.SE3, twist: np.ndarray, dt: float) -> np.ndarray:
        frame_task.set_target(target)
        velocity = pink.solve_ik(config, [frame_task], dt, solver="quadprog", limits=limits)
        q_next = config.integrate(velocity, dt)
        config.update(q_next)
        return np.array(q_next)

    return _servo(robot, task, step)


# -- the run --------------------------------------------------------------------------------------


def run_case(name: str, task: Task) -> list[tuple[str, Result]]:
    robot = load_task_robot(task)
    rows: list[tuple[str, Result]] = []
    for method in ("auto", "wrist-joint", "axis", "exact"):
        t0 = time.perf_counter()
        try:
            traj = plan(task, method=method)
        except SingplanError as exc:
            rows.append((f"singplan {method}", Result(False, math.nan, math.nan, math.nan, math.nan, math.nan,
                                                      math.nan, f"exit {exc.exit_code}")))
            continue
        res = measure(robot, task, traj.q, traj.period, time.perf_counter() - t0)
        chosen = ""
        if method == "auto":
            chosen = ", ".join(sorted({s.method for s in traj.segments if s.kind == "crossing" and s.method}))
        rows.append((f"singplan {method}", Result(*list(res.__dict__.values())[:-1], note=chosen or res.note)))
    for peer, fn in (("newton+toppra", newton_toppra), ("dls", dls), ("pink", pink_ik)):
        t0 = time.perf_counter()
        try:
            q = fn(robot, task)
        except Exception as exc:  # a peer that fails is a result, whatever it raises
            rows.append((peer, Result(False, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan,
                                      type(exc).__name__)))
            continue
        rows.append((peer, measure(robot, task, q, task.period_s, time.perf_counter() - t0)))
    return rows


def cases(scenarios: Path) -> list[tuple[str, Task]]:
    out = [(p.stem, load_task(p)) for p in sorted(scenarios.glob("*_lin.yaml"))
           if "near_lin" in p.stem or "exact_lin" in p.stem]
    out.append(("ur5 S1 (through)", ur5_case(0.0)))
    out.append(("ur5 S1, start joint 5 + 1e-9 deg", ur5_case(0.0, nudge_deg=1e-9)))
    out.append(("ur5 S2 (1 deg miss)", ur5_case(1.0)))
    return out


def table(results: list[tuple[str, list[tuple[str, Result]]]]) -> str:
    lines = ["### Crossing singular LINs: singplan and peers (`bench/bench_crossing.py`)", "",
             f"Machine: {machine()}; Python {platform.python_version()}, pin {version('pin')}, toppra "
             f"{version('toppra')}, pin-pink {version('pin-pink')}.", "",
             "| case | method | ok | pos err [mm] | ori err [deg] | joint speed ratio | joint accel ratio "
             "| duration [s] | plan [us/sample] | note |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---|"]
    for name, rows in results:
        for method, r in rows:
            lines.append(f"| {name} | {method} | {'yes' if r.ok else 'no'} | {r.pos_mm:.4f} | {r.ori_deg:.3f} | "
                         f"{r.speed_ratio:.2f} | {r.accel_ratio:.2f} | {r.duration_s:.3f} | {r.us_per_sample:.0f} "
                         f"| {r.note} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=Path, default=HERE.parents[1] / "shared" / "scenarios")
    parser.add_argument("--write", type=Path, default=None)
    args = parser.parse_args(argv)
    results = []
    for name, task in cases(args.scenarios):
        results.append((name, run_case(name, task)))
        sys.stderr.write(f"done {name}\n")
    text = table(results)
    sys.stdout.write(text + "\n")
    if args.write:
        write_section(args.write, text, "bench_crossing")
    return 0


if __name__ == "__main__":
    sys.exit(main())

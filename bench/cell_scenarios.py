"""Cell scenarios of the public kinds (../shared/scenarios_cell) generated for any arm, to check the
collision checking on arms the public tasks do not use.

    python bench/cell_scenarios.py OUT [--arm NAME_OR_URDF[=SRDF] ...] [--seed N] [--tries N]
    python ../shared/scenarios_cell/run_cell.py OUT --singplan singplan

For each arm it writes up to four tasks and an ``expect.yaml`` in run_cell.py's format:

- ``a`` wrist crossing with a tool: a LIN through a wrist near miss (bench/robots_acceptance.py's
  generator) with a torch offset from the flange axis; the crossing auto chooses without a cell
  swings the torch away from where keeping the pose (exact) puts it, and a sphere is placed on that
  swing, clear of the exact motion: auto must choose a clear crossing (exit 0, checker passes);
- ``b`` configuration change: a PTP to a pose with ``config: auto``; a sphere on the path of the
  nearest end configuration, clear of another one's joint line: exit 0 in another configuration;
- ``c`` PTP with no alternative: a PTP to joint values whose straight joint line passes a sphere
  (clear at both ends): exit 3 naming the move and the sphere;
- ``d`` clear program: a PTP, LIN and CIRC near the start with a table 40 mm under the lowest point of
  any body, clearance 10 mm: exit 0, the closest approach reported.

Each scenario is planned here first (in process) to confirm that it is of its kind: the obstacle
blocks what it should and leaves another way clear. An arm given as ``URDF=SRDF`` uses that SRDF
(``collision.srdf``), e.g. example-robot-data's ``ur5.srdf`` for its UR arms.
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import math
import sys
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from singplan.errors import CollisionError, SingplanError
from singplan.kinematics.clearance import check_clearance
from singplan.kinematics.collision import collision_model
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.shapes import CollisionSettings, Shape
from singplan.planning.orchestration.targets import ptp_targets
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory
from singplan.task.load import load_task
from singplan.task.schema import Move, PoseSpec

HERE = Path(__file__).resolve().parent
TORCH = {"cylinder": {"radius": 0.02, "length": 0.3}, "xyz": [0.0, 0.06, 0.2]}  # in the tip frame
TORCH_AXIS = np.array([[0.0, 0.06, z] for z in np.linspace(0.05, 0.35, 13)])  # points on its axis
TORCH_RADIUS_M = 0.02
OBSTACLE = "obstacle"


WRIST_MISS_DEG = 6.0  # kind a passes the wrist singularity this far inside a 10 deg zone (the public one: 6.7)


@lru_cache(maxsize=1)
def _acceptance() -> Any:
    """bench/robots_acceptance.py's near-miss generator, its miss set to :data:`WRIST_MISS_DEG`."""
    spec = importlib.util.spec_from_file_location("cell_near_miss", HERE / "robots_acceptance.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["cell_near_miss"] = module  # dataclasses look their module up while it loads
    spec.loader.exec_module(module)
    module.WRIST_MISS_RAD = math.radians(WRIST_MISS_DEG)
    return module


def _write(task: dict[str, Any], folder: Path, name: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(task, sort_keys=False))
    return path


def _plan(task: dict[str, Any], folder: Path, name: str, method: str | None = None) -> Trajectory | SingplanError:
    try:
        return plan(_write(task, folder, name), method=method)
    except SingplanError as exc:
        return exc


def _base(robot_ref: str, robot: Robot, srdf: str | None) -> dict[str, Any]:
    task: dict[str, Any] = {"robot": robot_ref}
    if robot.entry is None:
        task["tip"] = robot.tip
    if srdf is not None:
        task["collision"] = {"srdf": srdf}
    return task


def _with_collision(task: dict[str, Any], cell: list[dict[str, Any]], clearance_mm: float) -> dict[str, Any]:
    out = copy.deepcopy(task)
    out["cell"] = cell
    out["collision"] = {**out.get("collision", {}), "clearance_mm": clearance_mm}
    return out


def _tool_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """The torch axis points (N * 13, 3) in the base frame at joint samples q."""
    out = []
    for row in q:
        T = robot.fk_tip(row)
        out.append(TORCH_AXIS @ T.rotation.T + T.translation)
    return np.concatenate(out)


def kind_a(robot_ref: str, robot: Robot, srdf: str | None, rng: np.random.Generator,
           work: Path) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A wrist crossing that would swing the torch into a sphere, with a pose-keeping crossing clear of it."""
    found = _acceptance().near_miss_task(robot, "wrist", rng, 0.3)
    if found is None:
        return None
    task = {**_base(robot_ref, robot, srdf), **{k: v for k, v in found[0].items() if k not in ("robot", "tip")}}
    task["tool"] = {"xyz": [0.0, 0.0, 0.0], "geometry": [TORCH]}
    task["singularity"] = {"method": "auto", "orientation_tolerance_deg": 10.0, "zone": {"wrist_deg": 10.0}}
    free = _plan(task, work, "a_free")
    if not isinstance(free, Trajectory):
        return None
    crossed = [s.method for s in free.segments if s.kind == "crossing"]
    if not crossed or crossed[0] in ("exact", "null-space"):
        return None  # auto keeps the pose already: nothing to choose
    exact = _plan(task, work, "a_exact", method="exact")
    if not isinstance(exact, Trajectory):
        return None
    swing, kept = _tool_points(robot, free.q), _tool_points(robot, exact.q)
    apart = np.array([np.min(np.linalg.norm(kept - p, axis=1)) for p in swing])
    k = int(np.argmax(apart))
    radius = min(0.02, float(apart[k]) - TORCH_RADIUS_M - 0.002 - 0.004)
    if radius < 0.004:
        return None
    cell = [{"name": OBSTACLE, "sphere": {"radius": round(radius, 5)}, "xyz": [round(float(v), 6) for v in swing[k]]}]
    blocked = _with_collision(task, cell, 2.0)
    if not isinstance(_plan(blocked, work, "a_swing", method=crossed[0]), CollisionError):
        return None
    chosen = _plan(blocked, work, "a_auto")
    if not isinstance(chosen, Trajectory):
        return None
    return blocked, {"exit": 0, "checker": "pass", "min_clearance_reported": True, "kind": "a-wrist-crossing-tool",
                     "reason": f"without the sphere auto crosses with {crossed[0]}, swinging the torch "
                               f"{apart[k] * 1e3:.0f} mm from where exact keeps it; the sphere sits on that swing"}


def _clear_line(model: Any, q0: np.ndarray, q1: np.ndarray) -> bool:
    return check_clearance(model, np.linspace(q0, q1, 80), exact=False).clear


def _sphere_model(robot: Robot, centre: np.ndarray, radius: float, srdf: str | None, clearance_mm: float) -> Any:
    shape = Shape("sphere", (radius,), tuple(float(v) for v in centre), name=OBSTACLE, field="cell[0]")
    return collision_model(robot, cell=(shape,), settings=CollisionSettings(clearance_mm, srdf=srdf))


def _start(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    lo, hi = np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi)
    return rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo))


def kind_b(robot_ref: str, robot: Robot, srdf: str | None, rng: np.random.Generator,
           work: Path) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A PTP to a pose whose nearest end configuration's line passes a sphere another one's avoids."""
    if robot.n_joints != 6:
        return None
    q0 = _start(robot, rng)
    q1 = np.clip(q0 + rng.normal(0.0, 0.5, robot.n_joints), robot.lower_rad, robot.upper_rad)
    T = robot.fk(q1)
    pose = {"xyz": [float(v) for v in T.translation],
            "rpy_deg": [float(v) for v in np.degrees(_rpy(T.rotation))]}
    move = Move("ptp", to=PoseSpec(tuple(pose["xyz"]), tuple(pose["rpy_deg"])))
    targets = ptp_targets(robot, 0, move, q0)
    if len(targets) < 2:
        return None
    centre = _blocking_point(robot, srdf, q0, targets)
    if centre is None:
        return None
    task = {**_base(robot_ref, robot, srdf), "start": {"joints_deg": [float(v) for v in np.degrees(q0)]},
            "moves": [{"ptp": {"to": pose, "config": "auto"}}]}
    blocked = _with_collision(task, [{"name": OBSTACLE, "sphere": {"radius": 0.04},
                                      "xyz": [float(v) for v in centre]}], 5.0)
    if not isinstance(_plan(blocked, work, "b_auto"), Trajectory):
        return None
    return blocked, {"exit": 0, "checker": "pass", "min_clearance_reported": True, "kind": "b-configuration-change",
                     "reason": "the nearest end configuration's joint line passes the sphere; another's is clear"}


def _blocking_point(robot: Robot, srdf: str | None, q0: np.ndarray, targets: list[np.ndarray]) -> np.ndarray | None:
    """A point on the nearest target's joint line where a sphere blocks it and leaves the start and another
    target's line clear (a joint origin of the wrist or elbow part way along)."""
    for fraction in (0.5, 0.35, 0.65):
        frames = robot.joint_frames((q0 + fraction * (targets[0] - q0))[None])[1][0]
        for joint in range(3, robot.model.njoints):
            model = _sphere_model(robot, frames[joint], 0.04, srdf, 5.0)
            if not check_clearance(model, q0[None]).clear or _clear_line(model, q0, targets[0]):
                continue
            if any(_clear_line(model, q0, t) for t in targets[1:]):
                return frames[joint]
    return None


def kind_c(robot_ref: str, robot: Robot, srdf: str | None, rng: np.random.Generator,
           work: Path) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A PTP to joint values straight through a sphere (clear at both ends): no plan."""
    q0 = _start(robot, rng)
    q1 = np.clip(q0 + rng.normal(0.0, 0.6, robot.n_joints), robot.lower_rad, robot.upper_rad)
    centre = robot.joint_frames(((q0 + q1) / 2)[None])[1][0][min(5, robot.n_joints - 1)]  # the wrist half way
    model = _sphere_model(robot, centre, 0.05, srdf, 0.0)
    ends_clear = check_clearance(model, q0[None]).clear and check_clearance(model, q1[None]).clear
    if not ends_clear or _clear_line(model, q0, q1):
        return None
    task = {**_base(robot_ref, robot, srdf), "start": {"joints_deg": [float(v) for v in np.degrees(q0)]},
            "moves": [{"ptp": {"to": {"joints_deg": [float(v) for v in np.degrees(q1)]}}}]}
    blocked = _with_collision(task, [{"name": "pillar", "sphere": {"radius": 0.05},
                                      "xyz": [float(v) for v in centre]}], 0.0)
    if not isinstance(_plan(blocked, work, "c_plan"), CollisionError):
        return None
    return blocked, {"exit": 3, "message_contains_all": ["move 0", "pillar"], "kind": "c-ptp-no-alternative",
                     "reason": "the straight joint line passes the sphere; both ends are clear of it"}


def kind_d(robot_ref: str, robot: Robot, srdf: str | None, rng: np.random.Generator,
           work: Path) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A short PTP / LIN / CIRC program with a table 40 mm under every body, clearance 10 mm."""
    q0 = _start(robot, rng)
    steps = [np.clip(q0 + rng.normal(0.0, 0.15, robot.n_joints), robot.lower_rad, robot.upper_rad)]
    for _ in range(3):
        steps.append(np.clip(steps[-1] + rng.normal(0.0, 0.08, robot.n_joints), robot.lower_rad, robot.upper_rad))
    pose = [{"xyz": [float(v) for v in robot.fk(q).translation],
             "rpy_deg": [float(v) for v in np.degrees(_rpy(robot.fk(q).rotation))]} for q in steps]
    task = {**_base(robot_ref, robot, srdf), "tool": {"xyz": [0.0, 0.0, 0.0], "geometry": [TORCH]},
            "start": {"joints_deg": [float(v) for v in np.degrees(q0)]},
            "moves": [{"ptp": {"to": {"joints_deg": [float(v) for v in np.degrees(steps[0])]}}},
                      {"lin": {"to": pose[1], "speed": 0.25}},
                      {"circ": {"via": {"xyz": pose[2]["xyz"]}, "to": pose[3], "speed": 0.2}}],
            "singularity": {"method": "auto"}}
    free = _plan({**task, "collision": {**task.get("collision", {}), "self": False}}, work, "d_free")
    if not isinstance(free, Trajectory):
        return None
    model = collision_model(robot, load_task(_write(task, work, "d_shapes")).tool_geometry)
    lowest = _lowest_point(model, free.q)
    table = {"name": "table", "box": {"size": [3.0, 3.0, 0.04]}, "xyz": [0.0, 0.0, round(lowest - 0.04 - 0.02, 6)]}
    cell_task = _with_collision(task, [table], 10.0)
    done = _plan(cell_task, work, "d_cell")
    if not isinstance(done, Trajectory):
        return None
    return cell_task, {"exit": 0, "checker": "pass", "min_clearance_reported": True, "kind": "d-program-clear",
                       "reason": "a short program with a table 40 mm under the lowest point of every body"}


def _lowest_point(model: Any, q: np.ndarray) -> float:
    """The lowest z [m] any robot body's capsules reach along the samples."""
    R, P = model.robot.joint_frames(q)
    low = math.inf
    for body in model.bodies:
        if body.joint is None:
            continue
        for g in body.geoms:
            ends = np.einsum("nij,ej->nei", R[:, body.joint], g.segment) + P[:, body.joint][:, None]
            low = min(low, float(ends[..., 2].min()) - g.radius_m)
    return low


def _rpy(R: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return np.asarray(pin.rpy.matrixToRpy(R))


KINDS = {"a": kind_a, "b": kind_b, "c": kind_c, "d": kind_d}


def generate(arm: str, out: Path, seed: int = 0, tries: int = 12, kinds: str = "abcd") -> dict[str, dict[str, Any]]:
    """Write the scenarios of ``kinds`` for one arm into ``out``; their expect.yaml entries, by task name."""
    ref, _, srdf = arm.partition("=")
    robot = load_robot(ref) if not ref.endswith(".urdf") else load_robot(Path(ref).resolve())
    label = Path(ref).stem if ref.endswith(".urdf") else ref
    expect: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="singplan-cell-gen-") as scratch:
        work = Path(scratch)
        for kind in kinds:
            rng = np.random.default_rng(seed)
            for _ in range(tries):
                found = KINDS[kind](str(Path(ref).resolve()) if ref.endswith(".urdf") else ref, robot,
                                    str(Path(srdf).resolve()) if srdf else None, rng, work)
                if found is not None:
                    name = f"{label}__{kind}"
                    _write(found[0], out, name)
                    expect[name] = found[1]
                    break
    return expect


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--arm", action="append", default=None, help="bundled name or URDF[=SRDF] (repeatable)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tries", type=int, default=12)
    parser.add_argument("--kinds", default="abcd")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    expect: dict[str, dict[str, Any]] = {}
    for arm in args.arm or ["fanuc_m10ia", "kuka_kr6_r700_sixx"]:
        found = generate(arm, args.out, args.seed, args.tries, args.kinds)
        sys.stdout.write(f"{arm}: {', '.join(sorted(found)) or 'none'}\n")
        expect.update(found)
    (args.out / "expect.yaml").write_text(yaml.safe_dump(expect, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())

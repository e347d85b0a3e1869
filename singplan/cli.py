"""The ``singplan`` command.

``main(argv) -> int`` returns the exit code (0 ok, 1 internal error, 2 bad input, 3 no plan,
130 interrupted) so tests can call it directly; :func:`run` is the console-script entry point.
Whatever goes wrong, the user gets one line on stderr, never a traceback (unless
SINGPLAN_DEBUG=1 asks for it).

Each command imports the modules it needs when it runs, not at the top of this file: that is
for start-up time (``singplan --help`` or ``singplan robots`` need no TOPP-RA, meshcat or
matplotlib), not to dodge an import cycle; the layers contract (pyproject.toml) holds either way.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import gc
import json
import logging
import math
import os
import signal
import sys
import time
import traceback
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TextIO, TypedDict

from singplan._version import __version__
from singplan.errors import InputError, SingplanError, UnreachableError, nearest
from singplan.outputs.choices import (
    CROSSING_METHODS,
    DEFAULT_FILE_NAMES,
    DEFAULT_HOST,
    DEFAULT_TOLERANCE_DEG,
    DEFAULT_TOLERANCE_MM,
    FORMATS,
    PROGRAM_FORMATS,
    UR_STEP_S,
)
from singplan.outputs.completion import SHELLS
from singplan.outputs.suggest import SuggestingParser

if TYPE_CHECKING:
    import pinocchio as pin

    from singplan.entry import MoveZones
    from singplan.kinematics.held import HeldJoint
    from singplan.kinematics.robot import Robot, RobotEntry


def _robot_rows() -> list[dict[str, object]]:
    from singplan.kinematics.robot import bundled_robots, load_robot

    rows = []
    for name, entry in bundled_robots().items():
        robot = load_robot(name)
        rows.append({"name": name, "display_name": entry.display_name, "dof": robot.n_joints,
                     "family": robot.family, "reach_m": round(robot.reach_m(), 4), "tip": entry.tip,
                     "urdf": str(robot.urdf_path), "source": _source(entry)})
    return rows


def _source(entry: RobotEntry) -> str:
    if entry.example_robot_data:
        return f"example-robot-data:{entry.example_robot_data}"
    chain = [s for s in entry.sources if s.startswith("chain ")]
    return chain[0].removeprefix("chain ").split(":")[0] if chain else ""


def cmd_robots(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    rows = _robot_rows()
    if args.json:
        out.write(json.dumps(rows, indent=2) + "\n")
        return 0
    out.write(f"{'name':22s} {'DOF':>3s} {'family':7s} {'reach [m]':>9s}  source\n")
    for r in rows:
        out.write(f"{r['name']!s:22s} {r['dof']!s:>3s} {r['family']!s:7s} {r['reach_m']:>9.3f}  {r['source']}\n")
    return 0


class _JointInfo(TypedDict):
    name: str
    lower_deg: float | None  # None: no position limit (a continuous joint)
    upper_deg: float | None
    velocity_deg_s: float


class _MethodInfo(TypedDict):
    method: str
    applies: bool
    note: str


class _Verification(TypedDict):
    samples: int
    residual_m: float
    residual_rad: float


class _RobotInfo(TypedDict):
    """What `singplan info` shows (and writes as JSON with --json)."""

    robot: str
    urdf: str
    family: str
    parameters: dict[str, object] | None
    verification: _Verification | None
    not_recognised_as: dict[str, str]
    tip: str
    joints: list[_JointInfo]
    crossing_methods: list[_MethodInfo]


def _info(robot: Robot) -> _RobotInfo:
    """What `singplan info` shows: family and its verified parameters, tip, joints, crossing methods."""
    from singplan.entry import method_uses
    from singplan.kinematics.families import VERIFY_SAMPLES

    rec = robot.recognition
    params: dict[str, object] | None = None
    if rec.opw is not None:
        p = rec.opw
        params = {"a1": p.a1, "a2": p.a2, "b": p.b, "c1": p.c1, "c2": p.c2, "c3": p.c3, "c4": p.c4,
                  "offsets_deg": [round(math.degrees(v), 9) for v in p.offsets_rad],
                  "sign_corrections": list(p.sign_corrections)}
    elif rec.ur is not None:
        params = dataclasses.asdict(rec.ur)
    joints: list[_JointInfo] = [
        {"name": name, "lower_deg": math.degrees(lo) if math.isfinite(lo) else None,
         "upper_deg": math.degrees(hi) if math.isfinite(hi) else None, "velocity_deg_s": math.degrees(v)}
        for name, lo, hi, v in zip(robot.joint_names, robot.lower_rad, robot.upper_rad, robot.velocity_rad_s,
                                   strict=True)]
    methods: list[_MethodInfo] = [{"method": u.method, "applies": u.applies, "note": u.note}
                                  for u in method_uses(robot)]
    return {"robot": robot.name, "urdf": str(robot.urdf_path), "family": rec.family, "parameters": params,
            "verification": {"samples": VERIFY_SAMPLES, "residual_m": rec.residual_m,
                             "residual_rad": rec.residual_rad} if params is not None else None,
            "not_recognised_as": dict(rec.rejected), "tip": robot.tip, "joints": joints, "crossing_methods": methods}


def cmd_info(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from singplan.kinematics.robot import load_robot

    info = _info(load_robot(args.robot, tip=args.tip))
    if args.json:
        out.write(json.dumps(info, indent=2) + "\n")
        return 0
    out.write(f"{info['robot']}: {info['urdf']}\nfamily: {info['family']}\n")
    params, check = info["parameters"], info["verification"]
    if params is not None and check is not None:
        out.write("parameters: " + ", ".join(f"{k} {v}" for k, v in params.items()) + "\n")
        out.write(f"verified by FK on {check['samples']} random joint values: {check['residual_m']:.2g} m, "
                  f"{check['residual_rad']:.2g} rad\n")
    for name, why in info["not_recognised_as"].items():
        out.write(f"not {name}: {why}\n")
    out.write(f"tip: {info['tip']}\n{'joint':24s} {'lower [deg]':>11s} {'upper [deg]':>11s} {'speed [deg/s]':>13s}\n")
    for j in info["joints"]:
        lower, upper = j["lower_deg"], j["upper_deg"]
        limits = (f"{lower:11.2f} {upper:11.2f}" if lower is not None and upper is not None
                  else f"{'unlimited (continuous)':>23s}")
        out.write(f"{j['name']:24s} {limits} {j['velocity_deg_s']:13.2f}\n")
    out.write("crossing methods:\n")
    for m in info["crossing_methods"]:
        out.write(f"  {m['method']:12s} {'yes' if m['applies'] else 'no':3s} {m['note']}\n")
    return 0


def _pose(xyz: Sequence[float], rpy_deg: Sequence[float]) -> pin.SE3:
    import numpy as np
    import pinocchio as pin

    rpy = np.radians(np.asarray(rpy_deg, dtype=float))
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.asarray(xyz, dtype=float))


def _hold(robot: Robot, text: str | None) -> HeldJoint | None:
    """``--hold JOINT=DEG`` on a 7-joint arm: the joint locked at the value."""
    from singplan.kinematics.held import hold_joint

    if text is None:
        return None
    joint, sep, value = text.partition("=")
    try:
        value_deg = float(value)
    except ValueError:
        value_deg = math.nan
    if not sep or not math.isfinite(value_deg):
        raise InputError(f"--hold: expected JOINT=DEG (e.g. {robot.joint_names[-1]}=0), got {text!r}")
    return hold_joint(robot, joint.strip(), math.radians(value_deg), field="--hold")


def _column(value: float, width: int, decimals: int) -> str:
    """A number right-aligned, or "-" where there is none (a 7-joint arm's 6R distances)."""
    return f"{value:{width}.{decimals}f}" if math.isfinite(value) else f"{'-':>{width}s}"


def cmd_ik(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    import numpy as np

    from singplan.kinematics.configuration import singularity_distances
    from singplan.kinematics.ik.solve import solve_all
    from singplan.kinematics.robot import load_robot
    from singplan.task.schema import ANGLE_DEG, COORDINATE_M, JOINT_DEG, TOOL_OFFSET_M, check_vector

    for flag, values, bounds in (("--xyz", args.xyz, COORDINATE_M), ("--rpy-deg", args.rpy_deg, ANGLE_DEG),
                                 ("--tool-xyz", args.tool_xyz, TOOL_OFFSET_M),
                                 ("--tool-rpy-deg", args.tool_rpy_deg, ANGLE_DEG)):
        check_vector(flag, values, 3, bounds)  # before any solve: NaN or 1e300 is bad input, not "no solution"
    full = load_robot(args.robot, tip=args.tip, tool=_pose(args.tool_xyz, args.tool_rpy_deg))
    if args.seed_deg is not None:  # NaN or 1e300 is bad input naming the option, not an internal error
        check_vector("--seed-deg", args.seed_deg, full.n_joints, JOINT_DEG)
    held = _hold(full, args.hold)
    robot = held.reduced if held is not None else full  # a held joint leaves a 6R chain: its branches and labels
    # one solution per branch (nearest the seed, default zero) unless every 2*pi variant is asked for
    seed_full = np.radians(args.seed_deg or [0.0] * full.n_joints)
    seed = None if args.all_variants else held.reduce(seed_full) if held is not None else seed_full
    target = _pose(args.xyz, args.rpy_deg)
    sols = solve_all(robot, target, seed=seed)
    if len(sols) == 0:
        raise UnreachableError(f"no solution inside the joint limits for xyz={list(args.xyz)} "
                               f"rpy_deg={list(args.rpy_deg)}")
    rows = []
    for q, label in zip(sols.q, sols.labels, strict=True):
        d = singularity_distances(robot, q)
        rows.append({"config": label, "joints_deg": np.degrees(held.expand(q) if held is not None else q).tolist(),
                     "wrist_deg": math.degrees(d.wrist_rad), "shoulder_mm": d.shoulder_m * 1e3,
                     "elbow_deg": math.degrees(d.elbow_rad), "sigma_min": float(d.sigma_min)})
    if args.json:
        from singplan.outputs import documents

        pose = {"xyz": list(args.xyz), "rpy_deg": list(args.rpy_deg)}
        tool = {"xyz": list(args.tool_xyz), "rpy_deg": list(args.tool_rpy_deg)}
        hold = {"joint": held.joint, "value_deg": math.degrees(held.value_rad)} if held is not None else None
        out.write(documents.dumps(documents.ik_document(full.name, str(full.urdf_path), full.tip, full.joint_names,
                                                        pose, tool, hold, rows)))
        return 0
    widths = [max(9, len(n)) for n in full.joint_names]  # full names: panda_joint1..7 were all "panda_joi"
    names = " ".join(f"{n:>{w}s}" for n, w in zip(full.joint_names, widths, strict=True))
    held_note = f", {held.joint} held at {math.degrees(held.value_rad):g} deg" if held is not None else ""
    out.write(f"{len(sols)} solution(s) of {robot.name} (joint values in deg{held_note})\n")
    out.write(f"{'config':7s} {names}  wrist[deg] shoulder[mm] elbow[deg] sigma_min\n")
    for row in rows:
        joints = " ".join(f"{v:{w}.3f}" for v, w in zip(row["joints_deg"], widths, strict=True))
        out.write(f"{row['config']:7s} {joints}  {_column(row['wrist_deg'], 10, 3)} "
                  f"{_column(row['shoulder_mm'], 12, 2)} {_column(row['elbow_deg'], 10, 3)} "
                  f"{row['sigma_min']:9.4f}\n")
    return 0


@contextlib.contextmanager
def _replay_warnings(err: TextIO) -> Iterator[None]:
    """The replay's warnings (visuals it cannot draw, a URDF with none) as the command's own: the
    library logs them (singplan's loggers stay silent unless their user listens), a user of the
    CLI must see them."""
    handler = logging.StreamHandler(err)
    handler.setFormatter(logging.Formatter("singplan: warning: %(message)s"))
    log = logging.getLogger("singplan.outputs.scene")
    log.addHandler(handler)
    try:
        yield
    finally:
        log.removeHandler(handler)


@contextlib.contextmanager
def _imports_frozen() -> Iterator[None]:
    """Leave every object alive now out of garbage collection until the block ends (gc.freeze).

    After a command's imports (Pinocchio, TOPP-RA, scipy, numba: ~170k tracked objects) a full
    collection traverses all of them, ~70 ms on the development machine, and frees none; at
    the default pace a small plan ran two or three (numba's first kernel call alone allocates
    enough to start one), 0.2-0.4 s of a 1.6 s ``singplan plan``. The block's own garbage is
    collected as usual, and leaving it hands the frozen objects back to the collector (a
    caller of :func:`main` in a long-lived process keeps its normal collection).
    """
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def cmd_plan(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from singplan.entry import check_method_name, load_task, plan_into
    from singplan.kinematics.closedform.opw import kernels_cached
    from singplan.outputs.progress import plan_bar
    from singplan.outputs.summary import summary

    def note_compiling() -> None:
        if not args.quiet and not kernels_cached():
            err.write(f"singplan: first run after an install: compiling the planner's kernels ({COMPILE_NOTE}; "
                      "cached on disk afterwards)\n")

    if args.method is not None:  # named as the user gave it: the option, not the task's field it overrides
        check_method_name("--method", args.method)
    with _imports_frozen(), plan_bar(err, args.quiet) as bar:  # imports stay alive until exit: no collection
        task = load_task(args.task)

        def start() -> None:
            note_compiling()
            if bar is not None:
                bar.start()

        done = plan_into(task, args.output, method=args.method, report=not args.no_report,
                         replay=not args.no_replay, progress=bar.progress if bar is not None else None,
                         before_planning=start)
        if bar is not None:
            bar.close()
        for name, reason in done.skipped.items():
            err.write(f"singplan: warning: {name} not written (the plan succeeded): {reason}\n")
        if done.stale:
            err.write(f"singplan: warning: {', '.join(done.stale)} in {done.folder} "
                      f"{'is' if len(done.stale) == 1 else 'are'} from an earlier run and "
                      f"{'does' if len(done.stale) == 1 else 'do'} not show this plan "
                      "(remove them, or write the pages or exports again)\n")
        if args.json:
            from singplan.outputs import documents

            out.write(documents.dumps(documents.plan_document(str(args.task), done)))
        elif args.quiet:
            out.write(f"planned {args.task}: {done.traj.duration_s:.3f} s, {len(done.traj.t)} samples -> "
                      f"{done.folder}\n")
        else:
            out.write(summary(done.traj, task, full=args.full))
            out.write(f"wrote {', '.join(str(done.folder / name) for name in done.files)}\n")
            for name, reason in done.skipped.items():
                out.write(f"not written: {name} ({reason})\n")
        return 0


def cmd_check(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from singplan.entry import detect, load_task

    task = load_task(args.task)
    found = detect(task)
    refusal = next((m.no_plan for m in found if m.no_plan is not None), None)
    if args.json:
        from singplan.outputs import documents

        out.write(documents.dumps(documents.check_document(str(args.task), found)))
    else:
        _write_check(args.task, found, out)
    if refusal is None:
        return 0
    err.write(f"singplan: error: {refusal}\n")  # as plan says it (exit 3): the task has no plan
    return refusal.exit_code


def _write_check(task: Path, found: Sequence[MoveZones], out: TextIO) -> None:
    """``singplan check``'s text: the zones, the stopping bound (or why there is none), the clearances."""
    out.write(f"{task}: {sum(len(m.zones) for m in found)} singular zone(s) along the programmed path\n")
    for m in found:
        for z in m.zones:
            out.write(f"  move {m.index} ({m.kind}) {z.kind:8s} s {z.u_entry * m.length_m * 1e3:8.1f} .. "
                      f"{z.u_exit * m.length_m * 1e3:8.1f} mm, closest {z.describe_distance()} at "
                      f"s {z.u_closest * m.length_m * 1e3:.1f} mm\n")
    unplanned = [f"{m.index} ({m.kind})" for m in found if m.no_plan is not None]
    bounded = [(m, m.stopping) for m in found if m.stopping is not None]
    if unplanned:
        which = f"moves {', '.join(unplanned)} have" if len(unplanned) > 1 else f"move {unplanned[0]} has"
        out.write(f"stopping distance: no bound: {which} no plan (no method's joint path stays within the "
                  f"limits and tolerances, clear of collisions; the reason below)\n")
    elif bounded:
        worst, figure = max(bounded, key=lambda mf: mf[1].bound_m)
        where = (f"{figure.at:.2f} of the joint motion" if worst.kind == "ptp"
                 else f"s {figure.at * worst.length_m * 1e3:.1f} mm")
        out.write(f"stopping distance: at most {figure.bound_m * 1e3:.3f} mm (a bound for every plan of the "
                  f"task), reached in move {worst.index} ({worst.kind}) at {where}\n")
    _write_clearances(found, out)


def _write_clearances(found: Sequence[MoveZones], out: TextIO) -> None:
    """``singplan check``'s least clearance of each move along its programmed path (collision checking on)."""
    from singplan.kinematics.collision import describe_distance

    checked = [(m, m.clearance) for m in found if m.clearance is not None]
    if not checked:
        return
    out.write(f"clearance along the programmed path (start branch, not planned; clearance "
              f"{checked[0][1].clearance_m * 1e3:g} mm):\n")
    for m, clearance in checked:
        least = clearance.closest
        text = (f"closest {least.bodies[0]} / {least.bodies[1]} {describe_distance(least.distance_m)} at "
                f"{m.where(least.sample)}" if least is not None else "no pair checked")
        if clearance.contacts:
            c = clearance.contacts[0]
            text += (f"; collides: {c.bodies[0]} and {c.bodies[1]} {describe_distance(c.distance_m)} at "
                     f"{m.where(c.sample, c.fraction)}")
        out.write(f"  move {m.index} ({m.kind}) {text}\n")
    for contact in checked[0][0].fixed:  # the same in every move: `singplan plan` refuses the task
        out.write(f"  fixed base: {contact.advice(checked[0][1].clearance_m)}\n")


def cmd_demo(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    task_path = Path(__file__).with_name("demo_task.yaml")
    out.write(f"singplan demo: planning {task_path.name} (a LIN through a wrist singularity, KUKA KR 6 R900-2)\n")
    code = cmd_plan(argparse.Namespace(task=task_path, output=args.output, method=None, quiet=False,
                                       no_report=False, no_replay=False, json=False, full=False), out, err)
    out.write(f"task: {task_path}\n")
    return code


def cmd_replay(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from singplan.outputs.viewer import replay

    if args.serve:
        return _serve(args, out, err)
    if args.host is not None:
        raise InputError("replay: --host goes with --serve")
    if args.speed is not None:  # the page has its own: Open Controls -> Animations
        raise InputError("replay: --speed goes with --serve (the --html page sets its speed in its own controls: "
                         "Open Controls -> Animations)")
    if args.html is None:
        raise InputError("replay: give --html FILE (write the page) or --serve (live meshcat server)")
    written = replay(args.trajectory, html=args.html)
    out.write(f"wrote {written}: open it in a browser (offline, self-contained)\n")
    return 0


def _serve(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Play the trajectory on a live meshcat server until Ctrl-C (or SIGTERM)."""
    from singplan.outputs.viewer import LiveReplay, check_host, is_loopback, replay

    host = DEFAULT_HOST if args.host is None else args.host
    check_host(host)  # an address that names nothing is refused before any warning about it
    if not is_loopback(host):
        err.write(f"singplan: warning: --host {host} is not a loopback address: anyone who can reach this "
                  f"machine there can open the replay (the default {DEFAULT_HOST} serves this machine only)\n")
    live = replay(args.trajectory, serve=True, speed=1.0 if args.speed is None else args.speed,
                  loop=not args.no_loop, host=host)
    assert isinstance(live, LiveReplay)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        out.write(f"replay served at {live.url} (Ctrl-C stops it)\n")
        out.flush()
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        out.write("replay server stopped\n")
    finally:
        live.close()
        signal.signal(signal.SIGTERM, previous)
    return 0


def cmd_batch(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Plan many tasks (singplan.batch): a line per finished task on stderr, the totals on stdout."""
    from singplan import batch
    from singplan.entry import check_method_name

    if args.method is not None:  # refused once, up front, rather than by every task
        check_method_name("--method", args.method)
    if args.scheduler is None and not args.quiet:
        warning = batch.memory_warning(batch.local_workers(args.workers, len(args.tasks)))
        if warning:
            err.write(f"singplan: warning: {warning}\n")

    def show(record: batch.TaskRecord, done: int, total: int) -> None:
        seconds = "" if record.wall_s is None else f" {record.wall_s:7.2f} s"
        message = " ".join(record.message.split())
        err.write(f"[{done}/{total}] exit {record.exit_code}{seconds}  {record.task}: {message}\n")
        err.flush()

    result = batch.plan_many(args.tasks, args.output, workers=args.workers, scheduler=args.scheduler,
                             method=args.method, report=not args.no_report, replay=not args.no_replay,
                             progress=None if args.quiet else show)
    counts: dict[int, int] = {}
    for record in result.records:
        counts[record.exit_code] = counts.get(record.exit_code, 0) + 1
    tally = ", ".join(f"{n} exit {code}" for code, n in sorted(counts.items()))
    state = "interrupted" if result.interrupted else "done"
    out.write(f"batch {state}: {len(result.records)} task(s) ({tally}) in {result.wall_s:.1f} s; "
              f"summary {result.summary_csv}, {result.summary_json}\n")
    return result.exit_code


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def cmd_export(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Write a planned output folder's trajectory in a controller format (singplan.outputs.exports)."""
    from singplan.outputs import exports
    from singplan.results.trajectory import load

    fmt = args.format
    if fmt not in FORMATS:
        near = nearest(fmt, FORMATS)
        raise InputError(f"--format: unknown format {fmt!r}{f' (did you mean {near}?)' if near else ''}; "
                         f"valid formats: {', '.join(FORMATS)}")
    folder = Path(args.out).parent if Path(args.out).is_file() else Path(args.out)  # a trajectory.json: its folder
    program = fmt in PROGRAM_FORMATS
    given = [flag for flag, value in (("--name", args.name), ("--tolerance-mm", args.tolerance_mm),
                                      ("--tolerance-deg", args.tolerance_deg)) if value is not None]
    if given and not program:
        raise InputError(f"{', '.join(given)}: only for the controller programs ({', '.join(PROGRAM_FORMATS)}), "
                         f"not --format {fmt}")
    traj = load(args.out)
    if program:
        from singplan.outputs import programs

        program_options = programs.ProgramOptions(
            args.name, DEFAULT_TOLERANCE_MM if args.tolerance_mm is None else args.tolerance_mm,
            DEFAULT_TOLERANCE_DEG if args.tolerance_deg is None else args.tolerance_deg,
            source=str(folder / "trajectory.json" if Path(args.out).is_dir() else args.out))
        if args.vendor_config:
            raise InputError("--vendor-config: only the csv-deg format carries a vendor configuration per sample; "
                             "a controller program notes each move's configuration in a comment")
        target = args.file if args.file is not None else programs.program_path(folder, fmt, args.name)
        out.write(programs.write_program(traj, fmt, target, program_options).message() + "\n")
        return 0
    target = args.file if args.file is not None else exports.default_path(folder, fmt)
    options = exports.UrScriptOptions(controller=args.ur_controller, lookahead_time_s=args.lookahead_time,
                                      gain=args.gain)
    if fmt == "urscript" and not exports.is_ur_robot(traj):
        err.write(f"singplan: warning: {traj.robot} is not a Universal Robots arm; "
                  "check the URScript program's joint order and signs before running it\n")
    written = exports.export(traj, fmt, target, urscript=options, vendor_config=args.vendor_config)
    out.write(f"wrote {written}\n")
    return 0


def cmd_completion(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Print the shell completion script (singplan.outputs.completion)."""
    from singplan.kinematics.robot import bundled_robots
    from singplan.outputs.completion import completion_script

    out.write(completion_script(build_parser(), args.shell, list(bundled_robots())))
    return 0


def _version() -> str:
    """``singplan --version``: singplan's version, then Python's and the planning libraries' (for bug reports)."""
    from importlib.metadata import PackageNotFoundError, version

    found = []
    for name in ("pin", "toppra", "numba", "numpy", "meshcat"):
        try:
            found.append(f"{name} {version(name)}")
        except PackageNotFoundError:
            found.append(f"{name} missing")
    return f"singplan {__version__}\nPython {sys.version.split()[0]}; {', '.join(found)}"


class _VersionAction(argparse.Action):
    """``--version``: the versions are looked up only when asked for (a few ms of metadata reads)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="print the versions of singplan, Python and the planning libraries, and exit")

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        sys.stdout.write(_version() + "\n")
        parser.exit()


COMPILE_NOTE = "about 6 s of CPU: 10 s on two cores, 25 s when they are busy"  # docs/kinematics.md, measured


def build_parser() -> argparse.ArgumentParser:
    parser = SuggestingParser(prog="singplan", description="Plan robot motions through singularities.")
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                help="`singplan COMMAND --help` tells more")
    robots = sub.add_parser("robots", help="list the bundled robots")
    robots.add_argument("--json", action="store_true", help="machine-readable output")
    robots.set_defaults(func=cmd_robots)
    info = sub.add_parser("info", help="a robot's kinematic family, parameters, tip, joints and crossing methods")
    info.add_argument("robot", help="bundled robot name or path to a URDF")
    info.add_argument("--tip", default=None, help="frame the tool hangs on (default: the robot's)")
    info.add_argument("--json", action="store_true", help="machine-readable output")
    info.set_defaults(func=cmd_info)
    ik = sub.add_parser("ik", help="every IK solution of a TCP pose, with labels and singular distances")
    ik.add_argument("robot", help="bundled robot name or path to a URDF")
    ik.add_argument("--xyz", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"), help="TCP position [m]")
    ik.add_argument("--rpy-deg", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("R", "P", "Y"),
                    help="TCP orientation, URDF fixed-axis roll pitch yaw [deg]")
    ik.add_argument("--tool-xyz", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("X", "Y", "Z"),
                    help="tool offset from the tip frame, in the tip's axes [m] (default 0 0 0: the TCP is the tip)")
    ik.add_argument("--tool-rpy-deg", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("R", "P", "Y"),
                    help="tool orientation in the tip frame, roll pitch yaw [deg] (default 0 0 0)")
    ik.add_argument("--tip", default=None, help="frame the tool hangs on (default: the robot's)")
    ik.add_argument("--seed-deg", type=float, nargs="+", default=None,
                    help="joint values to stay near: the 2*pi variant nearest them (default all zero)")
    ik.add_argument("--hold", default=None, metavar="JOINT=DEG",
                    help="7-joint arms: hold this joint at DEG and list the 6R chain's branches")
    ik.add_argument("--all-variants", action="store_true",
                    help="list every 2*pi variant inside the limits, not one solution per branch")
    ik.add_argument("--json", action="store_true", help=_JSON_HELP.format("ik"))
    ik.set_defaults(func=cmd_ik)
    plan_p = sub.add_parser("plan", help="plan a task YAML into a timed trajectory")
    plan_p.add_argument("task", help="task file (YAML v1)")
    plan_p.add_argument("-o", "--output", default="singplan-out", help="output folder (default: singplan-out)")
    plan_p.add_argument("--method", default=None, help=_METHOD_HELP.format("the task's"))
    plan_p.add_argument("--quiet", action="store_true", help="one line instead of the summary")
    plan_p.add_argument("--no-report", action="store_true", help="do not write report.html")
    plan_p.add_argument("--no-replay", action="store_true", help="do not write replay.html")
    plan_p.add_argument("--full", action="store_true",
                        help="list every move in the summary (programs of more than 20 moves get an overview)")
    plan_p.add_argument("--json", action="store_true", help=_JSON_HELP.format("plan"))
    plan_p.set_defaults(func=cmd_plan)
    check = sub.add_parser("check", help="print the singular zones along a task's path, without planning")
    check.add_argument("task", help="task file (YAML v1)")
    check.add_argument("--json", action="store_true", help=_JSON_HELP.format("check"))
    check.set_defaults(func=cmd_check)
    rep = sub.add_parser("replay", help="replay a planned trajectory in the browser (HTML file or live server)")
    rep.add_argument("trajectory", help="trajectory.json or the output folder holding it")
    rep.add_argument("--html", default=None, help="write the self-contained replay page to this file")
    rep.add_argument("--serve", action="store_true", help="start a live meshcat server on loopback and play there")
    rep.add_argument("--host", default=None,
                     help=f"--serve: address the server listens on (default {DEFAULT_HOST}, this machine only)")
    rep.add_argument("--speed", type=float, default=None, help="--serve: playback speed, x real time (default 1)")
    rep.add_argument("--no-loop", action="store_true", help="--serve: play once instead of looping")
    rep.set_defaults(func=cmd_replay)
    demo = sub.add_parser("demo", help="plan the bundled demo task into ./singplan-demo")
    demo.add_argument("-o", "--output", default="singplan-demo", help="output folder (default: singplan-demo)")
    demo.set_defaults(func=cmd_demo)
    exp = sub.add_parser("export", help="write a planned trajectory as ROS 2, URScript, degree CSV or a KUKA, ABB "
                                        "or FANUC controller program")
    exp.add_argument("out", help="output folder of `singplan plan` (or its trajectory.json)")
    exp.add_argument("--format", required=True, help=f"one of {', '.join(FORMATS)}")
    exp.add_argument("-o", "--output", dest="file", default=None,
                     help="file to write (default: " + ", ".join(f"{k}: {v}" for k, v in
                                                               DEFAULT_FILE_NAMES.items()) + " in OUT)")
    exp.add_argument("--vendor-config", action="store_true",
                     help="csv-deg: add the vendor configuration data (ABB/KUKA/FANUC) of every sample")
    exp.add_argument("--ur-controller", default="e-series", choices=sorted(UR_STEP_S),
                     help="urscript: controller generation, its servo step (e-series 0.002 s, cb3 0.008 s)")
    exp.add_argument("--lookahead-time", type=float, default=0.1, help="urscript: servoj lookahead_time, 0.03-0.2 s")
    exp.add_argument("--gain", type=float, default=300.0, help="urscript: servoj gain, 100-2000")
    exp.add_argument("--name", default=None,
                     help="krl, rapid, fanuc-ls: the program name (default: the -o file's name, else singplan)")
    exp.add_argument("--tolerance-mm", type=float, default=None,
                     help=f"krl, rapid, fanuc-ls: the most the TCP may leave the plan between program points "
                          f"(default {DEFAULT_TOLERANCE_MM:g} mm)")
    exp.add_argument("--tolerance-deg", type=float, default=None,
                     help=f"krl, rapid, fanuc-ls: the same for the TCP orientation "
                          f"(default {DEFAULT_TOLERANCE_DEG:g} deg)")
    exp.set_defaults(func=cmd_export)
    bat = sub.add_parser("batch", help="plan many tasks, one output folder each, plus summary.csv / summary.json")
    bat.add_argument("tasks", nargs="+", help="task files (YAML v1); each one's folder is named after its file")
    bat.add_argument("-o", "--output", required=True, help="batch folder (created if absent; other files kept)")
    where = bat.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="local worker processes (default: the number of CPUs; each task may take 1.5 GB)")
    where.add_argument("--scheduler", default=None,
                       help="a Dask scheduler's address (tcp://host:8786) to plan on instead (needs dask[distributed])")
    bat.add_argument("--method", default=None, help=_METHOD_HELP.format("every task's"))
    bat.add_argument("--quiet", action="store_true", help="no line per finished task")
    bat.add_argument("--no-report", action="store_true", help="do not write report.html")
    bat.add_argument("--no-replay", action="store_true", help="do not write replay.html")
    bat.set_defaults(func=cmd_batch)
    comp = sub.add_parser("completion", help="print a shell completion script (bash, zsh or tcsh)",
                          description="Print the completion script of the singplan command for SHELL. "
                                      'bash: eval "$(singplan completion bash)" in ~/.bashrc; '
                                      "zsh: singplan completion zsh > a folder of $fpath, named _singplan.")
    comp.add_argument("shell", choices=SHELLS, help="the shell the script is for")
    comp.set_defaults(func=cmd_completion)
    return parser


_METHOD_HELP = ("crossing method, overriding {0} singularity.method: " + ", ".join(CROSSING_METHODS)
                + " (or one registered from Python)")
_JSON_HELP = "print one JSON document (format singplan.{0}/1; see docs/json-output.md) instead of the text"


def main(argv: Sequence[str] | None = None, out: TextIO | None = None, err: TextIO | None = None) -> int:
    """Run the CLI; returns the exit code."""
    out = out or sys.stdout
    err = err or sys.stderr
    parser = build_parser()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):  # usage, --help, --version
            args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse already printed the usage error
        return int(exc.code or 0) if exc.code in (0, None) else 2
    try:
        with _replay_warnings(err):
            return int(args.func(args, out, err))
    except SingplanError as exc:
        return _failed(args, out, err, exc.exit_code, f"error: {exc}")
    except KeyboardInterrupt:
        return _failed(args, out, err, 130, "interrupted")
    except BrokenPipeError:  # the reader went away (`singplan robots | head`): nothing left to say
        return _SIGPIPE_EXIT
    except Exception as exc:  # a bug (or an input no check caught): one line, not a traceback
        if os.environ.get("SINGPLAN_DEBUG", "") not in ("", "0"):
            traceback.print_exc(file=err)
        return _failed(args, out, err, 1, f"internal error: {type(exc).__name__}: {_one_line(exc)} "
                                          "(please report this; run with SINGPLAN_DEBUG=1 for the traceback)")


def _failed(args: argparse.Namespace, out: TextIO, err: TextIO, code: int, message: str) -> int:
    """Report a failed command: one line on stderr, and with --json the failure document on stdout."""
    err.write(f"singplan: {message}\n")
    if getattr(args, "json", False) and args.command in ("plan", "check", "ik"):
        from singplan.outputs import documents

        out.write(documents.dumps(documents.failure(args.command, code, message.removeprefix("error: "))))
    return code


_SIGPIPE_EXIT = 141  # 128 + SIGPIPE, what a shell reports for a writer whose pipe closed


def _one_line(exc: BaseException, max_chars: int = 300) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= max_chars else text[:max_chars] + " ..."


def run() -> None:
    """Console-script entry point; SIGTERM stops like Ctrl-C (temporary files are removed)."""
    signal.signal(signal.SIGTERM, _interrupt)
    code = main()
    if code == _SIGPIPE_EXIT:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit's flush
    # The interpreter's exit runs full collections over every object still alive (~175k after a plan:
    # ~0.4 s of a 1.6 s `singplan plan`, most of it numba's registries), only to free memory the OS takes
    # back anyway; frozen objects are skipped. Files are closed and atexit handlers run as before.
    gc.freeze()
    sys.exit(code)

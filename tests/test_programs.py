"""Controller programs (KUKA KRL, ABB RAPID, FANUC LS) read back by independent readers.

Every public scenario of a bundled KUKA, ABB or FANUC arm is planned, exported in its vendor's
format and read back by ``tests/program_readers.py`` (which parses the program as the controller
language defines it and undoes the controller convention from robots.yaml on its own). Checked:

* at every program point the joint values are the plan's at that time to within 0.001 deg, and the
  time is the plan's to within one period (and the format's printed resolution);
* every segment boundary is a point; the robot stops exactly where the plan rests (unblended move
  ends, null-space pause ends) and only at samples where the plan is at rest;
* the TCP of the straight joint segments between points stays within T of the planned TCP path
  (both ways: every planned sample near a segment, every segment point near the planned path),
  with forward kinematics by Pinocchio from the URDF, not singplan's;
* the reconstructed motion (the points, linearly interpolated in time at the plan's period) passes
  the independent checker, with what does not apply to a piecewise-linear stand-in for the
  controller's own interpolation lifted (see :func:`checker_task`).
"""

from __future__ import annotations

import json
import math
import re
import shutil
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.errors import InputError, OutputPathError
from singplan.kinematics.robot import load_robot, robots_dir
from singplan.kinematics.vendor_config import convention_for, printed_axes_deg
from singplan.outputs import programs
from singplan.outputs.programs import ProgramOptions, program_texts, write_program
from singplan.outputs.programs.model import printed_times
from singplan.outputs.programs.points import PointTolerance, choose_points, weave_scale
from singplan.outputs.timeline import robot_of
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory, save
from singplan.task.load import load_task
from tests.cli_helpers import run_cli
from tests.program_readers import convention, read_program, urdf_joints_deg
from tests.shared import SHARED, require, run_checker

FORMAT_OF_VENDOR = {"kuka": "krl", "abb": "rapid", "fanuc": "fanuc-ls"}
EXTENSION = {"krl": ".src", "rapid": ".mod", "fanuc-ls": ".ls"}
TOLERANCE_MM = 0.1
PRINTED_DEG = {"krl": 5e-5, "rapid": 5e-5, "fanuc-ls": 5e-4}  # half the last printed digit
FLOAT32_DEG = 2.0**-15  # a single-precision float's spacing at 256..512 deg, the largest axis values here


def public_scenarios() -> list[str]:
    """``folder/name`` of every exit-0 public scenario of a bundled KUKA, ABB or FANUC arm."""
    out = []
    for folder in ("scenarios", "scenarios_programs"):
        expect = SHARED / folder / "expect.yaml"
        if not expect.is_file():
            return [f"{folder}/absent"]
        for name, spec in yaml.safe_load(expect.read_text()).items():
            if spec.get("exit") == 0 and name.split("_")[0] in FORMAT_OF_VENDOR:
                out.append(f"{folder}/{name}")
    return out


SCENARIO_NAMES = public_scenarios()


@cache
def planned(name: str) -> Trajectory:
    folder, stem = name.split("/")
    task = require(SHARED / folder / f"{stem}.yaml")
    return plan(load_task(task))


def fmt_of(traj: Trajectory) -> str:
    return FORMAT_OF_VENDOR[traj.robot.split("_")[0]]


def export(traj: Trajectory, folder: Path, fmt: str | None = None, **options: object) -> programs.ProgramExport:
    fmt = fmt or fmt_of(traj)
    return write_program(traj, fmt, folder / ("prog" + EXTENSION[fmt]), ProgramOptions(**options))  # type: ignore[arg-type]


def read_back(traj: Trajectory, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times [s], URDF joints [deg] and stop flags of the program at ``path``."""
    speeds = np.degrees(load_robot(traj.urdf, tip=traj.tip).velocity_rad_s).tolist()
    reading = read_program(path, speeds)
    t, axes, stop = reading.arrays()
    matrix, offsets = convention(traj.robot, traj.urdf)
    return t, urdf_joints_deg(axes, matrix, offsets), stop


# --- independent geometry ------------------------------------------------------------------------

class Fk:
    """TCP positions by Pinocchio from the trajectory's URDF, tip and tool."""

    def __init__(self, traj: Trajectory) -> None:
        self.model = pin.buildModelFromUrdf(traj.urdf)
        self.data = self.model.createData()
        self.frame = self.model.getFrameId(traj.tip)
        rpy = np.radians(traj.tool.get("rpy_deg", [0, 0, 0]))
        self.tool = pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.asarray(traj.tool.get("xyz", [0, 0, 0]), dtype=float))
        self.index = [self.model.joints[self.model.getJointId(n)].idx_q for n in traj.joint_names]

    def positions(self, q: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), 3))
        full = pin.neutral(self.model)
        for k, row in enumerate(q):
            full[self.index] = row
            pin.framesForwardKinematics(self.model, self.data, full)
            out[k] = (self.data.oMf[self.frame] * self.tool).translation
        return out


def distances_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 3) to the polyline through ``line`` (M, 3)."""
    a, b = line[:-1], line[1:]
    d = b - a
    length2 = np.maximum(np.sum(d * d, axis=1), 1e-30)
    u = np.clip(np.einsum("nmk,mk->nm", points[:, None, :] - a[None], d) / length2, 0.0, 1.0)
    nearest = a[None] + u[..., None] * d[None]
    return np.min(np.linalg.norm(points[:, None, :] - nearest, axis=2), axis=1) if len(line) > 1 else \
        np.linalg.norm(points - line[0], axis=1)


def segment_deviation_mm(traj: Trajectory, t: np.ndarray, q_deg: np.ndarray, fk: Fk) -> float:
    """The largest distance [mm], both ways, between the planned TCP samples of each stretch between
    consecutive program points and the TCP along the straight joint segment over that stretch (drawn
    at four points per planned sample, so that its own polyline is as fine as the plan's)."""
    q_plan = np.asarray(traj.q)
    p_plan = fk.positions(q_plan)
    k = np.rint(t / traj.period).astype(int)
    worst = 0.0
    for a, b, qa, qb in zip(k[:-1], k[1:], np.radians(q_deg[:-1]), np.radians(q_deg[1:]), strict=True):
        s = np.linspace(0.0, 1.0, 4 * (b - a) + 1)
        chord = fk.positions(qa + s[:, None] * (qb - qa))
        plan_part = p_plan[a:b + 1]
        worst = max(worst, float(distances_to_polyline(plan_part, chord).max()),
                    float(distances_to_polyline(chord, plan_part).max()))
    return worst * 1e3


def plan_rests_at(traj: Trajectory, k: int) -> bool:
    """The checker's rest rule: the steps on both sides of sample k no longer than a dt^2."""
    accel = float(np.max(traj.task.limits.acceleration_rad_s2))
    bound = accel * traj.period**2 * 1.02
    q = np.asarray(traj.q)
    steps = [np.abs(q[k + 1] - q[k]) if k + 1 < len(q) else 0.0, np.abs(q[k] - q[k - 1]) if k > 0 else 0.0]
    return all(np.all(s <= bound) for s in steps)


def required_stops(traj: Trajectory) -> set[int]:
    """Samples where the task's plan must be at rest: the ends of unblended moves, and the ends of each
    null-space pause (the run of samples at which the TCP stands still inside a crossing that paused)."""
    stops = {0, len(traj.t) - 1}
    fk = Fk(traj)
    p = None
    moves = traj.task.moves
    for seg in traj.segments:
        if seg is [s for s in traj.segments if s.move == seg.move][-1] and not moves[seg.move].blend_mm:
            stops.add(round(seg.t1 / traj.period))
        if seg.pause_s is not None:
            p = fk.positions(np.asarray(traj.q)) if p is None else p
            k0, k1 = round(seg.t0 / traj.period), round(seg.t1 / traj.period)
            still = np.flatnonzero(np.linalg.norm(np.diff(p[k0:k1 + 1], axis=0), axis=1) < 1e-7) + k0
            if len(still):
                runs = np.split(still, np.flatnonzero(np.diff(still) > 1) + 1)
                longest = max(runs, key=len)
                stops.update({int(longest[0]), int(longest[-1]) + 1})
    return stops


# --- the round trip on every public scenario ------------------------------------------------------

# one of each kind in the default run (LIN through a wrist singularity and fly-by per vendor, the
# null-space pauses); every public scenario with -m slow
ROUND_TRIP_BY_DEFAULT = ("scenarios/kuka_kr6_r900_2__wrist_exact_lin", "scenarios/abb_irb2400__wrist_exact_lin",
                         "scenarios/fanuc_lrmate200id__wrist_exact_lin",
                         "scenarios_programs/kuka_kr6_r900_2__nullspace_wrist_exact_hit",
                         "scenarios_programs/abb_irb2400__flyby_pick_place",
                         "scenarios_programs/fanuc_lrmate200id__flyby_seam_lin_circ_lin")


@pytest.mark.parametrize("name", ROUND_TRIP_BY_DEFAULT)
def test_a_public_scenario_reads_back_as_planned(name: str, tmp_path: Path) -> None:
    assert_reads_back(planned(name), tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in SCENARIO_NAMES if n not in ROUND_TRIP_BY_DEFAULT])
def test_every_public_scenario_reads_back_as_planned(name: str, tmp_path: Path) -> None:
    assert_reads_back(planned(name), tmp_path)


def assert_reads_back(traj: Trajectory, tmp_path: Path) -> None:
    fmt = fmt_of(traj)
    result = export(traj, tmp_path, fmt)
    t, q_deg, stop = read_back(traj, result.files[0])
    k = np.rint(t / traj.period).astype(int)

    assert len(t) == result.points and t[0] == 0.0 and k[-1] == len(traj.t) - 1
    assert np.all(np.diff(k) > 0)
    time_error = np.abs(t - np.asarray(traj.t)[k])
    assert time_error.max() < min(traj.period, programs.DIALECTS[fmt].time_step_s / 2 + 1e-9)
    joint_error = np.abs(q_deg - np.degrees(np.asarray(traj.q)[k]))
    assert joint_error.max() <= PRINTED_DEG[fmt] + FLOAT32_DEG < 0.001  # printed, then held in single precision

    boundaries = {round(x / traj.period) for seg in traj.segments for x in (seg.t0, seg.t1)}
    assert boundaries <= set(k.tolist())
    stops = set(k[stop].tolist())
    assert required_stops(traj) <= stops
    assert all(plan_rests_at(traj, s) for s in stops), "an exact stop where the plan moves"

    deviation = segment_deviation_mm(traj, t, q_deg, Fk(traj))
    assert deviation <= TOLERANCE_MM + 0.005
    assert result.max_position_error_mm <= TOLERANCE_MM


def checker_task(task: dict, traj: Trajectory, t: np.ndarray, q_deg: np.ndarray, tolerance_mm: float) -> dict:
    """The task as the checker should judge the reconstructed motion: the straight joint segments
    between program points stand in for the controller's own interpolation (spline, zones, CNT),
    which rounds their corners, so what only that rounding provides is lifted:

    * joint acceleration (the piecewise-linear stand-in has velocity steps at every point; the
      checker's rest test is the same bound), jerk and torque: ``limits`` lifted;
    * the TCP speed (constant joint speed along a segment swings the TCP speed around its mean by a
      few percent near the crossings): every programmed ``speed`` lifted;
    * position: the plan's tolerance plus the program's T; joint targets (the start, PTP ``to``
      joints): the program's own points there, as printed (FANUC's 0.001 deg moves them by up to
      0.0005 deg, which the checker's exact joint-target test would take for a miss).
    Kept: path position and orientation (0.01 deg outside crossings), blend spheres, joint limits
    and speeds, the moves' targets, crossings near a singularity, timing.
    """
    task = json.loads(json.dumps(task))
    sing = task.setdefault("singularity", {})
    sing["position_tolerance_mm"] = float(sing.get("position_tolerance_mm", 0.01)) + tolerance_mm
    limits = task.setdefault("limits", {})
    limits["acceleration"] = 1e9
    limits.pop("jerk", None)
    limits.pop("torque_scale", None)
    for move in task["moves"]:
        spec = next(iter(move.values()))
        if isinstance(spec, dict) and "speed" in spec:
            spec["speed"] = 1e9
    if "joints_deg" in task["start"]:
        task["start"]["joints_deg"] = [float(v) for v in q_deg[0]]
    point_at = {int(k): n for n, k in enumerate(np.rint(t / traj.period).astype(int))}
    for m, segs in traj.segments_by_move().items():
        to = task["moves"][m].get("ptp", {}).get("to", {})
        if "joints_deg" in to and segs[-1].kind != "blend":  # a blended move's target is not a point
            to["joints_deg"] = [float(v) for v in q_deg[point_at[round(segs[-1].t1 / traj.period)]]]
    return task


def reconstructed(traj: Trajectory, t: np.ndarray, q_deg: np.ndarray, out: Path) -> Path:
    """trajectory.json of the program's points interpolated linearly in time at the plan's period:
    each point at the controller cycle its time falls on (the round trip holds every time within
    half a cycle), the cycles between them on the straight joint segment."""
    doc = traj.to_json()
    k = np.rint(t / traj.period)
    samples = np.arange(len(traj.t))
    q = np.stack([np.interp(samples, k, np.radians(q_deg[:, j])) for j in range(q_deg.shape[1])], axis=1)
    doc.update(q=q.tolist(), qd=np.zeros_like(q).tolist(), qdd=np.zeros_like(q).tolist())
    out.mkdir()
    (out / "trajectory.json").write_text(json.dumps(doc))
    return out


# FANUC positions hold 0.001 deg: a move's end pose is within ~0.0015 deg, not the checker's 0.001 deg
_PRINTED_TARGET = re.compile(r"move \d+ \((lin|circ)\) is (\S+) mm / (\S+) deg from its target")
# outside crossings the plan keeps the orientation within the checker's 0.01 deg, and the program
# keeps within DEFAULT_TOLERANCE_DEG of the plan between its points: together at most their sum
_KEPT_ORIENTATION = re.compile(r"orientation deviates (\S+) deg outside the segments marked as crossings")
_PLAN_ORIENTATION_DEG = 0.01


def scenario_task(name: str) -> dict:
    folder, stem = name.split("/")
    return yaml.safe_load((SHARED / folder / f"{stem}.yaml").read_text())


def assert_checker_passes(traj: Trajectory, task_doc: dict, tmp_path: Path) -> None:
    fmt = fmt_of(traj)
    result = export(traj, tmp_path, fmt)
    t, q_deg, _ = read_back(traj, result.files[0])
    task = checker_task(task_doc, traj, t, q_deg, TOLERANCE_MM)
    task_file = tmp_path / "task.yaml"
    task_file.write_text(yaml.safe_dump(task))
    proc = run_checker(task_file, reconstructed(traj, t, q_deg, tmp_path / "rec"), "--json")
    result_doc = json.loads(proc.stdout[:proc.stdout.rindex("}") + 1])
    failures = [f for f in result_doc["failures"]
                if not (fmt == "fanuc-ls" and (m := _PRINTED_TARGET.match(f)) and float(m.group(3)) <= 0.002)
                and not ((m := _KEPT_ORIENTATION.match(f))
                         and float(m.group(1)) <= _PLAN_ORIENTATION_DEG + ProgramOptions().tolerance_deg)]
    assert not failures, failures


CHECKED_BY_DEFAULT = ("scenarios_programs/kuka_kr6_r900_2__nullspace_wrist_exact_hit",
                      "scenarios_programs/abb_irb2400__flyby_pick_place",
                      "scenarios_programs/fanuc_lrmate200id__flyby_seam_lin_circ_lin")


@pytest.mark.parametrize("name", CHECKED_BY_DEFAULT)
def test_the_reconstructed_motion_passes_the_checker(name: str, tmp_path: Path) -> None:
    assert_checker_passes(planned(name), scenario_task(name), tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in SCENARIO_NAMES if n not in CHECKED_BY_DEFAULT])
def test_the_reconstructed_motion_passes_the_checker_on_every_scenario(name: str, tmp_path: Path) -> None:
    assert_checker_passes(planned(name), scenario_task(name), tmp_path)


# Random valid tasks (tests/task_strategies.py) of the bundled KUKA, ABB and FANUC arms that plan:
# other arms (M-10iA, R-2000iB, KR 6 R700, KR 120, IRB 6700), random periods (1-20 ms), tolerances,
# tools, speeds and methods. Seeds found by planning seeds 0-30 and keeping those that plan (seed 18
# starts the LR Mate folded into its own base: refused, exit 3, since the bundled arms check self-collision).
GENERATED_SEEDS = (4, 11, 12, 13, 14, 15, 16, 17, 21, 22, 29, 30)


@cache
def generated(seed: int) -> tuple[Trajectory, dict]:
    from singplan.task.load import parse_task
    from tests.task_strategies import seeded_task

    task = seeded_task(seed)
    return plan(parse_task(task)), task


@pytest.mark.parametrize("seed", GENERATED_SEEDS[:3])
def test_a_generated_task_reads_back_as_planned(seed: int, tmp_path: Path) -> None:
    assert_reads_back(generated(seed)[0], tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("seed", GENERATED_SEEDS)
def test_a_generated_task_reads_back_and_passes_the_checker(seed: int, tmp_path: Path) -> None:
    traj, task = generated(seed)
    assert_reads_back(traj, tmp_path / "read")
    assert_checker_passes(traj, task, tmp_path / "checked")


# --- robots without a convention, names, options ---------------------------------------------------


@pytest.fixture(scope="module")
def ur5_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    task = Path(__file__).resolve().parents[1] / "examples" / "ur5_wrist_auto.yaml"
    return save(plan(load_task(task)), tmp_path_factory.mktemp("ur5"))


@pytest.mark.parametrize("fmt", ["krl", "rapid", "fanuc-ls"])
def test_a_robot_without_a_vendor_convention_is_refused_by_name(fmt: str, ur5_folder: Path) -> None:
    before = sorted(p.name for p in ur5_folder.iterdir())
    code, _, err = run_cli("export", str(ur5_folder), "--format", fmt)
    assert code == 2
    assert "robot 'ur5' has no controller convention" in err and "robots.yaml records none" in err
    assert sorted(p.name for p in ur5_folder.iterdir()) == before


def test_a_robot_of_another_vendor_is_refused_with_its_format(planned_kuka: Path) -> None:
    code, _, err = run_cli("export", str(planned_kuka), "--format", "rapid")
    assert code == 2 and "controller convention of KUKA, not ABB (use --format krl)" in err


def _user_copy(traj: Trajectory, folder: Path) -> Trajectory:
    """The trajectory of a user's URDF: the bundled file copied, under another robot name."""
    from dataclasses import replace

    urdf = folder / "my_arm.urdf"
    shutil.copy(traj.urdf, urdf)
    return replace(traj, robot="my_arm", urdf=str(urdf))


def test_a_user_urdf_needs_its_sidecar_and_then_writes_the_same_program(planned_kuka: Path, tmp_path: Path) -> None:
    from singplan.results.trajectory import load

    traj = load(planned_kuka)
    user = _user_copy(traj, tmp_path)
    with pytest.raises(InputError, match=r"robot 'my_arm' has no controller convention.*add .*my_arm.controller.yaml"):
        program_texts(user, "krl")
    spec = yaml.safe_load((robots_dir() / "robots.yaml").read_text())["robots"][traj.robot]["controller"]
    (tmp_path / "my_arm.controller.yaml").write_text(yaml.safe_dump({"controller": spec}))
    mine, bundled = program_texts(user, "krl")["singplan.src"], program_texts(traj, "krl")["singplan.src"]
    body = [line for line in mine.splitlines() if "robot:" not in line]
    assert body == [line for line in bundled.splitlines() if "robot:" not in line]


def test_a_sidecar_convention_is_undone_by_the_reader(planned_kuka: Path, tmp_path: Path) -> None:
    """A made-up convention (offsets, a flipped sign, a coupling) round-trips through the reader."""
    from singplan.results.trajectory import load

    traj = _user_copy(load(planned_kuka), tmp_path)
    convention_spec = {"vendor": "kuka", "axis_signs": [1, -1, 1, 1, -1, 1],
                       "axis_offsets_deg": [0, 90, -90, 0, 0, 180], "couplings": [{"axis": 3, "joint": 2, "factor": 1}]}
    (tmp_path / "my_arm.controller.yaml").write_text(yaml.safe_dump({"controller": convention_spec}))
    result = export(traj, tmp_path, "krl")
    t, q_deg, _ = read_back(traj, result.files[0])
    k = np.rint(t / traj.period).astype(int)
    assert np.abs(q_deg - np.degrees(np.asarray(traj.q)[k])).max() <= PRINTED_DEG["krl"] + FLOAT32_DEG
    header = result.files[0].read_text().replace("\n; ", " ")  # comment lines joined
    assert "a2 = -q2 + 90; a3 = q3 + q2 - 90; a5 = -q5; a6 = q6 + 180" in header


@pytest.mark.parametrize(("args", "message"), [
    (("--name", "9lives"), "--name: '9lives' is not a valid KUKA KRL program name"),
    (("--name", "a" * 25), "at most 24 characters"),
    (("--name", "weld", "-o", "{out}/seam.src"), "a KUKA KRL program is named after its file"),
    (("-o", "{out}/my-prog.src"), "is not a valid KUKA KRL program name"),
    (("--tolerance-mm", "0"), "--tolerance-mm: expected a positive number"),
    (("--tolerance-deg", "nan"), "--tolerance-deg: expected a positive number"),
    (("--vendor-config",), "--vendor-config: only the csv-deg format"),
])
def test_bad_program_options_exit_2_naming_the_option(args: tuple[str, ...], message: str, planned_kuka: Path) -> None:
    before = sorted(p.name for p in planned_kuka.iterdir())
    code, _, err = run_cli("export", str(planned_kuka), "--format", "krl", *(a.format(out=planned_kuka) for a in args))
    assert code == 2 and message in err
    assert sorted(p.name for p in planned_kuka.iterdir()) == before


def test_program_options_are_refused_for_other_formats(planned_kuka: Path) -> None:
    code, _, err = run_cli("export", str(planned_kuka), "--format", "ros2", "--tolerance-mm", "0.5")
    assert code == 2 and "--tolerance-mm: only for the controller programs" in err


def test_the_cli_names_the_file_after_the_program_and_prints_the_figures(planned_kuka: Path, tmp_path: Path) -> None:
    code, out, _ = run_cli("export", str(planned_kuka), "--format", "krl", "--name", "Seam_1")
    assert code == 0 and (planned_kuka / "Seam_1.src").is_file()
    assert "DEF Seam_1( )" in (planned_kuka / "Seam_1.src").read_text()
    # two moves, neither blended: three exact stops
    assert re.search(r"wrote .*Seam_1.src: KUKA KRL program Seam_1, \d+ points \(3 exact stops\)", out)
    assert re.search(r"the TCP keeps within 0\.\d{4} mm / 0\.\d{4} deg of the plan \(tolerance 0\.1 mm", out)
    code, out, _ = run_cli("export", str(planned_kuka / "trajectory.json"), "--format", "krl", "-o",
                           str(tmp_path / "other" / "prog.src"), "--tolerance-mm", "0.5")
    assert code == 0 and "DEF prog( )" in (tmp_path / "other" / "prog.src").read_text()


def test_a_looser_tolerance_takes_fewer_points(planned_kuka: Path, tmp_path: Path) -> None:
    from singplan.results.trajectory import load

    traj = load(planned_kuka)
    counts = [export(traj, tmp_path / str(t), tolerance_mm=t).points for t in (0.01, 0.1, 1.0)]
    assert counts[0] > counts[1] > counts[2] >= 3


def _short_segments(traj: Trajectory, **tolerance: float) -> tuple[int, int]:
    """How many of a KRL program's segments are shorter than 12 ms, of how many."""
    motions = programs.build_program(traj, "krl", ProgramOptions(**tolerance)).model.motions()[1:]
    return sum(m.duration_s < 0.012 for m in motions), len(motions)


def test_the_short_segment_note_names_the_tolerance_that_binds(tmp_path: Path) -> None:
    """On the fly-by example the orientation tolerance (0.005 deg) ends the short segments: the note said
    a larger --tolerance-mm helps (2 mm still left 96 of 111 short); it names the one that binds and
    what ten times it gives, as an export with that value counts it."""
    traj = plan(load_task(Path(__file__).resolve().parents[1] / "examples" / "flyby_pick_place.yaml"))
    export = write_program(traj, "krl", tmp_path / "a" / "prog.src")
    (note,) = [n for n in export.notes if "shorter than 12 ms" in n]
    short, total = _short_segments(traj)
    assert note.startswith(f"{short} of {total} segments are shorter than 12 ms")
    assert "the orientation tolerance (0.005 deg) is what ends" in note and "--tolerance-mm" not in note
    short, total = _short_segments(traj, tolerance_deg=0.05)
    assert note.endswith(f"--tolerance-deg 0.05 gives {short} of {total} segments shorter")
    assert short < total / 3
    wider = write_program(traj, "krl", tmp_path / "b" / "prog.src", ProgramOptions(tolerance_deg=0.05))
    (note,) = [n for n in wider.notes if "shorter than 12 ms" in n]
    assert "the position tolerance (0.1 mm) is what ends" in note and "--tolerance-mm 1 gives" in note


# --- the output file rules ----------------------------------------------------------------------

def test_an_unusable_path_is_bad_input_and_nothing_is_written(planned_kuka: Path, tmp_path: Path) -> None:
    (tmp_path / "a_folder.src").mkdir()
    (tmp_path / "a_file").write_text("x")
    for target in (tmp_path / "a_folder.src", tmp_path / "a_file" / "prog.src"):
        code, _, err = run_cli("export", str(planned_kuka), "--format", "krl", "-o", str(target))
        assert code == 2 and str(target) in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "a_folder.src"]


def test_a_failure_while_writing_parts_leaves_nothing(planned_kuka: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from singplan.results.trajectory import load

    dialect = programs.DIALECTS["krl"]
    monkeypatch.setattr(dialect, "max_part_lines", 20)

    def broken(stream: object, model: object, part: programs.model.Part) -> None:
        if part.name.endswith("_P2"):
            raise RuntimeError("disk gone")
        type(dialect).write_part(dialect, stream, model, part)  # type: ignore[arg-type]

    monkeypatch.setattr(dialect, "write_part", broken)
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(RuntimeError, match="disk gone"):
        write_program(load(planned_kuka), "krl", tmp_path / "prog.src")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


# --- controller limits: parts and blocks --------------------------------------------------------

@pytest.mark.parametrize("fmt", ["krl", "rapid", "fanuc-ls"])
def test_a_long_program_is_split_into_parts_that_read_back_as_one(fmt: str, tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    name = {"krl": "scenarios_programs/kuka_kr6_r900_2__nullspace_wrist_exact_hit",
            "rapid": "scenarios_programs/abb_irb2400__flyby_pick_place",
            "fanuc-ls": "scenarios_programs/fanuc_lrmate200id__flyby_seam_lin_circ_lin"}[fmt]
    traj = planned(name)
    monkeypatch.setattr(programs.DIALECTS[fmt], "max_part_lines", 30)
    result = export(traj, tmp_path, fmt)
    assert result.parts >= 2 and [p.name for p in result.files[1:]] == \
        [f"{programs.DIALECTS[fmt].program_name('prog')}_P{n}{EXTENSION[fmt]}" for n in range(1, result.parts + 1)]
    assert f"split into {result.parts} parts" in result.message()
    for part in result.files[1:]:  # each within the limit: its motion and note lines (FANUC: all of /MN)
        text = part.read_text()
        if fmt == "fanuc-ls":
            assert int(re.search(r"LINE_COUNT\t= (\d+);", text).group(1)) <= 30  # type: ignore[union-attr]
        else:
            assert len(text.splitlines()) <= 30 + 12  # + the file's own opening and closing lines
    t, q_deg, stop = read_back(traj, result.files[0])
    whole = export(traj, tmp_path / "whole", fmt)
    t1, q1, stop1 = read_back(traj, whole.files[0])
    assert np.array_equal(t, t1) and np.array_equal(q_deg, q1) and np.array_equal(stop, stop1)


def test_a_krl_stretch_longer_than_a_spline_block_continues_in_flight(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    traj = planned("scenarios_programs/kuka_kr6_r900_2__weave_lin_sine")
    monkeypatch.setattr(programs.DIALECTS["krl"], "block_segments", 10)
    result = export(traj, tmp_path, "krl")
    text = result.files[0].read_text()
    assert text.count("ENDSPLINE C_SPL") >= 5 and any("continue in flight" in n for n in result.notes)
    speeds = np.degrees(load_robot(traj.urdf, tip=traj.tip).velocity_rad_s).tolist()
    reading = read_program(result.files[0], speeds)
    t, axes, _ = reading.arrays()
    matrix, offsets = convention(traj.robot, traj.urdf)
    q_deg = urdf_joints_deg(axes, matrix, offsets)
    whole = read_back(traj, export(traj, tmp_path / "whole", "krl").files[0])
    assert np.array_equal(q_deg, whole[1])  # the same points
    planned_d, read_d = np.diff(whole[0]), np.diff(t)
    for n, percent in enumerate(reading.speed_percent[1:]):
        if percent is None:
            assert read_d[n] == pytest.approx(planned_d[n], abs=1e-9)
        else:  # the leading axis at the nearest whole percent: within half a percent of the planned time
            assert abs(read_d[n] / planned_d[n] - 1.0) <= 0.5 / percent + 1e-6


def test_fanuc_segments_never_exceed_32000_msec(tmp_path: Path) -> None:
    traj = planned("scenarios_programs/kuka_kr6_r900_2__nullspace_wrist_exact_hit")
    points = choose_points(traj, robot_of(traj), PointTolerance(1.0, 1.0, max_segment_s=0.1))  # only the cap binds
    assert np.diff(np.asarray(traj.t)[points.index]).max() <= 0.1 + 1e-12
    assert programs.DIALECTS["fanuc-ls"].max_segment_s == 32.0


# --- the numbers a program prints ---------------------------------------------------------------

def test_coupled_axes_are_rounded_so_the_joints_they_stand_for_are_nearest(rng: np.random.Generator) -> None:
    robot = load_robot("fanuc_lrmate200id")
    conv = convention_for(robot)
    assert conv is not None
    q = rng.uniform(robot.lower_rad, robot.upper_rad, (5000, 6))
    axes = printed_axes_deg(conv, q, 3)
    assert np.allclose(axes * 1000, np.round(axes * 1000), atol=1e-6)
    decoded = np.degrees(conv.joints_rad(np.radians(axes)))
    assert np.abs(decoded - np.degrees(q)).max() <= 0.0005 + 1e-9
    naive = np.round(np.degrees(conv.axes_rad(q)), 3)
    assert np.abs(np.degrees(conv.joints_rad(np.radians(naive))) - np.degrees(q)).max() > 0.0006  # what it avoids
    plain = convention_for(load_robot("kuka_kr6_r900_2"))
    assert plain is not None
    assert np.array_equal(printed_axes_deg(plain, q, 4), np.round(np.degrees(plain.axes_rad(q)), 4))


def test_printed_times_round_from_the_start_and_always_advance() -> None:
    t = np.arange(0, 2000) * 0.0037 + 0.1
    printed = printed_times(t, 1e-3)
    assert printed[0] == 0.0 and np.all(np.diff(printed) > 0)
    assert np.abs(printed - (t - t[0])).max() <= 0.0005 + 1e-12  # rounding never adds up
    tight = printed_times(np.arange(10) * 2e-4, 1e-3)  # periods under the step: a step each
    assert np.allclose(np.diff(tight), 1e-3)


def test_a_woven_move_takes_the_slope_share_of_the_tolerance() -> None:
    traj = planned("scenarios_programs/kuka_kr6_r900_2__weave_lin_sine")
    robot = robot_of(traj)  # with the task's tool
    scale = weave_scale(traj, robot)
    (weave,) = [m.weave for m in traj.task.moves if m.weave is not None]
    p = robot.tcp_positions(np.asarray(traj.q)[[0, -1]])
    length = float(np.linalg.norm(p[1] - p[0]))  # the LIN's base length (the weave starts and ends on it)
    periods = max(1, round(length / (weave.wavelength_mm / 1e3)))
    slope = weave.amplitude_mm / 1e3 * 2 * math.pi * periods / length
    assert scale.max() == pytest.approx(1 / math.sqrt(1 + slope**2), rel=1e-6)
    assert scale.min() == scale.max()  # the task is the one woven move
    flyby = planned("scenarios_programs/abb_irb2400__flyby_pick_place")
    assert np.all(weave_scale(flyby, robot_of(flyby)) == 1.0)


def test_the_points_keep_every_segment_boundary_and_stop(planned_kuka: Path) -> None:
    from singplan.results.trajectory import load

    traj = load(planned_kuka)
    points = choose_points(traj, robot_of(traj), PointTolerance(1e-4, math.radians(0.005)))
    k = set(points.index.tolist())
    assert {round(x / traj.period) for s in traj.segments for x in (s.t0, s.t1)} <= k
    assert set(points.index[points.stop].tolist()) == required_stops(traj) == {0, round(traj.moves[0].t1 / traj.period),
                                                                              len(traj.t) - 1}
    assert points.max_position_error_m <= 1e-4 and points.max_orientation_error_rad <= math.radians(0.005)


def test_errors_are_input_errors(planned_kuka: Path) -> None:
    from singplan.results.trajectory import load

    with pytest.raises(InputError, match="not a controller program format"):
        program_texts(load(planned_kuka), "urscript")
    with pytest.raises(OutputPathError):
        write_program(load(planned_kuka), "krl", planned_kuka / "trajectory.json" / "prog.src")


def test_an_arm_without_six_axes_is_refused() -> None:
    from singplan.kinematics.vendor_config import require_convention

    with pytest.raises(InputError, match="robot 'panda' has 7 joints; controller programs are written for 6-axis arms"):
        require_convention(load_robot("panda"), "kuka", "--format krl (KUKA KRL)")

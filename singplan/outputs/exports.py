"""Controller exports of a planned trajectory: ROS 2, URScript, CSV in degrees.

* ``ros2``: a ``trajectory_msgs/msg/JointTrajectory`` as YAML, the form ``ros2 topic pub``
  and launch files take (header, joint_names, points with positions, velocities,
  accelerations, effort, time_from_start {sec, nanosec}); ``ros2-json`` the same as JSON.
  ``time_from_start`` is a ``builtin_interfaces/Duration`` (sec int32, nanosec uint32): a
  trajectory that starts before 0 or lasts beyond 2 147 483 647 s is refused, not written wrong.
* ``urscript``: ``def singplan_move(): ... end``: ``movej`` to the first sample, then one
  ``servoj`` per sample at the trajectory's period. UR controllers run their servo loop at a
  fixed step (e-series 500 Hz, 0.002 s; CB3 125 Hz, 0.008 s); a period that is not a whole
  number of steps is resampled (cubic Hermite from positions and velocities) to the nearest
  whole number of steps, at least one.
* ``csv-deg``: header ``t [s],<joint> [deg]...,<joint> [deg/s]...``, one row per sample;
  optionally a ``vendor_config`` column (:mod:`singplan.kinematics.vendor_config`) per sample.
* ``krl``, ``rapid``, ``fanuc-ls``: controller programs, written by :mod:`singplan.outputs.programs`.
  Texts are quoted as Python's csv module does (a joint name may hold commas or quotes).

Every writer streams a chunk of samples at a time. Files are written by the rules of
:mod:`singplan.results.files` (temporary name, renamed when complete, nothing else touched).
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, TextIO

import numpy as np

from singplan.errors import InputError
from singplan.kinematics.vendor_config import format_vendor_config, vendor_configs
from singplan.outputs.checks import check_trajectory
from singplan.outputs.choices import DEFAULT_FILE_NAMES, FORMATS, PROGRAM_FORMATS, UR_STEP_S
from singplan.outputs.programs import ProgramOptions, write_program
from singplan.outputs.timeline import robot_of
from singplan.results.files import Writer, check_output_file, write_file
from singplan.results.trajectory import Trajectory, csv_line, csv_rows

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

LOOKAHEAD_RANGE_S = (0.03, 0.2)  # servoj lookahead_time, as the URScript manual allows
GAIN_RANGE = (100.0, 2000.0)  # servoj gain, as the URScript manual allows
_UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")
_CHUNK = 4096
INT32_MAX = 2**31 - 1  # builtin_interfaces/Duration.sec


@dataclass(frozen=True)
class UrScriptOptions:
    """servoj and movej parameters of the URScript export."""

    controller: Literal["e-series", "cb3"] = "e-series"
    lookahead_time_s: float = 0.1
    gain: float = 300.0
    movej_speed_rad_s: float = 0.5  # to the first sample, before streaming
    movej_accel_rad_s2: float = 1.0


# --- ROS 2 --------------------------------------------------------------------------------------

def check_durations(traj: Trajectory) -> None:
    """Refuse (InputError naming ``t``) times a ``builtin_interfaces/Duration`` cannot carry: before
    0, or at and beyond 2**31 s (``sec`` is an int32; ``nanosec`` a uint32 below 1e9)."""
    if traj.t[0] < 0.0:
        raise InputError(f"t[0]: {traj.t[0]!r} s is before the start; a ROS 2 time_from_start is not negative")
    if traj.t[-1] >= INT32_MAX + 1:
        raise InputError(f"t[{len(traj.t) - 1}]: {traj.t[-1]!r} s is beyond what a ROS 2 Duration holds "
                         f"(sec is an int32: at most {INT32_MAX} s)")


def _duration(t_s: float) -> tuple[int, int]:
    """builtin_interfaces/Duration (sec int32, nanosec uint32 < 1e9) of 0 <= t_s < 2**31 (:func:`check_durations`)."""
    sec, nanosec = divmod(round(t_s * 1e9), 10**9)
    return int(sec), int(nanosec)


_EXPONENT_WITHOUT_DOT = re.compile(r"(?<![\d.])(-?\d+)e")


def _yaml_float(x: float) -> str:
    """A float YAML 1.1 (PyYAML, as ROS 2 tools read it) parses as a float: '1e-05' is a string there."""
    return _yaml_list([x])[1:-1]


def _yaml_list(row: list[float]) -> str:
    """A flow list of floats, shortest round-trip text with a dot before any exponent."""
    text = ", ".join(map(repr, row))
    if "e" in text:
        text = _EXPONENT_WITHOUT_DOT.sub(r"\1.0e", text)
    return "[" + text + "]"


def _json_list(row: list[float]) -> str:
    return "[" + ", ".join(map(repr, row)) + "]"  # finite floats (checked): repr is valid JSON


_Point = tuple[int, int, list[float], list[float], list[float]]  # sec, nanosec, positions, velocities, accelerations


def _point_chunks(traj: Trajectory) -> Iterator[list[_Point]]:
    """The message's points, ``_CHUNK`` samples at a time (the file is streamed, never held whole)."""
    for start in range(0, len(traj.t), _CHUNK):
        stop = start + _CHUNK
        yield [(*_duration(t), q, qd, qdd)
               for t, q, qd, qdd in zip(traj.t[start:stop].tolist(), traj.q[start:stop].tolist(),
                                        traj.qd[start:stop].tolist(), traj.qdd[start:stop].tolist(), strict=True)]


def write_ros2_yaml(stream: TextIO, traj: Trajectory) -> None:
    """trajectory_msgs/msg/JointTrajectory as YAML (block style, one flow list per array)."""
    check_trajectory(traj)
    check_durations(traj)
    stream.write("header:\n  stamp: {sec: 0, nanosec: 0}\n  frame_id: ''\n")
    stream.write("joint_names: [" + ", ".join(json.dumps(n) for n in traj.joint_names) + "]\npoints:\n")
    for chunk in _point_chunks(traj):
        stream.write("".join(f"- positions: {_yaml_list(q)}\n  velocities: {_yaml_list(qd)}\n"
                             f"  accelerations: {_yaml_list(qdd)}\n  effort: []\n"
                             f"  time_from_start: {{sec: {sec}, nanosec: {nanosec}}}\n"
                             for sec, nanosec, q, qd, qdd in chunk))


def write_ros2_json(stream: TextIO, traj: Trajectory) -> None:
    """The same message as JSON."""
    check_trajectory(traj)
    check_durations(traj)
    stream.write('{"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}, "joint_names": '
                 + json.dumps(list(traj.joint_names)) + ', "points": [')
    for i, chunk in enumerate(_point_chunks(traj)):
        stream.write((", " if i else "") + ", ".join(
            f'{{"positions": {_json_list(q)}, "velocities": {_json_list(qd)}, '
            f'"accelerations": {_json_list(qdd)}, "effort": [], '
            f'"time_from_start": {{"sec": {sec}, "nanosec": {nanosec}}}}}'
            for sec, nanosec, q, qd, qdd in chunk))
    stream.write("]}\n")


# --- URScript -----------------------------------------------------------------------------------

def is_ur_robot(traj: Trajectory) -> bool:
    """A Universal Robots arm: a ur<digits> name or the ur_description joint names."""
    return bool(re.fullmatch(r"ur\d+e?", traj.robot.lower())) or tuple(traj.joint_names) == _UR_JOINTS


def servo_period(period_s: float, step_s: float) -> float:
    """The servoj period: ``period_s`` if a whole number of controller steps, else the nearest that is (>= 1)."""
    steps = period_s / step_s
    if abs(steps - round(steps)) < 1e-9 and round(steps) >= 1:
        return period_s
    return max(1, round(steps)) * step_s


def resample(traj: Trajectory, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions (M, n) and times at ``period_s`` from t = 0, cubic Hermite from q and qd; the last sample kept."""
    t_end = float(traj.t[-1])
    count = math.floor(t_end / period_s + 1e-9) + 1
    t_new = np.arange(count) * period_s
    if t_new[-1] < t_end - 1e-12:
        t_new = np.append(t_new, t_end)  # the end point is where the motion stops: keep it
    k = np.clip(np.searchsorted(traj.t, t_new, side="right") - 1, 0, max(len(traj.t) - 2, 0))
    if len(traj.t) == 1:
        return np.repeat(traj.q, len(t_new), axis=0), t_new
    h = (traj.t[k + 1] - traj.t[k])[:, None]
    s = (t_new[:, None] - traj.t[k][:, None]) / h
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    q = h00 * traj.q[k] + h10 * h * traj.qd[k] + h01 * traj.q[k + 1] + h11 * h * traj.qd[k + 1]
    return q, t_new


def _check_ur_options(opts: UrScriptOptions) -> None:
    if opts.controller not in UR_STEP_S:
        raise InputError(f"--ur-controller: expected one of {', '.join(UR_STEP_S)}, got {opts.controller!r}")
    lo, hi = LOOKAHEAD_RANGE_S
    if not lo <= opts.lookahead_time_s <= hi:
        raise InputError(f"--lookahead-time: expected {lo} to {hi} s, got {opts.lookahead_time_s!r}")
    lo, hi = GAIN_RANGE
    if not lo <= opts.gain <= hi:
        raise InputError(f"--gain: expected {lo:g} to {hi:g}, got {opts.gain!r}")
    for name, v in (("movej speed", opts.movej_speed_rad_s), ("movej acceleration", opts.movej_accel_rad_s2)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{name}: expected a positive number, got {v!r}")


def _short(x: float, decimals: int = 9) -> str:
    """Fixed-point text (URScript number literals: no exponent)."""
    return f"{x:.{decimals}f}".rstrip("0").rstrip(".")


_ZERO = re.compile(r"(?<![\d.])-?0\.0{12}(?!\d)")  # a joint value that prints as zero, "-0.000000000000" too


def _zeros(text: str) -> str:
    """URScript text with every joint value that prints as zero written ``0`` (a value a rounding below
    zero printed ``-0.000000000000``)."""
    return _ZERO.sub("0", text)


def write_urscript(stream: TextIO, traj: Trajectory, options: UrScriptOptions | None = None) -> None:
    """The URScript program (see the module's docstring)."""
    opts = options or UrScriptOptions()
    check_trajectory(traj)
    _check_ur_options(opts)
    if len(traj.joint_names) != 6:
        raise InputError(f"joint_names: URScript drives 6 joints, the trajectory has {len(traj.joint_names)}")
    off_grid = np.abs(traj.t - np.arange(len(traj.t)) * traj.period) > 1e-6
    if off_grid.any():
        i = int(np.argmax(off_grid))
        raise InputError(f"t[{i}]: servoj streams samples uniform at the period from 0; got {traj.t[i]!r} s, "
                         f"expected {i * traj.period!r} s")
    step = UR_STEP_S[opts.controller]
    period = servo_period(traj.period, step)
    q = traj.q if period == traj.period else resample(traj, period)[0]
    name = re.sub(r"[^\w.\-]", "_", traj.robot)  # a file name may hold anything; a comment is one line
    stream.write("def singplan_move():\n")
    stream.write(f"  # singplan export: robot {name}, {len(q)} samples, servoj every {period:g} s "
                 f"({opts.controller} controller step {step:g} s)\n")
    if period != traj.period:
        stream.write(f"  # resampled from the planned period {traj.period:g} s (not a whole number of steps)\n")
    if not is_ur_robot(traj):
        stream.write(f"  # WARNING: {name} is not a Universal Robots arm; check joint order and signs\n")
    row = "[" + ", ".join(["%.12f"] * 6) + "]"  # 1e-12 rad: far below any encoder's resolution
    stream.write(_zeros(f"  movej({row % tuple(q[0])}, a={_short(opts.movej_accel_rad_s2)}, "
                        f"v={_short(opts.movej_speed_rad_s)})\n"))
    tail = (f", 0, 0, t={_short(period)}, lookahead_time={_short(opts.lookahead_time_s)}, "
            f"gain={_short(opts.gain)})\n")
    for start in range(0, len(q), _CHUNK):
        stream.write(_zeros("".join("  servoj(" + row % tuple(v) + tail for v in q[start:start + _CHUNK].tolist())))
    stream.write("  stopj(2.0)\nend\n")


# --- CSV in degrees -----------------------------------------------------------------------------

def write_csv_deg(stream: TextIO, traj: Trajectory, vendor_config: bool = False) -> None:
    """``t [s]``, positions [deg], velocities [deg/s] (and the vendor configuration per sample)."""
    check_trajectory(traj)
    header = (["t [s]"] + [f"{n} [deg]" for n in traj.joint_names] + [f"{n} [deg/s]" for n in traj.joint_names]
              + (["vendor_config"] if vendor_config else []))
    stream.write(csv_line(header) + "\n")
    robot = robot_of(traj) if vendor_config else None
    for start in range(0, len(traj.t), _CHUNK):
        stop = start + _CHUNK
        block = np.hstack([traj.t[start:stop, None], np.degrees(traj.q[start:stop]),
                           np.degrees(traj.qd[start:stop])])
        lines = csv_rows(block.tolist()).splitlines()
        if robot is not None:
            texts = [format_vendor_config(c) for c in vendor_configs(robot, traj.q[start:stop])]
            lines = [f"{line},{csv_line([text])}" for line, text in zip(lines, texts, strict=True)]
        stream.write("\n".join(lines) + "\n")


# --- strings and files --------------------------------------------------------------------------

def _writer(fmt: str, traj: Trajectory, urscript: UrScriptOptions | None, vendor_config: bool) -> Writer:
    writers: dict[str, Callable[[TextIO], None]] = {
        "ros2": lambda s: write_ros2_yaml(s, traj), "ros2-json": lambda s: write_ros2_json(s, traj),
        "urscript": lambda s: write_urscript(s, traj, urscript),
        "csv-deg": lambda s: write_csv_deg(s, traj, vendor_config)}
    if fmt not in writers:
        raise InputError(f"--format: unknown format {fmt!r}; valid formats: {', '.join(FORMATS)}")
    if vendor_config and fmt != "csv-deg":
        raise InputError("--vendor-config: only the csv-deg format carries a vendor configuration per sample")
    return writers[fmt]


def _text(write: Writer) -> str:
    buffer = io.StringIO()
    write(buffer)
    return buffer.getvalue()


def to_ros2_yaml(traj: Trajectory) -> str:
    """The JointTrajectory message as YAML text."""
    return _text(lambda s: write_ros2_yaml(s, traj))


def to_ros2_json(traj: Trajectory) -> str:
    """The JointTrajectory message as JSON text."""
    return _text(lambda s: write_ros2_json(s, traj))


def to_urscript(traj: Trajectory, options: UrScriptOptions | None = None) -> str:
    """The URScript program text."""
    return _text(lambda s: write_urscript(s, traj, options))


def to_csv_deg(traj: Trajectory, vendor_config: bool = False) -> str:
    """The degree CSV text."""
    return _text(lambda s: write_csv_deg(s, traj, vendor_config))


def export(traj: Trajectory, fmt: str, path: str | os.PathLike[str], urscript: UrScriptOptions | None = None,
           vendor_config: bool = False, program: ProgramOptions | None = None) -> Path:
    """Write ``traj`` in format ``fmt`` to the file ``path`` (temporary name, renamed when complete).

    The controller programs (``krl``, ``rapid``, ``fanuc-ls``; ``program`` their options) go through
    :func:`singplan.outputs.programs.write_program`, which may add numbered part files beside ``path``
    and returns what it wrote; this returns the main program's file.
    """
    if fmt in PROGRAM_FORMATS:
        if vendor_config:
            raise InputError("--vendor-config: only the csv-deg format carries a vendor configuration per sample; "
                             "a controller program notes each move's configuration in a comment")
        return write_program(traj, fmt, path, program).files[0]
    if program is not None:
        raise InputError(f"--name, --tolerance-mm, --tolerance-deg: only for the controller programs "
                         f"({', '.join(PROGRAM_FORMATS)}), not --format {fmt}")
    write = _writer(fmt, traj, urscript, vendor_config)
    check_trajectory(traj)  # before the file is touched: bad input never leaves a file behind
    if fmt in ("ros2", "ros2-json"):
        check_durations(traj)
    check_output_file(path)  # an unusable path is bad input before the file is touched
    if fmt == "urscript" and not is_ur_robot(traj):
        log.warning("%s is not a Universal Robots arm: the URScript program needs checking", traj.robot)
    return write_file(path, write)  # holds the folder (one run per folder) while it writes


def default_path(out_dir: str | os.PathLike[str], fmt: str) -> Path:
    """The file an export writes into an output folder when no file is named."""
    if fmt not in DEFAULT_FILE_NAMES:
        raise InputError(f"--format: unknown format {fmt!r}; valid formats: {', '.join(FORMATS)}")
    return Path(out_dir) / DEFAULT_FILE_NAMES[fmt]

"""What report and replay both show, computed once per trajectory (:class:`PageBasis`): the TCP
track, the timeline and the joint speeds.

:func:`tcp_track` runs forward kinematics over every sample once (in chunks) and keeps the TCP
positions, the distance between samples and the path length; the report plots them and the
replay picks its points from them, so neither redoes FK. :func:`timeline` turns the segments
into stretches to colour: each segment by its kind ("path", "pre", "crossing", "post", "ptp",
"blend", or any other kind a newer planner writes), a woven move's segments other than its
crossings as "weave", and inside a null-space crossing (one with ``pause_s``) the samples at
which the TCP stands still as "pause". No plotting or viewer module is imported here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.errors import InputError
from singplan.kinematics.files import display_path
from singplan.kinematics.geometry import rpy_deg_to_rotation
from singplan.kinematics.robot import Robot, bundled_robots, load_robot
from singplan.results.path import woven_moves
from singplan.results.trajectory import Segment, Trajectory

# one colour per stretch kind, for the report's shading and the replay's path, markers, strip and legend
# (the one home of the pages' colours, with svgplot's curve palette and limit colour)
SEGMENT_COLOURS = {"path": 0x2E7D32, "pre": 0x1565C0, "crossing": 0xF4B400, "post": 0x6A1B9A, "ptp": 0x757575,
                   "blend": 0xE53935, "weave": 0x00897B, "pause": 0x8D6E63}
OTHER_COLOUR = 0x000000  # a segment kind this version does not know
# stretch kinds shaded over the time plots (report) and the speed strip (replay), with the shade's opacity
SHADED_OPACITY = {"crossing": 0.18, "weave": 0.10, "blend": 0.16, "pause": 0.30}
PROGRAMMED_COLOUR = 0x9E9E9E  # the programmed path, drawn under the executed one
_STILL_M = 1e-7  # a TCP step below this between two samples counts as standing still (0.1 um)


@dataclass(frozen=True)
class TcpTrack:
    """The TCP at every sample.

    Attributes:
        xyz: positions [m] (K, 3) in the base frame.
        step_m: distance [m] (K - 1,) between consecutive samples.
        length_m: path length [m] (K,) travelled since t = 0.
    """

    xyz: np.ndarray
    step_m: np.ndarray
    length_m: np.ndarray


def tcp_track(traj: Trajectory, robot: Robot) -> TcpTrack:
    """FK once over every sample (``Robot.tcp_positions`` works in chunks: bounded temporaries)."""
    xyz = robot.tcp_positions(traj.q)
    step = np.empty(max(0, len(xyz) - 1))
    for c in range(0, len(step), _CHUNK):
        step[c:c + _CHUNK] = np.linalg.norm(np.diff(xyz[c:c + _CHUNK + 1], axis=0), axis=1)
    return TcpTrack(xyz, step, np.concatenate([[0.0], np.cumsum(step)]))


_CHUNK = 65_536  # samples differenced at once (a few MB of temporaries)


@dataclass(frozen=True)
class Stretch:
    """A coloured stretch of the timeline.

    Attributes:
        kind: the segment's kind, "weave" for a woven move's segment, or "pause".
        segment: index of the segment it belongs to.
        k0, k1: first and last sample (both included).
        t0, t1: their times [s].
    """

    kind: str
    segment: int
    k0: int
    k1: int
    t0: float
    t1: float

    @property
    def colour(self) -> int:
        return kind_colour(self.kind)


@dataclass(frozen=True)
class PageBasis:
    """What both pages draw of a trajectory, computed once (:func:`page_basis`) and passed to each.

    Attributes:
        track: the TCP at every sample (:func:`tcp_track`).
        stretches: the coloured timeline (:func:`timeline`).
        speed_ratio: |qd| / limit (K - 1, n) of each step between samples (:func:`joint_speed_ratios`).
    """

    track: TcpTrack
    stretches: list[Stretch]
    speed_ratio: np.ndarray


def page_basis(traj: Trajectory, robot: Robot) -> PageBasis:
    track = tcp_track(traj, robot)
    return PageBasis(track, timeline(traj, track), joint_speed_ratios(traj, speed_limits(traj, robot)))


def kind_colour(kind: str) -> int:
    """The colour (0xRRGGBB) of a stretch kind; black for a kind this version does not know."""
    return SEGMENT_COLOURS.get(kind, OTHER_COLOUR)


def sample_range(traj: Trajectory, seg: Segment) -> tuple[int, int]:
    """First and last sample of a segment."""
    last = len(traj.t) - 1
    return min(last, max(0, round(seg.t0 / traj.period))), min(last, max(0, round(seg.t1 / traj.period)))


def speed_limits(traj: Trajectory, robot: Robot) -> np.ndarray:
    """The joint speed limits (n,) [rad/s] the trajectory was planned under (URDF x ``limits.velocity_scale``)."""
    return robot.velocity_rad_s * traj.task.limits.velocity_scale


def joint_speed_ratios(traj: Trajectory, vmax_rad_s: np.ndarray) -> np.ndarray:
    """|qd| / limit (K - 1, n) of each step between samples, the step k -> k + 1 drawn at t[k + 1]:
    forward differences (q[k + 1] - q[k]) / period, the joint speed the checker and the metrics'
    ``max_joint_speed_ratio`` measure (not the record's central ``qd``). Single precision, formed a
    chunk at a time: a plot's figure, a quarter of the samples' own memory."""
    q = traj.q
    out = np.empty((max(0, len(q) - 1), q.shape[1]), dtype=np.float32)
    scale = traj.period * vmax_rad_s
    for c in range(0, len(out), _CHUNK):
        out[c:c + _CHUNK] = np.abs(np.diff(q[c:c + _CHUNK + 1], axis=0)) / scale
    return out


def display_kind(seg: Segment, woven: frozenset[int]) -> str:
    """A segment's colour kind: its own, or "weave" for a woven move's segments other than crossings."""
    return "weave" if seg.move in woven and seg.kind not in ("crossing", "blend") else seg.kind


def timeline(traj: Trajectory, track: TcpTrack) -> list[Stretch]:
    """The stretches in time order: one a segment, a null-space crossing split around its pause."""
    woven = woven_moves(traj.task)
    out = []
    for n, seg in enumerate(traj.segments):
        k0, k1 = sample_range(traj, seg)
        kind = display_kind(seg, woven)
        pause = pause_window(track.step_m, k0, k1) if seg.pause_s is not None else None
        parts = [(kind, k0, k1)] if pause is None else [(kind, k0, pause[0]), ("pause", *pause), (kind, pause[1], k1)]
        out += [Stretch(name, n, a, b, float(traj.t[a]), float(traj.t[b])) for name, a, b in parts if b > a]
    return out


def pause_window(step_m: np.ndarray, k0: int, k1: int) -> tuple[int, int] | None:
    """The longest run of samples in k0..k1 between which the TCP stands still, as (first, last)
    sample, or None if it never stands still for a step."""
    still = np.concatenate([[False], step_m[k0:k1] < _STILL_M, [False]])
    edges = np.flatnonzero(np.diff(still.astype(np.int8)))  # starts and ends of the runs of still steps
    if len(edges) == 0:
        return None
    starts, ends = edges[0::2], edges[1::2]
    i = int(np.argmax(ends - starts))
    return k0 + int(starts[i]), k0 + int(ends[i])


def robot_of(traj: Trajectory) -> Robot:
    """The robot a trajectory was planned for, with its tool: its URDF, or the bundled arm of that
    name when it was planned from the bundled URDF (or that file is gone, e.g. another install).

    A user's URDF whose file name matches a bundled arm is drawn as itself, not as the bundled arm.
    Every output that reads a trajectory's robot again (exports, replay, programs) loads it here.

    Raises:
        InputError: the URDF's chain to the tip has other joints than the trajectory's
            (``joint_names``; the URDF changed since the plan).
    """
    rpy = np.asarray(traj.tool.get("rpy_deg", [0, 0, 0]), dtype=float)
    tool = pin.SE3(rpy_deg_to_rotation(rpy), np.asarray(traj.tool.get("xyz", [0, 0, 0]), dtype=float))
    entry = bundled_robots().get(traj.robot)
    bundled = entry is not None and (str(entry.urdf_path()) == traj.urdf or not Path(traj.urdf).is_file())
    source = traj.robot if bundled else traj.urdf
    robot = load_robot(source, tip=traj.tip, tool=tool)
    if robot.joint_names != tuple(traj.joint_names):
        raise InputError(f"joint_names: the trajectory's joints {list(traj.joint_names)} are not those of "
                         f"{display_path(robot.urdf_path)} to {traj.tip} {list(robot.joint_names)}; "
                         "the URDF changed since the plan?")
    return robot

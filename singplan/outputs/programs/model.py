"""What every controller program holds, whatever its language: the points with their printed axis
values and times, the notes an operator reads, and the numbered parts a long program is split into.

A program starts with a reduced-speed motion to the plan's first point and an exact stop there
(:attr:`ProgramModel.start`), then moves through the points (:class:`Motion`), flying by each
except where the plan stops. The times are the plan's, printed at the format's resolution: each
point's time from the start is rounded (not each segment's duration), so rounding never adds up
along a long program, and a point's printed time is within half a step of the plan's.

A format's limits (lines per program file) split a long program into parts: the main program runs
the first motion and calls the parts in order. A part ends at an exact stop where one lies in its
second half, else at its limit (the motion then flies on across the call).
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from singplan._version import __version__
from singplan.errors import InputError
from singplan.kinematics.robot import Robot
from singplan.kinematics.vendor_config import (
    ControllerConvention,
    Vendor,
    format_vendor_config,
    printed_axes_deg,
    vendor_configs,
)
from singplan.outputs.programs.points import ProgramPoints
from singplan.outputs.timeline import sample_range
from singplan.results.trajectory import Trajectory

_SAFE = re.compile(r"[^A-Za-z0-9 _.,:;=+\-/()\[\]%<>#@$*\\]")  # what any of the three comment forms carries
APPROACH_PERCENT = 10  # the first motion's speed, percent of the robot's (KRL $VEL_AXIS, FANUC J %)


@dataclass(frozen=True)
class Motion:
    """A motion to one program point.

    Attributes:
        point: the point's number in the program (0: the start point).
        sample: its sample index in the trajectory.
        axes_deg: controller axis values [deg] as printed (6,).
        t_s: printed time from the start of the planned motion [s] (the plan's, rounded).
        duration_s: printed time from the previous point [s] (difference of the rounded times, > 0).
        stop: True for an exact stop (the plan is at rest here), False to fly by.
    """

    point: int
    sample: int
    axes_deg: tuple[float, ...]
    t_s: float
    duration_s: float
    stop: bool


@dataclass(frozen=True)
class Note:
    """A comment line an operator reads above the motion that follows it."""

    text: str


Item = Motion | Note


@dataclass(frozen=True)
class Part:
    """The motions of one program file.

    Attributes:
        name: the program name of this part (the main program's when there is one part).
        items: its notes and motions, in order.
        before: the motion whose point the part starts from (the previous part's last, or the start).
    """

    name: str
    items: tuple[Item, ...]
    before: Motion


@dataclass(frozen=True)
class ProgramModel:
    """A whole program before it is written in a controller language.

    Attributes:
        name: the main program's name.
        header: comment lines (task, robot, tool, tip, duration, version, tolerance, convention).
        start: the first point, reached by a reduced-speed motion and an exact stop.
        parts: the motions after it; one part is the main program's own body, more are called by it.
        axis_speed_deg_s: the robot's axis speed limits [deg/s] (6,), for formats timing a motion by speed.
        tolerance_mm, tolerance_deg: how far the program's joint segments may take the TCP from the plan.
    """

    name: str
    header: tuple[str, ...]
    start: Motion
    parts: tuple[Part, ...]
    axis_speed_deg_s: tuple[float, ...]
    tolerance_mm: float
    tolerance_deg: float

    @property
    def split(self) -> bool:
        return len(self.parts) > 1

    def motions(self) -> list[Motion]:
        return [self.start] + [m for part in self.parts for m in part.items if isinstance(m, Motion)]


class Dialect:
    """A controller language: its names, number formats, limits, and how it writes a program.

    Subclasses set the class attributes and implement :meth:`write_main` and :meth:`write_part`.
    """

    fmt: str
    title: str  # e.g. "KUKA KRL"
    vendor: Vendor
    extension: str  # with the dot
    name_max: int  # the longest program name the controller takes
    name_pattern: re.Pattern[str]
    name_rule: str  # the pattern in words, for the error message
    named_after_file = True  # the controller takes the program's name from its file's (KRL DEF, FANUC /PROG)
    axis_decimals: int
    time_step_s: float  # the printed time's resolution
    max_segment_s: float = math.inf  # the longest time between two points the format can express
    max_part_lines: int  # motion lines per program file
    comment_width: int  # characters of one comment line's text
    manual: str  # the manual sections the format follows (the docs and the header cite them)

    def program_name(self, name: str) -> str:
        """The name as the controller writes it (FANUC: upper case)."""
        return name

    def motion_lines(self, motion: Motion) -> int:
        """An upper bound of the lines one motion takes in a program body."""
        return 1

    def overhead_lines(self, header: tuple[str, ...], main: bool) -> int:
        """Lines of a program file that count against :attr:`max_part_lines` besides its motions and
        notes: the main program's header and first motion (``main``), or a part's opening remark."""
        return 0

    def notes(self, model: ProgramModel) -> list[str]:
        """What the summary should say about how this program carries the plan, beyond the figures."""
        return []

    def write_main(self, stream: TextIO, model: ProgramModel) -> None:
        raise NotImplementedError

    def write_part(self, stream: TextIO, model: ProgramModel, part: Part) -> None:
        raise NotImplementedError

    def check_name(self, name: str, where: str) -> str:
        """Refuse (InputError naming ``where``) a name the controller would not take; return it as written."""
        if not self.name_pattern.fullmatch(name) or len(name) > self.name_max:
            raise InputError(f"{where}: {name!r} is not a valid {self.title} program name ({self.name_rule}, "
                             f"at most {self.name_max} characters)")
        return self.program_name(name)


def part_name(name: str, number: int) -> str:
    """The program name of part ``number`` (1-based) of program ``name``."""
    return f"{name}_P{number}"


def clean(text: str) -> str:
    """One line of text every comment form carries: printable ASCII, no line breaks."""
    return _SAFE.sub("_", " ".join(str(text).split()))


def wrap(text: str, width: int) -> list[str]:
    """``text`` cut into lines of at most ``width`` characters, at spaces where possible."""
    words, lines, line = clean(text).split(" "), [], ""
    for word in words:
        while len(word) > width:
            if line:
                lines.append(line)
                line = ""
            lines.append(word[:width])
            word = word[width:]
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    return [*lines, line] if line else lines


def number(value: float, decimals: int) -> str:
    """Fixed-point text with ``decimals`` digits; never ``-0.000`` (every controller reads it, none needs it)."""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def seconds(value: float) -> str:
    """A time [s] to the microsecond, without trailing zeros (``0.048``, ``1.124``, ``0.000037``)."""
    return number(value, 6).rstrip("0").rstrip(".") if value else "0"


def printed_times(t_s: np.ndarray, step_s: float) -> np.ndarray:
    """Times [s] rounded to ``step_s`` from the start, each later than the one before by a step at least."""
    steps = np.round((t_s - t_s[0]) / step_s).astype(np.int64)
    steps = np.maximum(steps, np.arange(len(steps)))  # a step per point at least (periods under a step)
    return np.maximum.accumulate(steps) * step_s


def build_model(traj: Trajectory, robot: Robot, conv: ControllerConvention, points: ProgramPoints,
                dialect: Dialect, name: str, tolerance_mm: float, tolerance_deg: float,
                source: str | None) -> ProgramModel:
    """The program of a trajectory's chosen points in a dialect's units and limits."""
    q = traj.q[points.index]
    axes = printed_axes_deg(conv, q, dialect.axis_decimals)
    times = printed_times(traj.t[points.index], dialect.time_step_s)
    durations = np.diff(times, prepend=times[0])
    motions = [Motion(p, int(k), tuple(a.tolist()), float(t), float(d), bool(s))
               for p, (k, a, t, d, s) in enumerate(zip(points.index, axes, times, durations, points.stop, strict=True))]
    items = _with_notes(traj, robot, points, motions)
    header = tuple(_header(traj, conv, points, dialect, motions, tolerance_mm, tolerance_deg, source))
    parts = _split(items, motions[0], dialect, name, header)
    speed = np.degrees(np.abs(np.diag(np.asarray(conv.matrix))) * robot.velocity_rad_s)
    return ProgramModel(name, header, motions[0], tuple(parts), tuple(speed.tolist()), tolerance_mm, tolerance_deg)


def _header(traj: Trajectory, conv: ControllerConvention, points: ProgramPoints, dialect: Dialect,
            motions: Sequence[Motion], tolerance_mm: float, tolerance_deg: float, source: str | None) -> list[str]:
    kinds = [m.kind for m in traj.task.moves]
    xyz, rpy = _short_list(traj.tool.get("xyz", [0, 0, 0])), _short_list(traj.tool.get("rpy_deg", [0, 0, 0]))
    reached_mm, reached_deg = points.max_position_error_m * 1e3, math.degrees(points.max_orientation_error_rad)
    lines = [f"singplan {__version__}: {dialect.title} joint-space replay of a planned trajectory",
             f"task: {len(kinds)} move(s) ({', '.join(kinds[:12])}{', ...' if len(kinds) > 12 else ''})"
             + (f" from {source}" if source else ""),
             f"robot: {traj.robot} ({os.path.basename(traj.urdf)}), tip {traj.tip}",
             f"tool: xyz {xyz} m, rpy {rpy} deg",
             f"duration: {motions[-1].t_s:.3f} s in {len(motions)} points, {sum(m.stop for m in motions)} exact stops",
             f"TCP within {tolerance_mm:g} mm / {tolerance_deg:g} deg of the plan between points "
             f"(reached {reached_mm:.4f} mm / {reached_deg:.4f} deg)",
             f"axes [deg]: {_convention_text(conv)}",
             f"follows: {dialect.manual}",
             "first motion: to the start point at reduced speed, then an exact stop; check the way there"]
    return lines


def _short_list(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def _convention_text(conv: ControllerConvention) -> str:
    """The controller axes in URDF joints, e.g. ``a3 = q3 - q2``; the plain ones (``a_i = q_i``) summed up."""
    m, off = np.asarray(conv.matrix), np.degrees(conv.offsets_rad)
    terms = []
    for i in range(len(m)):
        order = [i] + [j for j in range(len(m)) if j != i]  # the axis' own joint first
        text = ""
        for j in order:
            c = m[i, j]
            if c != 0:
                factor = "" if abs(c) == 1 else f"{abs(c):g} "
                sign = ("-" if c < 0 else "") if not text else (" - " if c < 0 else " + ")
                text += f"{sign}{factor}q{j + 1}"
        if off[i] != 0:
            text += f" {'-' if off[i] < 0 else '+'} {abs(off[i]):g}"
        if text != f"q{i + 1}":
            terms.append(f"a{i + 1} = {text}")
    return "controller axes a1..a6 = URDF joints q1..q6" + (", except " + "; ".join(terms) if terms else "")


def _with_notes(traj: Trajectory, robot: Robot, points: ProgramPoints, motions: list[Motion]) -> list[Item]:
    """The motions after the start, each move's first one preceded by a note of the move (its time and
    the configuration it ends in, in the vendor's form) and each null-space pause's by a note of it."""
    sample_point = {m.sample: m.point for m in motions}
    notes: dict[int, list[str]] = {}  # point the motion starts from -> notes
    by_move = traj.segments_by_move()
    ends = [sample_range(traj, segs[-1])[1] for segs in by_move.values()]
    configs = vendor_configs(robot, traj.q[ends]) if ends else []
    kinds = [m.kind for m in traj.task.moves]
    for (move, segs), config in zip(by_move.items(), configs, strict=True):
        first = sample_range(traj, segs[0])[0]
        kind = kinds[move] if move < len(kinds) else "move"
        ending = format_vendor_config(config)
        notes.setdefault(sample_point[first], []).append(
            f"move {move} ({kind}) {segs[0].t0:.3f} .. {segs[-1].t1:.3f} s" + (f", ends in {ending}" if ending else ""))
    for k0, k1 in points.pauses:  # both ends are points (exact stops)
        notes.setdefault(sample_point[k0], []).append(
            f"null-space pause {traj.t[k0]:.3f} .. {traj.t[k1]:.3f} s: "
            "the TCP stands still while the aligned joints turn")
    items: list[Item] = []
    for m in motions[1:]:
        items += [Note(text) for text in notes.get(m.point - 1, [])]
        items.append(m)
    return items


def _split(items: list[Item], start: Motion, dialect: Dialect, name: str, header: tuple[str, ...]) -> list[Part]:
    """Items cut into parts of at most ``dialect.max_part_lines`` lines (their own lines counted): at
    the last exact stop in a part's second half, else where the limit falls. A motion keeps the notes
    above it. One part (the main program's body) when everything fits there."""
    units: list[list[Item]] = [[]]  # each: notes, then the motion they stand above
    for item in items:
        units[-1].append(item)
        if isinstance(item, Motion):
            units.append([])
    units = [u for u in units if u]
    cost = [cost_of(u, dialect) for u in units]
    if sum(cost) <= dialect.max_part_lines - dialect.overhead_lines(header, main=True):
        return [Part(name, tuple(items), start)]
    budget = dialect.max_part_lines - dialect.overhead_lines(header, main=False)
    chunks: list[list[list[Item]]] = [[]]
    lines = 0
    for unit, c in zip(units, cost, strict=True):
        if lines + c > budget and chunks[-1]:
            current = chunks[-1]
            stops = [n for n, u in enumerate(current) if isinstance(u[-1], Motion) and u[-1].stop]
            cut = stops[-1] + 1 if stops and stops[-1] + 1 >= len(current) / 2 else len(current)
            chunks[-1], rest = current[:cut], current[cut:]
            chunks.append(rest)
            lines = sum(cost_of(u, dialect) for u in rest)
        chunks[-1].append(unit)
        lines += c
    flat = [[i for u in chunk for i in u] for chunk in chunks]
    parts, before = [], start
    for n, chunk in enumerate(flat, start=1):
        parts.append(Part(part_name(name, n), tuple(chunk), before))
        before = next(i for i in reversed(chunk) if isinstance(i, Motion))
    return parts


def cost_of(unit: Sequence[Item], dialect: Dialect) -> int:
    """The lines a motion and its notes take at most."""
    return sum(dialect.motion_lines(i) if isinstance(i, Motion) else len(wrap(i.text, dialect.comment_width))
               for i in unit)


def stamp() -> time.struct_time:
    """The time a program says it was made: ``SOURCE_DATE_EPOCH`` when set (reproducible files), else now (UTC)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "")
    return time.gmtime(int(epoch) if epoch.isdigit() else None)

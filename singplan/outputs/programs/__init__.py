"""Controller programs: a planned trajectory as a KUKA KRL, ABB RAPID or FANUC TP (LS) program.

The program replays the planned joint motion on the vendor's own controller, without a ROS driver
or a real-time option: joint values in the controller's convention (robots.yaml, or the URDF's
``.controller.yaml`` sidecar: :mod:`singplan.kinematics.vendor_config`), points chosen so that
straight joint segments between them keep the TCP within a tolerance of the plan
(:mod:`~singplan.outputs.programs.points`), each point reached at its planned time through the
controller's time-based means, flying by every point except where the plan stops.

* ``krl`` (:mod:`~singplan.outputs.programs.krl`): PTP spline blocks with TIME_BLOCK.
* ``rapid`` (:mod:`~singplan.outputs.programs.rapid`): MoveAbsJ with ``\\T``.
* ``fanuc-ls`` (:mod:`~singplan.outputs.programs.fanuc`): J moves with ``msec`` times, CNT100 / FINE.

From Python::

    from singplan.outputs.programs import ProgramOptions, write_program
    export = write_program(traj, "krl", "out/singplan.src", ProgramOptions(tolerance_mm=0.1))
    print(export.message())

This package is imported only when a program is asked for (``singplan export``, :func:`write_program`).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from singplan.errors import InputError
from singplan.kinematics.vendor_config import require_convention
from singplan.outputs.checks import check_trajectory
from singplan.outputs.choices import DEFAULT_PROGRAM_NAME, DEFAULT_TOLERANCE_DEG, DEFAULT_TOLERANCE_MM, PROGRAM_FORMATS
from singplan.outputs.programs.fanuc import FanucLs
from singplan.outputs.programs.krl import Krl
from singplan.outputs.programs.model import Dialect, Motion, Part, ProgramModel, build_model, printed_times
from singplan.outputs.programs.points import ORIENTATION, POSITION, PointTolerance, ProgramPoints, choose_points
from singplan.outputs.programs.rapid import Rapid
from singplan.outputs.timeline import robot_of
from singplan.results.files import Writer, check_output_file, write_files
from singplan.results.trajectory import Trajectory

DIALECTS: dict[str, Dialect] = {d.fmt: d for d in (Krl(), Rapid(), FanucLs())}
SHORT_SEGMENT_S = 0.012  # KUKA's interpolation cycle; FANUC's is 8 ms: shorter segments are worth a note


@dataclass(frozen=True)
class ProgramOptions:
    """What a controller program is called and how closely it follows the plan.

    Attributes:
        name: the program name (default: the output file's name, else "singplan").
        tolerance_mm: the most the TCP may leave the plan between program points [mm].
        tolerance_deg: the same for the TCP's orientation [deg].
        source: where the trajectory came from, for the program's header (e.g. its trajectory.json).
    """

    name: str | None = None
    tolerance_mm: float = DEFAULT_TOLERANCE_MM
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG
    source: str | None = None


@dataclass(frozen=True)
class Program:
    """A program ready to be written.

    Attributes:
        fmt: its format ("krl", "rapid", "fanuc-ls").
        model: its points, times, notes and parts (:class:`~singplan.outputs.programs.model.ProgramModel`).
        points: the plan's samples it moves through, and how close its segments keep to the plan.
        files: file name -> writer: the main program first, then its parts in order.
        notes: what the summary says beyond the figures (e.g. approximate timing somewhere).
    """

    fmt: str
    model: ProgramModel
    points: ProgramPoints
    files: dict[str, Writer]
    notes: tuple[str, ...]


@dataclass(frozen=True)
class ProgramExport:
    """What :func:`write_program` wrote.

    Attributes:
        format: "krl", "rapid" or "fanuc-ls"; title its language ("KUKA KRL", ...).
        name: the main program's name.
        files: the files written: the main program first, then its parts.
        points: program points, the start point included; exact_stops of them are exact stops.
        duration_s: the planned motion's duration after the first motion [s].
        max_position_error_mm, max_orientation_error_deg: the largest TCP deviation of the straight
            joint segments between points from the plan's samples.
        shortest_segment_s: the shortest time between two points [s].
        part_lines: the most lines a program file of this format holds (parts are split at it).
        notes: further remarks (approximate timing, very short segments).
    """

    format: str
    title: str
    name: str
    files: tuple[Path, ...]
    points: int
    exact_stops: int
    duration_s: float
    tolerance_mm: float
    tolerance_deg: float
    max_position_error_mm: float
    max_orientation_error_deg: float
    shortest_segment_s: float
    part_lines: int
    notes: tuple[str, ...]

    @property
    def parts(self) -> int:
        """Part files the main program calls (0: the main program holds every motion)."""
        return len(self.files) - 1

    def message(self) -> str:
        """What the CLI prints: the files, the figures, the parts and the notes."""
        lines = [f"wrote {self.files[0]}: {self.title} program {self.name}, {self.points} points "
                 f"({self.exact_stops} exact stops), {self.duration_s:.3f} s after the first motion",
                 f"  between points the TCP keeps within {self.max_position_error_mm:.4f} mm / "
                 f"{self.max_orientation_error_deg:.4f} deg of the plan (tolerance {self.tolerance_mm:g} mm / "
                 f"{self.tolerance_deg:g} deg); shortest segment {self.shortest_segment_s * 1e3:.1f} ms"]
        if self.parts:
            lines.append(f"  split into {self.parts} parts (a {self.title} program file here holds at most "
                         f"{self.part_lines} motion lines), called in order by {self.files[0].name}: "
                         + ", ".join(p.name for p in self.files[1:]))
        return "\n".join(lines + [f"  note: {n}" for n in self.notes])


def build_program(traj: Trajectory, fmt: str, options: ProgramOptions | None = None,
                  main_file: str | os.PathLike[str] | None = None) -> Program:
    """The program of ``traj`` in format ``fmt`` (InputError, exit 2, for a robot without the
    vendor's controller convention, a name the controller would not take, a bad tolerance).

    ``main_file`` is the file the main program will be written to; its name is the program's name
    when ``options.name`` is not given (a KRL program's name must be its file's).
    """
    opts = options or ProgramOptions()
    dialect = _dialect(fmt)
    check_trajectory(traj)
    main = Path(main_file) if main_file is not None else None
    name = _program_name(dialect, opts.name, main)
    tolerance = PointTolerance(_positive(opts.tolerance_mm, "--tolerance-mm") / 1e3,
                               math.radians(_positive(opts.tolerance_deg, "--tolerance-deg")), dialect.max_segment_s)
    robot = robot_of(traj)
    conv = require_convention(robot, dialect.vendor, f"--format {fmt} ({dialect.title})",
                              {d.vendor: f" (use --format {d.fmt})" for d in DIALECTS.values()})
    points = choose_points(traj, robot, tolerance)
    model = build_model(traj, robot, conv, points, dialect, name, opts.tolerance_mm, opts.tolerance_deg, opts.source)
    for part in model.parts if model.split else ():
        dialect.check_name(part.name, f"--name (part {part.name})")
    files: dict[str, Writer] = {(main.name if main else name + dialect.extension):
                                lambda s: dialect.write_main(s, model)}
    for part in model.parts if model.split else ():
        files[part.name + dialect.extension] = _part_writer(dialect, model, part)
    note = _short_segment_note(lambda index: _short(traj, index, dialect.time_step_s), points, tolerance,
                               lambda tol: choose_points(traj, robot, tol).index)
    return Program(fmt, model, points, files, tuple(dialect.notes(model) + note))


def program_texts(traj: Trajectory, fmt: str, options: ProgramOptions | None = None) -> dict[str, str]:
    """The program's files as text: file name -> text, the main program first."""
    out = {}
    for file_name, write in build_program(traj, fmt, options).files.items():
        buffer = io.StringIO()
        write(buffer)
        out[file_name] = buffer.getvalue()
    return out


def write_program(traj: Trajectory, fmt: str, path: str | os.PathLike[str],
                  options: ProgramOptions | None = None) -> ProgramExport:
    """Write the program to ``path`` (its parts, if any, beside it): every file under a temporary name,
    renamed when all are complete, nothing else touched (DESIGN.md "Outputs")."""
    program = build_program(traj, fmt, options, path)  # before any file is touched: bad input leaves none
    target = check_output_file(path)
    written = write_files(target.parent, program.files)
    return _export(program, tuple(written))


def program_path(out_dir: str | os.PathLike[str], fmt: str, name: str | None = None) -> Path:
    """The main program's file in an output folder: ``<name><extension>`` (name default "singplan")."""
    return Path(out_dir) / ((name or DEFAULT_PROGRAM_NAME) + _dialect(fmt).extension)


def _export(program: Program, files: tuple[Path, ...]) -> ProgramExport:
    dialect, model, points = DIALECTS[program.fmt], program.model, program.points
    motions = model.motions()
    return ProgramExport(program.fmt, dialect.title, model.name, files, len(motions), sum(m.stop for m in motions),
                         motions[-1].t_s, model.tolerance_mm, model.tolerance_deg,
                         points.max_position_error_m * 1e3, math.degrees(points.max_orientation_error_rad),
                         _shortest(motions), dialect.max_part_lines, program.notes)


def _shortest(motions: list[Motion]) -> float:
    return min((m.duration_s for m in motions[1:]), default=0.0)


def _short_segment_note(shorter: Callable[[np.ndarray], np.ndarray], points: ProgramPoints, tolerance: PointTolerance,
                        choose: Callable[[PointTolerance], np.ndarray]) -> list[str]:
    """The note on segments shorter than a controller's interpolation cycle (``shorter``: which segments
    between points (sample indices) are), naming the tolerance that ended most of them (measured:
    :attr:`ProgramPoints.ended_by`) and what ten times it gives (the points chosen again: ``choose``)."""
    short = shorter(points.index)
    if not short.any():
        return []
    ended = points.ended_by[short]
    by_position = int(np.count_nonzero(ended & POSITION))
    by_orientation = int(np.count_nonzero(ended & ORIENTATION))
    text = (f"{np.count_nonzero(short)} of {len(short)} segments are shorter than {SHORT_SEGMENT_S * 1e3:g} ms "
            "(a controller's interpolation cycle): the controller may not keep their planned times")
    if not by_position and not by_orientation:  # forced points (segment boundaries, stops) only
        return [text + "; they lie between points the plan forces (its segment ends and stops)"]
    if by_orientation > by_position:
        option, now = "--tolerance-deg", math.degrees(tolerance.orientation_rad)
        wider = replace(tolerance, orientation_rad=tolerance.orientation_rad * 10.0)
    else:
        option, now = "--tolerance-mm", tolerance.position_m * 1e3
        wider = replace(tolerance, position_m=tolerance.position_m * 10.0)
    tried = shorter(choose(wider))
    which, unit = ("orientation", "deg") if option == "--tolerance-deg" else ("position", "mm")
    return [f"{text}; the {which} tolerance ({now:g} {unit}) is what ends {max(by_position, by_orientation)} of them "
            f"(the position tolerance {by_position}, the orientation tolerance {by_orientation}): {option} "
            f"{now * 10:g} gives {np.count_nonzero(tried)} of {len(tried)} segments shorter"]


def _short(traj: Trajectory, index: np.ndarray, step_s: float) -> np.ndarray:
    """(P - 1,): which segments between the program points (sample indices (P,)) are shorter than
    :data:`SHORT_SEGMENT_S` in the program's printed times (resolution ``step_s``)."""
    return np.diff(printed_times(np.asarray(traj.t)[index], step_s)) < SHORT_SEGMENT_S


def _part_writer(dialect: Dialect, model: ProgramModel, part: Part) -> Writer:
    return lambda s: dialect.write_part(s, model, part)


def _dialect(fmt: str) -> Dialect:
    if fmt not in DIALECTS:
        raise InputError(f"--format: {fmt!r} is not a controller program format; valid: {', '.join(PROGRAM_FORMATS)}")
    return DIALECTS[fmt]


def _program_name(dialect: Dialect, name: str | None, main: Path | None) -> str:
    stem = main.stem if main is not None else None
    if name is not None:
        checked = dialect.check_name(name, "--name")
        if dialect.named_after_file and stem is not None and stem.lower() != name.lower():
            raise InputError(f"--name: a {dialect.title} program is named after its file; -o {main} makes it "
                             f"{stem!r}, not {name!r} (give one of them, or the same name)")
        return checked
    if stem is not None:
        return dialect.check_name(stem, f"-o {main} (the program is named after its file; give --name)")
    return dialect.check_name(DEFAULT_PROGRAM_NAME, "--name")


def _positive(value: float, where: str) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise InputError(f"{where}: expected a positive number, got {value!r}")
    return float(value)

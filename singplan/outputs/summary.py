"""The human-readable summary `singplan plan` prints: moves, zones and crossings, metrics."""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path

from singplan.results.methods import PAUSING
from singplan.results.metrics import Alternative, BlendFigures, ClearanceFigures, CrossingFigures
from singplan.results.trajectory import Segment, Trajectory
from singplan.task.schema import Task

LISTED_MOVES = 20  # a program with more moves gets the overview (``full`` lists every move)
NOTABLE_SHOWN = 5  # moves listed in the overview, and stopped corners listed without ``full``


def summary(traj: Trajectory, task: Task, full: bool = False) -> str:
    """Multi-line text: one line per move, one per crossing, then the metrics.

    A program of more than :data:`LISTED_MOVES` moves gets an overview instead of the listing
    (counts, crossings by kind and method, the moves that lost the most time), unless ``full``.
    """
    lines = [f"{traj.robot} (tip {traj.tip}): {len(task.moves)} move(s), {traj.duration_s:.3f} s, "
             f"{len(traj.t)} samples at {traj.period * 1e3:g} ms"]
    by_move = traj.segments_by_move()
    short = full or len(task.moves) <= LISTED_MOVES
    if short:
        lines += _move_lines(traj, task, by_move, range(len(task.moves)))
    else:
        lines += overview_lines(traj, task, by_move)
    m = traj.metrics
    lines.append(f"metrics: position error {m.max_position_error_mm:.5f} mm, orientation error "
                 f"{m.max_orientation_error_deg:.5f} deg, joint speed x{m.max_joint_speed_ratio:.3f}, "
                 f"joint accel x{m.max_joint_accel_ratio:.3f}, planning {m.planning_time_s:.2f} s")
    lines.append(_torque_line(traj, task))
    if m.jerk is not None:
        ratio = m.jerk.max_joint_jerk_ratio
        jerk = f"joint jerk x{ratio:.3f}, " if ratio is not None else ""
        law = "quintic PTP law, " if task.limits.ptp_time_law == "quintic" else ""
        lines.append(f"jerk: {jerk}{law}{m.jerk.jerk_time_lost_s:.3f} s longer than the acceleration-limited "
                     f"{m.jerk.acceleration_limited_duration_s:.3f} s")
    stopped = [f"fly-by after move {b.move} ({b.requested_mm:g} mm asked): {b.reduced}" for b in m.blends
               if not b.flown]
    lines += stopped if short or len(stopped) <= NOTABLE_SHOWN else [
        *stopped[:NOTABLE_SHOWN], f"... and {len(stopped) - NOTABLE_SHOWN} more corners stopped at (--full lists them)"]
    lines += _collision_lines(m.clearance)
    lines.append(f"stopping distance: up to {m.max_stopping_distance_mm:.3f} mm at "
                 f"t = {m.max_stopping_distance_at_s:.3f} s (every joint braking at its acceleration limit)")
    return "\n".join(lines) + "\n"


def _move_lines(traj: Trajectory, task: Task, by_move: dict[int, list[Segment]], moves: Iterable[int]) -> list[str]:
    """A line per move (its span, speed and configurations), and its crossings' and corners' lines."""
    lines = []
    for i in moves:
        move, segs = task.moves[i], by_move[i]
        t0, t1 = segs[0].t0, segs[-1].t1
        what = f"{move.speed_m_s:g} m/s" if move.kind != "ptp" else f"velocity x{move.velocity_scale:g}"
        lines.append(f"  move {i} {move.kind:4s} {t0:8.3f} .. {t1:8.3f} s  {what:16s} "
                     f"{segs[0].config_before} -> {segs[-1].config_after}")
        for s in segs:
            lines.extend(_segment_lines(s, traj.zone_times(s) if s.kind == "crossing" else None,
                                        task.singularity.deviation_cost_percent))
    return lines


def overview_lines(traj: Trajectory, task: Task, by_move: dict[int, list[Segment]]) -> list[str]:
    """A long program in a few lines: moves by kind, corners, crossings by kind and method with the
    time they lost and the worst deviation, then the notable moves (a crossing, a configuration
    change) that lost the most time, listed as in the full summary."""
    kinds = Counter(move.kind for move in task.moves)
    corners = [s for s in traj.segments if s.kind == "blend"]
    changed = [i for i, segs in by_move.items() if segs[0].config_before != segs[-1].config_after]
    lines = [f"  moves: {_counted(kinds)}; {len(changed)} change configuration; {len(corners)} fly-by corner(s)"]
    crossings = [s for s in traj.segments if isinstance(s.details, CrossingFigures)]
    if crossings:
        figures = [s.details for s in crossings if isinstance(s.details, CrossingFigures)]
        worst = max(crossings, key=lambda s: _worst_first(s.details))
        lines.append(f"  crossings: {len(crossings)} ({_counted(Counter(str(s.singularity) for s in crossings))}; "
                     f"methods {_counted(Counter(str(s.method) for s in crossings))}), "
                     f"{sum(f.time_lost_s for f in figures):.3f} s lost, largest deviation "
                     f"{max(f.max_position_error_mm for f in figures):.4f} mm / "
                     f"{max(f.max_orientation_error_deg for f in figures):.4f} deg (worst in move {worst.move})")
    else:
        lines.append("  crossings: none")
    lost = {i: sum(s.details.time_lost_s for s in segs if isinstance(s.details, CrossingFigures))
            for i, segs in by_move.items()}
    notable = sorted({s.move for s in crossings} | set(changed), key=lambda i: (-lost[i], i))
    if notable:
        shown = sorted(notable[:NOTABLE_SHOWN])
        lines.append(f"  {len(shown)} of {len(notable)} notable move(s) (a crossing or a configuration change), "
                     "those that lost the most time; --full lists every move:")
        lines += _move_lines(traj, task, by_move, shown)
    return lines


def _counted(counts: Counter[str]) -> str:
    return ", ".join(f"{n} {name}" for name, n in counts.most_common())


def _worst_first(d: object) -> tuple[float, float]:
    """A crossing's deviation as a sort key: orientation, then position."""
    return (d.max_orientation_error_deg, d.max_position_error_mm) if isinstance(d, CrossingFigures) else (0.0, 0.0)


def _collision_lines(c: ClearanceFigures | None) -> list[str]:
    """The closest approach and what was checked, or why nothing was (none when neither the task nor the
    robot has anything to check)."""
    if c is None:
        return []
    notes = [f"collision: {note}" for note in c.notes]
    if c.min_clearance_mm is None or c.min_clearance_pair is None or c.min_clearance_t is None:
        return [*notes, "collision: no pair of bodies to check"]
    skipped = ", ".join(f"{n} {why.replace('_', ' ')}" for why, n in c.skipped.items() if n)
    srdf = f", SRDF {Path(c.srdf).name}" if c.srdf else ""
    a, b = c.min_clearance_pair
    return [f"collision: closest approach {c.min_clearance_mm:.2f} mm ({a} / {b}) at t = {c.min_clearance_t:.3f} s, "
            f"clearance {c.clearance_mm:g} mm; {c.pairs} pairs checked{srdf}"
            f"{f' ({skipped} left out)' if skipped else ''}", *notes]


def _torque_line(traj: Trajectory, task: Task) -> str:
    """The torque figures: the peak against the limit, or why there are none."""
    torques = traj.metrics.torques
    if isinstance(torques, str):
        return f"torques: {torques}"
    scale = task.limits.torque_scale
    limit = f"effort x{scale:g} (enforced)" if scale is not None else "the URDF effort (not enforced: no torque_scale)"
    return f"torques: peak x{torques.max_torque_ratio:.3f} of {limit} at {torques.max_torque_joint}"


def _segment_lines(s: Segment, zone: tuple[float, float] | None, cost_percent: float) -> list[str]:
    """The lines of a fly-by corner or a crossing (none for other segments); ``zone``: when the
    path is inside a crossing's zone; ``cost_percent``: auto's rule (what a whole tolerance costs)."""
    d = s.details
    if isinstance(d, BlendFigures):
        reduced = f" ({d.reduced})" if d.reduced else ""
        return [f"      fly-by {s.t0:.3f} .. {s.t1:.3f} s: radius {d.radius_mm:g} mm{reduced}"]
    if not isinstance(d, CrossingFigures):
        return []
    unit_value = (f"{d.min_distance * 1e3:.3f} mm" if d.min_distance_unit == "m"
                  else f"{math.degrees(d.min_distance):.4f} deg")
    how = "changing branch" if d.changes_branch else "keeping the branch (joints swing, path slowed)"
    if d.pause_s is not None:  # null-space
        how = f"pausing {d.pause_s:.3f} s on the singular point while the aligned joints turn"
    elif s.method in PAUSING:  # null-space pauses only where exact's way on leaves a joint limit
        how = f"{how} as exact does (no pause needed)"
    lines = [f"      {s.singularity} {_span(s, zone)}: closest {unit_value}, "
             f"method {s.method} {how}, {s.config_before} -> {s.config_after}, "
             f"dev {d.max_position_error_mm:.4f} mm / {d.max_orientation_error_deg:.4f} deg, "
             f"time lost {d.time_lost_s:.3f} s"]
    return [*lines, *(f"        {line}" for line in _choice(d.alternatives, cost_percent))]


def _span(s: Segment, zone: tuple[float, float] | None) -> str:
    """A crossing's times and, where the segment is wider (a method's window), its zone's."""
    crossing = f"{s.t0:.3f} .. {s.t1:.3f} s"
    if zone is None:
        return f"crossing {crossing}"
    inside = f"{zone[0]:.3f} .. {zone[1]:.3f} s"
    return f"zone {crossing}" if inside == crossing else f"crossing {crossing} (zone {inside})"


def _choice(alternatives: Sequence[Alternative], cost_percent: float) -> list[str]:
    """What auto compared on the move, as a small table: each candidate's move duration (or, for one
    not timed, the least it can have), the deviation of its crossings, and why it was not chosen."""
    feasible = [a for a in alternatives if a.feasible and a.duration_s is not None]
    if len(alternatives) < 2 or not feasible:
        return []
    best = feasible[0]
    rule = (f"a crossing that uses its whole tolerance counts {cost_percent:g} % slower"
            if cost_percent > 0 else "the fastest within the tolerances")
    untimed = sorted((a for a in alternatives if a.feasible is None), key=_seconds)
    rows = [*feasible, *untimed, *(a for a in alternatives if a.feasible is False)]
    width = max(len(_name(a)) for a in rows)
    methods = {a.method for a in alternatives}  # one: the task's own method comparing its variants
    chooser = "auto" if len(methods) > 1 else f"{best.method} (its variants)"
    lines = [f"{chooser} chose {_name(best)} ({rule}, singularity.deviation_cost_percent):",
             f"  {'method':{width}s}  {'move':>10s}  deviation"]
    for a in rows:
        row = f"  {_name(a):{width}s}  {_move_time(a):>10s}  {_alternative_deviation(a):22s}  {_note(a, best)}"
        lines.append(row.rstrip())
    return lines


def _move_time(a: Alternative) -> str:
    if a.feasible:
        return f"{float(a.duration_s or 0.0):.3f} s"
    return f">= {float(a.at_least_s or 0.0):.3f} s" if a.feasible is None else "-"


def _alternative_deviation(a: Alternative) -> str:
    if a.position_mm is None or a.orientation_deg is None:
        return "-"
    return f"{a.position_mm:.3f} mm / {a.orientation_deg:.3f} deg"


def _note(a: Alternative, best: Alternative) -> str:
    if a is best:
        return "chosen"
    if a.feasible:
        return "planned, not chosen"
    if a.feasible is None:
        return "not timed: cannot win"
    return f"infeasible: {_short(a.reason)}"


def _short(reason: str, limit: int = 110) -> str:
    """An infeasible candidate's reason without the move's name, up to its first clause."""
    text = re.sub(r"^move \d+ \(\w+\): ", "", reason).split("; ")[0]
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _name(a: Alternative) -> str:
    return f"{a.method}{' ' + a.variant if a.variant else ''}"


def _seconds(a: Alternative) -> float:
    """A candidate's duration [s], or for one not timed the bound that ruled it out."""
    seconds = a.duration_s if a.feasible else a.at_least_s
    return float(seconds or 0.0)

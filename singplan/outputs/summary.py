"""The human-readable summary `singplan plan` prints: moves, zones and crossings, metrics."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

from singplan.planning.alternatives import Alternative
from singplan.results.metrics import BlendFigures, CrossingFigures
from singplan.results.trajectory import Segment, Trajectory
from singplan.task.schema import Task


def summary(traj: Trajectory, task: Task) -> str:
    """Multi-line text: one line per move, one per crossing, then the metrics."""
    lines = [f"{traj.robot} (tip {traj.tip}): {len(task.moves)} move(s), {traj.duration_s:.3f} s, "
             f"{len(traj.t)} samples at {traj.period * 1e3:g} ms"]
    by_move = traj.segments_by_move()
    for i, move in enumerate(task.moves):
        segs = by_move[i]
        t0, t1 = segs[0].t0, segs[-1].t1
        what = f"{move.speed_m_s:g} m/s" if move.kind != "ptp" else f"velocity x{move.velocity_scale:g}"
        lines.append(f"  move {i} {move.kind:4s} {t0:8.3f} .. {t1:8.3f} s  {what:16s} "
                     f"{segs[0].config_before} -> {segs[-1].config_after}")
        for s in segs:
            lines.extend(_segment_lines(s, traj.zone_times(s) if s.kind == "crossing" else None,
                                        task.singularity.deviation_cost_percent))
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
    lines += [f"fly-by after move {b.move} ({b.requested_mm:g} mm asked): {b.reduced}" for b in m.blends if not b.flown]
    lines.append(f"stopping distance: up to {m.max_stopping_distance_mm:.3f} mm at "
                 f"t = {m.max_stopping_distance_at_s:.3f} s (every joint braking at its acceleration limit)")
    return "\n".join(lines) + "\n"


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
    elif s.method == "null-space":  # it pauses only where exact's way on leaves a joint limit
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
    lines = [f"auto chose {_name(best)} ({rule}, singularity.deviation_cost_percent):",
             f"  {'method':{width}s}  {'move':>10s}  deviation"]
    for a in rows:
        lines.append(f"  {_name(a):{width}s}  {_move_time(a):>10s}  {_deviation(a):22s}  {_note(a, best)}".rstrip())
    return lines


def _move_time(a: Alternative) -> str:
    if a.feasible:
        return f"{float(a.duration_s or 0.0):.3f} s"
    return f">= {float(a.at_least_s or 0.0):.3f} s" if a.feasible is None else "-"


def _deviation(a: Alternative) -> str:
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

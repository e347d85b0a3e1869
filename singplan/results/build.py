"""Stitch timed moves into a :class:`~singplan.results.trajectory.Trajectory`: samples, segments,
events and metrics (DESIGN.md's contract).

Moves share their boundary sample (one ends at rest where the next starts). A LIN/CIRC with
no zone is one ``path`` segment; with zones it is ``pre``, ``crossing`` (one per zone, merged
where zones overlap; it spans every sample its method replaced, and a blend window may be wider
than the zone), ``post``. The zone events mark where the samples enter and leave the zone
itself. Deviations are measured per sample against the programmed pose at the sample's own path
parameter, an upper bound of the distance to the path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from decimal import Decimal
from typing import Any, Literal

import numpy as np

from singplan.kinematics.clearance import Approach, Clearance
from singplan.kinematics.collision import CollisionModel
from singplan.kinematics.configuration import distances_batch, labels_from_distances, positive_sides
from singplan.kinematics.dynamics import central_differences, effort_limits_nm, no_dynamics_reason, trajectory_torques
from singplan.kinematics.held import HeldJoint
from singplan.kinematics.robot import Robot
from singplan.kinematics.stopping import stopping_distances, worst_stopping
from singplan.kinematics.vendor_config import vendor_configs
from singplan.planning.crossing.methods import Exact, Stop
from singplan.planning.orchestration.blending import Blend
from singplan.planning.orchestration.checks import tcp_speed_ratios
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.path.cartesian import sample_deviations
from singplan.planning.path.zones import Zone
from singplan.planning.timing.ratios import sample_ratios, third_difference_ratio
from singplan.planning.timing.records import TimedMove
from singplan.results.metrics import (
    BlendFigures,
    BlendReport,
    ClearanceFigures,
    CrossingFigures,
    CrossingReport,
    JerkFigures,
    Metrics,
    TorqueFigures,
)
from singplan.results.trajectory import Event, MoveRecord, Segment, SegmentKind, Trajectory
from singplan.task.schema import Task


def sample_times(count: int, period_s: float) -> np.ndarray:
    """The times of ``count`` samples from 0 at ``period_s`` [s], shape (count,).

    Sample k is at the float nearest the decimal k x period as the task wrote it (its shortest
    round-trip text: 0.004), not at the float product k * 0.004, which drifts off the decimal
    grid by an ulp (410 * 0.004 = 1.6400000000000001): the files and the summary then show 1.64.
    The period is m / 10**d with integers m, d; (k * m) is exact while below 2**53 and one
    correctly rounded division by the exact 10**d gives the nearest float to the decimal.
    """
    sign, digits, exponent = Decimal(repr(period_s)).as_tuple()
    m = int("".join(map(str, digits)))
    d = -int(exponent)
    k = np.arange(count, dtype=float)
    if sign or not 0 <= d <= 22 or m * max(count - 1, 0) >= 2**53:  # no exact form: the plain product
        return k * period_s
    return k * m / 10.0**d


def sample_time(k: int, period_s: float) -> float:
    """The time of sample ``k`` [s], as :func:`sample_times` gives it."""
    return float(Decimal(k) * Decimal(repr(period_s)))


def build_trajectory(robot: Robot, task: Task, method: str, planned: list[PlannedMove], timed: list[TimedMove],
                     q_planned: np.ndarray, planning_time_s: float, held: HeldJoint | None = None,
                     blends: tuple[Blend, ...] = (), collision: tuple[CollisionModel, Clearance] | None = None
                     ) -> Trajectory:
    """The trajectory of the planned moves of ``robot`` (``method``: the crossing method asked for).

    With ``held`` (``robot`` is then its 6R chain) the held joint comes back as a constant column,
    so samples, limits and torques are the 7-joint arm's. ``blends``: the corners that asked for
    a fly-by; a flown one is its incoming move's ``blend`` segment, and every one is reported.
    ``collision``: the bodies checked and the check of these samples (one span per move).
    ``planned`` is consumed: after its pass each move is replaced by :meth:`PlannedMove.for_messages`
    (what the final gate's messages need of it), so that where nothing else holds them the moves'
    joint maps and deviations are freed as the record is built, not after it.
    ``q_planned`` (K, n): the moves' samples stitched (:class:`~singplan.planning.orchestration.planner.PlannedTask`'s
    ``q``), the record's own samples unless a joint is held.
    """
    period = task.period_s
    t = sample_times(len(q_planned), period)
    distances = distances_batch(robot, q_planned)  # (K, 3): the labels of the chain that was planned
    labels = _Labels(distances)
    segments: list[Segment] = []
    events: list[Event] = []
    crossings: list[CrossingReport] = []
    worst_pos, worst_ori = 0.0, 0.0
    k0 = 0
    # (K,) each sample's deviations, and the TCP speed over the programmed one of the step arriving at it
    position_error, orientation_error, tcp_ratio = np.zeros(len(t)), np.zeros(len(t)), np.zeros(len(t))
    flown = {b.move: b for b in blends if b.jmap is not None}
    for i, (pm, tm) in enumerate(zip(planned, timed, strict=True)):
        k1 = k0 + len(tm.q) - 1
        pos_err, ori_err, tcp = _deviations(robot, pm, tm, period, planned[i + 1] if i + 1 < len(planned) else None)
        position_error[k0 + 1:k1 + 1], orientation_error[k0 + 1:k1 + 1] = pos_err[1:], ori_err[1:]
        tcp_ratio[k0 + 1:k1 + 1] = tcp
        worst_pos = max(worst_pos, float(pos_err.max(initial=0.0)))
        worst_ori = max(worst_ori, float(ori_err.max(initial=0.0)))
        spans = _own_spans(pm, tm, k1 - k0)  # once for the move's segments and its zone events
        segs = _move_segments(pm, tm, k0, k1, t, period, labels, pos_err, ori_err, flown.get(pm.index), spans)
        segments.extend(segs)
        events.extend(_move_events(pm, tm, k0, k1, t, labels, spans))
        crossings.extend(CrossingReport(s.move, s.t0, s.t1, s.singularity, s.method, s.config_before, s.config_after,
                                        s.details) for s in segs if isinstance(s.details, CrossingFigures))
        planned[i] = pm.for_messages()
        k0 = k1
    arm, q = (held.full, held.expand(q_planned)) if held is not None else (robot, q_planned)
    acceleration_rad_s2 = task.limits.joint_accelerations(arm.n_joints)  # (n,) the task's, every joint of the arm
    speed, accel = _chunked_ratios(q, period, arm.velocity_rad_s * task.joint_speed_scale(), acceleration_rad_s2)
    qd, qdd = central_differences(q, period)
    stopping_m = stopping_distances(arm, q, qd, acceleration_rad_s2)
    stop_mm, stop_at_s = worst_stopping(stopping_m, t)
    metrics = Metrics(worst_pos * 1e3, math.degrees(worst_ori), speed, accel, float(t[-1]), planning_time_s, len(t),
                      method, tuple(crossings), _torque_metrics(arm, task, q, t), stop_mm, stop_at_s,
                      _jerk_metrics(arm, task, q, timed), _blend_reports(blends),
                      _clearance_figures(*collision, period) if collision is not None else None,
                      float(tcp_ratio.max(initial=0.0)))
    tool = {"xyz": list(task.tool_xyz), "rpy_deg": list(task.tool_rpy_deg)}
    samples = {"position_error_m": position_error, "orientation_error_rad": orientation_error,
               "stopping_distance_m": stopping_m, "tcp_speed_ratio": tcp_ratio}
    if not np.isnan(distances).all():  # an arm without labels (7 joints) has no singular distances to store
        samples["distances"] = distances
    least = collision[1].least if collision is not None and collision[0].active else None
    return Trajectory(arm.name, str(arm.urdf_path), arm.tip, tool, task, arm.joint_names,
                      period, t, q, qd, qdd, tuple(segments), tuple(events), metrics, samples,
                      _move_records(arm, task, segments, q, period, least))


def _move_records(robot: Robot, task: Task, segments: list[Segment], q: np.ndarray, period: float,
                  least: tuple[Approach | None, ...] | None) -> tuple[MoveRecord, ...]:
    """Per task move: span, end configuration and vendor configuration data at its last sample, and
    its closest approach (``least``, one per move, when collision checking is on)."""
    spans: dict[int, list[Segment]] = {}
    for s in segments:
        spans.setdefault(s.move, []).append(s)
    ends = [min(len(q) - 1, round(segs[-1].t1 / period)) for segs in spans.values()]
    vendor = vendor_configs(robot, q[ends])
    records = []
    for (i, segs), v in zip(spans.items(), vendor, strict=True):
        closest = least[i] if least is not None else None
        records.append(MoveRecord(i, task.moves[i].kind, segs[0].t0, segs[-1].t1, segs[-1].config_after, v,
                                  None if closest is None else closest.distance_m * 1e3,
                                  None if closest is None else list(closest.bodies)))
    return tuple(records)


def _clearance_figures(model: CollisionModel, found: Clearance, period: float) -> ClearanceFigures:
    """The trajectory's collision figures: its closest approach and what was checked."""
    closest = found.closest
    return ClearanceFigures(
        model.clearance_m * 1e3, None if closest is None else closest.distance_m * 1e3,
        None if closest is None else closest.bodies, None if closest is None else closest.sample * period,
        None if closest is None else (closest.point_a, closest.point_b), tuple(b.name for b in model.bodies),
        len(model.pairs), dict(model.skipped), model.self_collision, None if model.srdf is None else str(model.srdf),
        model.notes, found.distance_calls)


_CHUNK = 16_384  # samples whose ratios are formed at once (~600 bytes of temporaries each)


def _jerk_metrics(robot: Robot, task: Task, q: np.ndarray, timed: list[TimedMove]) -> JerkFigures | None:
    """With a jerk limit or the quintic PTP law: the jerk ratio and the time they cost against the
    acceleration-limited optimum (TOPP-RA's duration of every move)."""
    jerk = task.limits.jerk_rad_s3
    if jerk is None and task.limits.ptp_time_law == "optimal":
        return None
    optimal_s = sum(tm.optimal_duration_s if tm.optimal_duration_s is not None else tm.duration_s for tm in timed)
    ratio = (third_difference_ratio(q, task.period_s, np.broadcast_to(np.asarray(jerk, dtype=float),
                                                                      (robot.n_joints,)))
             if jerk is not None else None)
    return JerkFigures(optimal_s, sum(tm.duration_s for tm in timed) - optimal_s, ratio)


def _torque_metrics(robot: Robot, task: Task, q: np.ndarray, t: np.ndarray) -> TorqueFigures | str:
    """Inverse-dynamics torques of the samples against the efforts x ``limits.torque_scale`` (1 if unset).

    A robot without dynamics gets the reason instead (no torque is invented for it).
    """
    reason = no_dynamics_reason(robot)
    if reason is not None:
        return f"not computed: {reason}"
    limit_nm = effort_limits_nm(robot) * (task.limits.torque_scale or 1.0)
    peaks, _ = trajectory_torques(robot, q, task.period_s, limit_nm)
    return TorqueFigures(peaks.ratio, float(t[peaks.sample]), robot.joint_names[peaks.joint],
                         dict(zip(robot.joint_names, peaks.peak_nm.tolist(), strict=True)),
                         dict(zip(robot.joint_names, limit_nm.tolist(), strict=True)))


class _Labels:
    """Configuration labels of the samples, kept as one sign code per sample.

    A list of a million label strings takes ~60 MB; the codes take 1 MB and give the same
    labels (those of :func:`labels_from_distances`) where they are asked for.
    """

    def __init__(self, distances: np.ndarray) -> None:
        signs = positive_sides(distances)  # NaN counts as negative, as in labels_from_distances ...
        self.codes = (signs[:, 0] * 1 + signs[:, 1] * 2 + signs[:, 2] * 4).astype(np.int8)
        self.codes[np.isnan(distances).all(axis=1)] = 8  # ... but a row with no distance has no label
        rows = np.array([[bit & 1, bit & 2, bit & 4] for bit in range(8)] + [[np.nan] * 3], dtype=float) - 0.5
        self.table = labels_from_distances(rows)

    def __getitem__(self, k: int) -> str:
        return self.table[self.codes[k]]

    def changes(self, k0: int, k1: int) -> np.ndarray:
        """Samples k in (k0, k1] whose label differs from sample k - 1's."""
        return k0 + 1 + np.nonzero(self.codes[k0 + 1:k1 + 1] != self.codes[k0:k1])[0]


def _chunked_ratios(q: np.ndarray, period: float, vmax: np.ndarray, amax: np.ndarray) -> tuple[float, float]:
    """:func:`sample_ratios` of all samples, a chunk at a time (its temporaries take ~150 bytes a
    sample); chunks overlap by the two samples a second difference spans, so the maxima are exact."""
    ratios = [sample_ratios(q[c:c + _CHUNK + 2], period, vmax, amax) for c in range(0, max(len(q) - 2, 1), _CHUNK)]
    return max(r[0] for r in ratios), max(r[1] for r in ratios)


def _sample_at(u: np.ndarray, value: float) -> int:
    return min(len(u) - 1, int(np.searchsorted(u, value - 1e-12)))


def _sample_span(u: np.ndarray, u0: float, u1: float, last: int) -> tuple[int, int]:
    """The samples a stretch [u0, u1] of the path runs between: the first at or past u0 and the first
    at or past u1 (where the path has left it), at least one step apart, within 0 .. ``last``."""
    a = min(_sample_at(u, u0), last - 1)
    return a, min(max(_sample_at(u, u1), a + 1), last)


def _merged_spans(pm: PlannedMove, tm: TimedMove, last: int) -> Spans:
    """Sample spans (up to sample ``last``) of the zones' crossings (a zone's window where a method
    crossed it wider than the zone), overlapping ones merged; at least one step long.

    Zones wholly in a fly-by corner (before the move's first sample or after ``last``) are the corner's.
    """
    spans: Spans = []
    visible = [z for z in pm.zones if z.span[1] > tm.u[0] and z.span[0] < tm.u[last]]
    for zone in sorted(visible, key=lambda z: z.span[0]):
        a, b = _sample_span(tm.u, *zone.span, last)
        if spans and a <= spans[-1][1]:
            pa, pb, zs = spans[-1]
            spans[-1] = (pa, max(pb, b), [*zs, zone])
        else:
            spans.append((a, b, [zone]))
    return spans


def _deviations(robot: Robot, pm: PlannedMove, tm: TimedMove, period: float,
                nxt: PlannedMove | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each sample's position [m] and orientation [rad] deviation from the move's path, and each
    step's TCP speed over the programmed one: the figures measured when the move was checked where
    its samples are those. A fly-by corner's samples leave the path on purpose (their own figures)
    and count 0; their TCP speed is held to the faster of the two moves' (when both have one)."""
    measured = pm.deviations.of(tm.u, tm.q) if pm.deviations is not None else None
    if measured is not None:
        return measured.position_m, measured.orientation_rad, measured.tcp_speed_ratio
    own = len(tm.q) if tm.blend_from is None else tm.blend_from + 1
    pos, ori, tcp = np.zeros(len(tm.q)), np.zeros(len(tm.q)), np.zeros(len(tm.q) - 1)
    pos[:own], ori[:own] = sample_deviations(robot, pm.piece, tm.u[:own], tm.q[:own])
    tcp[:own - 1] = tcp_speed_ratios(robot, pm, tm.u[:own], tm.q[:own], period)
    speeds = [p.limits.tcp_speed_m_s or 0.0 for p in (pm, nxt) if p is not None and p.piece is not None]
    if own < len(tm.q) and len(speeds) == 2 and min(speeds) > 0.0:
        corner = np.linalg.norm(np.diff(robot.tcp_positions(tm.q[own - 1:]), axis=0), axis=1)
        tcp[own - 1:] = corner / (period * max(speeds))
    return pos, ori, tcp


def _blend_reports(blends: tuple[Blend, ...]) -> tuple[BlendReport, ...]:
    """Every corner that asked for a fly-by: the radius asked for, the radius used and why it differs."""
    return tuple(BlendReport(b.move, b.requested_m * 1e3, b.radius_m * 1e3, b.jmap is not None, b.note)
                 for b in blends)


Spans = list[tuple[int, int, list[Zone]]]  # (first sample, last sample, the zones crossed there), merged


def _own_spans(pm: PlannedMove, tm: TimedMove, end: int) -> Spans:
    """The crossings' sample spans on the move's own path (samples 0 .. ``end``, a fly-by corner's
    left out): :func:`_merged_spans`; none for a PTP or a move that is all corner."""
    last = end if tm.blend_from is None else tm.blend_from
    return [] if pm.kind == "ptp" or last == 0 else _merged_spans(pm, tm, last)


def _move_segments(pm: PlannedMove, tm: TimedMove, k0: int, k1: int, t: np.ndarray, period: float,
                   labels: _Labels, pos_err: np.ndarray, ori_err: np.ndarray, blend: Blend | None,
                   spans: Spans) -> list[Segment]:
    def seg(kind: SegmentKind, a: int, b: int, **extra: Any) -> Segment:
        return Segment(pm.index, kind, float(t[k0 + a]), float(t[k0 + b]), labels[k0 + a], labels[k0 + b], **extra)

    if tm.blend_from is None:
        return _path_segments(pm, tm, k1 - k0, seg, period, pos_err, ori_err, spans)
    assert blend is not None
    own = _path_segments(pm, tm, tm.blend_from, seg, period, pos_err, ori_err, spans) if tm.blend_from > 0 else []
    return [*own, seg("blend", tm.blend_from, k1 - k0,
                      details=BlendFigures(blend.radius_m * 1e3, blend.requested_m * 1e3, blend.note, blend.ramp))]


SegmentMaker = Callable[..., Segment]


def _path_segments(pm: PlannedMove, tm: TimedMove, last: int, seg: SegmentMaker, period: float,
                   pos_err: np.ndarray, ori_err: np.ndarray, spans: Spans) -> list[Segment]:
    """The segments of the move's samples 0 .. last on its own path, its crossings at ``spans``."""
    if pm.kind == "ptp":
        return [seg("ptp", 0, last)]
    if not spans:
        return [seg("path", 0, last)]
    out: list[Segment] = []
    cursor = 0
    for n, (a, b, zones) in enumerate(spans):
        if a > cursor:
            out.append(seg("pre" if n == 0 else "post", cursor, a))
        closest = min(zones, key=lambda z: z.min_distance / z.threshold)
        out.append(seg("crossing", a, b, singularity=closest.kind, method=_zone_method(pm, closest),
                       details=_crossing_figures(pm, tm, a, b, closest, pos_err, ori_err, period)))
        cursor = b
    if cursor < last:
        out.append(seg("post", cursor, last))
    return out


def _zone_method(pm: PlannedMove, zone: Zone) -> str:
    """The method that crossed the zone (exact kept the branch where no crossing was made)."""
    for c in pm.crossings:
        if c.zone.u_closest == zone.u_closest:
            return c.method
    return Exact.name if pm.method != Stop.name else pm.method


def _crossing_figures(pm: PlannedMove, tm: TimedMove, a: int, b: int, zone: Zone, pos_err: np.ndarray,
                      ori_err: np.ndarray, period: float) -> CrossingFigures:
    k = a + int(np.argmax(ori_err[a:b + 1]))
    speed = pm.limits.tcp_speed_m_s or 0.0
    nominal = (tm.u[b] - tm.u[a]) * pm.limits.length_m / speed if speed > 0 else 0.0
    through = any(c.zone.u_closest == zone.u_closest for c in pm.crossings)
    # a null-space pause: the samples that stay at the singular point's u while the joints turn
    waits = [int(np.count_nonzero(np.abs(tm.u[a:b + 1] - c.pause.u) < 1e-12)) - 1 for c in pm.crossings
             if c.pause is not None and c.zone.u_closest == zone.u_closest]
    return CrossingFigures(zone.min_distance, zone.unit, float(pos_err[a:b + 1].max()) * 1e3,
                           math.degrees(float(ori_err[a:b + 1].max())), float(tm.u[k] * pm.limits.length_m),
                           max(0.0, (b - a) * period - nominal), through, pm.alternatives,
                           sample_time(max(0, sum(waits)), period) if waits else None)


def _move_events(pm: PlannedMove, tm: TimedMove, k0: int, k1: int, t: np.ndarray,
                 labels: _Labels, spans: Spans) -> list[Event]:
    """The move's zone entries and exits (its crossings at ``spans``), and its configuration changes."""
    events = [Event(float(t[k0 + k]), pm.index, kind, zone.kind)
              for k, kind, zone in _zone_samples(tm, k1 - k0, spans)]
    for k in labels.changes(k0, k1).tolist():
        events.append(Event(float(t[k]), pm.index, "config_change", config_from=labels[k - 1], config_to=labels[k]))
    return sorted(events, key=lambda e: e.t)


ZoneEventKind = Literal["zone_entry", "zone_exit"]


def _zone_samples(tm: TimedMove, end: int, spans: Spans) -> list[tuple[int, ZoneEventKind, Zone]]:
    """Where the move's samples enter and leave each zone (not its crossing's window, which may be
    wider): the first sample at or past the zone's entry and the first at or past its exit, the
    move's first / last sample for a zone open there, kept inside the zone's crossing segment."""
    last = end if tm.blend_from is None else tm.blend_from  # a fly-by corner's samples are not the path's
    out: list[tuple[int, ZoneEventKind, Zone]] = []
    for a, b, zones in spans:
        for zone in zones:
            if zone.u_exit <= tm.u[0] or zone.u_entry >= tm.u[last]:
                continue  # only the window reaches the move's own samples; the zone is the corner's
            entry, exit_ = _sample_span(tm.u, zone.u_entry, zone.u_exit, last)
            entry = min(max(entry, a), b)
            out += [(entry, "zone_entry", zone), (min(max(exit_, entry), b), "zone_exit", zone)]
    return out

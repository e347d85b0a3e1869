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
from collections.abc import Callable, Sequence
from dataclasses import replace
from decimal import Decimal
from functools import cache
from typing import Any, Literal, NamedTuple

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
from singplan.planning.orchestration.rows import RowStore
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


def sample_times(count: int, period_s: float, start: int = 0) -> np.ndarray:
    """The times of ``count`` samples from sample ``start`` at ``period_s`` [s], shape (count,).

    Sample k is at the float nearest the decimal k x period as the task wrote it (its shortest
    round-trip text: 0.004), not at the float product k * 0.004, which drifts off the decimal
    grid by an ulp (410 * 0.004 = 1.6400000000000001): the files and the summary then show 1.64.
    The period is m / 10**d with integers m, d; (k * m) is exact while below 2**53 and one
    correctly rounded division by the exact 10**d gives the nearest float to the decimal.
    """
    k = np.arange(start, start + count, dtype=float)
    decimal = _decimal_form(period_s, start + count - 1)
    if decimal is None:  # no exact form: the plain product
        return k * period_s
    m, d = decimal
    return k * m / 10.0**d


def _decimal_form(period_s: float, last: int) -> tuple[int, int] | None:
    """(m, d) with period = m / 10**d where k * m is exact for every sample k up to ``last``; None where not."""
    sign, digits, exponent = Decimal(repr(period_s)).as_tuple()
    m = int("".join(map(str, digits)))
    d = -int(exponent)
    if sign or not 0 <= d <= 22 or m * max(last, 0) >= 2**53:
        return None
    return m, d


def sample_time(k: int, period_s: float) -> float:
    """The time of sample ``k`` [s], as :func:`sample_times` gives it."""
    return float(Decimal(k) * Decimal(repr(period_s)))


class MoveReports:
    """The trajectory record's parts of each move, made as the planner hands the move over
    (:class:`~singplan.planning.orchestration.planner.MoveSink`): its segments, events and crossing
    reports, and its samples' deviations from the path and singular distances (kept in blocks,
    :class:`~singplan.planning.orchestration.rows.RowStore`), so that a long program keeps no
    planned move whole until its record is built.

    Moves share their boundary sample: each move's first sample is the one its predecessor ended at.
    """

    def __init__(self, robot: Robot, task: Task) -> None:
        self.robot = robot  # the chain planned (a 7-joint arm's 6R chain): its labels and deviations
        self.period_s = task.period_s
        self.segments: list[Segment] = []
        self.events: list[Event] = []
        self.crossings: list[CrossingReport] = []
        self.worst_position_m = 0.0
        self.worst_orientation_rad = 0.0
        self.worst_tcp_ratio = 0.0
        self.position_m = RowStore()  # (K,) each sample's position deviation [m]
        self.orientation_rad = RowStore()  # (K,) orientation deviation [rad]
        self.tcp_ratio = RowStore()  # (K,) the TCP speed over the programmed one of the step arriving at each sample
        self.distances = RowStore((3,))  # (K, 3) signed singular distances: the samples' labels
        self.last_distances = np.zeros((0, 3))  # (0 or 1, 3) the last move's last row: the next move's first
        self.samples = 0  # samples taken so far
        self._series: _Series | None = None

    def take(self, pm: PlannedMove, tm: TimedMove, nxt: PlannedMove | None, blend: Blend | None) -> None:
        """Move ``pm``'s record parts, from its samples ``tm`` (see :class:`MoveSink`)."""
        k0 = max(self.samples - 1, 0)
        last = len(tm.q) - 1  # the move's samples are k0 .. k0 + last
        pos_err, ori_err, tcp = _deviations(self.robot, pm, tm, self.period_s, nxt)
        self.worst_position_m = max(self.worst_position_m, float(pos_err.max(initial=0.0)))
        self.worst_orientation_rad = max(self.worst_orientation_rad, float(ori_err.max(initial=0.0)))
        self.worst_tcp_ratio = max(self.worst_tcp_ratio, float(tcp.max(initial=0.0)))
        # (last + 1, 3): the labels of the chain that was planned; the boundary sample's row is the
        # predecessor's (its last sample, which the stitched samples keep; this move's own first
        # differs from it by round-off)
        own = distances_batch(self.robot, tm.q[1:] if self.samples else tm.q)
        distances = np.concatenate([self.last_distances, own])
        self.last_distances = distances[-1:]
        if not self.samples:  # the trajectory's first sample: no step arrives at it, its deviations count 0
            for series in (self.position_m, self.orientation_rad, self.tcp_ratio):
                series.kept(np.zeros(1))
        self.position_m.kept(pos_err[1:])  # the boundary sample is the predecessor's
        self.orientation_rad.kept(ori_err[1:])
        self.tcp_ratio.kept(tcp)
        self.distances.kept(own)
        t = sample_times(last + 1, self.period_s, k0)
        labels = _Labels(distances)
        spans = _own_spans(pm, tm, last)  # once for the move's segments and its zone events
        segs = _move_segments(pm, tm, last, t, self.period_s, labels, pos_err, ori_err, blend, spans)
        self.segments.extend(segs)
        self.events.extend(_move_events(pm, tm, last, t, labels, spans))
        self.crossings.extend(CrossingReport(s.move, s.t0, s.t1, s.singularity, s.method, s.config_before,
                                             s.config_after, s.details)
                              for s in segs if isinstance(s.details, CrossingFigures))
        self.samples = k0 + last + 1

    def series(self) -> _Series:
        """The samples' series, stitched once (every move taken)."""
        if self._series is None:
            self._series = _Series(self.position_m.stitched(), self.orientation_rad.stitched(),
                                   self.tcp_ratio.stitched(), self.distances.stitched())
        return self._series


class _Series(NamedTuple):
    """Every sample's figures (K,) / (K, 3), made as the moves were taken."""

    position_m: np.ndarray  # (K,) position deviation [m]
    orientation_rad: np.ndarray  # (K,) orientation deviation [rad]
    tcp_ratio: np.ndarray  # (K,) the TCP speed over the programmed one of the step arriving at each sample
    distances: np.ndarray  # (K, 3) signed singular distances


def build_trajectory(robot: Robot, task: Task, method: str, reports: MoveReports, timed: Sequence[TimedMove],
                     q_planned: np.ndarray, planning_time_s: float, held: HeldJoint | None = None,
                     blends: tuple[Blend, ...] = (), collision: tuple[CollisionModel, Clearance] | None = None
                     ) -> Trajectory:
    """The trajectory of the planned moves of ``robot`` (``method``: the crossing method asked for),
    each move's parts in ``reports`` (every move handed over; its series stitched once).

    With ``held`` (``robot`` is then its 6R chain) the held joint comes back as a constant column,
    so samples, limits and torques are the 7-joint arm's. ``blends``: the corners that asked for
    a fly-by; every one is reported. ``collision``: the bodies checked and the check of these
    samples (one span per move). ``q_planned`` (K, n): the moves' samples stitched
    (:class:`~singplan.planning.orchestration.planner.PlannedTask`'s ``q``), the record's own samples
    unless a joint is held.
    """
    period = task.period_s
    t = sample_times(len(q_planned), period)
    if reports.samples != len(t):
        raise AssertionError(f"the moves' reports cover {reports.samples} samples, the trajectory {len(t)}")
    position_error, orientation_error, tcp_ratio, distances = reports.series()
    segments, events, crossings = reports.segments, reports.events, reports.crossings
    if _decimal_form(period, len(t) - 1) is None:  # the trajectory's times are the plain products ...
        segments, events, crossings = _on_times(t, period, segments, events, crossings)
    arm, q = (held.full, held.expand(q_planned)) if held is not None else (robot, q_planned)
    acceleration_rad_s2 = task.limits.joint_accelerations(arm.n_joints)  # (n,) the task's, every joint of the arm
    speed, accel = _chunked_ratios(q, period, arm.velocity_rad_s * task.joint_speed_scale(), acceleration_rad_s2)
    qd, qdd = central_differences(q, period)
    stopping_m = stopping_distances(arm, q, qd, acceleration_rad_s2)
    stop_mm, stop_at_s = worst_stopping(stopping_m, t)
    metrics = Metrics(reports.worst_position_m * 1e3, math.degrees(reports.worst_orientation_rad), speed, accel,
                      float(t[-1]), planning_time_s, len(t), method, tuple(crossings),
                      _torque_metrics(arm, task, q, t), stop_mm, stop_at_s, _jerk_metrics(arm, task, q, timed),
                      _blend_reports(blends),
                      _clearance_figures(*collision, period) if collision is not None else None,
                      reports.worst_tcp_ratio)
    tool = {"xyz": list(task.tool_xyz), "rpy_deg": list(task.tool_rpy_deg)}
    samples = {"position_error_m": position_error, "orientation_error_rad": orientation_error,
               "stopping_distance_m": stopping_m, "tcp_speed_ratio": tcp_ratio}
    if not np.isnan(distances).all():  # an arm without labels (7 joints) has no singular distances to store
        samples["distances"] = distances
    least = collision[1].least if collision is not None and collision[0].active else None
    return Trajectory(arm.name, str(arm.urdf_path), arm.tip, tool, task, arm.joint_names,
                      period, t, q, qd, qdd, tuple(segments), tuple(events), metrics, samples,
                      _move_records(arm, task, segments, q, period, least))


def _on_times(t: np.ndarray, period: float, segments: list[Segment], events: list[Event],
              crossings: list[CrossingReport]) -> tuple[list[Segment], list[Event], list[CrossingReport]]:
    """... where a move's own samples may have had exact decimal times (their last index was small
    enough, :func:`sample_times`): every report's times made the trajectory's samples' ``t`` (K,)."""
    def at(time_s: float) -> float:
        return float(t[round(time_s / period)])

    return ([replace(s, t0=at(s.t0), t1=at(s.t1)) for s in segments], [replace(e, t=at(e.t)) for e in events],
            [replace(c, t0=at(c.t0), t1=at(c.t1)) for c in crossings])


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


def _jerk_metrics(robot: Robot, task: Task, q: np.ndarray, timed: Sequence[TimedMove]) -> JerkFigures | None:
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


@cache
def _label_table() -> list[str]:
    """The label of each sign code (bit 0: wrist, 1: shoulder, 2: elbow positive; 8: no distance), made
    once: every move's samples are labelled from it."""
    rows = np.array([[bit & 1, bit & 2, bit & 4] for bit in range(8)] + [[np.nan] * 3], dtype=float) - 0.5
    return labels_from_distances(rows)


class _Labels:
    """Configuration labels of the samples, kept as one sign code per sample.

    A list of a million label strings takes ~60 MB; the codes take 1 MB and give the same
    labels (those of :func:`labels_from_distances`) where they are asked for.
    """

    def __init__(self, distances: np.ndarray) -> None:
        signs = positive_sides(distances)  # NaN counts as negative, as in labels_from_distances ...
        self.codes = (signs[:, 0] * 1 + signs[:, 1] * 2 + signs[:, 2] * 4).astype(np.int8)
        self.codes[np.isnan(distances).all(axis=1)] = 8  # ... but a row with no distance has no label
        self.table = _label_table()

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


def _move_segments(pm: PlannedMove, tm: TimedMove, last: int, t: np.ndarray, period: float,
                   labels: _Labels, pos_err: np.ndarray, ori_err: np.ndarray, blend: Blend | None,
                   spans: Spans) -> list[Segment]:
    """The move's segments; ``t`` and ``labels``: of its samples 0 .. ``last``."""
    def seg(kind: SegmentKind, a: int, b: int, **extra: Any) -> Segment:
        return Segment(pm.index, kind, float(t[a]), float(t[b]), labels[a], labels[b], **extra)

    if tm.blend_from is None:
        return _path_segments(pm, tm, last, seg, period, pos_err, ori_err, spans)
    assert blend is not None
    own = _path_segments(pm, tm, tm.blend_from, seg, period, pos_err, ori_err, spans) if tm.blend_from > 0 else []
    return [*own, seg("blend", tm.blend_from, last,
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


def _move_events(pm: PlannedMove, tm: TimedMove, last: int, t: np.ndarray,
                 labels: _Labels, spans: Spans) -> list[Event]:
    """The move's zone entries and exits (its crossings at ``spans``), and its configuration changes;
    ``t`` and ``labels``: of its samples 0 .. ``last``."""
    events = [Event(float(t[k]), pm.index, kind, zone.kind)
              for k, kind, zone in _zone_samples(tm, last, spans)]
    for k in labels.changes(0, last).tolist():
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

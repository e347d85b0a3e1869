"""A self-contained HTML report of a trajectory: the summary tables and the curves people look at.

A timeline strip of the segments by kind, then plots (SVG written by :mod:`singplan.outputs.svgplot`,
so the page needs no network and no other file): joint positions with their limits, joint speed against
the limit, the signed singular distances with the detection thresholds, the position and
orientation deviation from the programmed path with the tolerances, the TCP speed against the
programmed speed, the stopping distance, and for a robot with dynamics the joint torques against
their limits. Crossings, fly-by blends, null-space pauses and woven moves are shaded on every
time plot in the timeline's colours. The TCP positions come from the shared
:class:`singplan.outputs.timeline.TcpTrack` (forward kinematics once for report and replay).
"""

from __future__ import annotations

import html
import math
from typing import Any, NamedTuple

import numpy as np

from singplan.kinematics.clearance import clearance_curve
from singplan.kinematics.collision import collision_model
from singplan.kinematics.dynamics import trajectory_torques
from singplan.kinematics.robot import Robot
from singplan.outputs.svgplot import Panel, envelope, figure_svg
from singplan.outputs.timeline import SHADED_OPACITY, PageBasis, Stretch, page_basis
from singplan.results.metrics import Metrics, TorqueFigures, crossing_costs
from singplan.results.trajectory import Segment, Trajectory

_PLOT_BUCKETS = 1000  # a curve longer than two points a bucket is drawn as its min/max envelope (> 1 a pixel)
_LEGEND = {"path": "path", "pre": "before a zone", "crossing": "crossing", "post": "after a zone", "ptp": "PTP",
           "blend": "fly-by blend", "weave": "woven move", "pause": "null-space pause (TCP still)"}

_STYLE = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1100px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}h2{margin-top:1.6em}
figure{margin:0 0 1.5em}figcaption{color:#555;font-size:0.9em}
.legend span{margin-right:1.2em;font-size:0.9em}
.legend i{display:inline-block;width:1em;height:0.8em;margin-right:0.3em}
.timeline{position:relative;height:18px;background:#eee;margin-top:0.5em}
.timeline i{position:absolute;top:0;bottom:0}"""

class _Figure(NamedTuple):
    """A figure of the page: its id key, caption, panels and layout (columns, height [in])."""

    key: str
    caption: str
    panels: list[Panel]
    columns: int = 1
    height_in: float = 3.0


def _hex(colour: int) -> str:
    return f"#{colour:06x}"


def _curve(panel: Panel, x: np.ndarray, y: np.ndarray, **style: Any) -> None:
    panel.curve(*envelope(x, y, _PLOT_BUCKETS), **style)


class _Shading:
    """The timeline's shaded spans (crossings, blends, pauses, weave), laid under every time plot."""

    def __init__(self, stretches: list[Stretch], duration_s: float) -> None:
        self.spans = [(t0, t1, _hex(s.colour), SHADED_OPACITY[s.kind]) for s in {s.kind: s for s in stretches}.values()
                      if s.kind in SHADED_OPACITY for t0, t1 in _covered(stretches, s.kind, duration_s)]

    def panel(self, **labels: Any) -> Panel:
        """A new panel with the shading (``labels``: its title, axis labels, legend, top axis)."""
        panel = Panel(**labels)
        for span in self.spans:
            panel.span(*span)
        return panel


def _covered(stretches: list[Stretch], kind: str, duration_s: float) -> list[tuple[float, float]]:
    """The time spans [s] of a kind, at most one a plot bucket: spans closer than a bucket (a
    program of thousands of fly-by corners) are merged, so the page stays bounded."""
    bucket = max(duration_s, 1e-9) / _PLOT_BUCKETS
    out: list[tuple[float, float]] = []
    for s in stretches:
        if s.kind != kind:
            continue
        if out and s.t0 - out[-1][1] < bucket:
            out[-1] = (out[-1][0], max(out[-1][1], s.t1))
        else:
            out.append((s.t0, s.t1))
    return out


def _path_length_axis(traj: Trajectory, s_mm: np.ndarray) -> Any:
    """A top axis in path length [mm] (the TCP distance travelled since t = 0), for :attr:`Panel.top`."""
    return "path length [mm]", lambda t: np.interp(t, traj.t, s_mm), lambda s: np.interp(s, s_mm, traj.t)


def _joints(traj: Trajectory, robot: Robot, shading: _Shading) -> list[Panel]:
    """A panel a joint: its position [deg] and its limits."""
    panels = []
    for j, name in enumerate(traj.joint_names):
        panel = shading.panel(title=name)
        _curve(panel, traj.t, np.degrees(traj.q[:, j]))
        for limit in (robot.lower_rad[j], robot.upper_rad[j]):
            if math.isfinite(limit):  # an unlimited (continuous) joint has none to draw
                panel.hline(math.degrees(limit))
        panels.append(panel)
    return panels


def _joint_ratios(traj: Trajectory, t: np.ndarray, ratios: np.ndarray, ylabel: str, shading: _Shading) -> list[Panel]:
    """One panel of each joint's ratio to its limit (``ratios``, (K, n)) against t (K,), and the limit line."""
    panel = shading.panel(xlabel="t [s]", ylabel=ylabel, legend=True)
    for j, name in enumerate(traj.joint_names):
        _curve(panel, t, ratios[:, j], label=name, width=1.0)
    panel.hline(1.0)
    return [panel]


def _torque_ratio(traj: Trajectory, robot: Robot, limit_nm: np.ndarray, shading: _Shading) -> list[Panel]:
    _, ratios = trajectory_torques(robot, traj.q, traj.period, limit_nm, series=True)
    assert ratios is not None
    return _joint_ratios(traj, traj.t, ratios, "|tau| / limit", shading)


def _distances(traj: Trajectory, thresholds: list[float], s_mm: np.ndarray, shading: _Shading) -> list[Panel]:
    """The signed wrist, shoulder and elbow distances with their detection thresholds."""
    d = traj.samples["distances"]
    panels = []
    for label, values, thr in (("wrist [deg]", np.degrees(d[:, 0]), thresholds[0]),
                               ("shoulder [mm]", d[:, 1] * 1e3, thresholds[1]),
                               ("elbow [deg]", np.degrees(d[:, 2]), thresholds[2])):
        panel = shading.panel(title=label, xlabel="t [s]", top=_path_length_axis(traj, s_mm))
        _curve(panel, traj.t, values)
        for sign in (-1, 1):
            panel.hline(sign * thr)
        panel.hline(0.0, colour="#000000", dashed=False)
        panels.append(panel)
    return panels


def _deviation(traj: Trajectory, pos_tol_mm: float, ori_tol_deg: float, s_mm: np.ndarray,
               shading: _Shading) -> list[Panel]:
    """The position and orientation deviation from the programmed path with their tolerances."""
    panels = []
    for label, values, tol in (
            ("position deviation [mm]", traj.samples["position_error_m"] * 1e3, pos_tol_mm),
            ("orientation deviation [deg]", np.degrees(traj.samples["orientation_error_rad"]), ori_tol_deg)):
        panel = shading.panel(title=label, xlabel="t [s]", top=_path_length_axis(traj, s_mm))
        _curve(panel, traj.t, values)
        panel.hline(tol)
        panels.append(panel)
    return panels


def _tcp_speed(traj: Trajectory, step_m: np.ndarray, shading: _Shading) -> list[Panel]:
    """The TCP speed between samples, and each LIN / CIRC's programmed speed over its time."""
    panel = shading.panel(xlabel="t [s]", ylabel="[m/s]")
    _curve(panel, traj.t[1:], step_m / traj.period, label="TCP speed")
    by_move = traj.segments_by_move()
    for i, move in enumerate(traj.task.moves):
        segs = by_move.get(i)
        if move.kind != "ptp" and segs:
            panel.hline(move.speed_m_s, x0=segs[0].t0, x1=segs[-1].t1)
    return [panel]


def _stopping(traj: Trajectory, shading: _Shading) -> list[Panel]:
    """The stopping distance, its worst sample marked."""
    distance_mm = traj.samples["stopping_distance_m"] * 1e3
    panel = shading.panel(xlabel="t [s]", ylabel="stopping distance [mm]")
    _curve(panel, traj.t, distance_mm)
    k = int(np.argmax(distance_mm))
    panel.point(traj.t[k], distance_mm[k], f"{distance_mm[k]:.1f} mm")
    return [panel]


_CLEARANCE_POINTS = 600  # samples at which the report measures the least distance of all pairs


def _clearance(traj: Trajectory, robot: Robot, shading: _Shading) -> list[Panel]:
    """The least distance of all checked pairs over time (measured at a few hundred samples, and at
    the closest approach), against the clearance asked for."""
    figures = traj.metrics.clearance
    assert figures is not None and figures.min_clearance_mm is not None and figures.min_clearance_t is not None
    task = traj.task  # the bodies and pairs as planned (planning.orchestration.targets)
    model = collision_model(robot, task.tool_geometry, task.cell, task.collision, traj.q[0])
    picks, distance_m = clearance_curve(model, traj.q, _CLEARANCE_POINTS)
    panel = shading.panel(xlabel="t [s]", ylabel="least distance [mm]")
    _curve(panel, traj.t[picks], distance_m * 1e3, label="closest pair")
    panel.hline(figures.clearance_mm)
    a, b = figures.min_clearance_pair or ("", "")
    panel.point(figures.min_clearance_t, figures.min_clearance_mm, f"{figures.min_clearance_mm:.1f} mm ({a} / {b})")
    return [panel]


def _timeline(traj: Trajectory, stretches: list[Stretch]) -> str:
    """A strip of the stretches coloured by kind (each names itself on hover; at most one a plot
    bucket per kind) and their legend."""
    scale = 100.0 / max(traj.duration_s, traj.period)
    kinds = {s.kind: s.colour for s in stretches}  # in order of first appearance
    strip = "".join(f'<i style="left:{t0 * scale:.3f}%;width:{max(0.05, (t1 - t0) * scale):.3f}%;'
                    f'background:{_hex(colour)}" title="{html.escape(_LEGEND.get(kind, kind))}, '
                    f't {t0:.3f}-{t1:.3f} s"></i>'
                    for kind, colour in kinds.items() for t0, t1 in _covered(stretches, kind, traj.duration_s))
    legend = "".join(f'<span><i style="background:{_hex(colour)}"></i>{html.escape(_LEGEND.get(kind, kind))}</span>'
                     for kind, colour in kinds.items())
    return (f'<div id="timeline" class="timeline">{strip}</div>'
            f'<p class="legend">{legend} (0 - {traj.duration_s:.3f} s)</p>')


def _deviation_cells(seg: Segment) -> list[str]:
    """A crossing's largest position [mm] and orientation [deg] deviation and its time lost [s], as table cells."""
    pos, ori, lost = crossing_costs(seg.details)
    return [f"{pos:.4f}", f"{ori:.4f}", f"{lost:.3f}"]


def _metric_figures(m: Metrics) -> dict[str, float | int | None]:
    """The figures the metrics table lists, in its order (None: the trajectory has no such figure)."""
    jerk, torques = m.jerk, m.torques if isinstance(m.torques, TorqueFigures) else None
    return {"duration_s": m.duration_s, "max_position_error_mm": m.max_position_error_mm,
            "max_orientation_error_deg": m.max_orientation_error_deg, "max_joint_speed_ratio": m.max_joint_speed_ratio,
            "max_joint_accel_ratio": m.max_joint_accel_ratio,
            "max_joint_jerk_ratio": None if jerk is None else jerk.max_joint_jerk_ratio,
            "acceleration_limited_duration_s": None if jerk is None else jerk.acceleration_limited_duration_s,
            "jerk_time_lost_s": None if jerk is None else jerk.jerk_time_lost_s,
            "max_torque_ratio": None if torques is None else torques.max_torque_ratio,
            "max_stopping_distance_mm": m.max_stopping_distance_mm,
            "max_stopping_distance_at_s": m.max_stopping_distance_at_s, "planning_time_s": m.planning_time_s}


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _tables(traj: Trajectory) -> str:
    moves = []
    by_move = traj.segments_by_move()
    for i, move in enumerate(traj.task.moves):
        segs = by_move.get(i)
        moves.append([i, move.kind, f"{segs[0].t0:.3f}", f"{segs[-1].t1:.3f}", segs[0].config_before,
                      segs[-1].config_after] if segs else [i, move.kind, "-", "-", "-", "-"])
    crossings = [[s.move, s.singularity, s.method, f"{s.t0:.3f} .. {s.t1:.3f}", _zone_cell(traj, s),
                  f"{s.config_before} -> {s.config_after}", *_deviation_cells(s)]
                 for s in traj.segments if s.kind == "crossing"]
    metrics = [[k, f"{v:.6g}"] for k, v in _metric_figures(traj.metrics).items() if isinstance(v, (int, float))]
    torques = traj.metrics.torques
    if isinstance(torques, str):
        metrics.append(["torques", torques])
    else:
        metrics += [[f"peak torque {name} [N m]", f"{value:.4g} of {torques.torque_limit_Nm[name]:.4g}"]
                    for name, value in torques.peak_torque_Nm.items()]
    return ("<h2>Moves</h2>" + _table(["move", "kind", "t0 [s]", "t1 [s]", "config before", "config after"], moves)
            + "<h2>Crossings</h2>" + (_table(["move", "singularity", "method", "time [s]", "zone [s]", "configuration",
                                              "max pos dev [mm]", "max ori dev [deg]", "time lost [s]"], crossings)
                                      if crossings else "<p>No singular zone on the path.</p>")
            + "<h2>Metrics</h2>" + _table(["metric", "value"], metrics))


def _zone_cell(traj: Trajectory, crossing: Segment) -> str:
    """When the path is inside the crossing's zone (its events), "-" if the zone is a fly-by corner's."""
    zone = traj.zone_times(crossing)
    return f"{zone[0]:.3f} .. {zone[1]:.3f}" if zone is not None else "-"


def report_html(traj: Trajectory, robot: Robot, basis: PageBasis | None = None) -> str:
    """The whole report page as one string; ``basis`` is what the pages share if already computed."""
    basis = basis if basis is not None else page_basis(traj, robot)
    body = "".join(f'<figure id="plot-{f.key}">{figure_svg(f.key, f.panels, f.columns, f.height_in)}'
                   f"<figcaption>{html.escape(f.caption)}</figcaption></figure>"
                   for f in _figures(traj, robot, basis))
    title = f"singplan report: {traj.robot}, {traj.duration_s:.3f} s"
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>{_tables(traj)}"
            f"<h2>Timeline</h2>{_timeline(traj, basis.stretches)}<h2>Plots</h2>{body}</body></html>")


def _figures(traj: Trajectory, robot: Robot, basis: PageBasis) -> list[_Figure]:
    """The page's figures, in order; a series the trajectory does not have is left out."""
    shading = _Shading(basis.stretches, traj.duration_s)
    sing = traj.task.singularity
    zone = sing.zone
    s_mm = basis.track.length_m * 1e3
    figures = [
        _Figure("joints", "Joint positions [deg] with their limits (dashed); crossings shaded.",
                _joints(traj, robot, shading), math.ceil(len(traj.joint_names) / 2), 4.5),
        _Figure("speed", "Joint speed as a fraction of its limit.",
                _joint_ratios(traj, traj.t[1:], basis.speed_ratio, "|qd| / limit", shading)),
    ]
    if "distances" in traj.samples:  # none for an arm without labels (7 joints)
        thresholds = [zone.wrist_deg, zone.shoulder_mm, zone.elbow_deg]
        figures.append(_Figure("distances", "Signed singular distances with the detection thresholds, against time "
                                            "(bottom) and path length (top).",
                               _distances(traj, thresholds, s_mm, shading), 3, 3.3))
    figures += [
        _Figure("deviation", "Deviation from the programmed path with the tolerances, against time and path length.",
                _deviation(traj, sing.position_tolerance_mm, sing.orientation_tolerance_deg, s_mm, shading),
                2, 3.3),
        _Figure("tcp", "TCP speed against the programmed speed (dashed).",
                _tcp_speed(traj, basis.track.step_m, shading)),
    ]
    if "stopping_distance_m" in traj.samples:
        figures.append(_Figure("stopping", "Stopping distance: how far the TCP would travel if every joint braked now "
                                           "at its acceleration limit (the worst marked).", _stopping(traj, shading)))
    clearance = traj.metrics.clearance
    if clearance is not None and clearance.min_clearance_mm is not None:
        figures.append(_Figure("clearance", f"Least distance between the checked bodies (robot links, tool, cell) "
                                            f"against the clearance asked for ({clearance.clearance_mm:g} mm, "
                                            f"dashed); the closest approach marked.", _clearance(traj, robot, shading)))
    torques = traj.metrics.torques
    if not isinstance(torques, str):  # the metrics' limits: efforts x limits.torque_scale (1 if unset)
        limit = ("effort x torque_scale" if traj.task.limits.torque_scale is not None
                 else "URDF effort, not enforced: no limits.torque_scale")
        limit_nm = np.array([torques.torque_limit_Nm[name] for name in traj.joint_names])
        figures.append(_Figure("torque", f"Joint torque (inverse dynamics of the samples) as a fraction of its limit "
                                         f"({limit}).", _torque_ratio(traj, robot, limit_nm, shading)))
    return figures

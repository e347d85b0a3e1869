"""A self-contained HTML report of a trajectory: the summary tables and the curves people look at.

Plots (matplotlib, embedded as SVG, so the page needs no network and no other file): joint
positions with their limits, joint speed against the limit, the signed singular distances
with the detection thresholds, the position and orientation deviation from the programmed
path with the tolerances, the TCP speed against the programmed speed, and for a robot with
dynamics the joint torques against their limits, and the stopping distance. Crossing segments
(and woven moves, in another colour) are shaded on every time plot.
"""

from __future__ import annotations

import html
import io
import math
from collections.abc import Callable
from typing import Any

import matplotlib

matplotlib.use("Agg")  # no display: render to files only
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from singplan.kinematics.dynamics import effort_limits_nm, no_dynamics_reason, trajectory_torques
from singplan.kinematics.robot import Robot
from singplan.planning.weave import woven_moves
from singplan.results.trajectory import Trajectory

_PLOT_BUCKETS = 2000  # a curve longer than two points a bucket is drawn as its min/max envelope

_STYLE = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1100px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}h2{margin-top:1.6em}
figure{margin:0 0 1.5em}figcaption{color:#555;font-size:0.9em}"""


def _svg(draw: Callable[[plt.Figure], None], height: float = 3.0) -> str:
    fig = plt.figure(figsize=(10, height))
    try:
        draw(fig)
        fig.tight_layout()
        buffer = io.StringIO()
        fig.savefig(buffer, format="svg")
    finally:
        plt.close(fig)
    text = buffer.getvalue()
    return text[text.index("<svg"):]


def _envelope(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The curve to draw: y itself, or for long series the min and max of each of
    ``_PLOT_BUCKETS`` buckets, so that an SVG of a million samples stays small and no peak
    (a speed or deviation spike) is lost."""
    if len(y) <= 2 * _PLOT_BUCKETS:
        return x, y
    starts = np.linspace(0, len(y), _PLOT_BUCKETS + 1).astype(int)[:-1]
    low, high = np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)
    return np.repeat(x[starts], 2), np.column_stack([low, high]).ravel()


def _shade(ax: Any, traj: Trajectory) -> None:
    woven = woven_moves(traj.task)
    for s in traj.segments:
        if s.kind == "crossing":
            ax.axvspan(s.t0, s.t1, color="#f4b400", alpha=0.18, lw=0)
        elif s.move in woven:
            ax.axvspan(s.t0, s.t1, color="#00897b", alpha=0.10, lw=0)


def _joints(traj: Trajectory, robot: Robot) -> Callable[[plt.Figure], None]:
    def draw(fig: plt.Figure) -> None:
        n = len(traj.joint_names)
        for j in range(n):
            ax = fig.add_subplot(2, math.ceil(n / 2), j + 1)
            _shade(ax, traj)
            ax.plot(*_envelope(traj.t, np.degrees(traj.q[:, j])), lw=1.2)
            for limit in (robot.lower_rad[j], robot.upper_rad[j]):
                ax.axhline(math.degrees(limit), color="r", ls="--", lw=0.8)
            ax.set_title(traj.joint_names[j], fontsize=9)
            ax.tick_params(labelsize=7)
    return draw


def _speed_ratio(traj: Trajectory, vmax: np.ndarray) -> Callable[[plt.Figure], None]:
    def draw(fig: plt.Figure) -> None:
        ax = fig.add_subplot(1, 1, 1)
        _shade(ax, traj)
        for j, name in enumerate(traj.joint_names):
            ratio = np.abs(np.diff(traj.q[:, j])) / traj.period / vmax[j]
            ax.plot(*_envelope(traj.t[1:], ratio), lw=1, label=name)
        ax.axhline(1.0, color="r", ls="--", lw=0.8)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("|qd| / limit")
        ax.legend(fontsize=7, ncol=len(traj.joint_names))
    return draw


def _torque_ratio(traj: Trajectory, robot: Robot, scale: float) -> Callable[[plt.Figure], None]:
    _, ratios = trajectory_torques(robot, traj.q, traj.period, effort_limits_nm(robot) * scale, series=True)
    assert ratios is not None

    def draw(fig: plt.Figure) -> None:
        ax = fig.add_subplot(1, 1, 1)
        _shade(ax, traj)
        for j, name in enumerate(traj.joint_names):
            ax.plot(*_envelope(traj.t, ratios[:, j]), lw=1, label=name)
        ax.axhline(1.0, color="r", ls="--", lw=0.8)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("|tau| / limit")
        ax.legend(fontsize=7, ncol=len(traj.joint_names))
    return draw


def _path_length_axis(ax: plt.Axes, traj: Trajectory, s_mm: np.ndarray) -> None:
    """A top axis in path length [mm]: the TCP distance travelled since t = 0."""
    def to_length(t: ArrayLike) -> ArrayLike:
        return np.interp(np.asarray(t, dtype=float), traj.t, s_mm)

    def to_time(s: ArrayLike) -> ArrayLike:
        return np.interp(np.asarray(s, dtype=float), s_mm, traj.t)

    top = ax.secondary_xaxis("top", functions=(to_length, to_time))
    top.set_xlabel("path length [mm]", fontsize=8)
    top.tick_params(labelsize=7)


def _distances(traj: Trajectory, thresholds: list[float], s_mm: np.ndarray) -> Callable[[plt.Figure], None]:
    d = traj.samples["distances"]
    series = [("wrist [deg]", np.degrees(d[:, 0]), thresholds[0]), ("shoulder [mm]", d[:, 1] * 1e3, thresholds[1]),
              ("elbow [deg]", np.degrees(d[:, 2]), thresholds[2])]

    def draw(fig: plt.Figure) -> None:
        for k, (label, values, thr) in enumerate(series):
            ax = fig.add_subplot(1, 3, k + 1)
            _shade(ax, traj)
            ax.plot(*_envelope(traj.t, values), lw=1.2)
            for sign in (-1, 1):
                ax.axhline(sign * thr, color="r", ls="--", lw=0.8)
            ax.axhline(0, color="k", lw=0.5)
            ax.set_title(label, fontsize=9)
            ax.set_xlabel("t [s]", fontsize=8)
            _path_length_axis(ax, traj, s_mm)
    return draw


def _deviation(traj: Trajectory, pos_tol_mm: float, ori_tol_deg: float,
               s_mm: np.ndarray) -> Callable[[plt.Figure], None]:
    def draw(fig: plt.Figure) -> None:
        for k, (label, values, tol) in enumerate((
                ("position deviation [mm]", traj.samples["position_error_m"] * 1e3, pos_tol_mm),
                ("orientation deviation [deg]", np.degrees(traj.samples["orientation_error_rad"]), ori_tol_deg))):
            ax = fig.add_subplot(1, 2, k + 1)
            _shade(ax, traj)
            ax.plot(*_envelope(traj.t, values), lw=1.2)
            ax.axhline(tol, color="r", ls="--", lw=0.8)
            ax.set_title(label, fontsize=9)
            ax.set_xlabel("t [s]", fontsize=8)
            _path_length_axis(ax, traj, s_mm)
    return draw


def _tcp_speed(traj: Trajectory, step_m: np.ndarray) -> Callable[[plt.Figure], None]:
    speed = step_m / traj.period
    moves = traj.task["moves"]

    def draw(fig: plt.Figure) -> None:
        ax = fig.add_subplot(1, 1, 1)
        _shade(ax, traj)
        ax.plot(*_envelope(traj.t[1:], speed), lw=1.2, label="TCP speed")
        for i, move in enumerate(moves):
            kind, spec = next(iter(move.items()))
            segs = [s for s in traj.segments if s.move == i]
            if kind != "ptp" and segs:
                ax.hlines(spec["speed"], segs[0].t0, segs[-1].t1, colors="r", linestyles="--", lw=0.8)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("[m/s]")
    return draw


def _stopping(traj: Trajectory) -> Callable[[plt.Figure], None]:
    distance_mm = traj.samples["stopping_distance_m"] * 1e3

    def draw(fig: plt.Figure) -> None:
        ax = fig.add_subplot(1, 1, 1)
        _shade(ax, traj)
        ax.plot(*_envelope(traj.t, distance_mm), lw=1.2)
        k = int(np.argmax(distance_mm))
        ax.plot([traj.t[k]], [distance_mm[k]], "o", color="r", ms=4)
        ax.annotate(f"{distance_mm[k]:.1f} mm", (traj.t[k], distance_mm[k]), textcoords="offset points",
                    xytext=(6, -10), fontsize=8)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("stopping distance [mm]")
    return draw


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _tables(traj: Trajectory) -> str:
    moves = []
    for i, move in enumerate(traj.task["moves"]):
        kind = next(iter(move))
        segs = [s for s in traj.segments if s.move == i]
        moves.append([i, kind, f"{segs[0].t0:.3f}", f"{segs[-1].t1:.3f}", segs[0].config_before, segs[-1].config_after])
    crossings = [[s.move, s.singularity, s.method, f"{s.t0:.3f} .. {s.t1:.3f}",
                  f"{s.config_before} -> {s.config_after}", f"{s.details.get('max_position_error_mm', 0.0):.4f}",
                  f"{s.details.get('max_orientation_error_deg', 0.0):.4f}", f"{s.details.get('time_lost_s', 0.0):.3f}"]
                 for s in traj.segments if s.kind == "crossing"]
    m = traj.metrics
    metrics = [[k, f"{m[k]:.6g}"] for k in ("duration_s", "max_position_error_mm", "max_orientation_error_deg",
                                            "max_joint_speed_ratio", "max_joint_accel_ratio", "max_joint_jerk_ratio",
                                            "acceleration_limited_duration_s", "jerk_time_lost_s", "max_torque_ratio",
                                            "max_stopping_distance_mm", "max_stopping_distance_at_s",
                                            "planning_time_s") if isinstance(m.get(k), (int, float))]
    metrics += [[f"peak torque {name} [N m]", f"{value:.4g} of {m['torque_limit_Nm'][name]:.4g}"]
                for name, value in m.get("peak_torque_Nm", {}).items()]
    if "torques" in m:
        metrics.append(["torques", str(m["torques"])])
    return ("<h2>Moves</h2>" + _table(["move", "kind", "t0 [s]", "t1 [s]", "config before", "config after"], moves)
            + "<h2>Crossings</h2>" + (_table(["move", "singularity", "method", "time [s]", "configuration",
                                              "max pos dev [mm]", "max ori dev [deg]", "time lost [s]"], crossings)
                                      if crossings else "<p>No singular zone on the path.</p>")
            + "<h2>Metrics</h2>" + _table(["metric", "value"], metrics))


def report_html(traj: Trajectory, robot: Robot) -> str:
    """The whole report page as one string."""
    sing = traj.task.get("singularity", {})
    zone = sing.get("zone", {})
    vmax = robot.velocity_rad_s * float(traj.task.get("limits", {}).get("velocity_scale", 1.0))
    tcp = robot.tcp_positions(traj.q)  # (K, 3), formed in chunks
    step_m = np.linalg.norm(np.diff(tcp, axis=0), axis=1)  # (K - 1,)
    s_mm = np.concatenate([[0.0], np.cumsum(step_m)]) * 1e3  # (K,)
    distances = [("distances", "Signed singular distances with the detection thresholds, against time (bottom) and "
                                "path length (top).",
                   _distances(traj, [zone.get("wrist_deg", 5.0), zone.get("shoulder_mm", 20.0),
                                     zone.get("elbow_deg", 5.0)], s_mm), 3.3)
                  ] if "distances" in traj.samples else []  # none for an arm without labels (7 joints)
    figures = [
        ("joints", "Joint positions [deg] with their limits (dashed); crossings shaded.", _joints(traj, robot), 4.5),
        ("speed", "Joint speed as a fraction of its limit.", _speed_ratio(traj, vmax), 3.0),
        *distances,
        ("deviation", "Deviation from the programmed path with the tolerances, against time and path length.",
         _deviation(traj, sing.get("position_tolerance_mm", 0.01), sing.get("orientation_tolerance_deg", 5.0), s_mm),
         3.3),
        ("tcp", "TCP speed against the programmed speed (dashed).", _tcp_speed(traj, step_m), 3.0),
    ]
    if "stopping_distance_m" in traj.samples:
        figures.append(("stopping", "Stopping distance: how far the TCP would travel if every joint braked now at its "
                                    "acceleration limit (the worst marked).", _stopping(traj), 3.0))
    limits = traj.task.get("limits", {})
    if no_dynamics_reason(robot) is None:
        scale = limits.get("torque_scale")
        limit = "effort x torque_scale" if scale is not None else "URDF effort, not enforced: no limits.torque_scale"
        figures.append(("torque", f"Joint torque (inverse dynamics of the samples) as a fraction of its limit "
                                  f"({limit}).", _torque_ratio(traj, robot, float(scale or 1.0)), 3.0))
    body = "".join(f'<figure id="plot-{key}">{_svg(draw, h)}<figcaption>{html.escape(cap)}</figcaption></figure>'
                   for key, cap, draw, h in figures)
    title = f"singplan report: {traj.robot}, {traj.duration_s:.3f} s"
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>{_tables(traj)}"
            f"<h2>Plots</h2>{body}</body></html>")

"""Replay a trajectory in the browser: one self-contained HTML file built on meshcat's viewer.

No meshcat server is started: a recorder stands in for meshcat's ZMQ window and keeps the
scene commands (the robot's visual geometry through Pinocchio's MeshcatVisualizer, the
programmed and executed TCP paths, markers at the crossings, and an animation of every link
at the trajectory's real timing). The page inlines meshcat's viewer bundle and replays the
commands in order, so it works offline in any current browser; the animation controls
(play, pause, time scrub) are meshcat's own.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import meshcat
import meshcat.animation
import meshcat.geometry as mg
import meshcat.transformations as mtf
import numpy as np
import pinocchio as pin
import umsgpack
from pinocchio.visualize import MeshcatVisualizer

from singplan.errors import RobotModelError
from singplan.path import rpy_deg_to_rotation
from singplan.planner import plan_move_piece
from singplan.robot import Robot, bundled_robots, load_robot
from singplan.task import parse_task
from singplan.trajectory import Trajectory, load

ANIMATION_STEP_S = 0.02  # animation keyframes; the browser interpolates between them
SEGMENT_COLOURS = {"path": 0x2E7D32, "pre": 0x1565C0, "crossing": 0xF4B400, "post": 0x6A1B9A, "ptp": 0x757575}


class _Recorder:
    """Stands in for meshcat's ZMQ window: keeps the lowered commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[dict[str, Any]] = []

    def send(self, command: Any) -> None:
        self.commands.append(command.lower())


def _line(points: np.ndarray, colour: int, width: float = 2.0) -> mg.Line:
    geometry = mg.PointsGeometry(np.asarray(points, dtype=np.float32).T)
    return mg.Line(geometry, mg.LineBasicMaterial(color=colour, linewidth=width))


def _scene(traj: Trajectory, robot: Robot, tcp: np.ndarray, programmed: np.ndarray | None) -> _Recorder:
    recorder = _Recorder()
    vis = meshcat.Visualizer(window=recorder)
    # package:// meshes resolve against every folder above the URDF (example-robot-data's layout)
    package_dirs = [str(p) for p in robot.urdf_path.parents]
    try:
        model, collision, visual = pin.buildModelsFromUrdf(str(robot.urdf_path), package_dirs=package_dirs)
    except ValueError as exc:
        raise RobotModelError(str(robot.urdf_path), f"cannot load its visual geometry for the replay ({exc})") from None
    viz = MeshcatVisualizer(model, collision, visual)
    viz.initViewer(viewer=vis)
    viz.loadViewerModel(rootNodeName="robot")
    full = _full_configuration(model, robot)
    viz.display(full(traj.q[0]))
    if programmed is not None:
        vis["paths/programmed"].set_object(_line(programmed, 0x9E9E9E, 1.0))
    period = traj.period
    for n, seg in enumerate(traj.segments):
        k0, k1 = round(seg.t0 / period), round(seg.t1 / period)
        colour = SEGMENT_COLOURS.get(seg.kind, 0)
        vis[f"paths/executed/{n:03d}_{seg.kind}"].set_object(_line(tcp[k0:k1 + 1], colour, 3.0))
        if seg.kind == "crossing":
            marker = vis[f"crossings/{n:03d}_{seg.singularity}_{seg.method}"]
            marker.set_object(mg.Sphere(0.012), mg.MeshLambertMaterial(color=0xF4B400, opacity=0.8))
            marker.set_transform(mtf.translation_matrix(tcp[(k0 + k1) // 2]))
    animation = meshcat.animation.Animation(default_framerate=round(1.0 / ANIMATION_STEP_S))
    step = max(1, round(ANIMATION_STEP_S / period))
    for frame_index, k in enumerate(range(0, len(traj.t), step)):
        with animation.at_frame(vis, frame_index) as frame:
            viz.viewer = frame
            viz.display(full(traj.q[k]))
    viz.viewer = vis
    vis.set_animation(animation, play=False, repetitions=1)
    return recorder


def _full_configuration(model: pin.Model, robot: Robot) -> Any:
    """Map the chain's joint values into the full URDF model (extra joints at neutral)."""
    neutral = pin.neutral(model)
    index = [model.joints[model.getJointId(name)].idx_q for name in robot.joint_names]

    def full(q: np.ndarray) -> np.ndarray:
        out = neutral.copy()
        out[index] = q
        return out

    return full


def programmed_path(traj: Trajectory, robot: Robot, tcp: np.ndarray) -> np.ndarray:
    """Points (M, 3) [m] of the programmed path: LIN/CIRC geometry from the task; PTP as executed."""
    task = parse_task(traj.task)
    points = []
    T = robot.fk(traj.q[0])
    for i, move in enumerate(task.moves):
        segs = [s for s in traj.segments if s.move == i]
        k0, k1 = round(segs[0].t0 / traj.period), round(segs[-1].t1 / traj.period)
        if move.kind == "ptp":
            points.append(tcp[k0:k1 + 1])
            T = robot.fk(traj.q[k1])
            continue
        piece = plan_move_piece(i, move, T)
        points.append(piece.positions(np.linspace(0.0, 1.0, 64)))
        T = piece.T_end
    return np.concatenate(points)


def replay_html(traj: Trajectory, robot: Robot) -> str:
    """The replay page, a self-contained HTML document."""
    tcp = np.array([robot.fk(q).translation for q in traj.q])
    programmed = programmed_path(traj, robot, tcp)
    recorder = _scene(traj, robot, tcp, programmed)
    bundle = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text()
    blobs = json.dumps([base64.b64encode(umsgpack.packb(c)).decode("ascii") for c in recorder.commands])
    legend = " ".join(f'<span style="color:#{colour:06x}">&#9632; {kind}</span>'
                      for kind, colour in SEGMENT_COLOURS.items())
    title = f"singplan replay: {traj.robot}, {traj.duration_s:.3f} s"
    return (f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>{title}</title></head>'
            f'<body style="margin:0;font-family:sans-serif">'
            f'<div style="position:absolute;left:8px;bottom:8px;z-index:10;background:#fff8;padding:4px">'
            f"{title}<br>{legend}</div>"
            f'<div id="meshcat-pane" style="width:100vw;height:100vh"></div>'
            f"<script>{bundle}</script>"
            f"<script>var viewer = new MeshCat.Viewer(document.getElementById('meshcat-pane'));\n"
            f"for (const b64 of {blobs}) {{\n"
            f"  viewer.handle_command_bytearray(Uint8Array.from(atob(b64), c => c.charCodeAt(0)));\n}}\n"
            f"window.singplanReady = true;</script></body></html>")


def robot_of(traj: Trajectory) -> Robot:
    """The robot a trajectory was planned for (bundled name, else its URDF), with its tool."""
    rpy = np.asarray(traj.tool.get("rpy_deg", [0, 0, 0]), dtype=float)
    tool = pin.SE3(rpy_deg_to_rotation(rpy), np.asarray(traj.tool.get("xyz", [0, 0, 0]), dtype=float))
    source = traj.robot if traj.robot in bundled_robots() else traj.urdf
    return load_robot(source, tip=traj.tip, tool=tool)


def replay(traj: Trajectory | str | Path, html: str | Path) -> Path:
    """Write the replay page of a trajectory (object, or a trajectory.json / output folder) to ``html``."""
    trajectory = traj if isinstance(traj, Trajectory) else load(traj)
    out = Path(html)
    out.write_text(replay_html(trajectory, robot_of(trajectory)))
    return out

"""Replay a trajectory in the browser: a self-contained HTML page, or a live meshcat server.

The scene is the same in both: the robot's visual geometry (:mod:`singplan.outputs.scene`), the
programmed and executed TCP paths coloured by stretch kind (:mod:`singplan.outputs.timeline`),
markers at the crossings, and an animation of every link at the trajectory's real timing. For
the page, no server is started: a recorder stands in for meshcat's ZMQ window and keeps the
commands, and the template in :func:`viewer_dir` inlines meshcat's viewer bundle, replays them
in order and adds the legend, the segment list, the crossing labels and the joint-speed strip,
so it works offline in any current browser. :func:`serve_replay` sends the same commands to a
meshcat server listening on loopback only, unless another address is asked for
(:mod:`singplan.outputs.meshcat_server`).
"""

from __future__ import annotations

import atexit
import base64
import contextlib
import io
import ipaddress
import itertools
import json
import math
import re
import socket
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import Any

import meshcat
import meshcat.geometry as mg
import meshcat.transformations as mtf
import numpy as np
import pinocchio as pin
import umsgpack

from singplan.errors import InputError
from singplan.kinematics.collision import MAX_MESH_BYTES
from singplan.kinematics.files import read_bounded
from singplan.kinematics.geometry import rpy_deg_to_rotation
from singplan.kinematics.robot import Robot
from singplan.kinematics.shapes import Shape
from singplan.outputs.choices import DEFAULT_HOST
from singplan.outputs.scene import ROOT, AnimationCommand, RobotScene, ZCylinder
from singplan.outputs.svgplot import LIMIT_COLOUR, PALETTE
from singplan.outputs.timeline import (
    PROGRAMMED_COLOUR,
    SHADED_OPACITY,
    PageBasis,
    Stretch,
    TcpTrack,
    display_kind,
    kind_colour,
    page_basis,
    robot_of,
    sample_range,
    tcp_track,
    timeline,
)
from singplan.results.files import check_output_file, hold_output_folder, text_writer, write_file
from singplan.results.metrics import crossing_costs
from singplan.results.path import programmed_path, woven_moves
from singplan.results.trajectory import Segment, Trajectory, load

_SERVER_START_S = 60.0  # longest wait for the live server to report its address
ANIMATION_STEP_S = 0.02  # animation keyframes at most this often; the browser interpolates between them
# What the page holds is bounded whatever the number of samples (a million samples would be
# hundreds of MB of page and a minute of building): a time grid of at most so many points, more
# where the joints move fast (no joint turns more than the turn between two kept samples, so a
# wrist flip stays a flip and not a shortcut; at most so many such points), and the segments'
# boundaries and crossings' midpoints, exactly.
_KEYFRAMES = 600  # animation keyframes on the time grid (~1 kB of page each; a 60-move program: ~2.5 MB)
_KEYFRAME_TURN_RAD = 0.15  # ... and one at least every 0.15 rad of a joint (a 3 mm chord at 1 m)
_PATH_POINTS = 10_000  # executed-path points on the time grid (a line, and every _DOT_EVERY-th a dot)
_PATH_TURN_RAD = 0.01  # ... and at least every 0.01 rad of a joint
_DOT_EVERY = 3  # executed-path dots: one per this many path points
_STRIP_POINTS = 1500  # joint-speed strip: at most this many points (each bucket's lowest and highest)
_STRIP_SHADED = ("crossing", "blend", "pause")  # where the robot leaves the plain path or the TCP waits
_VIEW_DIRECTION = np.array([0.8, -1.0, 0.75]) / np.linalg.norm([0.8, -1.0, 0.75])  # camera side of the scene
_PACKAGE_DIR = Path(__file__).resolve().parents[1]  # the singplan package folder


def viewer_dir() -> Path:
    """Folder of the replay page's template, script and style (in the wheel or a source checkout)."""
    installed = _PACKAGE_DIR / "_viewer"
    return installed if installed.is_dir() else _PACKAGE_DIR.parent / "viewer"


class _Recorder:
    """Stands in for meshcat's ZMQ window: keeps the lowered commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[dict[str, Any] | bytes] = []

    def send(self, command: Any) -> None:
        self.commands.append(command.packed() if isinstance(command, AnimationCommand) else command.lower())


def _line(points: np.ndarray, colour: int, width: float = 2.0) -> mg.Line:
    geometry = mg.PointsGeometry(np.asarray(points, dtype=np.float32).T)
    return mg.Line(geometry, mg.LineBasicMaterial(color=colour, linewidth=width))


@dataclass(frozen=True)
class TcpPath:
    """The executed TCP path at a bounded set of kept samples.

    Attributes:
        index: kept sample indices (M,), ascending, with every segment's first and last sample
            and every crossing's midpoint.
        xyz: TCP positions [m] (M, 3) at those samples.
    """

    index: np.ndarray
    xyz: np.ndarray

    def between(self, k0: int, k1: int) -> np.ndarray:
        """Positions (m, 3) [m] of the kept samples k0..k1 (both included)."""
        return self.xyz[np.searchsorted(self.index, k0):np.searchsorted(self.index, k1, side="right")]

    def at(self, k: int) -> np.ndarray:
        """Position (3,) [m] at a kept sample ``k``."""
        i = int(np.searchsorted(self.index, k))
        assert i < len(self.index) and self.index[i] == k, f"sample {k} is not kept"
        return self.xyz[i]


def tcp_path(traj: Trajectory, track: TcpTrack, travel: np.ndarray) -> TcpPath:
    """The TCP path at the samples the page shows (:func:`kept_samples` at the path's density),
    picked from ``track`` (FK already done for every sample); ``travel`` is :func:`joint_travel`."""
    index = kept_samples(traj, travel, 1, _PATH_POINTS, _PATH_TURN_RAD)
    return TcpPath(index, track.xyz[index])


def kept_samples(traj: Trajectory, travel: np.ndarray, min_stride: int, grid_points: int,
                 turn_rad: float) -> np.ndarray:
    """Sample indices (ascending) that stand for the trajectory, about 2 x ``grid_points`` at most
    plus three a segment: a time grid (every ``min_stride`` samples or coarser, at most
    ``grid_points``), a sample each time some joint has turned ``turn_rad`` more along ``travel``
    (:func:`joint_travel`; coarser too if that would be more than ``grid_points``), the last
    sample, each segment's first and last and each crossing's midpoint."""
    last = len(traj.t) - 1
    stride = max(min_stride, math.ceil(last / grid_points))
    turn = max(turn_rad, float(travel[-1]) / grid_points)
    marks = np.searchsorted(travel, np.arange(turn, travel[-1], turn))  # first sample past each mark
    bounds = [k for seg in traj.segments for k in (*sample_range(traj, seg), _midpoint(traj, seg))]
    keep = np.concatenate([np.arange(0, last + 1, stride), marks, np.clip(bounds, 0, last), [last]])
    return np.unique(keep.astype(np.int64))


def joint_travel(q: np.ndarray) -> np.ndarray:
    """Cumulative sum over samples of the largest joint step [rad] (K,), non-decreasing, formed in
    chunks; computed once for both of the page's sample picks (path points and keyframes)."""
    travel = np.zeros(len(q))
    total = 0.0
    for c in range(0, len(q) - 1, _CHUNK):
        steps = np.abs(np.diff(q[c:c + _CHUNK + 1], axis=0)).max(axis=1)
        travel[c + 1:c + 1 + len(steps)] = total + np.cumsum(steps)
        total = float(travel[c + len(steps)])
    return travel


_CHUNK = 65_536  # samples differenced at once (a few MB of temporaries)


def _midpoint(traj: Trajectory, seg: Segment) -> int:
    k0, k1 = sample_range(traj, seg)
    return (k0 + k1) // 2


def _scene(vis: meshcat.Visualizer, traj: Trajectory, robot: Robot, tcp: TcpPath, stretches: list[Stretch],
           travel: np.ndarray, speed: float = 1.0, loop: bool = False, play: bool = False) -> None:
    """Send the replay scene to ``vis``: robot, paths, crossing markers and the animation."""
    scene = RobotScene.of(robot)
    shown = scene.send(vis, traj.q[0])
    vis["/Grid"].set_property("visible", False)  # the robot's base axes show the ground frame
    vis["paths/programmed"].set_object(_line(programmed_points(traj, robot, tcp), PROGRAMMED_COLOUR, 1.0))
    _draw_segments(vis, traj, tcp, stretches)
    _draw_cell(vis, traj)
    # a frame is a sample: keyframes at kept samples, the exact joint values there
    step = max(1, round(ANIMATION_STEP_S / traj.period))
    frames = kept_samples(traj, travel, step, _KEYFRAMES, _KEYFRAME_TURN_RAD)
    xyz, quat = scene.poses(traj.q[frames])
    # nodes that never move (the base) are left out: the scene already shows them there
    moving = [g for g, name in enumerate(scene.names) if name in shown
              and not (np.all(xyz[:, g] == xyz[0, g]) and np.all(quat[:, g] == quat[0, g]))]
    paths = tuple(vis[f"{ROOT}/{scene.names[g]}"].path.lower() for g in moving)
    tool_paths, tool_xyz, tool_quat = _draw_tool(vis, traj, robot, frames)
    vis.window.send(AnimationCommand(paths + tool_paths, frames.astype(float),
                                     np.concatenate([xyz[:, moving], tool_xyz], axis=1),
                                     np.concatenate([quat[:, moving], tool_quat], axis=1), speed / traj.period,
                                     play, _LOOP_REPETITIONS if loop else 1))


def _draw_segments(vis: meshcat.Visualizer, traj: Trajectory, tcp: TcpPath, stretches: list[Stretch]) -> None:
    """The executed TCP path by stretch kind (a line plus dots), and a marker at each crossing."""
    parts = Counter(s.segment for s in stretches)  # a segment split around a null-space pause has three
    for j, stretch in enumerate(stretches):
        seg = traj.segments[stretch.segment]
        name = f"{stretch.segment:03d}_{seg.kind}" + (f"_{j}_{stretch.kind}" if parts[stretch.segment] > 1 else "")
        path = tcp.between(stretch.k0, stretch.k1)
        vis[f"paths/executed/{name}"].set_object(_line(path, stretch.colour, 3.0))
        # browsers draw lines one pixel wide: dots make the executed path readable at a glance
        points = np.asarray(path[::_DOT_EVERY], dtype=np.float32).T  # (3, M)
        colour = stretch.colour
        rgb = np.array([(colour >> 16) & 255, (colour >> 8) & 255, colour & 255], dtype=np.float32)[:, None] / 255
        dots = mg.PointsGeometry(points, color=np.repeat(rgb, points.shape[1], axis=1))
        vis[f"paths/dots/{name}"].set_object(mg.Points(dots, mg.PointsMaterial(size=0.006)))
    for n, seg in enumerate(traj.segments):
        if seg.kind == "crossing":
            marker = vis[f"crossings/{n:03d}_{seg.singularity}_{seg.method}"]
            marker.set_object(mg.Sphere(0.012), mg.MeshLambertMaterial(color=kind_colour("crossing"), opacity=0.8))
            marker.set_transform(mtf.translation_matrix(tcp.at(_midpoint(traj, seg))))


_LOOP_REPETITIONS = 1_000_000  # meshcat's "loop": repeat the clip this many times
CELL_COLOUR = 0x8A8F98  # the cell's shapes: grey, see-through
TOOL_COLOUR = 0xD9A441  # the tool's shapes
CLOSEST_COLOUR = 0xE0301E  # the closest approach: a line between the two closest points


def _shape_object(shape: Shape, colour: int, opacity: float) -> tuple[Any, np.ndarray]:
    """A cell or tool shape of the task as a meshcat geometry and the transform that scales it
    (a mesh's ``scale``; identity otherwise). The mesh file is read through the bounded reader."""
    material = mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1.0)
    scale = np.eye(4)
    dims = shape.dimensions_m
    if shape.kind == "box":
        geometry: Any = mg.Box(list(dims))
    elif shape.kind == "cylinder":
        geometry = ZCylinder(dims[1], dims[0])  # (length, radius)
    elif shape.kind == "sphere":
        geometry = mg.Sphere(dims[0])
    else:
        assert shape.mesh_file is not None  # a validated mesh shape names its file
        data = read_bounded(shape.mesh_file, MAX_MESH_BYTES, "mesh")
        geometry = (mg.StlMeshGeometry.from_stream(io.BytesIO(data)) if shape.mesh_file.lower().endswith(".stl")
                    else mg.ObjMeshGeometry.from_stream(io.StringIO(data.decode("utf-8", "replace"))))
        scale = np.diag([*shape.mesh_scale, 1.0])
    return (geometry, material), scale


def _shape_pose(shape: Shape) -> np.ndarray:
    """A shape's pose (4, 4) in its frame (the base for the cell, the tip for the tool)."""
    T = np.eye(4)
    T[:3, :3] = rpy_deg_to_rotation(shape.rpy_deg)
    T[:3, 3] = shape.xyz
    return T


def _draw_cell(vis: meshcat.Visualizer, traj: Trajectory) -> None:
    """The task's cell (fixed shapes, see-through) and the closest approach of the collision check (a line
    between the two closest points, a dot at each)."""
    for i, shape in enumerate(traj.task.cell):
        obj, scale = _shape_object(shape, CELL_COLOUR, 0.55)
        node = vis[f"cell/{i:03d}_{shape.name}"]
        node.set_object(*obj)
        node.set_transform(_shape_pose(shape) @ scale)
    clearance = traj.metrics.clearance
    if clearance is None or clearance.min_clearance_points is None:
        return
    a, b = (np.asarray(p, dtype=float) for p in clearance.min_clearance_points)
    vis["closest/line"].set_object(_line(np.array([a, b]), CLOSEST_COLOUR, 3.0))
    for name, point in (("a", a), ("b", b)):
        vis[f"closest/{name}"].set_object(mg.Sphere(0.006), mg.MeshLambertMaterial(color=CLOSEST_COLOUR))
        vis[f"closest/{name}"].set_transform(mtf.translation_matrix(point))


def _draw_tool(vis: meshcat.Visualizer, traj: Trajectory, robot: Robot, frames: np.ndarray
               ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """The tool's shapes (``tool.geometry``) fixed to the tip: their nodes, and their positions (F, S, 3) and
    quaternions (x, y, z, w) (F, S, 4) at the animation's frames."""
    shapes = traj.task.tool_geometry
    xyz, quat = np.empty((len(frames), len(shapes), 3)), np.empty((len(frames), len(shapes), 4))
    tips = [robot.fk_tip(traj.q[k]).homogeneous for k in frames]
    paths = []
    for s, shape in enumerate(shapes):
        obj, scale = _shape_object(shape, TOOL_COLOUR, 1.0)
        node = vis[f"tool/{s:02d}"]
        node.set_object(*obj)
        local = _shape_pose(shape)
        node.set_transform(tips[0] @ local @ scale if tips else local @ scale)
        paths.append(node.path.lower())
        for f, tip in enumerate(tips):
            T = tip @ local
            xyz[f, s] = T[:3, 3]
            quat[f, s] = pin.Quaternion(T[:3, :3]).coeffs()
    return tuple(paths), xyz, quat


def programmed_points(traj: Trajectory, robot: Robot, tcp: TcpPath) -> np.ndarray:
    """Points (M, 3) [m] of the programmed path: each LIN / CIRC (woven if it weaves) is its
    piece of the trajectory's programmed path (:func:`singplan.results.path.programmed_path`); a
    PTP as executed."""
    points = []
    by_move = traj.segments_by_move()
    for i, programmed in enumerate(programmed_path(traj.task, robot, traj.q[0])):
        piece, segs = programmed.piece, by_move.get(i)
        if piece is not None:
            points.append(piece.positions(np.linspace(0.0, 1.0, piece.drawing_count())))
        elif segs:
            points.append(tcp.between(sample_range(traj, segs[0])[0], sample_range(traj, segs[-1])[1]))
    return np.concatenate(points) if points else tcp.xyz[:1]


def replay_html(traj: Trajectory, robot: Robot, basis: PageBasis | None = None) -> str:
    """The replay page, a self-contained HTML document (the template and assets of :func:`viewer_dir`);
    ``basis`` is what the pages share if already computed (the report's)."""
    basis = basis if basis is not None else page_basis(traj, robot)
    travel = joint_travel(traj.q)
    tcp = tcp_path(traj, basis.track, travel)
    recorder = _Recorder()
    _scene(meshcat.Visualizer(window=recorder), traj, robot, tcp, basis.stretches, travel)
    assets = viewer_dir()
    data = _page_data(traj, tcp, basis)
    data["commands"] = [base64.b64encode(_packed(c)).decode("ascii") for c in recorder.commands]
    title = escape(f"singplan replay: {traj.robot}, {traj.duration_s:.3f} s")
    fills = {"__TITLE__": title, "__CSS__": (assets / "replay.css").read_text(),
             "__MESHCAT__": _meshcat_bundle(), "__DATA__": json.dumps(data).replace("</", "<\\/"),
             "__JS__": (assets / "replay.js").read_text()}
    template = (assets / "replay.html").read_text()
    return re.sub(r"__(TITLE|CSS|MESHCAT|DATA|JS)__", lambda m: fills[m.group(0)], template)  # values not rescanned


def _packed(command: dict[str, Any] | bytes) -> bytes:
    """A command as meshcat's viewer reads it (the animation comes packed, its keyframes in
    single precision: a third less of the page than doubles)."""
    return command if isinstance(command, bytes) else bytes(umsgpack.packb(command, force_float_precision="double"))


def _meshcat_bundle() -> str:
    return (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text()


def _page_data(traj: Trajectory, tcp: TcpPath, basis: PageBasis) -> dict[str, Any]:
    """What replay.js shows besides the scene: segments, crossing labels, speed strip, camera, legend."""
    segments, labels = [], []
    stretches = basis.stretches
    woven = woven_moves(traj.task)
    pauses = {s.segment: s for s in stretches if s.kind == "pause"}
    for n, seg in enumerate(traj.segments):
        title, detail = _describe(seg, pauses.get(n))
        title += " (woven)" if seg.move in woven and seg.kind != "crossing" else ""
        crossing = seg.kind == "crossing"
        t_jump = traj.t[_midpoint(traj, seg)] if crossing else seg.t0
        segments.append({"kind": seg.kind, "move": seg.move, "t0": seg.t0, "t1": seg.t1, "t_jump": float(t_jump),
                         "colour": _colour(seg, woven), "title": title, "detail": detail})
        if crossing:
            pos_mm, ori_deg, _ = crossing_costs(seg.details)
            text = f"{title.split(': ', 1)[1]}; {pos_mm:.3f} mm / {ori_deg:.2f} deg"
            labels.append({"text": text, "xyz": tcp.at(_midpoint(traj, seg)).tolist()})
    clearance = traj.metrics.clearance
    if clearance is not None and clearance.min_clearance_points is not None and clearance.min_clearance_pair:
        a, b = (np.asarray(p, dtype=float) for p in clearance.min_clearance_points)
        pair = " / ".join(clearance.min_clearance_pair)
        text = f"closest {clearance.min_clearance_mm:.1f} mm: {pair} at {clearance.min_clearance_t:.3f} s"
        labels.append({"text": text, "xyz": ((a + b) / 2).tolist()})
    ratio = basis.speed_ratio.max(axis=1, initial=0.0).astype(float)  # (K - 1,), at t[1:]
    keep = _extremes(ratio, _STRIP_POINTS)
    points = np.vstack([tcp.xyz, np.zeros((1, 3))])  # the path and the robot's base
    lo, hi = points.min(axis=0), points.max(axis=0)
    radius = max(0.3, 0.5 * float(np.linalg.norm(hi - lo)))
    bands = [{"kind": s.kind, "t0": s.t0, "t1": s.t1, "colour": s.colour} for s in stretches] if stretches else \
        [{"kind": display_kind(seg, woven), "t0": seg.t0, "t1": seg.t1, "colour": _colour(seg, woven)}
         for seg in traj.segments]
    return {"duration": traj.duration_s, "colours": {b["kind"]: b["colour"] for b in bands},
            "segments": segments, "labels": labels, "bands": bands,
            "palette": {"limit": LIMIT_COLOUR, "curve": PALETTE[0], "label": kind_colour("crossing"),
                        "shaded": {kind: SHADED_OPACITY[kind] for kind in _STRIP_SHADED}},
            "speed": {"t": np.round(traj.t[1:][keep], 4).tolist(), "ratio": np.round(ratio[keep], 4).tolist()},
            "frame": {"center": (0.5 * (lo + hi)).tolist(), "distance": 2.2 * radius,
                      "direction": _VIEW_DIRECTION.tolist()}}


def _colour(seg: Segment, woven: frozenset[int]) -> int:
    """A segment's colour: its kind's, or the weave's for a woven move's segments other than crossings."""
    return kind_colour(display_kind(seg, woven))


def _extremes(values: np.ndarray, count: int) -> np.ndarray:
    """Indices (ascending) of at most ``count`` values that draw the same peaks: all of them when
    few, else the lowest and the highest of each of count / 2 buckets."""
    if len(values) <= count:
        return np.arange(len(values))
    bounds = np.linspace(0, len(values), count // 2 + 1).astype(np.int64).tolist()
    return np.unique([a + int(pick(values[a:b])) for a, b in itertools.pairwise(bounds)
                      for pick in (np.argmin, np.argmax)])


def _describe(seg: Segment, pause: Stretch | None = None) -> tuple[str, str]:
    """A segment's list entry: a title and a line of figures."""
    span = f"t {seg.t0:.3f}-{seg.t1:.3f} s, {seg.config_before}"
    if seg.kind != "crossing":
        what = "fly-by blend" if seg.kind == "blend" else seg.kind
        return f"move {seg.move}: {what}", span + ("" if seg.config_after == seg.config_before
                                                   else f" -> {seg.config_after}")
    pos_mm, ori_deg, lost_s = crossing_costs(seg.details)
    title = f"move {seg.move}: {seg.singularity} crossing, {seg.method}, {seg.config_before} -> {seg.config_after}"
    detail = (f"t {seg.t0:.3f}-{seg.t1:.3f} s; deviation {pos_mm:.4f} mm / {ori_deg:.3f} deg; "
              f"time lost {lost_s:.3f} s")
    if seg.pause_s is not None:
        at = f" at t {pause.t0:.3f}-{pause.t1:.3f} s" if pause is not None else ""
        detail += f"; TCP paused {seg.pause_s:.3f} s{at} while the aligned joints turn"
    return title, detail



@dataclass
class LiveReplay:
    """A meshcat server playing a trajectory; :meth:`close` stops it.

    Attributes:
        url: the page to open (meshcat's viewer, with play / pause / time / speed controls).
        host: the address the server listens on.
    """

    url: str
    host: str
    visualizer: meshcat.Visualizer
    server: subprocess.Popen[str]

    def close(self) -> None:
        """Stop the meshcat server process."""
        _stop(self.server)

    def __enter__(self) -> LiveReplay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _stop(server: subprocess.Popen[str]) -> None:
    if server.poll() is None:
        server.kill()
    server.wait()
    for pipe in (server.stdin, server.stdout):
        if pipe is not None:
            pipe.close()


def is_loopback(host: str) -> bool:
    """Whether every address ``host`` names is this machine's loopback (only this machine can connect).

    ``0.0.0.0`` and ``::`` (every interface), a LAN address or a name that resolves to one are not.
    """
    try:
        found = socket.getaddrinfo(host, None)
    except (OSError, UnicodeError, ValueError):
        return False
    addresses = {str(info[4][0]) for info in found}
    return bool(addresses) and all(ipaddress.ip_address(a.split("%")[0]).is_loopback for a in addresses)


def check_host(host: str) -> None:
    """Refuse (InputError) a ``--host`` that names no address."""
    try:
        socket.getaddrinfo(host, None)
    except (OSError, UnicodeError, ValueError) as exc:
        raise InputError(f"replay --host {host!r}: not an address of this machine ({exc})") from None


def _start_server(host: str) -> tuple[subprocess.Popen[str], str]:
    """Start :mod:`singplan.outputs.meshcat_server` listening on ``host``; return it and its command address."""
    check_host(host)
    script = Path(__file__).with_name("meshcat_server.py")
    # stdin: a pipe this process holds and never writes; the server exits when it closes (this process ended)
    server = subprocess.Popen([sys.executable, "-u", str(script), host], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    atexit.register(_stop, server)
    try:
        assert server.stdout is not None
        line = server.stdout.readline().strip()
        if not line.startswith("zmq_url="):
            reason = line.removeprefix("error=") or f"the server exited with code {server.wait(_SERVER_START_S)}"
            raise InputError(f"replay --host {host!r}: cannot serve there ({reason})")
        server.stdout.readline()  # web_url=...: the visualiser asks the server for it
    except BaseException:
        _stop(server)
        raise
    return server, line.removeprefix("zmq_url=")


def serve_replay(traj: Trajectory, robot: Robot, speed: float = 1.0, loop: bool = True,
                 host: str = DEFAULT_HOST) -> LiveReplay:
    """Start a meshcat server (on ``host``, a free port from 7000 up) and play the trajectory there."""
    server, command_url = _start_server(host)
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its URL; the caller decides
            vis = meshcat.Visualizer(zmq_url=command_url)
        live = LiveReplay(vis.url(), host, vis, server)
        track, travel = tcp_track(traj, robot), joint_travel(traj.q)
        _scene(vis, traj, robot, tcp_path(traj, track, travel), timeline(traj, track), travel, speed=speed, loop=loop,
               play=True)
    except BaseException:
        _stop(server)
        raise
    return live


def replay(traj: Trajectory | str | Path, html: str | Path | None = None, serve: bool = False,
           speed: float = 1.0, loop: bool = True, host: str = DEFAULT_HOST) -> Path | LiveReplay:
    """Replay a trajectory (object, or a trajectory.json / output folder) in the browser.

    ``html=path`` writes the self-contained page and returns its path (written under a
    temporary name and renamed when complete; an unusable path, or a folder another run is
    writing into, is an OutputPathError before anything is built). ``serve=True`` starts a live
    meshcat server listening on ``host`` (loopback by default) playing it (``speed`` x real time,
    looping unless ``loop=False``) and returns the running :class:`LiveReplay`, whose ``url`` to
    open and ``close()`` to stop it.
    """
    if (html is None) == (not serve):
        raise InputError("replay: give exactly one of html=PATH or serve=True")
    if not (math.isfinite(speed) and 0.01 <= speed <= 100.0):
        raise InputError(f"replay --speed: expected a number in [0.01, 100] (x real time), got {speed}")
    if html is None:
        trajectory = traj if isinstance(traj, Trajectory) else load(traj)
        return serve_replay(trajectory, robot_of(trajectory), speed=speed, loop=loop, host=host)
    target = check_output_file(html)
    with hold_output_folder(target.parent, (target.name,)):  # one run per folder, from reading to writing
        trajectory = traj if isinstance(traj, Trajectory) else load(traj)
        return write_file(target, text_writer(replay_html(trajectory, robot_of(trajectory))))

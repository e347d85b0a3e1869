"""Robots: the bundled registry, URDF loading through Pinocchio, FK and Jacobians.

A :class:`Robot` is a Pinocchio model reduced to the serial chain from the base to the tip
frame, plus a fixed tool transform ``T_tip_tcp``. Every pose it returns is the TCP in the
robot base frame (``T_base_tcp``).
"""

from __future__ import annotations

import logging
import math
import os
import tempfile
from dataclasses import dataclass
from functools import cache, cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pinocchio as pin
import yaml

from singplan.errors import RobotModelError, UnknownNameError
from singplan.kinematics.chain import ChainArrays, faithful
from singplan.kinematics.closedform.ur import UrParameters
from singplan.kinematics.continuous import UNLIMITED_RAD, as_revolute
from singplan.kinematics.families import Family, OpwParameters, Recognition, recognise
from singplan.kinematics.urdf_scan import MAX_URDF_BYTES as MAX_URDF_BYTES  # the cap, named where robots load
from singplan.kinematics.urdf_scan import UrdfScan, check_no_mimic, read_urdf

logger = logging.getLogger(__name__)

SUPPORTED_JOINT_COUNTS = (5, 6, 7)  # actuated revolute joints from the root to the tip
VELOCITY_LIMIT_RAD_S = (1e-3, 1e3)  # a joint slower than 0.001 rad/s would make durations overflow
MAX_JOINT_SPAN_RAD = 8 * math.pi  # 4 turns: the IK lists every 2*pi variant inside the range
_FK_CHUNK = 16_384  # samples whose chain transforms are formed at once (~0.5 kB of temporaries each)
MAX_REACH_M = 1000.0  # any joint or the tip farther from the base is a unit error (mm for m)
_PACKAGE_DIR = Path(__file__).resolve().parents[1]  # the singplan package folder


def _read_only(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


def robots_dir() -> Path:
    """Folder of the bundled URDFs and robots.yaml (in the wheel or in a source checkout)."""
    installed = _PACKAGE_DIR / "_robots"
    return installed if installed.is_dir() else _PACKAGE_DIR.parent / "robots" / "urdf"


@dataclass(frozen=True)
class RobotEntry:
    """One robot of the registry (``singplan robots``)."""

    name: str
    display_name: str
    family: str  # as written in robots.yaml: a test reference for the recognition (singplan.kinematics.families)
    tip: str
    sources: tuple[str, ...]
    urdf_file: str | None = None  # bundled URDF name, relative to robots_dir()
    example_robot_data: str | None = None  # loader name in example-robot-data
    opw: OpwParameters | None = None  # robots.yaml's published parameters: a test reference only

    def urdf_path(self) -> Path:
        """Absolute path of the URDF (bundled, or resolved from example-robot-data)."""
        if self.urdf_file is not None:
            return robots_dir() / self.urdf_file
        import example_robot_data.robots_loader as loaders

        loader = loaders.ROBOTS[str(self.example_robot_data)]
        root = Path(loaders.getModelPath(loader.path))
        return (root / loader.path / loader.urdf_subpath / loader.urdf_filename).resolve()


def _entry(name: str, spec: dict[str, Any]) -> RobotEntry:
    opw = None
    if spec.get("family") == "opw":
        p = spec["opw"]
        opw = OpwParameters(
            a1=float(p["a1"]), a2=float(p["a2"]), b=float(p["b"]), c1=float(p["c1"]),
            c2=float(p["c2"]), c3=float(p["c3"]), c4=float(p["c4"]),
            offsets_rad=tuple(math.radians(v) for v in spec["opw_offsets_deg"]),
            sign_corrections=tuple(float(v) for v in spec["opw_sign_corrections"]),
        )
    return RobotEntry(name=name, display_name=str(spec["display_name"]), family=str(spec["family"]),
                      tip=str(spec["tip"]), sources=tuple(spec.get("sources", ())),
                      urdf_file=spec.get("urdf"), example_robot_data=spec.get("example_robot_data"), opw=opw)


# libyaml's safe loader when PyYAML has it: robots.yaml (16 kB) in ~10 ms instead of ~70 ms
_RegistryLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


@cache
def registry_specs() -> dict[str, dict[str, Any]]:
    """robots.yaml's ``robots`` mapping, read once per process (callers must not modify it).

    The registry (:func:`bundled_robots`) and the controller conventions
    (:mod:`singplan.kinematics.vendor_config`) both read it.
    """
    specs: dict[str, dict[str, Any]] = yaml.load((robots_dir() / "robots.yaml").read_text(),
                                                 Loader=_RegistryLoader)["robots"]
    return specs


@cache
def bundled_robots() -> dict[str, RobotEntry]:
    """The registry of robots/urdf/robots.yaml, by name."""
    return {name: _entry(name, spec) for name, spec in registry_specs().items()}


class Robot:
    """A serial arm: Pinocchio model and data, tip frame, tool, limits.

    Attributes:
        name: registry name, or the URDF file stem.
        urdf_path: absolute path of the URDF that was loaded.
        model, data: the Pinocchio model reduced to the base -> tip chain, and its data.
        tip: name of the frame the tool hangs on.
        T_tip_tcp: tool transform (TCP in the tip frame).
        joint_names: the chain's joint names, base to tip.
        lower_rad, upper_rad: joint position limits, shape (n,); -inf and +inf for an unlimited
            joint (a URDF continuous joint, :mod:`singplan.kinematics.continuous`).
        unlimited: which joints have no position limit, shape (n,).
        velocity_rad_s: joint speed limits, shape (n,).
        entry: registry entry for a bundled robot, else None.

    A robot is not changed after it is made (its limit arrays are read-only): functions cache
    their work per robot (``lru_cache`` keyed on the object), so another tool makes another robot.
    The joint acceleration limits are not the URDF's but the task's: they live in the task's
    ``limits`` (:class:`singplan.task.schema.Limits`) and each move's timing limits are made from there.
    """

    def __init__(self, name: str, urdf_path: Path, model: pin.Model, tip: str, T_tip_tcp: pin.SE3,
                 entry: RobotEntry | None) -> None:
        self.name = name
        self.urdf_path = urdf_path
        self.model = model
        self.data = model.createData()
        self.tip = tip
        self.tip_frame_id = frame_id(model, tip)
        self.T_tip_tcp = T_tip_tcp
        self.T_tcp_tip_h = T_tip_tcp.inverse().homogeneous  # (4, 4): TCP poses -> tip poses, many at a time
        self.entry = entry
        self.joint_names = tuple(model.names[i] for i in range(1, model.njoints))
        self.unlimited = _read_only(unlimited_joints(model))
        self.lower_rad = _read_only(np.where(self.unlimited, -np.inf, np.array(model.lowerPositionLimit, dtype=float)))
        self.upper_rad = _read_only(np.where(self.unlimited, np.inf, np.array(model.upperPositionLimit, dtype=float)))
        self.velocity_rad_s = _read_only(np.array(model.velocityLimit, dtype=float))

    @property
    def n_joints(self) -> int:
        return int(self.model.nq)

    @cached_property
    def recognition(self) -> Recognition:
        """The kinematic family read from the chain and its tip (:mod:`singplan.kinematics.families`, cached)."""
        return recognise(self.model, self.tip_frame_id)

    @property
    def family(self) -> Family:
        return self.recognition.family

    @property
    def opw(self) -> OpwParameters | None:
        """Verified OPW parameters of the chain to the tip, or None when it is not an OPW arm."""
        return self.recognition.opw

    @property
    def ur(self) -> UrParameters | None:
        """Verified UR parameters of the chain to the tip, or None when it is not a UR-type arm."""
        return self.recognition.ur

    def reach_m(self) -> float:
        """Largest distance of the flange from axis 1 [m] (OPW: exact; else a link-length bound)."""
        p = self.opw
        if p is not None:
            return p.a1 + p.c2 + math.hypot(p.a2, p.c3) + p.c4
        return self._offsets_m()

    @cached_property
    def link_lengths_m(self) -> np.ndarray:
        """(n + 1,) [m]: entry i is the length of joint i's fixed offset from joint i - 1's origin
        (joint 1's from the base; entry 0, the base's, is 0), joints numbered as Pinocchio does."""
        placements = self.model.jointPlacements
        return _read_only(np.array([np.linalg.norm(placements[i].translation) for i in range(self.model.njoints)]))

    def offsets_m(self, first: int, last: int) -> float:
        """The summed lengths [m] of joints ``first`` .. ``last``'s fixed offsets (both included; 0 when
        ``first > last``): each joint only turns the offsets after it, so no point carried at joint
        ``last``'s origin is ever farther than this from joint ``first - 1``'s origin (the reach sum
        of the stopping, collision and out-of-reach bounds). Summed in joint order."""
        return float(sum(self.link_lengths_m[first:last + 1]))

    def _offsets_m(self) -> float:
        """The summed lengths of the chain's fixed offsets after joint 1 up to the flange [m]: each
        joint only turns them, so no flange point is farther from joint 1's origin."""
        tip = float(np.linalg.norm(self.model.frames[self.tip_frame_id].placement.translation))
        return self.offsets_m(2, self.model.njoints - 1) + tip

    def with_tool(self, T_tip_tcp: pin.SE3) -> Robot:
        """The same robot with another tool (a new Data, the model is shared; the recognition carried
        over when already made: the family depends on the model and the tip only)."""
        robot = Robot(self.name, self.urdf_path, self.model, self.tip, T_tip_tcp, self.entry)
        if "recognition" in self.__dict__:  # the family depends on the model and the tip only
            robot.__dict__["recognition"] = self.__dict__["recognition"]
        return robot

    def fk(self, q: np.ndarray) -> pin.SE3:
        """TCP pose in the base frame, ``T_base_tcp``, for joint values ``q`` (n,) [rad]."""
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.tip_frame_id) * self.T_tip_tcp

    def tcp_positions(self, q: np.ndarray) -> np.ndarray:
        """TCP positions [m] in the base frame (N, 3) of joint samples ``q`` (N, n).

        The chain's transforms are composed for a chunk of samples at a time: one Pinocchio call
        per sample costs ~5 us and a Python object each, which for a million samples is seconds and
        hundreds of MB. In numpy each 3 x 3 product of a chunk is a BLAS call per sample; where
        :func:`singplan.kinematics.chain.faithful` holds, one compiled loop forms the same products
        (the same numbers, bit for bit) at a tenth of that.
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.n_joints)
        out = np.empty((len(q), 3))
        for c in range(0, len(q), _FK_CHUNK):
            out[c:c + _FK_CHUNK] = self._tcp_chunk(q[c:c + _FK_CHUNK])[0]
        return out

    def tcp_frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions [m] (N, 3) and rotations (N, 3, 3) in the base frame of joint samples q (N, n):
        ``T_base_tcp`` of each, composed in numpy like :meth:`tcp_positions`."""
        position, rotation, _ = self.tcp_kinematics(q, 0)
        return position, rotation

    def tcp_jacobians(self, q: np.ndarray) -> np.ndarray:
        """Linear part of the TCP Jacobian (N, 3, n) [m/rad] in the base frame, of joint samples q (N, n)
        (:meth:`tcp_kinematics`' first three rows)."""
        return self.tcp_kinematics(q, 3)[2]

    def tcp_kinematics(self, q: np.ndarray, rows: Literal[0, 3, 6] = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """TCP positions [m] (N, 3), rotations (N, 3, 3) and Jacobians (N, rows, n) of joint samples q
        (N, n), from one walk of the chain composed in numpy a chunk at a time like
        :meth:`tcp_positions` (a Pinocchio call per sample costs ten times more).

        The Jacobian is :meth:`jacobian`'s (rows 0-2 the TCP point's linear velocity [m/rad], rows
        3-5 the angular velocity [rad/rad], base coordinates), its first ``rows`` rows: column j
        is ``(axis_j x (p_tcp - origin_j), axis_j)``.
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.n_joints)
        position, rotation = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
        jacobian = np.zeros((len(q), rows, self.n_joints))
        for c in range(0, len(q), _FK_CHUNK):
            if rows and self._compiled_chain is not None:  # the same numbers, compiled
                position[c:c + _FK_CHUNK], rotation[c:c + _FK_CHUNK], jacobian[c:c + _FK_CHUNK] = \
                    self._compiled_chain.kinematics(q[c:c + _FK_CHUNK], rows, self.n_joints)
                continue
            joints: list[tuple[int, np.ndarray, np.ndarray]] | None = [] if rows else None
            position[c:c + _FK_CHUNK], rotation[c:c + _FK_CHUNK] = self._tcp_chunk(q[c:c + _FK_CHUNK], joints)
            for iq, origin, axis_base in joints or ():
                arm = position[c:c + _FK_CHUNK] - origin
                jacobian[c:c + _FK_CHUNK, :3, iq] = axis_base[:, [1, 2, 0]] * arm[:, [2, 0, 1]] - \
                    axis_base[:, [2, 0, 1]] * arm[:, [1, 2, 0]]  # axis x arm
                jacobian[c:c + _FK_CHUNK, 3:, iq] = axis_base[:, :rows - 3]
        return position, rotation, jacobian

    def _tcp_chunk(self, q: np.ndarray, joints: list[tuple[int, np.ndarray, np.ndarray]] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions (N, 3) and rotations (N, 3, 3) of joint samples q (N, n); with ``joints``,
        also appends each chain joint's (q index, origin (N, 3), unit axis (N, 3)) in the base frame to it."""
        if self._compiled_chain is not None:  # the same numbers, compiled (singplan.kinematics.chain)
            return self._compiled_chain.tcp(q, joints)
        rotation = np.broadcast_to(np.eye(3), (len(q), 3, 3))  # (N, 3, 3): base -> current joint frame
        position = np.zeros((len(q), 3))
        for placement, axis, iq in self._chain_steps:
            position = position + rotation @ placement.translation
            rotation = rotation @ placement.rotation
            if joints is not None:
                joints.append((iq, position, rotation @ axis))
            rotation = rotation @ _rotations_about(axis, q[:, iq])
        tool = self.model.frames[self.tip_frame_id].placement * self.T_tip_tcp
        return position + rotation @ tool.translation, rotation @ tool.rotation

    def joint_frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (N, J, 3, 3) and origins (N, J, 3) [m] in the base frame of the model's joint
        frames 0 (the base) .. J-1 (Pinocchio's ``oMi``) for joint samples q (N, n), composed in numpy
        like :meth:`tcp_positions` (the model is the base -> tip chain: joint i is the chain's i-th)."""
        q = np.asarray(q, dtype=float).reshape(-1, self.n_joints)
        rotation = np.empty((len(q), self.model.njoints, 3, 3))
        origin = np.empty((len(q), self.model.njoints, 3))
        if len(q) == 1:  # one sample: Pinocchio's own pass costs a tenth of the numpy one
            pin.forwardKinematics(self.model, self.data, q[0])
            for i, placement in enumerate(self.data.oMi):
                rotation[0, i], origin[0, i] = placement.rotation, placement.translation
            return rotation, origin
        if self._compiled_chain is not None and self.model.njoints == len(self._chain_steps) + 1:
            return self._compiled_chain.frames(q)  # the same numbers, compiled (singplan.kinematics.chain)
        rotation[:, 0], origin[:, 0] = np.eye(3), 0.0
        for i, (placement, axis, iq) in enumerate(self._chain_steps, start=1):
            origin[:, i] = origin[:, i - 1] + rotation[:, i - 1] @ placement.translation
            rotation[:, i] = rotation[:, i - 1] @ placement.rotation @ _rotations_about(axis, q[:, iq])
        return rotation, origin

    @cached_property
    def joint_axes(self) -> np.ndarray:
        """(n, 3) each chain joint's unit axis in its own joint frame."""
        return np.array([axis for _, axis, _ in self._chain_steps])

    @cached_property
    def _chain_steps(self) -> list[tuple[pin.SE3, np.ndarray, int]]:
        """Base to tip: each joint's placement in its parent's frame, its unit axis and its q index.

        The axis is read from Pinocchio's own motion of the joint (1 rad from neutral), so any
        revolute joint kind (RX, RY, RZ, unaligned) gives it without a case per kind.
        """
        data = self.model.createData()
        pin.forwardKinematics(self.model, data, pin.neutral(self.model) + 1.0)  # liMi[j] = placement * turn(1 rad)
        steps = []
        for j in list(self.model.supports[self.model.frames[self.tip_frame_id].parentJoint])[1:]:
            placement = self.model.jointPlacements[j]
            turn = placement.rotation.T @ data.liMi[j].rotation
            steps.append((placement, pin.log3(turn), self.model.joints[j].idx_q))
        return steps

    @cached_property
    def _compiled_chain(self) -> ChainArrays | None:
        """The chain's arrays for the compiled composition, where its products are numpy's here bit for
        bit (:func:`~singplan.kinematics.chain.faithful`); None: numpy composes it."""
        if not faithful():
            return None
        tool = self.model.frames[self.tip_frame_id].placement * self.T_tip_tcp
        steps = self._chain_steps
        return ChainArrays(np.array([p.translation for p, _, _ in steps]).reshape(-1, 3),
                           np.array([p.rotation for p, _, _ in steps]).reshape(-1, 3, 3),
                           np.array([axis for _, axis, _ in steps]).reshape(-1, 3),
                           np.array([pin.skew(axis) for _, axis, _ in steps]).reshape(-1, 3, 3),
                           [iq for _, _, iq in steps], tool.translation, tool.rotation)

    def beyond_reach(self, xyz: np.ndarray) -> str:
        """Why a TCP position [m] (3,) in the base frame is certainly out of reach, or "" when it may not be.

        No TCP position is farther from joint 1's origin than the sum of the lengths of the chain's
        fixed offsets (joint placements 2..n, the tip frame's, the tool's): each joint only turns them.
        A target past that is named with its distance; one more than ten times past it, with the reading
        in centimetres or millimetres that would be within it (a task's positions are in metres)."""
        centre = np.asarray(self.model.jointPlacements[1].translation, dtype=float)
        reach = self._offsets_m() + float(np.linalg.norm(self.T_tip_tcp.translation))
        xyz = np.asarray(xyz, dtype=float)
        distance = float(np.linalg.norm(xyz - centre))
        if not distance > reach:
            return ""
        note = f"the target is {distance:.3g} m from the base, beyond the arm's reach of {reach:.3g} m"
        for unit, scale in (("centimetres", 1e-2), ("millimetres", 1e-3)):
            if distance > 10.0 * reach and float(np.linalg.norm(xyz * scale - centre)) <= reach:
                shown = ", ".join(f"{v:g}" for v in np.round(xyz * scale, 6))
                return f"{note} (positions are in metres: read as {unit} it would be [{shown}] m)"
        return f"{note} (positions are in metres)"

    def fk_tip(self, q: np.ndarray) -> pin.SE3:
        """Tip-frame pose in the base frame (no tool)."""
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.tip_frame_id).copy()

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """TCP Jacobian (6, n) in the LOCAL_WORLD_ALIGNED frame.

        Rows 0-2 map qd to the TCP point's linear velocity in base coordinates [m/s], rows 3-5
        to the tool's angular velocity in base coordinates [rad/s].
        """
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        J = pin.getFrameJacobian(self.model, self.data, self.tip_frame_id, pin.LOCAL_WORLD_ALIGNED)
        # shift the reference point from the tip origin to the TCP: v_tcp = v_tip + w x r
        r = self.data.oMf[self.tip_frame_id].rotation @ self.T_tip_tcp.translation
        J = J.copy()
        J[:3] -= pin.skew(r) @ J[3:]
        return J

    def fk_and_joint(self, q: np.ndarray, joint: int) -> tuple[pin.SE3, pin.SE3]:
        """``T_base_tcp`` and the placement of joint frame ``joint`` (1..n) in the base frame, from one
        forward-kinematics pass (copies: ``data`` changes on the next call)."""
        T_tcp = self.fk(q)
        return T_tcp, self.data.oMi[joint].copy()

    def joint_placements(self, q: np.ndarray) -> list[pin.SE3]:
        """Placements of the joint frames 1..n in the base frame (copies: ``data`` changes on the next call)."""
        pin.forwardKinematics(self.model, self.data, q)
        return [self.data.oMi[i].copy() for i in range(1, self.model.njoints)]

    def wrist_center(self, q: np.ndarray) -> np.ndarray:
        """Wrist centre [m] in the base frame: the origin of joint 5's frame.

        For a spherical wrist this point lies on axes 4, 5 and 6. For other 6R arms (UR) it is
        the point on axis 5 where the joint frame sits.
        """
        pin.forwardKinematics(self.model, self.data, q)
        return np.array(self.data.oMi[5].translation)

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> bool:
        return bool(np.all(q >= self.lower_rad - tol) and np.all(q <= self.upper_rad + tol))


def unlimited_joints(model: pin.Model) -> np.ndarray:
    """(nq,) True for each joint without position limits: limits at or past -/+UNLIMITED_RAD
    (a URDF continuous joint, read as revolute: :func:`load_full_model`)."""
    lower, upper = np.asarray(model.lowerPositionLimit, dtype=float), np.asarray(model.upperPositionLimit, dtype=float)
    return np.asarray((lower <= -UNLIMITED_RAD) & (upper >= UNLIMITED_RAD))


def _rotations_about(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) about the unit ``axis`` by ``angle_rad`` (N,) (Rodrigues)."""
    k = pin.skew(axis)
    s, c = np.sin(angle_rad)[:, None, None], np.cos(angle_rad)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def frame_id(model: pin.Model, name: str) -> int:
    """The frame named ``name``; the link's where a joint has the same name (the SO-100's ``gripper``)."""
    if model.existFrame(name, pin.FrameType.BODY):
        return int(model.getFrameId(name, pin.FrameType.BODY))
    return int(model.getFrameId(name))


def _chain_joint_ids(model: pin.Model, frame_id: int) -> list[int]:
    ids = []
    j = model.frames[frame_id].parentJoint
    while j > 0:
        ids.append(j)
        j = model.parents[j]
    return ids


def load_full_model(urdf_path: Path) -> tuple[pin.Model, UrdfScan]:
    """The whole URDF's Pinocchio model, one coordinate per joint, and what the scan found.

    The model is built from the text :func:`~singplan.kinematics.urdf_scan.read_urdf` read and
    scanned (Pinocchio parses exactly what was checked); continuous joints are read as unlimited
    revolute joints (:mod:`singplan.kinematics.continuous`), whose angle has no limit.

    Raises:
        RobotModelError: the file is missing, unreadable, over :data:`MAX_URDF_BYTES`, refused by
            the scan, not a URDF, or has no links.
    """
    scan = read_urdf(urdf_path)
    model = _build(urdf_path, scan.text)
    if any(joint.shortname().startswith("JointModelRUB") for joint in model.joints):
        model = _build(urdf_path, as_revolute(scan.text, str(urdf_path)))
    if not any(f.type == pin.FrameType.BODY for f in model.frames):
        raise RobotModelError(str(urdf_path), "has no links")
    return model, scan


def _build(urdf_path: Path, urdf_text: str) -> pin.Model:
    """Pinocchio's model of ``urdf_text``, its urdfdom messages kept for the error naming the joint."""
    with tempfile.TemporaryFile() as messages:
        try:
            return _build_quietly(urdf_text, messages.fileno())
        except (RuntimeError, ValueError) as exc:
            messages.seek(0)
            reason = _urdfdom_reason(messages.read(8192).decode("utf-8", "replace")) or str(exc)
            raise RobotModelError(str(urdf_path), f"cannot be read as URDF: {reason}") from None


def _build_quietly(urdf_text: str, sink_fd: int) -> pin.Model:
    """``pin.buildModelFromXML`` with urdfdom's messages (written to fd 2) sent to ``sink_fd``.

    urdfdom explains a rejected file only on stderr; keeping its lines lets the error name
    the joint and the value.
    """
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to redirect
        return pin.buildModelFromXML(urdf_text)
    os.dup2(sink_fd, 2)
    try:
        return pin.buildModelFromXML(urdf_text)
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _urdfdom_reason(messages: str) -> str:
    """urdfdom's first two error lines: the problem, then usually the joint or link it is in."""
    errors = [line.strip().removeprefix("Error:").strip()[:160] for line in messages.splitlines()
              if line.strip().startswith("Error:")]
    return "; ".join(errors[:2])


TIP_NAMES = ("tool0", "flange", "tcp")  # in this order of preference, also with a prefix ("ur_tool0")
END_EFFECTOR_JOINT_WORDS = ("gripper", "finger", "jaw")  # a joint so named moves a gripper, not the arm


def default_tip(model: pin.Model) -> str:
    """The tip of a URDF given by path (DESIGN "Robots"): a link named ``tool0``, ``flange`` or
    ``tcp`` (or ending in ``_tool0`` ...) at the end of the chain, else the chain's last link.

    The chain ends at its deepest movable joint that is not an end effector's (a joint whose
    name contains ``gripper``, ``finger`` or ``jaw``, e.g. the SO-100's revolute jaw or the
    Panda's prismatic fingers), whatever its type; its end links are those fixed to that joint
    (Pinocchio merges fixed joints into the body they hang on), which leaves out fingers and
    other joints branching off. The last link is the one most fixed joints away from that joint
    (the first in the file among equals). Outputs name the tip, and other tools (the checker)
    cannot look up a name that two frames carry: links whose name another frame carries too (a
    fixed joint named like its child link, e.g. the Unitree Z1's ``gripperStator``) are passed
    over while another is left, and when none is left the tip is a uniquely named frame at the
    same place (the SO-100's last link ``gripper`` shares its name with the jaw's joint: its tip
    is the frame of the joint ``wrist_roll`` that carries it, as the registry names it).
    """
    end = _chain_end(model)
    if end is None:
        return model.frames[len(model.frames) - 1].name
    links = [k for k, f in enumerate(model.frames) if f.type == pin.FrameType.BODY and f.parentJoint == end]
    names = [f.name for f in model.frames]
    links = [k for k in links if names.count(model.frames[k].name) == 1] or links
    for wanted in TIP_NAMES:
        named = [model.frames[k].name for k in links
                 if model.frames[k].name == wanted or model.frames[k].name.endswith("_" + wanted)]
        if named:
            return named[0]
    return _unique_name_at(model, max(links, key=lambda k: _fixed_depth(model, k)))


def _unique_name_at(model: pin.Model, k: int) -> str:
    """Frame k's name if no other frame carries it, else a uniquely named frame on the same joint
    at the same placement (the joint's own frame first, then fixed joints' frames), else k's name."""
    names = [f.name for f in model.frames]
    frame = model.frames[k]
    if names.count(frame.name) == 1:
        return frame.name
    same = [f for f in model.frames if f.parentJoint == frame.parentJoint and names.count(f.name) == 1
            and f.placement.isApprox(frame.placement, 1e-12)]
    order = (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT, pin.FrameType.BODY, pin.FrameType.OP_FRAME)
    same.sort(key=lambda f: order.index(f.type) if f.type in order else len(order))
    return same[0].name if same else frame.name


def _chain_end(model: pin.Model) -> int | None:
    """The deepest movable joint that is not an end effector's (None: the URDF has none).

    Joints of every type count, not only the revolute ones singplan plans with: a prismatic last
    axis must end the chain so that :func:`_check_chain` refuses it by name; leaving it out would
    silently plan the arm without its last axis.
    """
    arm = [j for j in range(1, model.njoints)
           if not any(word in model.names[j].lower() for word in END_EFFECTOR_JOINT_WORDS)]
    return max(arm, key=lambda j: len(model.supports[j])) if arm else None


def _fixed_depth(model: pin.Model, frame_id: int) -> int:
    """How many frames lie between a frame and its joint (fixed joints and the links they carry)."""
    depth = 0
    while model.frames[frame_id].type != pin.FrameType.JOINT and frame_id > 0:
        frame_id = model.frames[frame_id].parentFrame
        depth += 1
    return depth


def _reduce_to_chain(model: pin.Model, tip: str, urdf_path: Path) -> pin.Model:
    """Lock every joint that is not on the base -> tip chain (e.g. gripper fingers)."""
    frames = [f.name for f in model.frames]
    if not model.existFrame(tip):
        raise UnknownNameError("tip frame", tip, frames, where=str(urdf_path))
    chain = sorted(_chain_joint_ids(model, frame_id(model, tip)))
    _check_chain(model, chain, tip, urdf_path)
    others = [j for j in range(1, model.njoints) if j not in chain]
    if not others:
        return model
    _rename_clashing_joints(model, others)
    return pin.buildReducedModel(model, others, pin.neutral(model))


def _rename_clashing_joints(model: pin.Model, joints: list[int]) -> None:
    """Rename joints about to be locked whose name is also a link's (``gripper`` on the SO-100).

    A locked joint becomes a fixed frame, and Pinocchio refuses to reduce a model where that
    frame would share its name with the link; the locked joint's name is never used again.
    """
    for j in joints:
        name = model.names[j]
        if not model.existFrame(name, pin.FrameType.BODY):
            continue
        k = model.getFrameId(name, pin.FrameType.JOINT)
        frame = model.frames[k]
        frame.name = model.names[j] = f"{name}_locked_joint"
        model.frames[k] = frame


def _check_chain(model: pin.Model, chain: list[int], tip: str, urdf_path: Path) -> None:
    """Every chain joint revolute (continuous ones were read as unlimited revolute joints), and a
    supported number of them."""
    # a joint past the arm (a tool's spindle or slide) is left out by a tip before it
    tool_hint = f" (a joint of a tool rather than the arm: give the task a `tip` before it; the tip now is {tip})"
    for j in chain:
        kind = model.joints[j].shortname().removeprefix("JointModel")
        name = model.names[j]
        if kind in ("PX", "PY", "PZ", "PrismaticUnaligned"):
            raise RobotModelError(str(urdf_path),
                                  f"joint {name!r} is prismatic; singplan plans revolute arms{tool_hint}")
        if kind not in ("RX", "RY", "RZ", "RevoluteUnaligned"):
            raise RobotModelError(str(urdf_path),
                                  f"joint {name!r} is a {kind} joint; singplan needs revolute joints{tool_hint}")
    if len(chain) not in SUPPORTED_JOINT_COUNTS:
        counts = ", ".join(str(n) for n in SUPPORTED_JOINT_COUNTS[:-1]) + f" or {SUPPORTED_JOINT_COUNTS[-1]}"
        raise RobotModelError(str(urdf_path), f"{len(chain)} revolute joints from {_root_link(model)} to {tip}; "
                                              f"singplan plans arms with {counts} between the base and the tip "
                                              f"(`tip`, the frame the tool hangs on)")


def _root_link(model: pin.Model) -> str:
    return next((f.name for f in model.frames if f.type == pin.FrameType.BODY), "the root")


def _check_limits(model: pin.Model, urdf_path: Path) -> None:
    """Finite position limits, lower < upper, within 4 turns (or none: an unlimited joint); a usable
    velocity limit."""
    v_low, v_high = VELOCITY_LIMIT_RAD_S
    unlimited = unlimited_joints(model)
    for j in range(model.nq):
        name = model.names[j + 1]
        lower, upper = float(model.lowerPositionLimit[j]), float(model.upperPositionLimit[j])
        velocity = float(model.velocityLimit[j])
        if velocity == 0.0:  # also a continuous joint given no <limit> (singplan.kinematics.continuous)
            raise RobotModelError(str(urdf_path), f"joint {name!r} has no velocity limit (<limit velocity=...> "
                                                  f"missing or 0); singplan needs each joint's speed limit")
        if not v_low <= velocity <= v_high:
            raise RobotModelError(str(urdf_path), f"joint {name!r} has velocity limit {velocity:g} rad/s; it must be "
                                                  f"between {v_low:g} and {v_high:g}")
        if unlimited[j]:
            continue
        if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
            raise RobotModelError(str(urdf_path), f"joint {name!r} has position limits [{lower:g}, {upper:g}] rad; "
                                                  "they must be finite with lower < upper")
        if max(abs(lower), abs(upper), upper - lower) > MAX_JOINT_SPAN_RAD:
            raise RobotModelError(str(urdf_path), f"joint {name!r} has position limits [{lower:g}, {upper:g}] rad; "
                                                  f"at most {MAX_JOINT_SPAN_RAD:.4g} rad (4 turns) is supported, "
                                                  f"or none (a continuous joint)")


def _check_forward_kinematics(robot: Robot) -> None:
    """Finite joint and tip coordinates within MAX_REACH_M at the zero, lower, upper and mid joints
    (an unlimited joint at -pi and pi)."""
    lo = np.where(robot.unlimited, -math.pi, robot.lower_rad)
    hi = np.where(robot.unlimited, math.pi, robot.upper_rad)
    for q in (np.clip(np.zeros(robot.n_joints), lo, hi), lo, hi, (lo + hi) / 2):
        points = [T.translation for T in robot.joint_placements(q)] + [robot.fk_tip(q).translation]
        farthest = float(np.max(np.abs(points)))  # a coordinate, not a norm: no overflow on 1e308
        if not farthest <= MAX_REACH_M:  # also catches NaN
            raise RobotModelError(str(robot.urdf_path), f"forward kinematics puts a joint or the tip {farthest:g} m "
                                                        f"from the base (at most {MAX_REACH_M:g} m; units in mm?)")


def load_robot(name_or_urdf: str | Path, tip: str | None = None, tool: pin.SE3 | None = None) -> Robot:
    """Load a bundled robot by name, or any URDF by path.

    Args:
        name_or_urdf: a registry name (``singplan robots``) or a path to a ``.urdf`` file.
        tip: frame the tool hangs on; default the registry's tip, else :func:`default_tip`.
        tool: ``T_tip_tcp``; default identity.

    The chain from the URDF's root link to the tip must have :data:`SUPPORTED_JOINT_COUNTS`
    revolute or continuous joints, each with finite position limits (lower < upper, at most 4
    turns) or none (a continuous joint: :mod:`singplan.kinematics.continuous`) and a velocity limit
    in :data:`VELOCITY_LIMIT_RAD_S`; prismatic and other joints on the chain are refused (joints
    off the chain, e.g. gripper fingers, are locked).

    Raises:
        UnknownNameError: unknown robot name (lists the valid ones) or unknown tip frame.
        RobotModelError: the URDF is missing, not a regular file or over :data:`MAX_URDF_BYTES`; it
            is refused by its scan (:mod:`singplan.kinematics.urdf_scan`: too
            many joints or elements, a joint axis of no length, a mimic joint on the chain) or lacks
            what planning needs (named joint and reason).
    """
    registry = bundled_robots()
    text = str(name_or_urdf)
    entry = registry.get(text)
    if entry is None and not text.lower().endswith(".urdf"):
        raise UnknownNameError("robot", text, sorted(registry))
    urdf_path = entry.urdf_path() if entry is not None else Path(text).expanduser().resolve()
    model, scan = load_full_model(urdf_path)
    tip_name = tip or (entry.tip if entry is not None else default_tip(model))
    model = _reduce_to_chain(model, tip_name, urdf_path)
    check_no_mimic(scan, (model.names[j] for j in range(1, model.njoints)), str(urdf_path))
    _check_limits(model, urdf_path)
    name = entry.name if entry is not None else urdf_path.stem
    robot = Robot(name, urdf_path, model, tip_name, tool if tool is not None else pin.SE3.Identity(), entry)
    _check_forward_kinematics(robot)
    return robot

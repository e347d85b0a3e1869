"""The task records: the YAML format version 1 of DESIGN.md as frozen dataclasses, and the field rules.

:mod:`singplan.task.load` builds a :class:`Task` from a YAML file (``load_task``) or a mapping
(``parse_task``); every problem raises :class:`~singplan.errors.TaskError` naming the field path
(``moves[2].lin.to.xyz: expected 3 numbers, got 2``), through the field checks at the end of
this module. Checks that need the robot (joint counts, joint limits) are in
:func:`singplan.task.load.check_against_robot`.

Every number has a range, checked before it is used, so no later arithmetic (durations,
sample counts) can overflow:

=====================================  ===================  ==========================
field                                  range                unit
=====================================  ===================  ==========================
xyz, via.xyz                           -100 .. 100          m
tool.xyz                               -10 .. 10            m
rpy_deg, tool.rpy_deg                  -720 .. 720          deg
joints_deg                             -3600 .. 3600        deg (and the URDF limits)
lin/circ speed                         0.0001 .. 10         m/s
ptp velocity_scale, limits.velocity_   0.001 .. 1           fraction of the URDF limits
limits.acceleration                    0.01 .. 10000        rad/s^2
limits.torque_scale                    0.001 .. 1           fraction of the URDF efforts
limits.jerk                            0.1 .. 1e6           rad/s^3
singularity.position_tolerance_mm      0.0001 .. 1000       mm
singularity.orientation_tolerance_deg  0.001 .. 180         deg
singularity.zone wrist/elbow_deg       0.001 .. 90          deg
singularity.zone.shoulder_mm           0.001 .. 1000        mm
singularity.deviation_cost_percent     0 .. 1000            percent of a move's time
output.period                          0.0001 .. 1          s
weave.amplitude_mm                     0.001 .. 1000        mm
weave.wavelength_mm                    0.1 .. 100000        mm
blend_mm                               0 .. 10000           mm (0: the move ends at rest)
cell / tool.geometry sizes             0 .. 100 (exclusive) m (box size, radius, length)
mesh scale                             0 .. 1e6 (exclusive)
collision.clearance_mm                 0 .. 1000            mm
=====================================  ===================  ==========================

Names (robot, tip) are at most :data:`MAX_NAME_CHARS` characters without control
characters (URDF paths :data:`MAX_PATH_CHARS`); messages quote long values shortened.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from singplan.errors import TaskError
from singplan.kinematics.shapes import CollisionSettings, Shape
from singplan.kinematics.yamldoc import join_field as _join
from singplan.kinematics.yamldoc import key_text as _key_text
from singplan.kinematics.yamldoc import shorten as _short

MAX_MOVES = 10_000
MAX_OUTPUT_SAMPLES = 10_000_000
TASK_MEMORY_MB = 1500.0  # DESIGN.md "Bounded resources": the whole process, in all (planning.orchestration.budget)
MAX_FILE_BYTES = 8 * 1024 * 1024
MAX_DEPTH = 64  # nesting levels of the YAML document
MAX_YAML_NODES = 500_000  # 10 000 moves need < 300 000; building 1 M nodes takes ~10 s and ~400 MB
MAX_SCALAR_CHARS = 10_000
MAX_NAME_CHARS = 256
MAX_PATH_CHARS = 4096
MAX_JOINTS = 64
# not a method: auto compares the pose-keeping ones (singplan.planning.orchestration.select); the
# crossing methods' names live in singplan.planning.crossing.registry, which checks a task's
AUTO_METHOD = "auto"
# the defaults of optional task fields, written once: the records below, the YAML reader and
# the docs' tables take them from here
DEFAULT_SPEED_M_S = 0.25  # LIN / CIRC speed
DEFAULT_VELOCITY_SCALE = 1.0  # PTP velocity_scale and limits.velocity_scale
DEFAULT_METHOD = AUTO_METHOD
DEFAULT_CONFIG = "auto"
DEFAULT_ORIENTATION_TOLERANCE_DEG = 5.0
DEFAULT_POSITION_TOLERANCE_MM = 0.01
DEFAULT_ZONE_WRIST_DEG = 5.0
DEFAULT_ZONE_SHOULDER_MM = 20.0
DEFAULT_ZONE_ELBOW_DEG = 5.0
DEFAULT_DEVIATION_COST_PERCENT = 3.0  # singularity.deviation_cost_percent: what a whole tolerance costs auto
DEFAULT_PERIOD_S = 0.004  # output.period
DEFAULT_WEAVE_PATTERN = "sine"
DEFAULT_BLEND_MM = 0.0  # a move ends at rest on its point
DEFAULT_REDUNDANT_VALUE_DEG = 0.0
DEFAULT_TOOL = (0.0, 0.0, 0.0)  # tool.xyz [m] and tool.rpy_deg
MAX_KEY_CHARS = 256  # keys are field names; a longer one can only be a mistake (or a huge number)
MAX_CELL_SHAPES = 1000  # cell shapes (each is checked against every robot body)
MAX_TOOL_SHAPES = 100
DEFAULT_CLEARANCE_MM = 0.0  # collision.clearance_mm: no contact


class Range(NamedTuple):
    """Closed range of a numeric field; ``low > 0`` also reads as "must be positive"."""

    low: float
    high: float
    unit: str


COORDINATE_M = Range(-100.0, 100.0, "m")
TOOL_OFFSET_M = Range(-10.0, 10.0, "m")
ANGLE_DEG = Range(-720.0, 720.0, "deg")
JOINT_DEG = Range(-3600.0, 3600.0, "deg")
SPEED_M_S = Range(1e-4, 10.0, "m/s")
VELOCITY_SCALE = Range(1e-3, 1.0, "")
ACCELERATION_RAD_S2 = Range(1e-2, 1e4, "rad/s^2")
# limits.acceleration's default, every joint: a URDF has no acceleration limits, so the task's
# limits are their one home (each move's timing limits are made from them, a held joint's dropped)
DEFAULT_ACCELERATION_RAD_S2 = 10.0
TORQUE_SCALE = Range(1e-3, 1.0, "")
JERK_RAD_S3 = Range(0.1, 1e6, "rad/s^3")
PTP_TIME_LAWS = ("optimal", "quintic")  # limits.ptp_time_law
DEFAULT_PTP_TIME_LAW = "optimal"
POSITION_TOLERANCE_MM = Range(1e-4, 1000.0, "mm")
ORIENTATION_TOLERANCE_DEG = Range(1e-3, 180.0, "deg")
ZONE_ANGLE_DEG = Range(1e-3, 90.0, "deg")
ZONE_SHOULDER_MM = Range(1e-3, 1000.0, "mm")
DEVIATION_COST_PERCENT = Range(0.0, 1000.0, "%")
PERIOD_S = Range(1e-4, 1.0, "s")
WEAVE_AMPLITUDE_MM = Range(1e-3, 1000.0, "mm")
WEAVE_WAVELENGTH_MM = Range(0.1, 1e5, "mm")
BLEND_MM = Range(0.0, 1e4, "mm")
SHAPE_SIZE_M = Range(1e-9, 100.0, "m")  # low > 0: "must be positive"
MESH_SCALE = Range(1e-9, 1e6, "")
CLEARANCE_MM = Range(0.0, 1000.0, "mm")
WEAVE_PATTERNS = ("sine", "triangle")
MAX_COORDINATE_M = COORDINATE_M.high
MAX_SPEED_M_S = SPEED_M_S.high


@dataclass(frozen=True)
class PoseSpec:
    """A Cartesian target: position [m] in the base frame, optional orientation (held if None)."""

    xyz: tuple[float, float, float]
    rpy_deg: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Weave:
    """A move's ``weave`` as given in the task (millimetres, as written; the geometry is
    :mod:`singplan.planning.path.weave`)."""

    pattern: str  # "sine" | "triangle"
    amplitude_mm: float
    wavelength_mm: float

    def to_mapping(self) -> dict[str, float | str]:
        return asdict(self)


@dataclass(frozen=True)
class Move:
    """One motion. ``kind`` is "lin", "circ" or "ptp"; PTP targets may be joints or a pose."""

    kind: str
    to: PoseSpec | None = None
    to_joints_deg: tuple[float, ...] | None = None
    via_xyz: tuple[float, float, float] | None = None  # CIRC only
    speed_m_s: float = DEFAULT_SPEED_M_S  # LIN / CIRC TCP speed
    velocity_scale: float = DEFAULT_VELOCITY_SCALE  # PTP fraction of the joint speed limits
    config: str = DEFAULT_CONFIG  # "auto" | "keep" | a label like "F U N"
    weave: Weave | None = None  # LIN / CIRC only
    blend_mm: float = DEFAULT_BLEND_MM  # fly-by radius around the move's end point; 0: the move ends at rest



@dataclass(frozen=True)
class ZoneThresholds:
    """Detection thresholds of singular zones."""

    wrist_deg: float = DEFAULT_ZONE_WRIST_DEG
    shoulder_mm: float = DEFAULT_ZONE_SHOULDER_MM
    elbow_deg: float = DEFAULT_ZONE_ELBOW_DEG

    def si(self) -> np.ndarray:
        """(wrist [rad], shoulder [m], elbow [rad]) thresholds, the order of the signed distances."""
        return np.array([math.radians(self.wrist_deg), self.shoulder_mm / 1000.0, math.radians(self.elbow_deg)])


@dataclass(frozen=True)
class SingularitySettings:
    method: str = DEFAULT_METHOD
    orientation_tolerance_deg: float = DEFAULT_ORIENTATION_TOLERANCE_DEG
    position_tolerance_mm: float = DEFAULT_POSITION_TOLERANCE_MM
    zone: ZoneThresholds = field(default_factory=ZoneThresholds)
    # auto's rule: a candidate whose crossings use their whole tolerance (the larger share of the
    # position or the orientation tolerance) counts this many percent slower, one that uses a fifth
    # of it a fifth as much; auto keeps the least duration so counted (0: the fastest within the tolerances)
    deviation_cost_percent: float = DEFAULT_DEVIATION_COST_PERCENT


@dataclass(frozen=True)
class Limits:
    velocity_scale: float = DEFAULT_VELOCITY_SCALE
    # one value for all joints, or one per joint
    acceleration_rad_s2: tuple[float, ...] = (DEFAULT_ACCELERATION_RAD_S2,)
    torque_scale: float | None = None  # fraction of the URDF efforts, enforced; None: torques not limited
    jerk_rad_s3: tuple[float, ...] | None = None  # one value for all joints, or one per joint; None: not limited
    # limits.ptp_time_law: "quintic" times every PTP move by SEEDS 003's 10t^3 - 15t^4 + 6t^5 law
    # instead of the time-optimal one ("optimal")
    ptp_time_law: str = DEFAULT_PTP_TIME_LAW

    def __post_init__(self) -> None:
        """The per-joint ranges and the time law, checked once however the record is made (parsed,
        built or replaced in Python); the joint count needs the robot (check_against_robot)."""
        for where, values, bounds in (("limits.acceleration", self.acceleration_rad_s2, ACCELERATION_RAD_S2),
                                      ("limits.jerk", self.jerk_rad_s3 or (), JERK_RAD_S3)):
            for i, v in enumerate(values):
                _in_range(f"{where}[{i}]" if len(values) > 1 else where, _as_number(where, v, bounds), bounds)
        if self.ptp_time_law not in PTP_TIME_LAWS:
            raise TaskError("limits.ptp_time_law", f"expected one of {', '.join(PTP_TIME_LAWS)}, "
                                                   f"got {self.ptp_time_law!r}")

    def joint_accelerations(self, n_joints: int) -> np.ndarray:
        """The joint acceleration limits [rad/s^2] (n,), one value given for all joints spread out.
        These limits are their one home: a URDF has none, and each move's timing limits, the
        checks and the stopping figures are made from here (a held joint's value dropped first)."""
        return np.broadcast_to(np.asarray(self.acceleration_rad_s2, dtype=float), (n_joints,)).copy()


@dataclass(frozen=True)
class Redundancy:
    """A 7-joint arm's redundant joint, held at one value for the whole task (SEEDS 003)."""

    joint: str
    value_deg: float = DEFAULT_REDUNDANT_VALUE_DEG


@dataclass(frozen=True)
class Task:
    """A validated task. ``robot`` is a bundled name or an absolute URDF path."""

    robot: str
    moves: tuple[Move, ...]
    start_joints_deg: tuple[float, ...] | None = None
    start_pose: PoseSpec | None = None
    start_config: str | None = None
    tip: str | None = None
    tool_xyz: tuple[float, float, float] = DEFAULT_TOOL
    tool_rpy_deg: tuple[float, float, float] = DEFAULT_TOOL
    singularity: SingularitySettings = field(default_factory=SingularitySettings)
    limits: Limits = field(default_factory=Limits)
    period_s: float = DEFAULT_PERIOD_S
    redundancy: Redundancy | None = None
    tool_geometry: tuple[Shape, ...] = ()  # the tool's shapes, in the tip frame (the body `tool`)
    cell: tuple[Shape, ...] = ()  # fixed obstacles in the base frame
    collision: CollisionSettings | None = None  # None: the task has no cell, tool geometry or collision key

    def joint_speed_scale(self, move: Move | None = None) -> float:
        """The fraction of the URDF's joint speed limits the trajectory (or ``move``) may use:
        ``limits.velocity_scale``, times a PTP's own ``velocity_scale``."""
        own = move.velocity_scale if move is not None and move.kind == "ptp" else 1.0
        return self.limits.velocity_scale * own

    def with_method(self, method: str) -> Task:
        """The same task planned with another crossing method (a name the planner checks:
        :func:`singplan.planning.crossing.registry.check_name`)."""
        settings = replace(self.singularity, method=method)
        return Task(**{**self.__dict__, "singularity": settings})

    def to_mapping(self) -> dict[str, Any]:
        """The validated task as a YAML-v1 mapping, defaults filled in (for trajectory.json)."""
        start: dict[str, Any] = ({"joints_deg": list(self.start_joints_deg)} if self.start_joints_deg is not None
                                 else {"pose": _pose_mapping(self.start_pose)})
        if self.start_config:
            start["config"] = self.start_config
        acc = self.limits.acceleration_rad_s2
        tool: dict[str, Any] = {"xyz": list(self.tool_xyz), "rpy_deg": list(self.tool_rpy_deg)}
        if self.tool_geometry:
            tool["geometry"] = [s.to_mapping(named=False) for s in self.tool_geometry]
        out: dict[str, Any] = {
            "robot": self.robot,
            "tool": tool,
            "start": start,
            "moves": [_move_mapping(m) for m in self.moves],
            "singularity": {**asdict(self.singularity), "zone": asdict(self.singularity.zone)},
            "limits": {"velocity_scale": self.limits.velocity_scale,
                       "acceleration": acc[0] if len(acc) == 1 else list(acc),
                       **({"torque_scale": self.limits.torque_scale} if self.limits.torque_scale is not None
                          else {}),
                       **({"jerk": _one_or_list(self.limits.jerk_rad_s3)} if self.limits.jerk_rad_s3 is not None
                          else {}),
                       "ptp_time_law": self.limits.ptp_time_law},
            "output": {"period": self.period_s},
        }
        if self.tip:
            out["tip"] = self.tip
        if self.redundancy is not None:
            out["redundancy"] = asdict(self.redundancy)
        if self.cell:
            out["cell"] = [s.to_mapping() for s in self.cell]
        if self.collision is not None:
            out["collision"] = self.collision.to_mapping()
        return out


def _pose_mapping(pose: PoseSpec | None) -> dict[str, Any]:
    assert pose is not None  # a validated task has one start form
    out: dict[str, Any] = {"xyz": list(pose.xyz)}
    if pose.rpy_deg is not None:
        out["rpy_deg"] = list(pose.rpy_deg)
    return out


def _move_mapping(move: Move) -> dict[str, Any]:
    spec: dict[str, Any] = {}
    if move.to_joints_deg is not None:
        spec["to"] = {"joints_deg": list(move.to_joints_deg)}
    else:
        spec["to"] = _pose_mapping(move.to)
    if move.via_xyz is not None:
        spec["via"] = {"xyz": list(move.via_xyz)}
    if move.kind == "ptp":
        spec["velocity_scale"] = move.velocity_scale
    else:
        spec["speed"] = move.speed_m_s
    spec["config"] = move.config
    if move.weave is not None:
        spec["weave"] = move.weave.to_mapping()
    if move.blend_mm > 0:
        spec["blend_mm"] = move.blend_mm
    return {move.kind: spec}


def _floats(values: Sequence[Any]) -> tuple[float, float, float]:
    x, y, z = values
    return float(x), float(y), float(z)


def _one_or_list(values: tuple[float, ...]) -> float | list[float]:
    return values[0] if len(values) == 1 else list(values)


# -- field checks ----------------------------------------------------------------------------


def _path_text(path: str) -> str:
    """A file path for a message: as it is when printable, else quoted; shortened either way."""
    return _short(path if path.isprintable() else repr(path), 200)


def _check_mapping(where: str, value: Any) -> None:
    if not isinstance(value, Mapping):
        raise TaskError(where, f"expected a mapping, got {_describe(value)}")


def _optional_mapping(parent: Mapping[str, Any], key: str, where: str) -> Mapping[str, Any]:
    """An optional sub-mapping; absent or null is empty, any other non-mapping is bad input."""
    value = parent.get(key)
    if value is None:
        return {}
    _check_mapping(_join(where, key), value)
    return value


def _check_keys(where: str, value: Mapping[str, Any], required: Sequence[str] = (),
                optional: Sequence[str] = ()) -> None:
    allowed = (*required, *optional)
    for key in value:
        if key not in allowed:
            close = difflib.get_close_matches(str(key)[:MAX_NAME_CHARS], allowed, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; allowed: {', '.join(allowed)}"
            raise TaskError(_join(where, _key_text(key)), f"unknown key{hint}")
    for key in required:
        if key not in value:
            raise TaskError(_join(where, key), "missing (required)")
        if value[key] is None:  # the key is there (`moves:` with nothing after it): say so, not "missing"
            raise TaskError(_join(where, key), f"empty (null); give {_NULL_HINTS.get(key, 'a value')}")


# what a required key takes, for the message when it is given empty
_NULL_HINTS = {
    "robot": "a bundled robot name (singplan robots) or the path of a .urdf",
    "start": "a mapping with joints_deg or pose",
    "moves": "a list of moves",
    "to": "the target mapping",
    "via": "a mapping with xyz",
    "xyz": "3 numbers [m]",
    "rpy_deg": "3 numbers [deg]",
    "joints_deg": "one number per joint [deg]",
    "amplitude_mm": "a length [mm]",
    "wavelength_mm": "a length [mm]",
    "joint": "a joint name",
}


def _describe(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10**40:
        return f"an integer of {len(str(abs(value))) if abs(value) < 10**4000 else 'over 4000'} digits"
    text = repr(value) if not isinstance(value, (list, tuple, dict)) or len(value) <= 20 else f"{len(value)} items"
    return f"{type(value).__name__} {_short(text, 43)}"


def _number(where: str, value: Any, bounds: Range) -> float:
    return _in_range(where, _as_number(where, value, bounds), bounds)


def _as_number(where: str, value: Any, bounds: Range) -> float:
    """``value`` as a float: a number (not a bool) that a float holds; its range is not checked."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TaskError(where, f"expected a number, got {_describe(value)}")
    if isinstance(value, int) and abs(value) > 1e300:  # exact comparison: no float() overflow
        raise TaskError(where, f"number too large ({_describe(value)}); at most {bounds.high:g} {bounds.unit}")
    return float(value)


def _in_range(where: str, x: float, bounds: Range) -> float:
    unit = f" {bounds.unit}" if bounds.unit else ""
    if not math.isfinite(x):
        raise TaskError(where, f"must be finite, got {x}")
    if bounds.low > 0 and x <= 0:
        raise TaskError(where, f"must be positive, got {x:g}")
    if x < bounds.low:
        raise TaskError(where, f"must be at least {bounds.low:g}{unit}, got {x:g}")
    if x > bounds.high:
        raise TaskError(where, f"must be at most {bounds.high:g}{unit}, got {x:g}")
    return x


def check_vector(where: str, value: Any, n: int, bounds: Range) -> tuple[float, ...]:
    """``value`` as ``n`` finite numbers inside ``bounds``; a TaskError naming ``where[i]`` otherwise
    (task fields, and the CLI's numeric flags)."""
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)):
        raise TaskError(where, f"expected {n} numbers, got {_describe(value)}")
    if len(value) != n:
        raise TaskError(where, f"expected {n} numbers, got {len(value)}")
    return tuple(_number(f"{where}[{i}]", v, bounds) for i, v in enumerate(value))


def check_triple(where: str, value: Any, bounds: Range) -> tuple[float, float, float]:
    """:func:`check_vector` of three numbers (a position or roll-pitch-yaw), typed as a triple."""
    x, y, z = check_vector(where, value, 3, bounds)
    return x, y, z


def _string(where: str, value: Any, max_chars: int = MAX_NAME_CHARS) -> str:
    """A non-empty single-line string of at most ``max_chars`` characters, stripped."""
    if not isinstance(value, str) or not value.strip():
        raise TaskError(where, f"expected a non-empty string, got {_describe(value)}")
    if len(value) > max_chars:
        raise TaskError(where, f"{len(value)} characters is over the cap of {max_chars}: {_short(repr(value), 43)}")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise TaskError(where, f"contains the control character U+{ord(bad):04X}: {_short(repr(value), 43)}")
    return value.strip()


def check_choice(where: str, value: Any, choices: Sequence[str]) -> str:
    """``value``, one of ``choices``; else bad input naming ``where``, with the valid choices and the closest one."""
    text = _string(where, value)
    if text not in choices:
        close = difflib.get_close_matches(text, choices, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise TaskError(where, f"unknown value {_short(repr(text), 43)}{hint}; valid: {', '.join(choices)}")
    return text



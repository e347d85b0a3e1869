"""Task input: the YAML format version 1 of DESIGN.md and its Python equivalent.

``load_task(path)`` reads and validates a YAML file; ``parse_task(mapping)`` validates a
mapping built in Python. Every problem raises :class:`~singplan.errors.TaskError` naming the
field path (``moves[2].lin.to.xyz: expected 3 numbers, got 2``). Checks that need the robot
(joint counts, joint limits) live in :func:`check_against_robot`.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from singplan.configuration import parse_configuration
from singplan.errors import TaskError
from singplan.robot import Robot

MAX_MOVES = 10_000
MAX_OUTPUT_SAMPLES = 10_000_000
MAX_FILE_BYTES = 8 * 1024 * 1024
METHODS = ("auto", "wrist-joint", "axis", "exact", "dls", "average", "ptp", "stop")
MAX_COORDINATE_M = 100.0
MAX_SPEED_M_S = 10.0
DEFAULT_SPEED_M_S = 0.25


@dataclass(frozen=True)
class PoseSpec:
    """A Cartesian target: position [m] in the base frame, optional orientation (held if None)."""

    xyz: tuple[float, float, float]
    rpy_deg: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Move:
    """One motion. ``kind`` is "lin", "circ" or "ptp"; PTP targets may be joints or a pose."""

    kind: str
    to: PoseSpec | None = None
    to_joints_deg: tuple[float, ...] | None = None
    via_xyz: tuple[float, float, float] | None = None  # CIRC only
    speed_m_s: float = DEFAULT_SPEED_M_S  # LIN / CIRC TCP speed
    velocity_scale: float = 1.0  # PTP fraction of the joint speed limits
    config: str = "auto"  # "auto" | "keep" | a label like "F U N"


@dataclass(frozen=True)
class ZoneThresholds:
    """Detection thresholds of singular zones."""

    wrist_deg: float = 5.0
    shoulder_mm: float = 20.0
    elbow_deg: float = 5.0


@dataclass(frozen=True)
class SingularitySettings:
    method: str = "auto"
    orientation_tolerance_deg: float = 5.0
    position_tolerance_mm: float = 0.01
    zone: ZoneThresholds = field(default_factory=ZoneThresholds)


@dataclass(frozen=True)
class Limits:
    velocity_scale: float = 1.0
    acceleration_rad_s2: tuple[float, ...] = (10.0,)  # one value for all joints, or one per joint


@dataclass(frozen=True)
class Task:
    """A validated task. ``robot`` is a bundled name or an absolute URDF path."""

    robot: str
    moves: tuple[Move, ...]
    start_joints_deg: tuple[float, ...] | None = None
    start_pose: PoseSpec | None = None
    start_config: str | None = None
    tip: str | None = None
    tool_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    singularity: SingularitySettings = field(default_factory=SingularitySettings)
    limits: Limits = field(default_factory=Limits)
    period_s: float = 0.004

    def with_method(self, method: str) -> Task:
        """The same task planned with another crossing method."""
        _check_choice("singularity.method", method, METHODS)
        settings = SingularitySettings(method, self.singularity.orientation_tolerance_deg,
                                       self.singularity.position_tolerance_mm, self.singularity.zone)
        return Task(**{**self.__dict__, "singularity": settings})

    def to_mapping(self) -> dict[str, Any]:
        """The validated task as a YAML-v1 mapping, defaults filled in (for trajectory.json)."""
        start: dict[str, Any] = ({"joints_deg": list(self.start_joints_deg)} if self.start_joints_deg is not None
                                 else {"pose": _pose_mapping(self.start_pose)})
        if self.start_config:
            start["config"] = self.start_config
        acc = self.limits.acceleration_rad_s2
        out: dict[str, Any] = {
            "robot": self.robot,
            "tool": {"xyz": list(self.tool_xyz), "rpy_deg": list(self.tool_rpy_deg)},
            "start": start,
            "moves": [_move_mapping(m) for m in self.moves],
            "singularity": {**asdict(self.singularity), "zone": asdict(self.singularity.zone)},
            "limits": {"velocity_scale": self.limits.velocity_scale,
                       "acceleration": acc[0] if len(acc) == 1 else list(acc)},
            "output": {"period": self.period_s},
        }
        if self.tip:
            out["tip"] = self.tip
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
    return {move.kind: spec}


# -- reading ---------------------------------------------------------------------------------


class _NoAliasLoader(yaml.SafeLoader):
    """SafeLoader that refuses anchors/aliases: no billion-laughs expansion, tasks need none."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise TaskError("", f"YAML aliases are not allowed in a task (line {event.start_mark.line + 1})")
        return super().compose_node(parent, index)


def load_task(path: str | Path) -> Task:
    """Read and validate a task file (YAML v1)."""
    p = Path(path)
    if not p.is_file():
        raise TaskError("", f"{p}: no such task file")
    if p.stat().st_size > MAX_FILE_BYTES:
        raise TaskError("", f"{p}: {p.stat().st_size} bytes is over the {MAX_FILE_BYTES}-byte cap for a task file")
    try:
        doc = yaml.load(p.read_text(encoding="utf-8"), Loader=_NoAliasLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise TaskError("", f"{p.name}: not valid YAML{where}: {problem}") from None
    except UnicodeDecodeError:
        raise TaskError("", f"{p.name}: not a UTF-8 text file") from None
    return parse_task(doc, base_dir=p.parent)


def parse_task(doc: Any, base_dir: Path | None = None) -> Task:
    """Validate a task mapping (the YAML document, or built in Python)."""
    if doc is None:
        raise TaskError("", "the task is empty; it needs at least robot, start and moves")
    if not isinstance(doc, Mapping):
        raise TaskError("", f"the task must be a mapping of keys, got {type(doc).__name__}")
    _check_keys("", doc, required=("robot", "start", "moves"),
                optional=("tip", "tool", "singularity", "limits", "output"))
    robot = _robot_ref(doc["robot"], base_dir)
    tip = _string("tip", doc["tip"]) if doc.get("tip") is not None else None
    tool = doc.get("tool") or {}
    _check_mapping("tool", tool)
    _check_keys("tool", tool, optional=("xyz", "rpy_deg"))
    start_joints, start_pose, start_config = _start(doc["start"])
    moves = _moves(doc["moves"])
    return Task(
        robot=robot, moves=moves, start_joints_deg=start_joints, start_pose=start_pose, start_config=start_config,
        tip=tip,
        tool_xyz=_vector("tool.xyz", tool.get("xyz", (0, 0, 0)), 3, bound=10.0),  # type: ignore[arg-type]
        tool_rpy_deg=_vector("tool.rpy_deg", tool.get("rpy_deg", (0, 0, 0)), 3, bound=720.0),  # type: ignore[arg-type]
        singularity=_singularity(doc.get("singularity") or {}),
        limits=_limits(doc.get("limits") or {}),
        period_s=_output_period(doc.get("output") or {}),
    )


# -- field checks ----------------------------------------------------------------------------


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _check_mapping(where: str, value: Any) -> None:
    if not isinstance(value, Mapping):
        raise TaskError(where, f"expected a mapping, got {_describe(value)}")


def _check_keys(where: str, value: Mapping[str, Any], required: Sequence[str] = (),
                optional: Sequence[str] = ()) -> None:
    allowed = (*required, *optional)
    for key in value:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; allowed: {', '.join(allowed)}"
            raise TaskError(_join(where, str(key)), f"unknown key{hint}")
    for key in required:
        if key not in value or value[key] is None:
            raise TaskError(_join(where, key), "missing (required)")


def _describe(value: Any) -> str:
    if value is None:
        return "nothing"
    text = repr(value)
    return f"{type(value).__name__} {text[:40]}{'...' if len(text) > 40 else ''}"


def _number(where: str, value: Any, *, positive: bool = False, low: float | None = None,
            high: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TaskError(where, f"expected a number, got {_describe(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise TaskError(where, f"must be finite, got {x}")
    if positive and x <= 0:
        raise TaskError(where, f"must be positive, got {x:g}")
    if low is not None and x < low:
        raise TaskError(where, f"must be at least {low:g}, got {x:g}")
    if high is not None and x > high:
        raise TaskError(where, f"must be at most {high:g}, got {x:g}")
    return x


def _vector(where: str, value: Any, n: int, bound: float) -> tuple[float, ...]:
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)):
        raise TaskError(where, f"expected {n} numbers, got {_describe(value)}")
    if len(value) != n:
        raise TaskError(where, f"expected {n} numbers, got {len(value)}")
    return tuple(_number(f"{where}[{i}]", v, low=-bound, high=bound) for i, v in enumerate(value))


def _string(where: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise TaskError(where, f"expected a non-empty string, got {_describe(value)}")
    return value.strip()


def _check_choice(where: str, value: Any, choices: Sequence[str]) -> str:
    text = _string(where, value)
    if text not in choices:
        close = difflib.get_close_matches(text, choices, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise TaskError(where, f"unknown value {text!r}{hint}; valid: {', '.join(choices)}")
    return text


def _robot_ref(value: Any, base_dir: Path | None) -> str:
    name = _string("robot", value)
    if name.lower().endswith(".urdf"):
        path = Path(name).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        if not path.is_file():
            raise TaskError("robot", f"URDF file {path} does not exist")
        return str(path.resolve())
    return name


def _pose(where: str, value: Any, need_rpy: bool = False) -> PoseSpec:
    _check_mapping(where, value)
    _check_keys(where, value, required=("xyz", *(("rpy_deg",) if need_rpy else ())), optional=("rpy_deg",))
    xyz = _vector(f"{where}.xyz", value["xyz"], 3, bound=MAX_COORDINATE_M)
    rpy = value.get("rpy_deg")
    rpy_t = _vector(f"{where}.rpy_deg", rpy, 3, bound=720.0) if rpy is not None else None
    return PoseSpec(xyz, rpy_t)  # type: ignore[arg-type]


def _joints(where: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)) or not value:
        raise TaskError(where, f"expected a list of joint values [deg], got {_describe(value)}")
    if len(value) > 64:
        raise TaskError(where, f"{len(value)} joint values is more than any arm has")
    return tuple(_number(f"{where}[{i}]", v, low=-3600.0, high=3600.0) for i, v in enumerate(value))


def _config(where: str, value: Any) -> str:
    text = _string(where, value)
    if text in ("auto", "keep"):
        return text
    return parse_configuration(text, where).label


def _start(value: Any) -> tuple[tuple[float, ...] | None, PoseSpec | None, str | None]:
    _check_mapping("start", value)
    _check_keys("start", value, optional=("joints_deg", "pose", "config"))
    has_joints, has_pose = value.get("joints_deg") is not None, value.get("pose") is not None
    if has_joints == has_pose:
        raise TaskError("start", "give exactly one of joints_deg or pose" + (" (both given)" if has_joints else ""))
    config = _config("start.config", value["config"]) if value.get("config") is not None else None
    if has_joints:
        if config is not None:
            raise TaskError("start.config", "only with start.pose (joints already fix the configuration)")
        return _joints("start.joints_deg", value["joints_deg"]), None, None
    if config in ("auto", "keep"):
        raise TaskError("start.config", f"expected a configuration like 'F U N', got {config!r}")
    return None, _pose("start.pose", value["pose"], need_rpy=True), config


def _moves(value: Any) -> tuple[Move, ...]:
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)):
        raise TaskError("moves", f"expected a list of moves, got {_describe(value)}")
    if not value:
        raise TaskError("moves", "the list is empty; give at least one move")
    if len(value) > MAX_MOVES:
        raise TaskError("moves", f"{len(value)} moves is over the cap of {MAX_MOVES}")
    return tuple(_move(f"moves[{i}]", m) for i, m in enumerate(value))


def _move(where: str, value: Any) -> Move:
    _check_mapping(where, value)
    if len(value) != 1:
        raise TaskError(where, f"expected one of lin, circ, ptp as the only key, got {list(value)}")
    kind = str(next(iter(value)))
    _check_choice(f"{where} kind", kind, ("lin", "circ", "ptp"))
    where = f"{where}.{kind}"
    spec = value[kind]
    _check_mapping(where, spec)
    if kind == "ptp":
        _check_keys(where, spec, required=("to",), optional=("velocity_scale", "config"))
    else:
        _check_keys(where, spec, required=("to", *(("via",) if kind == "circ" else ())),
                    optional=("speed", "config"))
    config = _config(f"{where}.config", spec["config"]) if spec.get("config") is not None else "auto"
    to = spec["to"]
    _check_mapping(f"{where}.to", to)
    if kind == "ptp" and "joints_deg" in to:
        _check_keys(f"{where}.to", to, required=("joints_deg",))
        return Move(kind, to_joints_deg=_joints(f"{where}.to.joints_deg", to["joints_deg"]),
                    velocity_scale=_scale(f"{where}.velocity_scale", spec.get("velocity_scale", 1.0)), config=config)
    target = _pose(f"{where}.to", to)
    if kind == "ptp":
        return Move(kind, to=target, velocity_scale=_scale(f"{where}.velocity_scale", spec.get("velocity_scale", 1.0)),
                    config=config)
    speed = _number(f"{where}.speed", spec.get("speed", DEFAULT_SPEED_M_S), positive=True, high=MAX_SPEED_M_S)
    via = None
    if kind == "circ":
        via_spec = spec["via"]
        _check_mapping(f"{where}.via", via_spec)
        _check_keys(f"{where}.via", via_spec, required=("xyz",))
        via = _vector(f"{where}.via.xyz", via_spec["xyz"], 3, bound=MAX_COORDINATE_M)
    return Move(kind, to=target, via_xyz=via, speed_m_s=speed, config=config)  # type: ignore[arg-type]


def _scale(where: str, value: Any) -> float:
    return _number(where, value, positive=True, high=1.0)


def _singularity(value: Any) -> SingularitySettings:
    _check_mapping("singularity", value)
    _check_keys("singularity", value,
                optional=("method", "orientation_tolerance_deg", "position_tolerance_mm", "zone"))
    zone = value.get("zone") or {}
    _check_mapping("singularity.zone", zone)
    _check_keys("singularity.zone", zone, optional=("wrist_deg", "shoulder_mm", "elbow_deg"))
    defaults = ZoneThresholds()
    return SingularitySettings(
        method=_check_choice("singularity.method", value.get("method", "auto"), METHODS),
        orientation_tolerance_deg=_number("singularity.orientation_tolerance_deg",
                                          value.get("orientation_tolerance_deg", 5.0), positive=True, high=180.0),
        position_tolerance_mm=_number("singularity.position_tolerance_mm", value.get("position_tolerance_mm", 0.01),
                                      positive=True, high=1000.0),
        zone=ZoneThresholds(
            wrist_deg=_number("singularity.zone.wrist_deg", zone.get("wrist_deg", defaults.wrist_deg),
                              positive=True, high=90.0),
            shoulder_mm=_number("singularity.zone.shoulder_mm", zone.get("shoulder_mm", defaults.shoulder_mm),
                                positive=True, high=1000.0),
            elbow_deg=_number("singularity.zone.elbow_deg", zone.get("elbow_deg", defaults.elbow_deg),
                              positive=True, high=90.0)))


def _limits(value: Any) -> Limits:
    _check_mapping("limits", value)
    _check_keys("limits", value, optional=("velocity_scale", "acceleration"))
    acc = value.get("acceleration", 10.0)
    if isinstance(acc, Sequence) and not isinstance(acc, (str, bytes)):
        if not acc or len(acc) > 64:
            raise TaskError("limits.acceleration", "expected a number or one number per joint")
        accel = tuple(_number(f"limits.acceleration[{i}]", a, positive=True, high=1e4) for i, a in enumerate(acc))
    else:
        accel = (_number("limits.acceleration", acc, positive=True, high=1e4),)
    return Limits(velocity_scale=_scale("limits.velocity_scale", value.get("velocity_scale", 1.0)),
                  acceleration_rad_s2=accel)


def _output_period(value: Any) -> float:
    _check_mapping("output", value)
    _check_keys("output", value, optional=("period",))
    return _number("output.period", value.get("period", 0.004), positive=True, low=1e-4, high=1.0)


# -- robot-dependent checks ------------------------------------------------------------------


def check_against_robot(task: Task, robot: Robot) -> None:
    """Joint counts and joint limits of every joint-space value in the task."""
    n = robot.n_joints
    if task.start_joints_deg is not None:
        _check_joint_values("start.joints_deg", task.start_joints_deg, robot)
    for i, move in enumerate(task.moves):
        if move.to_joints_deg is not None:
            _check_joint_values(f"moves[{i}].ptp.to.joints_deg", move.to_joints_deg, robot)
    acc = task.limits.acceleration_rad_s2
    if len(acc) not in (1, n):
        raise TaskError("limits.acceleration", f"expected 1 or {n} numbers for {robot.name}, got {len(acc)}")


def _check_joint_values(where: str, values_deg: tuple[float, ...], robot: Robot) -> None:
    if len(values_deg) != robot.n_joints:
        raise TaskError(where, f"expected {robot.n_joints} joint values for {robot.name}, got {len(values_deg)}")
    for j, v in enumerate(values_deg):
        rad = math.radians(v)
        lo, hi = robot.lower_rad[j], robot.upper_rad[j]
        if rad < lo - 1e-9 or rad > hi + 1e-9:
            raise TaskError(f"{where}[{j}]", f"{robot.joint_names[j]} = {v:g} deg is outside its limits "
                                             f"[{math.degrees(lo):g}, {math.degrees(hi):g}] deg")

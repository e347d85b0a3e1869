"""Task loading: a YAML file or a mapping -> :class:`~singplan.task.schema.Task`, with field-named errors.

The file is scanned as YAML events before anything is built (size, depth, node count, key and
scalar length), then parsed with the safe loader, then checked field by field; every error names
the field (``moves[3].lin.speed``) and the valid values or range. The checks that need the robot
(joint counts, labels, limits) are in :func:`check_against_robot`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from singplan.errors import TaskError
from singplan.kinematics.configuration import parse_configuration
from singplan.kinematics.files import FileRefusedError, read_bounded_text
from singplan.kinematics.robot import Robot
from singplan.kinematics.shapes import MESH_SUFFIXES, SHAPE_KINDS, TOOL_BODY, CollisionSettings, Shape
from singplan.kinematics.yamldoc import YamlLimits, load_yaml
from singplan.task.schema import (
    ACCELERATION_RAD_S2,
    ANGLE_DEG,
    BLEND_MM,
    CLEARANCE_MM,
    COORDINATE_M,
    DEFAULT_ACCELERATION_RAD_S2,
    DEFAULT_BLEND_MM,
    DEFAULT_CLEARANCE_MM,
    DEFAULT_CONFIG,
    DEFAULT_DEVIATION_COST_PERCENT,
    DEFAULT_METHOD,
    DEFAULT_ORIENTATION_TOLERANCE_DEG,
    DEFAULT_PERIOD_S,
    DEFAULT_POSITION_TOLERANCE_MM,
    DEFAULT_PTP_TIME_LAW,
    DEFAULT_REDUNDANT_VALUE_DEG,
    DEFAULT_SPEED_M_S,
    DEFAULT_TOOL,
    DEFAULT_VELOCITY_SCALE,
    DEFAULT_WEAVE_PATTERN,
    DEFAULT_ZONE_ELBOW_DEG,
    DEFAULT_ZONE_SHOULDER_MM,
    DEFAULT_ZONE_WRIST_DEG,
    DEVIATION_COST_PERCENT,
    JERK_RAD_S3,
    JOINT_DEG,
    MAX_CELL_SHAPES,
    MAX_DEPTH,
    MAX_FILE_BYTES,
    MAX_JOINTS,
    MAX_KEY_CHARS,
    MAX_MOVES,
    MAX_NAME_CHARS,
    MAX_PATH_CHARS,
    MAX_SCALAR_CHARS,
    MAX_TOOL_SHAPES,
    MAX_YAML_NODES,
    MESH_SCALE,
    ORIENTATION_TOLERANCE_DEG,
    PERIOD_S,
    POSITION_TOLERANCE_MM,
    PTP_TIME_LAWS,
    SHAPE_SIZE_M,
    SPEED_M_S,
    TOOL_OFFSET_M,
    TORQUE_SCALE,
    VELOCITY_SCALE,
    WEAVE_AMPLITUDE_MM,
    WEAVE_PATTERNS,
    WEAVE_WAVELENGTH_MM,
    ZONE_ANGLE_DEG,
    ZONE_SHOULDER_MM,
    Limits,
    Move,
    PoseSpec,
    Range,
    Redundancy,
    SingularitySettings,
    Task,
    Weave,
    ZoneThresholds,
    _as_number,
    _check_keys,
    _check_mapping,
    _describe,
    _key_text,
    _number,
    _optional_mapping,
    _path_text,
    _short,
    _string,
    check_choice,
    check_triple,
)

_TASK_YAML = YamlLimits("a task", MAX_DEPTH, MAX_YAML_NODES, MAX_KEY_CHARS, MAX_SCALAR_CHARS)


def load_task(path: str | Path) -> Task:
    """Read and validate a task file (YAML v1).

    The YAML event stream is scanned first (iteratively, so no input can exhaust the stack):
    nesting deeper than :data:`MAX_DEPTH`, more than :data:`MAX_YAML_NODES` nodes, aliases,
    merge keys, keys given twice in one mapping, huge scalars and more than one document are
    refused with the key path and line before PyYAML builds anything.
    """
    p = Path(path)
    name = _path_text(p.name)
    doc = load_yaml(_read_text(p), _TASK_YAML,
                    lambda field, reason: TaskError(field, reason if field else f"{name}: {reason}"))
    if doc is None:
        raise TaskError("", f"{_path_text(p.name)}: the task file is empty; it needs at least robot, start and moves")
    if not isinstance(doc, Mapping):
        raise TaskError("", f"{_path_text(p.name)}: the task must be a mapping of keys (robot, start, moves, ...), "
                            f"got {_describe(doc)}")
    return parse_task(doc, base_dir=p.parent)


def _read_text(p: Path) -> str:
    """The file's text (:func:`~singplan.kinematics.files.read_bounded_text`: a regular UTF-8 file
    within :data:`MAX_FILE_BYTES`), refused when it holds nothing."""
    try:
        text = read_bounded_text(p, MAX_FILE_BYTES, "task file")
    except FileRefusedError as exc:
        raise TaskError("", str(exc)) from None
    if not text.strip():
        raise TaskError("", f"{_path_text(str(p))}: the task file is empty; it needs at least robot, start and moves")
    return text


def parse_task(doc: Any, base_dir: Path | None = None) -> Task:
    """Validate a task mapping (the YAML document, or built in Python)."""
    if doc is None:
        raise TaskError("", "the task is empty; it needs at least robot, start and moves")
    if not isinstance(doc, Mapping):
        raise TaskError("", f"the task must be a mapping of keys, got {type(doc).__name__}")
    _check_keys("", doc, required=("robot", "start", "moves"),
                optional=("tip", "tool", "singularity", "limits", "output", "redundancy", "cell", "collision"))
    robot = _robot_ref(doc["robot"], base_dir)
    tip = _string("tip", doc["tip"]) if doc.get("tip") is not None else None
    tool = _optional_mapping(doc, "tool", "")
    _check_keys("tool", tool, optional=("xyz", "rpy_deg", "geometry"))
    start_joints, start_pose, start_config = _start(doc["start"])
    moves = _moves(doc["moves"])
    tool_geometry = _shapes("tool.geometry", tool.get("geometry"), MAX_TOOL_SHAPES, base_dir)
    cell = _cell(doc.get("cell"), base_dir)
    checking = "cell" in doc or "collision" in doc or "geometry" in tool  # DESIGN "Collision": checking is on
    return Task(
        robot=robot, moves=moves, start_joints_deg=start_joints, start_pose=start_pose, start_config=start_config,
        tip=tip,
        tool_xyz=check_triple("tool.xyz", tool.get("xyz", DEFAULT_TOOL), TOOL_OFFSET_M),
        tool_rpy_deg=check_triple("tool.rpy_deg", tool.get("rpy_deg", DEFAULT_TOOL), ANGLE_DEG),
        singularity=_singularity(_optional_mapping(doc, "singularity", "")),
        limits=_limits(_optional_mapping(doc, "limits", "")),
        period_s=_output_period(_optional_mapping(doc, "output", "")),
        redundancy=_redundancy(doc["redundancy"]) if doc.get("redundancy") is not None else None,
        tool_geometry=tool_geometry, cell=cell,
        collision=_collision(_optional_mapping(doc, "collision", ""), cell, base_dir) if checking else None,
    )


def _shapes(where: str, value: Any, cap: int, base_dir: Path | None) -> tuple[Shape, ...]:
    """A list of shapes (``cell`` or ``tool.geometry``); absent or null is none."""
    if value is None:
        return ()
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)):
        raise TaskError(where, f"expected a list of shapes, got {_describe(value)}")
    if len(value) > cap:
        raise TaskError(where, f"{len(value)} shapes is over the cap of {cap}")
    return tuple(_shape(f"{where}[{i}]", v, base_dir) for i, v in enumerate(value))


def _cell(value: Any, base_dir: Path | None) -> tuple[Shape, ...]:
    """The cell's shapes with their unique names (default ``cell[i]``)."""
    shapes = _shapes("cell", value, MAX_CELL_SHAPES, base_dir)
    seen: dict[str, str] = {}
    named = []
    for shape in shapes:
        name = shape.name or shape.field
        if name == TOOL_BODY:
            raise TaskError(f"{shape.field}.name", f"{TOOL_BODY!r} names the tool's geometry; give the shape "
                                                   "another name")
        if name in seen:
            raise TaskError(f"{shape.field}.name", f"{name!r} is used twice ({seen[name]} and {shape.field}); "
                                                   "cell names are unique")
        seen[name] = shape.field
        named.append(replace(shape, name=name))
    return tuple(named)


def _shape(where: str, value: Any, base_dir: Path | None) -> Shape:
    """One shape: exactly one of box, cylinder, sphere, mesh, with its pose (and a name)."""
    _check_mapping(where, value)
    _check_keys(where, value, optional=("name", *SHAPE_KINDS, "xyz", "rpy_deg"))
    kinds = [k for k in SHAPE_KINDS if k in value]
    if len(kinds) != 1:
        got = f"got {', '.join(kinds)}" if kinds else "got none"
        raise TaskError(where, f"needs exactly one shape kind of {', '.join(SHAPE_KINDS)}; {got}")
    kind = kinds[0]
    w = f"{where}.{kind}"
    body = value[kind]
    _check_mapping(w, body)
    xyz = check_triple(f"{where}.xyz", value.get("xyz", DEFAULT_TOOL), COORDINATE_M)
    rpy = check_triple(f"{where}.rpy_deg", value.get("rpy_deg", DEFAULT_TOOL), ANGLE_DEG)
    name = _string(f"{where}.name", value["name"]) if value.get("name") is not None else ""
    if kind == "box":
        _check_keys(w, body, required=("size",))
        size = check_triple(f"{w}.size", body["size"], SHAPE_SIZE_M)
        return Shape("box", size, xyz, rpy, name=name, field=where)
    if kind == "cylinder":
        _check_keys(w, body, required=("radius", "length"))
        dims = (_number(f"{w}.radius", body["radius"], SHAPE_SIZE_M), _number(f"{w}.length", body["length"],
                                                                                SHAPE_SIZE_M))
        return Shape("cylinder", dims, xyz, rpy, name=name, field=where)
    if kind == "sphere":
        _check_keys(w, body, required=("radius",))
        return Shape("sphere", (_number(f"{w}.radius", body["radius"], SHAPE_SIZE_M),), xyz, rpy, name=name,
                     field=where)
    _check_keys(w, body, required=("file",), optional=("scale",))
    scale = body.get("scale", 1.0)
    if isinstance(scale, Sequence) and not isinstance(scale, (str, bytes)):
        scales = check_triple(f"{w}.scale", scale, MESH_SCALE)
    else:
        one = _number(f"{w}.scale", scale, MESH_SCALE)
        scales = (one, one, one)
    return Shape("mesh", (), xyz, rpy, _mesh_file(f"{w}.file", body["file"], base_dir), scales, name=name,
                 field=where)


def _mesh_file(where: str, value: Any, base_dir: Path | None) -> str:
    """An existing STL or OBJ file (relative to the task file's folder), as an absolute path."""
    name = _string(where, value, max_chars=MAX_PATH_CHARS)
    path = _task_relative(name, base_dir)
    if Path(name).suffix.lower() not in MESH_SUFFIXES:
        raise TaskError(where, f"{_path_text(name)} is not an STL or OBJ file (the name must end in "
                               f"{' or '.join(MESH_SUFFIXES)})")
    return _existing_file(where, name, path, "mesh file")


def _task_relative(name: str, base_dir: Path | None) -> Path:
    """A path a task names: absolute, or relative to the task file's folder (the working folder
    for a task given as a mapping)."""
    path = Path(name).expanduser()
    return path if path.is_absolute() else (base_dir if base_dir is not None else Path.cwd()) / path


def _existing_file(where: str, name: str, path: Path, what: str) -> str:
    """An existing path that is no folder, as an absolute path (what it is, a FIFO or a device, is for
    the bounded reader to refuse: kinematics.files)."""
    try:
        if path.is_dir():
            raise TaskError(where, f"{_path_text(name)} is a directory, not a {what}")
        if not path.exists():
            raise TaskError(where, f"{what} {_path_text(name)} does not exist{_looked_at(name, path)}")
        return str(path.resolve())
    except OSError as exc:  # e.g. a name too long for the file system
        raise TaskError(where, f"{what} {_path_text(str(path))} cannot be read ({exc.strerror})") from None


def _collision(value: Mapping[str, Any], cell: tuple[Shape, ...], base_dir: Path | None) -> CollisionSettings:
    """The ``collision`` key (absent or null: the defaults); ``allow`` names are checked against the robot later."""
    _check_keys("collision", value, optional=("clearance_mm", "self", "srdf", "allow"))
    self_check = value.get("self", True)
    if not isinstance(self_check, bool):
        raise TaskError("collision.self", f"expected true or false, got {_describe(self_check)}")
    srdf = None
    if value.get("srdf") is not None:
        name = _string("collision.srdf", value["srdf"], max_chars=MAX_PATH_CHARS)
        srdf = _existing_file("collision.srdf", name, _task_relative(name, base_dir), "SRDF file")
    return CollisionSettings(_number("collision.clearance_mm", value.get("clearance_mm", DEFAULT_CLEARANCE_MM),
                                     CLEARANCE_MM), self_check, srdf, _allow(value.get("allow")))


def _allow(value: Any) -> tuple[tuple[str, str], ...]:
    if value is None:
        return ()
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)):
        raise TaskError("collision.allow", f"expected a list of [body, body] pairs, got {_describe(value)}")
    pairs = []
    for i, pair in enumerate(value):
        if not isinstance(pair, Sequence) or isinstance(pair, (str, bytes)) or len(pair) != 2:
            raise TaskError(f"collision.allow[{i}]", f"expected a pair of body names [a, b], got {_describe(pair)}")
        a, b = (_string(f"collision.allow[{i}][{j}]", x) for j, x in enumerate(pair))
        pairs.append((a, b))
    return tuple(pairs)


def _robot_ref(value: Any, base_dir: Path | None) -> str:
    """A bundled robot name as given, or the absolute path of an existing ``.urdf`` file."""
    name = _string("robot", value, max_chars=MAX_PATH_CHARS)
    if not name.lower().endswith(".urdf"):
        if "/" in name or "\\" in name or "." in name:
            raise TaskError("robot", f"{_short(repr(name))} is not a bundled robot name, and a URDF path must "
                                     "end in .urdf")
        return _string("robot", name, max_chars=MAX_NAME_CHARS)
    path = Path(name).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    try:
        if path.is_dir():
            raise TaskError("robot", f"{_path_text(str(path))} is a directory, not a URDF file")
        if path.exists() and not path.is_file():
            raise TaskError("robot", f"{_path_text(str(path))} is not a regular file (a FIFO or a device?); "
                                     "a URDF must be one")
        if not path.is_file():
            raise TaskError("robot", f"URDF file {_path_text(name)} does not exist{_looked_at(name, path)}")
        return str(path.resolve())
    except OSError as exc:  # e.g. a name too long for the file system
        raise TaskError("robot", f"URDF file {_path_text(str(path))} cannot be read ({exc.strerror})") from None


def _looked_at(name: str, path: Path) -> str:
    """Where a URDF path was looked for, unless the task gave exactly that: a relative path is
    taken from the task file's folder, not the working directory, which users do not expect."""
    looked = str(path.absolute())
    return "" if looked == name else f" (looked for {_path_text(looked)})"


def _pose(where: str, value: Any, need_rpy: bool = False) -> PoseSpec:
    _check_mapping(where, value)
    _check_keys(where, value, required=("xyz", *(("rpy_deg",) if need_rpy else ())), optional=("rpy_deg",))
    xyz = check_triple(f"{where}.xyz", value["xyz"], COORDINATE_M)
    rpy = value.get("rpy_deg")
    rpy_t = check_triple(f"{where}.rpy_deg", rpy, ANGLE_DEG) if rpy is not None else None
    return PoseSpec(xyz, rpy_t)


def _joints(where: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, Sequence) or isinstance(value, (str, bytes)) or not value:
        raise TaskError(where, f"expected a list of joint values [deg], got {_describe(value)}")
    if len(value) > MAX_JOINTS:
        raise TaskError(where, f"{len(value)} joint values is more than any arm has")
    return tuple(_number(f"{where}[{i}]", v, JOINT_DEG) for i, v in enumerate(value))


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
    moves = tuple(_move(f"moves[{i}]", m) for i, m in enumerate(value))
    if moves[-1].blend_mm > 0:
        raise TaskError(f"moves[{len(moves) - 1}].{moves[-1].kind}.blend_mm",
                        "the last move ends the task at rest: it has no corner to fly by")
    return moves


def _move(where: str, value: Any) -> Move:
    _check_mapping(where, value)
    if len(value) != 1:
        keys = ", ".join(_key_text(k) for k in list(value)[:5]) + (", ..." if len(value) > 5 else "")
        raise TaskError(where, f"expected one of lin, circ, ptp as the only key, got {len(value)} keys: {keys}")
    kind = str(next(iter(value)))
    check_choice(f"{where} kind", kind, ("lin", "circ", "ptp"))
    where = f"{where}.{kind}"
    spec = value[kind]
    _check_mapping(where, spec)
    if kind == "ptp":
        _check_keys(where, spec, required=("to",), optional=("velocity_scale", "config", "blend_mm"))
    else:
        _check_keys(where, spec, required=("to", *(("via",) if kind == "circ" else ())),
                    optional=("speed", "config", "weave", "blend_mm"))
    config = _config(f"{where}.config", spec["config"]) if spec.get("config") is not None else DEFAULT_CONFIG
    blend = (_number(f"{where}.blend_mm", spec["blend_mm"], BLEND_MM) if spec.get("blend_mm") is not None
             else DEFAULT_BLEND_MM)
    to = spec["to"]
    _check_mapping(f"{where}.to", to)
    if kind == "ptp" and "joints_deg" in to:
        _check_keys(f"{where}.to", to, required=("joints_deg",))
        return Move(kind, to_joints_deg=_joints(f"{where}.to.joints_deg", to["joints_deg"]),
                    velocity_scale=_ptp_scale(where, spec), config=config, blend_mm=blend)
    target = _pose(f"{where}.to", to)
    if kind == "ptp":
        return Move(kind, to=target, velocity_scale=_ptp_scale(where, spec), config=config, blend_mm=blend)
    speed = _number(f"{where}.speed", spec.get("speed", DEFAULT_SPEED_M_S), SPEED_M_S)
    via = None
    if kind == "circ":
        via_spec = spec["via"]
        _check_mapping(f"{where}.via", via_spec)
        _check_keys(f"{where}.via", via_spec, required=("xyz",))
        via = check_triple(f"{where}.via.xyz", via_spec["xyz"], COORDINATE_M)
    weave = _weave(f"{where}.weave", spec["weave"]) if spec.get("weave") is not None else None
    return Move(kind, to=target, via_xyz=via, speed_m_s=speed, config=config, weave=weave, blend_mm=blend)


def _weave(where: str, value: Any) -> Weave:
    _check_mapping(where, value)
    _check_keys(where, value, required=("amplitude_mm", "wavelength_mm"), optional=("pattern",))
    return Weave(check_choice(f"{where}.pattern", value.get("pattern", DEFAULT_WEAVE_PATTERN), WEAVE_PATTERNS),
                 _number(f"{where}.amplitude_mm", value["amplitude_mm"], WEAVE_AMPLITUDE_MM),
                 _number(f"{where}.wavelength_mm", value["wavelength_mm"], WEAVE_WAVELENGTH_MM))


def _scale(where: str, value: Any) -> float:
    return _number(where, value, VELOCITY_SCALE)


def _ptp_scale(where: str, spec: Mapping[str, Any]) -> float:
    return _scale(f"{where}.velocity_scale", spec.get("velocity_scale", DEFAULT_VELOCITY_SCALE))


def _singularity(value: Any) -> SingularitySettings:
    _check_keys("singularity", value,
                optional=("method", "orientation_tolerance_deg", "position_tolerance_mm", "zone",
                          "deviation_cost_percent"))
    zone = _optional_mapping(value, "zone", "singularity")
    _check_keys("singularity.zone", zone, optional=("wrist_deg", "shoulder_mm", "elbow_deg"))
    return SingularitySettings(
        method=_string("singularity.method", value.get("method", DEFAULT_METHOD)),  # a name: the registry's to check
        orientation_tolerance_deg=_number(
            "singularity.orientation_tolerance_deg",
            value.get("orientation_tolerance_deg", DEFAULT_ORIENTATION_TOLERANCE_DEG), ORIENTATION_TOLERANCE_DEG),
        position_tolerance_mm=_number(
            "singularity.position_tolerance_mm",
            value.get("position_tolerance_mm", DEFAULT_POSITION_TOLERANCE_MM), POSITION_TOLERANCE_MM),
        zone=ZoneThresholds(
            wrist_deg=_number("singularity.zone.wrist_deg", zone.get("wrist_deg", DEFAULT_ZONE_WRIST_DEG),
                              ZONE_ANGLE_DEG),
            shoulder_mm=_number("singularity.zone.shoulder_mm", zone.get("shoulder_mm", DEFAULT_ZONE_SHOULDER_MM),
                                ZONE_SHOULDER_MM),
            elbow_deg=_number("singularity.zone.elbow_deg", zone.get("elbow_deg", DEFAULT_ZONE_ELBOW_DEG),
                              ZONE_ANGLE_DEG)),
        deviation_cost_percent=_number(
            "singularity.deviation_cost_percent",
            value.get("deviation_cost_percent", DEFAULT_DEVIATION_COST_PERCENT), DEVIATION_COST_PERCENT))


def _limits(value: Any) -> Limits:
    _check_keys("limits", value, optional=("velocity_scale", "acceleration", "jerk", "torque_scale", "ptp_time_law"))
    accel = _per_joint("limits.acceleration", value.get("acceleration", DEFAULT_ACCELERATION_RAD_S2),
                       ACCELERATION_RAD_S2)
    jerk = _per_joint("limits.jerk", value["jerk"], JERK_RAD_S3) if "jerk" in value else None
    torque = _number("limits.torque_scale", value["torque_scale"], TORQUE_SCALE) if "torque_scale" in value else None
    law = check_choice("limits.ptp_time_law", value.get("ptp_time_law", DEFAULT_PTP_TIME_LAW), PTP_TIME_LAWS)
    return Limits(velocity_scale=_scale("limits.velocity_scale", value.get("velocity_scale", DEFAULT_VELOCITY_SCALE)),
                  acceleration_rad_s2=accel, torque_scale=torque, jerk_rad_s3=jerk, ptp_time_law=law)


def _per_joint(where: str, value: Any, bounds: Range) -> tuple[float, ...]:
    """A number for all joints, or a list of one number per joint (the count is checked against the
    robot, the range by :class:`Limits`)."""
    if isinstance(value, Sequence) and not isinstance(value, (str, bytes)):
        if not value or len(value) > MAX_JOINTS:
            raise TaskError(where, f"expected a number or one number per joint, got {len(value)}")
        return tuple(_as_number(f"{where}[{i}]", v, bounds) for i, v in enumerate(value))
    return (_as_number(where, value, bounds),)


def _redundancy(value: Any) -> Redundancy:
    if not isinstance(value, Mapping):
        raise TaskError("redundancy", f"expected a mapping {{joint: NAME, value_deg: X}}, got {_describe(value)}")
    _check_keys("redundancy", value, required=("joint",), optional=("value_deg",))
    return Redundancy(_string("redundancy.joint", value["joint"]),
                      _number("redundancy.value_deg", value.get("value_deg", DEFAULT_REDUNDANT_VALUE_DEG), ANGLE_DEG))


def _output_period(value: Any) -> float:
    _check_keys("output", value, optional=("period",))
    return _number("output.period", value.get("period", DEFAULT_PERIOD_S), PERIOD_S)


# -- robot-dependent checks ------------------------------------------------------------------


def check_against_robot(task: Task, robot: Robot) -> None:
    """Joint counts and joint limits of every joint-space value in the task."""
    n = robot.n_joints
    if task.start_joints_deg is not None:
        _check_joint_values("start.joints_deg", task.start_joints_deg, robot)
    for i, move in enumerate(task.moves):
        if move.to_joints_deg is not None:
            _check_joint_values(f"moves[{i}].ptp.to.joints_deg", move.to_joints_deg, robot)
    for where, values in (("limits.acceleration", task.limits.acceleration_rad_s2),
                          ("limits.jerk", task.limits.jerk_rad_s3 or ())):
        if len(values) not in (0, 1, n):  # their ranges: Limits checks them when it is made
            raise TaskError(where, f"expected 1 or {n} numbers for {robot.name}, got {len(values)}")
    if robot.family == "seven" and task.redundancy is None:
        _check_no_labels(task, robot)


def _check_no_labels(task: Task, robot: Robot) -> None:
    """A 7-joint arm planned with all its joints has no configuration labels to honour."""
    named = [("start.config", task.start_config)] if task.start_config else []
    named += [(f"moves[{i}].{m.kind}.config", m.config) for i, m in enumerate(task.moves)
              if m.config not in ("auto", "keep")]
    if named:
        where, label = named[0]
        raise TaskError(where, f"{label!r} names a 6-axis configuration; {robot.name} has 7 joints and no "
                               "configuration labels (hold one joint with `redundancy` to plan it as a 6-axis "
                               "chain with labels, or leave config out)")


def _check_joint_values(where: str, values_deg: tuple[float, ...], robot: Robot) -> None:
    if len(values_deg) != robot.n_joints:
        raise TaskError(where, f"expected {robot.n_joints} joint values for {robot.name}, got {len(values_deg)}")
    for j, v in enumerate(values_deg):
        rad = math.radians(v)
        lo, hi = robot.lower_rad[j], robot.upper_rad[j]
        if rad < lo - 1e-9 or rad > hi + 1e-9:
            raise TaskError(f"{where}[{j}]", f"{robot.joint_names[j]} = {v:g} deg is outside its limits "
                                             f"[{math.degrees(lo):g}, {math.degrees(hi):g}] deg")

"""trajectory.json read back: every field checked for type, shape and range before anything uses it.

``singplan replay`` and ``singplan export`` take a trajectory.json from the user, who may have
edited it, cut it short or received it from someone else. It is read through
:func:`~singplan.kinematics.files.read_json` (a regular file of at most
:data:`MAX_TRAJECTORY_BYTES`, bounded parse work), and then each field is checked here against the
contract of DESIGN.md ("Outputs"): the format tag, names as short printable texts, the tool as
two triples in the task's ranges, ``period`` in the task's range, ``t`` as K >= 1 increasing
times from 0 or later within the longest a plan can last (at most the task's sample cap; a
message carries any increasing times, the URScript export asks for uniform ones), ``q``/``qd``/``qdd`` as (K, n) finite
arrays in range with n the number of joint names, segments, events and moves whose kinds,
indices and times lie inside the trajectory, the task as a valid task, metrics and per-sample
series of the right shapes. Anything else is a :class:`~singplan.kinematics.files.FileFieldError`
naming the file and the field (``segments[2].kind: expected one of ...``), exit code 2.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any, NoReturn, TypeVar

import numpy as np

from singplan.errors import TaskError
from singplan.kinematics.files import FileFieldError
from singplan.kinematics.yamldoc import shorten
from singplan.task.load import parse_task
from singplan.task.schema import (
    ANGLE_DEG,
    JOINT_DEG,
    MAX_JOINTS,
    MAX_OUTPUT_SAMPLES,
    PERIOD_S,
    TOOL_OFFSET_M,
    Range,
    Task,
)

MAX_TRAJECTORY_BYTES = 256 * 1024 * 1024  # ~500 000 samples of a 6-joint arm; parsing peaks at ~3.5x the file
MAX_NAME_CHARS = 256
MAX_LABEL_CHARS = 64  # configuration labels, method and singularity names
MAX_Q_RAD = math.radians(JOINT_DEG.high)
MAX_QD_RAD_S = 1e4  # far above any URDF's velocity limit (at most 1e3 rad/s, singplan.kinematics.robot)
MAX_QDD_RAD_S2 = 1e8
MAX_DURATION_S = MAX_OUTPUT_SAMPLES * PERIOD_S.high  # the longest a plan within the task's caps can last
SEGMENT_KINDS = ("path", "pre", "crossing", "post", "ptp", "blend")
EVENT_TYPES = ("zone_entry", "zone_exit", "config_change")
SINGULARITIES = ("wrist", "shoulder", "elbow")
_T = TypeVar("_T")


class FieldChecks:
    """Checks of one document's fields; each failure names the file and the field."""

    def __init__(self, name: str) -> None:
        self.name = name

    def fail(self, field: str, reason: str) -> NoReturn:
        raise FileFieldError(self.name, field, reason)

    def mapping(self, field: str, value: Any) -> dict[str, Any]:
        if not isinstance(value, dict):
            self.fail(field, f"expected a JSON object, got {_shown(value)}")
        return value

    def items(self, field: str, value: Any, max_count: int) -> list[Any]:
        if not isinstance(value, list):
            self.fail(field, f"expected a list, got {_shown(value)}")
        if len(value) > max_count:
            self.fail(field, f"{len(value)} items is over the {max_count} this trajectory can have")
        return value

    def text(self, field: str, value: Any, max_chars: int = MAX_NAME_CHARS, empty: bool = False) -> str:
        if not isinstance(value, str) or (not value and not empty):
            self.fail(field, f"expected a{'' if empty else ' non-empty'} text, got {_shown(value)}")
        if len(value) > max_chars:
            self.fail(field, f"{len(value)} characters is over the cap of {max_chars}")
        bad = next((c for c in value if not c.isprintable()), None)
        if bad is not None:
            self.fail(field, f"contains the control character U+{ord(bad):04X}")
        return value

    def optional_text(self, field: str, value: Any, choices: tuple[str, ...] | None = None) -> str | None:
        if value is None:
            return None
        text = self.text(field, value, MAX_LABEL_CHARS)
        if choices is not None and text not in choices:
            self.fail(field, f"expected one of {', '.join(choices)} or null, got {_shown(text)}")
        return text

    def choice(self, field: str, value: Any, choices: tuple[str, ...]) -> str:
        if not isinstance(value, str) or value not in choices:
            self.fail(field, f"expected one of {', '.join(choices)}, got {_shown(value)}")
        return value

    def number(self, field: str, value: Any, low: float, high: float, unit: str = "") -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"expected a number, got {_shown(value)}")
        if not low <= value <= high:  # NaN fails too; a huge int compares exactly, no overflow
            self.fail(field, f"expected a number in [{low:g}, {high:g}]{' ' + unit if unit else ''}, "
                             f"got {_shown(value)}")
        return float(value)

    def index(self, field: str, value: Any, count: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count:
            self.fail(field, f"expected an index 0..{count - 1}, got {_shown(value)}")
        return value

    def triple(self, field: str, value: Any, bounds: Range) -> list[float]:
        if not isinstance(value, list) or len(value) != 3:
            self.fail(field, f"expected 3 numbers, got {_shown(value)}")
        return [self.number(f"{field}[{i}]", v, bounds.low, bounds.high, bounds.unit) for i, v in enumerate(value)]

    def array(self, field: str, value: Any, shape: tuple[int | None, ...], bound: float | None,
              finite: bool = True) -> np.ndarray:
        """A JSON list (of lists) of numbers as float64 of ``shape`` (None: any length), within +-``bound``."""
        try:
            raw = np.asarray(value)
        except (ValueError, TypeError, OverflowError, RecursionError):  # ragged rows, a huge integer, ...
            self.fail(field, f"expected {_shape_text(shape)} numbers, got rows of different lengths or non-numbers")
        if raw.dtype.kind not in "if":  # strings, booleans, null, objects
            self.fail(field, f"expected numbers, got {_kind_text(raw)}")
        if raw.ndim != len(shape) or any(want is not None and got != want
                                         for got, want in zip(raw.shape, shape, strict=True)):
            self.fail(field, f"expected {_shape_text(shape)} numbers, got shape {raw.shape}")
        values = raw.astype(float, copy=False)
        bad = ~np.isfinite(values) if finite else np.isinf(values)
        if bound is not None:
            bad |= np.abs(values) > bound
        if bad.any():
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            what = "a finite number" if finite else "a number or NaN"
            self.fail(field + "".join(f"[{i}]" for i in where),
                      f"expected {what}{'' if bound is None else f' of magnitude at most {bound:g}'}, "
                      f"got {float(values[where])!r}")
        return values

    def record(self, field: str, make: Callable[[], _T]) -> _T:
        """``make()``, whose KeyError / TypeError / ValueError says this field is malformed."""
        try:
            return make()
        except KeyError as exc:
            self.fail(field, f"missing the key {shorten(str(exc), 60)}")
        except (TypeError, ValueError, AttributeError, OverflowError, IndexError) as exc:
            self.fail(field, f"malformed ({type(exc).__name__}: {shorten(str(exc), 100)})")


def _shown(value: Any) -> str:
    text = repr(value) if not isinstance(value, (list, dict)) or len(value) <= 8 else f"{len(value)} items"
    return f"{type(value).__name__} {shorten(text, 60)}"


def _shape_text(shape: tuple[int | None, ...]) -> str:
    return " x ".join("K" if n is None else str(n) for n in shape)


def _kind_text(raw: np.ndarray) -> str:
    return {"b": "true/false", "U": "texts", "S": "texts", "O": "null, objects or mixed values"}.get(
        raw.dtype.kind, str(raw.dtype))


def check_document(doc: Any, name: str, fmt: str) -> FieldChecks:
    """Check a parsed trajectory.json of format ``fmt`` from the file ``name``, in place: on return its
    fields are what :class:`~singplan.results.trajectory.Trajectory` takes (``t``, ``q``, ``qd``,
    ``qdd`` and the per-sample series as float arrays, converted one at a time so the lists and the
    arrays are not all held at once; ``tool`` and ``task`` in their canonical form). Returns the
    checks, for the records built from the checked fields (:meth:`FieldChecks.record`)."""
    f = FieldChecks(name)
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        f.fail("format", f"not a {fmt} file (expected a JSON object whose format is {fmt!r})")
    doc["joint_names"] = _joint_names(f, doc.get("joint_names"))
    doc["period"] = f.number("period", doc.get("period"), PERIOD_S.low, PERIOD_S.high, "s")
    _arrays(f, doc, len(doc["joint_names"]))
    k, duration = len(doc["t"]), float(doc["t"][-1])
    doc["task"] = _task(f, doc.get("task"))
    n_moves = len(doc["task"].moves)
    for key, max_chars in (("robot", MAX_NAME_CHARS), ("urdf", 4096), ("tip", MAX_NAME_CHARS)):
        f.text(key, doc.get(key), max_chars)
    if doc.get("urdf_source") is not None:  # the URDF planned, when "urdf" names its copy (continuous joints)
        f.text("urdf_source", doc["urdf_source"], 4096)
    tool = f.mapping("tool", doc.get("tool"))
    doc["tool"] = {"xyz": f.triple("tool.xyz", tool.get("xyz"), TOOL_OFFSET_M),
                   "rpy_deg": f.triple("tool.rpy_deg", tool.get("rpy_deg"), ANGLE_DEG)}
    for i, s in enumerate(f.items("segments", doc.get("segments"), k + 2 * n_moves)):
        _segment(f, f"segments[{i}]", s, n_moves, duration)
    for i, e in enumerate(f.items("events", doc.setdefault("events", []), 3 * k)):
        _event(f, f"events[{i}]", e, n_moves, duration)
    for i, m in enumerate(f.items("moves", doc.setdefault("moves", []), n_moves)):
        _move(f, f"moves[{i}]", m, n_moves, duration)
    f.mapping("metrics", doc.get("metrics"))
    doc["samples"] = _samples(f, doc.get("samples", {}), k)
    return f


def _joint_names(f: FieldChecks, value: Any) -> tuple[str, ...]:
    names = tuple(f.text(f"joint_names[{i}]", n) for i, n in enumerate(f.items("joint_names", value, MAX_JOINTS)))
    if not names:
        f.fail("joint_names", "expected at least one joint name")
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        f.fail("joint_names", f"{shorten(repr(twice), 60)} is given twice; each joint is named once")
    return names


def _arrays(f: FieldChecks, doc: dict[str, Any], n: int) -> None:
    """``t``, ``q``, ``qd``, ``qdd`` of ``doc`` replaced by their checked arrays, one after the other."""
    t = f.array("t", doc.get("t"), (None,), MAX_DURATION_S)
    doc["t"] = t
    k = len(t)
    if not 1 <= k <= MAX_OUTPUT_SAMPLES:
        f.fail("t", f"expected 1 to {MAX_OUTPUT_SAMPLES} sample times, got {k}")
    if t[0] < 0.0:
        f.fail("t[0]", f"times start at 0 or later, got {float(t[0])!r}")
    steps = np.diff(t) <= 0.0
    if steps.any():
        i = int(np.argmax(steps)) + 1
        f.fail(f"t[{i}]", f"times must increase, got {float(t[i - 1])!r} then {float(t[i])!r}")
    for field, bound in (("q", MAX_Q_RAD), ("qd", MAX_QD_RAD_S), ("qdd", MAX_QDD_RAD_S2)):
        value = doc.get(field)
        if isinstance(value, list) and value and isinstance(value[0], list) and len(value[0]) != n:
            f.fail(field, f"rows of {len(value[0])} values, but {n} joint names (one value per joint)")
        doc[field] = f.array(field, value, (k, n), bound)


def _task(f: FieldChecks, value: Any) -> Task:
    """The recorded task, parsed and checked once as a task (its URDF need not exist any more: the
    record names it, and ``robot`` is kept as written). Its mapping
    (:meth:`~singplan.task.schema.Task.to_mapping`: defaults filled in, ``null`` of an optional key
    gone) is what the file holds."""
    task = f.mapping("task", value)
    robot = f.text("task.robot", task.get("robot"), 4096)
    try:
        checked = parse_task({**task, "robot": "recorded"})
    except TaskError as exc:
        f.fail(f"task.{exc.field}" if exc.field else "task", exc.reason)
    return replace(checked, robot=robot)


def _span(f: FieldChecks, field: str, doc: Mapping[str, Any], duration: float) -> tuple[float, float]:
    t0 = f.number(f"{field}.t0", doc.get("t0"), 0.0, duration, "s")
    t1 = f.number(f"{field}.t1", doc.get("t1"), t0, duration, "s")
    return t0, t1


def _segment(f: FieldChecks, field: str, value: Any, n_moves: int, duration: float) -> dict[str, Any]:
    seg = f.mapping(field, value)
    f.index(f"{field}.move", seg.get("move"), n_moves)
    f.choice(f"{field}.kind", seg.get("kind"), SEGMENT_KINDS)
    _span(f, field, seg, duration)
    for key in ("config_before", "config_after"):
        f.text(f"{field}.{key}", seg.get(key), MAX_LABEL_CHARS, empty=True)
    f.optional_text(f"{field}.singularity", seg.get("singularity"), SINGULARITIES)
    f.optional_text(f"{field}.method", seg.get("method"))
    return seg


def _event(f: FieldChecks, field: str, value: Any, n_moves: int, duration: float) -> dict[str, Any]:
    event = f.mapping(field, value)
    f.number(f"{field}.t", event.get("t"), 0.0, duration, "s")
    f.index(f"{field}.move", event.get("move"), n_moves)
    kind = f.choice(f"{field}.type", event.get("type"), EVENT_TYPES)
    if kind == "config_change":
        for key in ("from", "to"):
            f.text(f"{field}.{key}", event.get(key), MAX_LABEL_CHARS, empty=True)
    else:
        f.optional_text(f"{field}.singularity", event.get("singularity"), SINGULARITIES)
    return event


_MOVE_KEYS = ("move", "kind", "t0", "t1", "config_end", "vendor_config", "min_clearance_mm", "min_clearance_pair")
_CLEARANCE_MM = 1e7  # any distance between two bodies of a cell [mm] (negative: a depth)


def _move(f: FieldChecks, field: str, value: Any, n_moves: int, duration: float) -> dict[str, Any]:
    move = f.mapping(field, value)
    unknown = [k for k in move if k not in _MOVE_KEYS]
    if unknown:
        f.fail(f"{field}.{shorten(unknown[0], 40)}", f"unknown key; a move record has {', '.join(_MOVE_KEYS)}")
    f.index(f"{field}.move", move.get("move"), n_moves)
    f.text(f"{field}.kind", move.get("kind"), MAX_LABEL_CHARS)
    _span(f, field, move, duration)
    f.text(f"{field}.config_end", move.get("config_end"), MAX_LABEL_CHARS, empty=True)
    vendor = move.get("vendor_config")
    if vendor is not None and (not isinstance(vendor, dict) or len(vendor) != 1):
        f.fail(f"{field}.vendor_config", f"expected null or one vendor's configuration, got {_shown(vendor)}")
    if "min_clearance_pair" in move or "min_clearance_mm" in move:  # collision checking was on
        f.number(f"{field}.min_clearance_mm", move.get("min_clearance_mm"), -_CLEARANCE_MM, _CLEARANCE_MM, "mm")
        pair = f.items(f"{field}.min_clearance_pair", move.get("min_clearance_pair"), 2)
        if len(pair) != 2:
            f.fail(f"{field}.min_clearance_pair", f"expected the two bodies' names, got {_shown(pair)}")
        for i, name in enumerate(pair):
            f.text(f"{field}.min_clearance_pair[{i}]", name)
    return move


_SERIES = ("position_error_mm", "orientation_error_deg", "stopping_distance_m", "tcp_speed_ratio")
_DISTANCES = ("wrist_deg", "shoulder_mm", "elbow_deg")


def _samples(f: FieldChecks, value: Any, k: int) -> dict[str, Any]:
    """The per-sample series, each K numbers (NaN allowed: a 7-joint arm has no 6R distances)."""
    series = f.mapping("samples", value)
    out: dict[str, Any] = {}
    for key in _SERIES:
        if key in series:
            out[key] = f.array(f"samples.{key}", series[key], (k,), None, finite=False)
    if "singular_distances" in series:
        d = f.mapping("samples.singular_distances", series["singular_distances"])
        out["singular_distances"] = {key: f.array(f"samples.singular_distances.{key}", d.get(key), (k,), None,
                                                  finite=False) for key in _DISTANCES}
    return out

"""The planned trajectory, its segments, events and metrics, and its files.

``trajectory.json`` (format ``singplan.trajectory/1``) and ``trajectory.csv`` follow the
contract of DESIGN.md. :func:`save` writes them into an output folder by the rules of
:mod:`singplan.results.files` (only its own files, all or nothing). Both files are streamed a chunk
of samples at a time, so writing needs little memory beyond the trajectory's own arrays.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from functools import cached_property, partial
from pathlib import Path
from typing import Any, Literal, TextIO

import numpy as np

from singplan.kinematics.continuous import continuous_joint_names, portable_urdf
from singplan.kinematics.files import FileFieldError, FileRefusedError, display_path, read_bounded_text, read_json
from singplan.kinematics.robot import MAX_URDF_BYTES
from singplan.results.files import Writer, text_writer, write_files
from singplan.results.metrics import CrossingFigures, Metrics, NoFigures, SegmentFigures, figures_from_json
from singplan.results.reading import MAX_TRAJECTORY_BYTES, check_document
from singplan.task.schema import Task

FORMAT = "singplan.trajectory/1"
CSV_FILE = "trajectory.csv"
JSON_FILE = "trajectory.json"
TRAJECTORY_FILES = (CSV_FILE, JSON_FILE)  # what save() writes into an output folder, in this order
# beside a trajectory of a URDF with continuous joints: that URDF with one coordinate per joint (and
# its SRDF), which trajectory.json's "urdf" names (singplan.kinematics.continuous)
URDF_FILE = "trajectory.urdf"
SRDF_FILE = "trajectory.srdf"
ROBOT_FILES = (URDF_FILE, SRDF_FILE)
_MAX_SRDF_BYTES = 8 * 1024 * 1024
SegmentKind = Literal["path", "pre", "crossing", "post", "ptp", "blend"]
_CHUNK_ROWS = 4096  # samples formatted at once when writing (bounds the text held in memory)


@dataclass(frozen=True)
class Segment:
    """A stretch of one move: "path", "pre", "crossing", "post", "ptp" or "blend".

    Crossing segments carry their figures (:class:`~singplan.results.metrics.CrossingFigures`:
    ``min_distance`` (rad or m), the largest position and orientation deviation from the
    programmed path, ``time_lost_s`` versus the programmed speed, what auto compared); a fly-by
    corner its radius (:class:`~singplan.results.metrics.BlendFigures`); the others none.
    """

    move: int
    kind: SegmentKind
    t0: float
    t1: float
    config_before: str
    config_after: str
    singularity: str | None = None
    method: str | None = None
    details: SegmentFigures = field(default_factory=NoFigures)

    @property
    def pause_s(self) -> float | None:
        """How long the TCP waits on the singular point in this crossing (null-space) [s]; None without a pause."""
        return self.details.pause_s if isinstance(self.details, CrossingFigures) else None

    def to_json(self) -> dict[str, Any]:
        """Its trajectory.json mapping: the segment's fields, then its figures' keys."""
        return {"move": self.move, "kind": self.kind, "t0": self.t0, "t1": self.t1,
                "config_before": self.config_before, "config_after": self.config_after,
                "singularity": self.singularity, "method": self.method, **self.details.to_json()}


@dataclass(frozen=True)
class Event:
    """Something that happens at one sample: a zone entered or left (``singularity`` says which
    kind), or the configuration label changing (``config_from`` -> ``config_to``).

    A zone's entry is the first sample at or past where the path enters it, its exit the first
    sample at or past where the path leaves it (the move's first / last sample for a zone open
    there, a fly-by corner's first sample for one that runs on into the corner), both inside
    the zone's ``crossing`` segment, which may start earlier and end later (the segment covers
    every sample its method replaced, e.g. a wrist-joint blend window).
    """

    t: float
    move: int
    type: Literal["zone_entry", "zone_exit", "config_change"]
    singularity: str | None = None
    config_from: str | None = None
    config_to: str | None = None

    def to_json(self) -> dict[str, Any]:
        if self.type == "config_change":
            return {"t": self.t, "move": self.move, "type": self.type, "from": self.config_from, "to": self.config_to}
        return {"t": self.t, "move": self.move, "type": self.type, "singularity": self.singularity}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Event:
        return cls(float(doc["t"]), int(doc["move"]), doc["type"], doc.get("singularity"), doc.get("from"),
                   doc.get("to"))


@dataclass(frozen=True)
class MoveRecord:
    """One task move: its time span, the configuration it ends in and that in the vendor's form.

    ``vendor_config`` is ``{"abb": {...}}``, ``{"kuka": {...}}``, ``{"fanuc": "..."}`` or None
    (see :mod:`singplan.kinematics.vendor_config`).
    """

    move: int
    kind: str  # "lin" | "circ" | "ptp"
    t0: float
    t1: float
    config_end: str
    vendor_config: dict[str, Any] | None = None
    min_clearance_mm: float | None = None  # the move's closest approach (collision checking on) [mm]
    min_clearance_pair: list[str] | None = None  # the two bodies there

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        if self.min_clearance_pair is None:  # collision checking off: the keys are left out
            del out["min_clearance_mm"], out["min_clearance_pair"]
        return out


@dataclass(frozen=True)
class Trajectory:
    """A timed joint trajectory at a uniform controller period.

    Attributes:
        t: sample times [s], shape (K,), from 0 at ``period`` steps.
        q, qd, qdd: joint positions [rad], velocities [rad/s], accelerations [rad/s^2], (K, n).
        segments: tile [0, t[-1]] in time, in move order.
        events: zone entries/exits and configuration changes.
        metrics: the figures of DESIGN.md ("Metrics every trajectory carries").
        task: the validated task (trajectory.json holds its mapping, :meth:`~singplan.task.schema.Task.to_mapping`).

    Its arrays are read-only. :func:`save` and :func:`load` give back every field: the arrays and
    ``samples`` exactly, except the per-sample series the file holds in mm and deg
    (``position_error_m``, ``orientation_error_rad``, ``distances``), which come back to within
    the round-off of one unit conversion (1e-15 relative).
    """

    robot: str
    urdf: str
    tip: str
    tool: dict[str, list[float]]
    task: Task
    joint_names: tuple[str, ...]
    period: float
    t: np.ndarray  # (K,)
    q: np.ndarray  # (K, n)
    qd: np.ndarray  # (K, n)
    qdd: np.ndarray  # (K, n)
    segments: tuple[Segment, ...]
    events: tuple[Event, ...]
    metrics: Metrics
    # per-sample series, each (K,) or (K, 3): position_error_m, orientation_error_rad, distances,
    # stopping_distance_m (singplan.kinematics.stopping)
    samples: dict[str, np.ndarray] = field(default_factory=dict)
    moves: tuple[MoveRecord, ...] = ()

    def __post_init__(self) -> None:
        # frozen all through: the arrays are made read-only in place (no copy of a million samples)
        for values in (self.t, self.q, self.qd, self.qdd, *self.samples.values()):
            values.flags.writeable = False

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])

    def segments_by_move(self) -> dict[int, list[Segment]]:
        """Each move's segments in time order (a move of a record without segments maps to none)."""
        out: dict[int, list[Segment]] = {}
        for seg in self.segments:
            out.setdefault(seg.move, []).append(seg)
        return out

    def zone_times(self, crossing: Segment) -> tuple[float, float] | None:
        """When the path is inside the singular zone(s) of a crossing segment, from its zone events
        (the first entry, the last exit); None if it has none (its zone lies in a fly-by corner).

        The segment may be wider: it spans the samples its method replaced (e.g. a blend window).
        Crossing segments of one move never share an end (touching ones are merged), so the
        events inside this one's span are its own.
        """
        inside = [e for e in self._zone_events_by_move.get(crossing.move, ()) if crossing.t0 <= e.t <= crossing.t1]
        entries = [e.t for e in inside if e.type == "zone_entry"]
        exits = [e.t for e in inside if e.type == "zone_exit"]
        return (min(entries), max(exits)) if entries and exits else None

    @cached_property
    def _zone_events_by_move(self) -> dict[int, list[Event]]:
        """Zone events by move, gathered once: the summary and the report ask per crossing, and a
        long program has thousands of crossings and events."""
        out: dict[int, list[Event]] = {}
        for e in self.events:
            if e.type != "config_change":
                out.setdefault(e.move, []).append(e)
        return out

    def to_json(self) -> dict[str, Any]:
        """The trajectory.json document as plain Python values."""
        return _listed(self.document())

    def document(self) -> dict[str, Any]:
        """The trajectory.json document with its per-sample series left as numpy arrays."""
        return {
            "format": FORMAT, "robot": self.robot, "urdf": self.urdf, "tip": self.tip, "tool": self.tool,
            "task": self.task.to_mapping(), "joint_names": list(self.joint_names), "period": self.period,
            "t": self.t, "q": self.q, "qd": self.qd, "qdd": self.qdd,
            "segments": [s.to_json() for s in self.segments], "events": [e.to_json() for e in self.events],
            "moves": [m.to_json() for m in self.moves], "metrics": _jsonable(self.metrics.to_json()),
            "samples": _sample_series(self.samples),
        }


def _sample_series(samples: dict[str, np.ndarray]) -> dict[str, Any]:
    """Per-sample series in the file's units: mm, deg (shoulder distance in mm)."""
    out: dict[str, Any] = {}
    if "position_error_m" in samples:
        out["position_error_mm"] = samples["position_error_m"] * 1e3
    if "orientation_error_rad" in samples:
        out["orientation_error_deg"] = np.degrees(samples["orientation_error_rad"])
    if "distances" in samples:
        d = samples["distances"]
        out["singular_distances"] = {"wrist_deg": np.degrees(d[:, 0]), "shoulder_mm": d[:, 1] * 1e3,
                                     "elbow_deg": np.degrees(d[:, 2])}
    if "stopping_distance_m" in samples:  # in metres as computed: loading gives back the same floats
        out["stopping_distance_m"] = samples["stopping_distance_m"]
    if "tcp_speed_ratio" in samples:  # the step arriving at each sample: TCP speed / programmed speed
        out["tcp_speed_ratio"] = samples["tcp_speed_ratio"]
    return out


def _samples_from_file(series: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The inverse of :func:`_sample_series`: back to m and rad."""
    out: dict[str, np.ndarray] = {}
    if "position_error_mm" in series:
        out["position_error_m"] = np.asarray(series["position_error_mm"], dtype=float) * 1e-3
    if "orientation_error_deg" in series:
        out["orientation_error_rad"] = np.radians(np.asarray(series["orientation_error_deg"], dtype=float))
    if "singular_distances" in series:
        d = series["singular_distances"]
        out["distances"] = np.column_stack([np.radians(np.asarray(d["wrist_deg"], dtype=float)),
                                            np.asarray(d["shoulder_mm"], dtype=float) * 1e-3,
                                            np.radians(np.asarray(d["elbow_deg"], dtype=float))])
    if "stopping_distance_m" in series:
        out["stopping_distance_m"] = np.asarray(series["stopping_distance_m"], dtype=float)
    if "tcp_speed_ratio" in series:
        out["tcp_speed_ratio"] = np.asarray(series["tcp_speed_ratio"], dtype=float)
    return out


def _listed(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _listed(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(float(value)) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def write_csv(stream: TextIO, traj: Trajectory) -> None:
    """trajectory.csv: header ``t,<joint names>``, then one row per sample, each number as its
    shortest round-trip text (``repr``: 0.004, not ``%.17g``'s 0.0040000000000000001).

    The header is written by Python's csv module (RFC 4180 quoting, :func:`csv_line`): a joint
    name holding a comma, a quote or a line break is quoted, so every row has as many fields as
    the header.
    """
    stream.write(csv_line(["t", *traj.joint_names]) + "\n")
    for start in range(0, len(traj.t), _CHUNK_ROWS):
        stop = start + _CHUNK_ROWS
        block = np.hstack([traj.t[start:stop, None], traj.q[start:stop]])
        stream.write(csv_rows(block.tolist()))


def csv_rows(rows: list[list[float]]) -> str:
    """Rows of floats as CSV lines, each number its shortest round-trip text (read back exactly)."""
    return "".join(",".join(map(repr, row)) + "\n" for row in rows)


def csv_line(fields: Sequence[str]) -> str:
    """One CSV line (without its end) of texts, quoted by Python's csv module: a field holding a
    comma, a quote, a carriage return or a line feed is quoted (with ``\\n`` alone as the line
    terminator the module would leave a bare ``\\r`` unquoted, which readers take for a line end)."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\r\n").writerow(fields)
    return buffer.getvalue()[:-2]


def write_json(stream: TextIO, traj: Trajectory, urdf_copy: str | None = None) -> None:
    """trajectory.json, the same text as ``json.dumps(traj.to_json())``, streamed chunk by chunk. With
    ``urdf_copy`` (:func:`robot_files`), ``urdf`` names that copy and ``urdf_source`` the URDF planned."""
    document = traj.document()
    if urdf_copy is not None:
        document.update(urdf=urdf_copy, urdf_source=traj.urdf)
    _dump(stream, document)


def _dump(stream: TextIO, value: Any) -> None:
    if isinstance(value, np.ndarray):
        stream.write("[")
        for start in range(0, len(value), _CHUNK_ROWS):
            if start:
                stream.write(", ")
            stream.write(json.dumps(value[start:start + _CHUNK_ROWS].tolist())[1:-1])
        stream.write("]")
    elif isinstance(value, dict) and _holds_array(value):
        stream.write("{")
        for n, (key, item) in enumerate(value.items()):
            stream.write(("" if n == 0 else ", ") + json.dumps(key) + ": ")
            _dump(stream, item)
        stream.write("}")
    else:
        stream.write(json.dumps(value))


def _holds_array(value: dict[str, Any]) -> bool:
    return any(isinstance(v, np.ndarray) or (isinstance(v, dict) and _holds_array(v)) for v in value.values())


def save(traj: Trajectory, out_dir: str | Path, extra_files: Mapping[str, str] | None = None,
         robot_copies: Mapping[str, str] | None = None) -> Path:
    """Write trajectory.csv, trajectory.json (:func:`robot_files` for a URDF with continuous joints,
    or ``robot_copies`` when the caller made them already, and extra text files) into ``out_dir``.

    Only these files are written; the rest of the folder is left alone. All are renamed into
    place together once written; on any failure the folder is as it was (see
    :mod:`singplan.results.files`). An unusable ``out_dir`` raises OutputPathError.
    """
    folder = Path(os.path.abspath(out_dir))  # absolute, but a symbolic link stays as named
    copies = robot_files(traj) if robot_copies is None else robot_copies
    # tools that need one coordinate per joint read the copy; singplan the URDF planned (load())
    urdf_copy = str(folder / URDF_FILE) if copies else None
    writers: dict[str, Writer] = {CSV_FILE: lambda stream: write_csv(stream, traj),
                                  JSON_FILE: lambda stream: write_json(stream, traj, urdf_copy)}
    writers.update({name: text_writer(text) for name, text in {**copies, **(extra_files or {})}.items()})
    write_files(out_dir, writers)
    return folder


def robot_files(traj: Trajectory) -> dict[str, str]:
    """{file name: text} of the robot files :func:`save` writes beside ``traj``: for a URDF with
    continuous joints, :data:`URDF_FILE` (:func:`~singplan.kinematics.continuous.portable_urdf`: the
    joints as unlimited revolute ones, one coordinate each, which other tools such as the
    independent checker need) and its ``<stem>.srdf`` as :data:`SRDF_FILE`; else none."""
    urdf = Path(traj.urdf)
    try:
        text = read_bounded_text(urdf, MAX_URDF_BYTES, "URDF")
    except FileRefusedError:
        return {}  # the URDF is gone: trajectory.json names it as it was planned
    if "continuous" not in text or not continuous_joint_names(text, traj.urdf):
        return {}
    out = {URDF_FILE: portable_urdf(text, urdf)}
    srdf = urdf.with_suffix(".srdf")
    if srdf.is_file():
        out[SRDF_FILE] = read_bounded_text(srdf, _MAX_SRDF_BYTES, "SRDF")
    return out


_SEGMENT_FIELDS = ("move", "kind", "t0", "t1", "config_before", "config_after", "singularity", "method")


def _segment(doc: Mapping[str, Any]) -> Segment:
    """A segment of trajectory.json (its fields checked), its own figures from the keys beyond its fields."""
    return Segment(int(doc["move"]), doc["kind"], float(doc["t0"]), float(doc["t1"]), str(doc["config_before"]),
                   str(doc["config_after"]), doc.get("singularity"), doc.get("method"),
                   details=figures_from_json(doc["kind"], {k: v for k, v in doc.items() if k not in _SEGMENT_FIELDS}))


def load(path: str | Path) -> Trajectory:
    """Read a trajectory.json (or the folder holding it), every field checked before it is used
    (:mod:`singplan.results.reading`).

    Raises:
        FileRefusedError: not a regular UTF-8 file within
            :data:`~singplan.results.reading.MAX_TRAJECTORY_BYTES` (a FIFO, a device, a folder ...).
        FileFieldError: not JSON, or a field that is not what the format says (file and field named).
    """
    p = Path(path)
    if p.is_dir():
        p = p / JSON_FILE
    try:
        doc = read_json(p, MAX_TRAJECTORY_BYTES, "trajectory.json")
    except FileFieldError as exc:
        if exc.field or p.suffix.lower() == ".json":
            raise
        # another file of the output folder (trajectory.csv, report.html): say what is read
        raise FileFieldError(exc.path, "", f"{exc.reason}; this is not a trajectory.json: give the output "
                                          f"folder of `singplan plan` ({p.parent}) or its {JSON_FILE}") from None
    f = check_document(doc, display_path(p), FORMAT)  # in place: the fields below are checked
    segments = tuple(f.record(f"segments[{i}]", partial(_segment, s)) for i, s in enumerate(doc["segments"]))
    events = tuple(f.record(f"events[{i}]", partial(Event.from_json, e)) for i, e in enumerate(doc["events"]))
    moves = tuple(f.record(f"moves[{i}]", partial(MoveRecord, **m)) for i, m in enumerate(doc["moves"]))
    metrics = f.record("metrics", partial(Metrics.from_json, doc["metrics"]))
    samples = f.record("samples", partial(_samples_from_file, doc["samples"]))
    source = doc.get("urdf_source")  # the URDF planned, when "urdf" is its copy with one coordinate per joint
    urdf = source if isinstance(source, str) and Path(source).is_file() else doc["urdf"]
    return Trajectory(doc["robot"], urdf, doc["tip"], doc["tool"], doc["task"], doc["joint_names"],
                      doc["period"], doc["t"], doc["q"], doc["qd"], doc["qdd"], segments, events, metrics, samples,
                      moves)

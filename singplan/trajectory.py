"""The planned trajectory, its segments, events and metrics, and its files.

``trajectory.json`` (format ``singplan.trajectory/1``) and ``trajectory.csv`` follow the
contract of DESIGN.md. :func:`save` writes a whole output folder atomically: everything goes
to a temporary sibling folder that replaces the target only when complete, so a failed plan
never leaves a partial folder behind.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from singplan.errors import InputError

FORMAT = "singplan.trajectory/1"


@dataclass(frozen=True)
class Segment:
    """A stretch of one move: "path", "pre", "crossing", "post" or "ptp".

    Crossing segments also carry their figures: ``min_distance`` (rad or m), the largest
    position and orientation deviation from the programmed path, and ``time_lost_s`` versus
    the same move timed with no singular zone.
    """

    move: int
    kind: str
    t0: float
    t1: float
    config_before: str
    config_after: str
    singularity: str | None = None
    method: str | None = None
    details: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if k != "details"}
        out.update(self.details)
        return out


@dataclass(frozen=True)
class Event:
    t: float
    move: int
    type: str  # "zone_entry" | "zone_exit" | "config_change"
    details: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"t": self.t, "move": self.move, "type": self.type, **self.details}


@dataclass(frozen=True)
class Trajectory:
    """A timed joint trajectory at a uniform controller period.

    Attributes:
        t: sample times [s], shape (K,), from 0 at ``period`` steps.
        q, qd, qdd: joint positions [rad], velocities [rad/s], accelerations [rad/s^2], (K, n).
        segments: tile [0, t[-1]] in time, in move order.
        events: zone entries/exits and configuration changes.
        metrics: the figures of DESIGN.md ("Metrics every trajectory carries").
        task: the validated task as a mapping.
    """

    robot: str
    urdf: str
    tip: str
    tool: dict[str, list[float]]
    task: dict[str, Any]
    joint_names: tuple[str, ...]
    period: float
    t: np.ndarray  # (K,)
    q: np.ndarray  # (K, n)
    qd: np.ndarray  # (K, n)
    qdd: np.ndarray  # (K, n)
    segments: tuple[Segment, ...]
    events: tuple[Event, ...]
    metrics: dict[str, Any]
    # per-sample series, each (K,) or (K, 3): position_error_m, orientation_error_rad, distances
    samples: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT, "robot": self.robot, "urdf": self.urdf, "tip": self.tip, "tool": self.tool,
            "task": self.task, "joint_names": list(self.joint_names), "period": self.period,
            "t": self.t.tolist(), "q": self.q.tolist(), "qd": self.qd.tolist(), "qdd": self.qdd.tolist(),
            "segments": [s.to_json() for s in self.segments], "events": [e.to_json() for e in self.events],
            "metrics": _jsonable(self.metrics),
            "samples": _sample_series(self.samples),
        }


def _sample_series(samples: dict[str, np.ndarray]) -> dict[str, Any]:
    """Per-sample series in the file's units: mm, deg (shoulder distance in mm)."""
    out: dict[str, Any] = {}
    if "position_error_m" in samples:
        out["position_error_mm"] = (samples["position_error_m"] * 1e3).tolist()
    if "orientation_error_rad" in samples:
        out["orientation_error_deg"] = np.degrees(samples["orientation_error_rad"]).tolist()
    if "distances" in samples:
        d = samples["distances"]
        out["singular_distances"] = {"wrist_deg": np.degrees(d[:, 0]).tolist(), "shoulder_mm": (d[:, 1] * 1e3).tolist(),
                                     "elbow_deg": np.degrees(d[:, 2]).tolist()}
    return out


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


def finite_differences(q: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations (K, n) of samples q (K, n): central differences, 0 at the ends."""
    qd = np.zeros_like(q)
    qdd = np.zeros_like(q)
    if len(q) > 2:
        qd[1:-1] = (q[2:] - q[:-2]) / (2 * period_s)
        qdd[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / period_s**2
    return qd, qdd


def write_csv(path: Path, traj: Trajectory) -> None:
    header = "t," + ",".join(traj.joint_names)
    data = np.hstack([traj.t[:, None], traj.q])
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.17g")


def save(traj: Trajectory, out_dir: str | Path, extra_files: dict[str, str] | None = None) -> Path:
    """Write trajectory.csv, trajectory.json (and extra text files) into ``out_dir`` atomically."""
    target = Path(out_dir).resolve()
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    umask = os.umask(0)
    os.umask(umask)
    staging.chmod(0o777 & ~umask)  # mkdtemp makes it private; the result is an ordinary folder
    try:
        write_csv(staging / "trajectory.csv", traj)
        (staging / "trajectory.json").write_text(json.dumps(traj.to_json()))
        for name, text in (extra_files or {}).items():
            (staging / name).write_text(text)
        _replace_dir(staging, target)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return target


def _replace_dir(staging: Path, target: Path) -> None:
    if target.exists():
        old = target.with_name(f".{target.name}.old-{os.getpid()}")
        target.rename(old)
        staging.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        staging.rename(target)


_SEGMENT_FIELDS = ("move", "kind", "t0", "t1", "config_before", "config_after", "singularity", "method")


def load(path: str | Path) -> Trajectory:
    """Read a trajectory.json (or the folder holding it)."""
    p = Path(path)
    if p.is_dir():
        p = p / "trajectory.json"
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{p}: cannot read a trajectory ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{p}: not a {FORMAT} file")
    segments = tuple(Segment(**{k: s.get(k) for k in _SEGMENT_FIELDS},
                             details={k: v for k, v in s.items() if k not in _SEGMENT_FIELDS})
                     for s in doc["segments"])
    events = tuple(Event(e["t"], e["move"], e["type"], {k: v for k, v in e.items() if k not in ("t", "move", "type")})
                   for e in doc["events"])
    arrays = {k: np.asarray(doc[k], dtype=float) for k in ("t", "q", "qd", "qdd")}
    return Trajectory(doc["robot"], doc["urdf"], doc["tip"], doc["tool"], doc["task"], tuple(doc["joint_names"]),
                      float(doc["period"]), arrays["t"], arrays["q"], arrays["qd"], arrays["qdd"], segments, events,
                      doc["metrics"])

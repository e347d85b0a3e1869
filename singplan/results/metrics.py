"""The figures a trajectory carries, as typed records (DESIGN.md "Metrics every trajectory carries").

Each record is a frozen dataclass with typed fields, read by attribute
(``traj.metrics.max_joint_accel_ratio``); ``to_json()`` writes it as trajectory.json holds it (the
keys of DESIGN.md, in the file's order) and ``from_json()`` reads it back from a checked file, so
the file contract and the Python API say the same thing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from singplan.planning.orchestration.alternatives import Alternative


def _f(value: Any) -> float:
    """A figure read back from trajectory.json, which writes a NaN or infinite figure as null."""
    return math.nan if value is None else float(value)


@dataclass(frozen=True)
class CrossingFigures:
    """What a crossing segment cost and how close it came (its trajectory.json keys beyond the segment's own).

    Attributes:
        min_distance: the closest approach to the singular configuration, in ``min_distance_unit``
            ("rad", or "m" for the shoulder).
        min_distance_unit: "rad" or "m".
        max_position_error_mm, max_orientation_error_deg: the largest deviation from the path in it [mm, deg].
        max_orientation_error_at_s: where along the move's path that orientation error is [m].
        time_lost_s: against crossing the same stretch at the programmed speed [s].
        changes_branch: the crossing changes the configuration on purpose.
        alternatives: what auto compared on this move, fastest first.
        pause_s: how long the TCP waits on the singular point (null-space) [s], None without a pause.
    """

    min_distance: float
    min_distance_unit: str
    max_position_error_mm: float
    max_orientation_error_deg: float
    max_orientation_error_at_s: float
    time_lost_s: float
    changes_branch: bool
    alternatives: tuple[Alternative, ...] = ()
    pause_s: float | None = None

    def to_json(self) -> dict[str, Any]:
        """Its keys in a crossing segment (and in ``metrics.crossings``), ``pause_s`` only with a pause."""
        out: dict[str, Any] = {} if self.pause_s is None else {"pause_s": self.pause_s}
        return {**out, "min_distance": self.min_distance, "min_distance_unit": self.min_distance_unit,
                "max_position_error_mm": self.max_position_error_mm,
                "max_orientation_error_deg": self.max_orientation_error_deg,
                "max_orientation_error_at_s": self.max_orientation_error_at_s, "time_lost_s": self.time_lost_s,
                "changes_branch": self.changes_branch, "alternatives": [a.to_json() for a in self.alternatives]}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> CrossingFigures:
        return cls(_f(doc["min_distance"]), str(doc["min_distance_unit"]), _f(doc["max_position_error_mm"]),
                   _f(doc["max_orientation_error_deg"]), _f(doc["max_orientation_error_at_s"]),
                   _f(doc["time_lost_s"]), bool(doc["changes_branch"]),
                   tuple(Alternative.from_json(a) for a in doc.get("alternatives", ())),
                   None if doc.get("pause_s") is None else _f(doc["pause_s"]))


@dataclass(frozen=True)
class BlendFigures:
    """A fly-by corner (the incoming move's ``blend`` segment).

    Attributes:
        radius_mm: the radius flown [mm].
        requested_mm: the radius the task asked for (``blend_mm``) [mm].
        reduced: why they differ ("" when they do not; the key is then left out of the file).
        ramp: the superposition's weights: "quartic" or "quadratic".
    """

    radius_mm: float
    requested_mm: float
    reduced: str = ""
    ramp: str = "quartic"

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"radius_mm": self.radius_mm, "requested_mm": self.requested_mm, "ramp": self.ramp}
        return {**out, "reduced": self.reduced} if self.reduced else out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> BlendFigures:
        return cls(_f(doc["radius_mm"]), _f(doc["requested_mm"]), str(doc.get("reduced", "")),
                   str(doc.get("ramp", "quartic")))


@dataclass(frozen=True)
class NoFigures:
    """The figures of a segment that has none of its own (path, pre, post, ptp): no keys in the file."""

    def to_json(self) -> dict[str, Any]:
        return {}


SegmentFigures = CrossingFigures | BlendFigures | NoFigures
NO_FIGURES = NoFigures()


def crossing_costs(figures: SegmentFigures) -> tuple[float, float, float]:
    """A segment's largest position [mm] and orientation [deg] deviation and its time lost [s]: a
    crossing's figures, 0 for a segment without them."""
    if isinstance(figures, CrossingFigures):
        return figures.max_position_error_mm, figures.max_orientation_error_deg, figures.time_lost_s
    return 0.0, 0.0, 0.0


def figures_from_json(kind: str, doc: Mapping[str, Any]) -> SegmentFigures:
    """A segment's figures as written in trajectory.json (its keys beyond the segment's own)."""
    if kind == "crossing":
        return CrossingFigures.from_json(doc)
    if kind == "blend":
        return BlendFigures.from_json(doc)
    return NO_FIGURES


@dataclass(frozen=True)
class CrossingReport:
    """One crossing of the trajectory (``metrics.crossings``): its segment's place and its figures.

    Attributes:
        move: the task move's index.
        t0, t1: the crossing segment's span [s].
        singularity: "wrist", "shoulder" or "elbow" (None: not known).
        method: the crossing method used.
        config_before, config_after: the configuration labels at its ends.
        figures: what it cost and how close it came (written flat, beside the fields above).
    """

    move: int
    t0: float
    t1: float
    singularity: str | None
    method: str | None
    config_before: str
    config_after: str
    figures: CrossingFigures

    def to_json(self) -> dict[str, Any]:
        return {"move": self.move, "t0": self.t0, "t1": self.t1, "singularity": self.singularity,
                "method": self.method, "config_before": self.config_before, "config_after": self.config_after,
                **self.figures.to_json()}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> CrossingReport:
        return cls(int(doc["move"]), _f(doc["t0"]), _f(doc["t1"]), doc.get("singularity"), doc.get("method"),
                   str(doc["config_before"]), str(doc["config_after"]), CrossingFigures.from_json(doc))


@dataclass(frozen=True)
class BlendReport:
    """A corner that asked for a fly-by (``metrics.blends``).

    Attributes:
        move: the incoming move's index.
        requested_mm: the radius asked for [mm].
        radius_mm: the radius flown [mm] (0 when stopped at).
        flown: the corner is flown.
        reduced: why the radius is smaller than asked, or why the corner is stopped at ("" for neither;
            the key is then left out of the file).
    """

    move: int
    requested_mm: float
    radius_mm: float
    flown: bool
    reduced: str = ""

    def to_json(self) -> dict[str, Any]:
        out = {"move": self.move, "requested_mm": self.requested_mm, "radius_mm": self.radius_mm, "flown": self.flown}
        return {**out, "reduced": self.reduced} if self.reduced else out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> BlendReport:
        return cls(int(doc["move"]), _f(doc["requested_mm"]), _f(doc["radius_mm"]), bool(doc["flown"]),
                   str(doc.get("reduced", "")))


@dataclass(frozen=True)
class TorqueFigures:
    """Inverse-dynamics torques of the samples against the efforts x ``limits.torque_scale``
    (written flat into ``metrics``).

    Attributes:
        max_torque_ratio: the largest |torque| / limit over samples and joints.
        max_torque_at_s: when [s].
        max_torque_joint: which joint.
        peak_torque_Nm: each joint's largest |torque| [N m], by joint name.
        torque_limit_Nm: each joint's limit [N m], by joint name.
    """

    max_torque_ratio: float
    max_torque_at_s: float
    max_torque_joint: str
    peak_torque_Nm: Mapping[str, float]  # noqa: N815 (the file's key)
    torque_limit_Nm: Mapping[str, float]  # noqa: N815

    def to_json(self) -> dict[str, Any]:
        return {"max_torque_ratio": self.max_torque_ratio, "max_torque_at_s": self.max_torque_at_s,
                "max_torque_joint": self.max_torque_joint, "peak_torque_Nm": dict(self.peak_torque_Nm),
                "torque_limit_Nm": dict(self.torque_limit_Nm)}


@dataclass(frozen=True)
class JerkFigures:
    """With a jerk limit or the quintic PTP law: what the smoother time law costs (written flat into ``metrics``).

    Attributes:
        acceleration_limited_duration_s: the duration timed under the acceleration limits alone [s].
        jerk_time_lost_s: what the smoother law adds to it [s].
        max_joint_jerk_ratio: the largest |jerk| / limit of the samples; None with the quintic law alone
            (no jerk limit to compare with; the key is then left out of the file).
    """

    acceleration_limited_duration_s: float
    jerk_time_lost_s: float
    max_joint_jerk_ratio: float | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"acceleration_limited_duration_s": self.acceleration_limited_duration_s,
                               "jerk_time_lost_s": self.jerk_time_lost_s}
        return out if self.max_joint_jerk_ratio is None else {**out, "max_joint_jerk_ratio": self.max_joint_jerk_ratio}


@dataclass(frozen=True)
class ClearanceFigures:
    """The collision check of a trajectory (DESIGN.md, "Collision").

    Attributes:
        clearance_mm: the clearance every checked pair keeps [mm].
        min_clearance_mm: the closest approach at the output samples [mm] (at most 0.4 mm above the
            true least); None when no pair is checked.
        min_clearance_pair: the two bodies there.
        min_clearance_t: when [s].
        min_clearance_points: the two closest points there, in the base frame [m].
        bodies: every body (links with collision geometry, ``tool``, the cell's shapes).
        pairs: how many pairs are checked.
        skipped: how many pairs each rule leaves out (same_group, adjacent, srdf, allow).
        self_collision: robot bodies are checked against each other.
        srdf: the SRDF whose pairs are skipped, or None.
        notes: what is not checked and why.
        distance_calls: coal distance queries the last check made.
    """

    clearance_mm: float
    min_clearance_mm: float | None
    min_clearance_pair: tuple[str, str] | None
    min_clearance_t: float | None
    min_clearance_points: tuple[tuple[float, float, float], tuple[float, float, float]] | None
    bodies: tuple[str, ...]
    pairs: int
    skipped: Mapping[str, int]
    self_collision: bool
    srdf: str | None
    notes: tuple[str, ...] = ()
    distance_calls: int = 0

    def to_json(self) -> dict[str, Any]:
        return {"clearance_mm": self.clearance_mm, "min_clearance_mm": self.min_clearance_mm,
                "min_clearance_pair": None if self.min_clearance_pair is None else list(self.min_clearance_pair),
                "min_clearance_t": self.min_clearance_t,
                "min_clearance_points": (None if self.min_clearance_points is None
                                         else [list(p) for p in self.min_clearance_points]),
                "bodies": list(self.bodies), "pairs": self.pairs, "skipped": dict(self.skipped),
                "self": self.self_collision, "srdf": self.srdf, "notes": list(self.notes),
                "distance_calls": self.distance_calls}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> ClearanceFigures:
        pair, points = doc.get("min_clearance_pair"), doc.get("min_clearance_points")
        least = doc.get("min_clearance_mm")
        closest = (least, pair, doc.get("min_clearance_t"), points)
        if any(v is None for v in closest) and any(v is not None for v in closest):  # a closest approach is whole
            raise ValueError("min_clearance_mm, min_clearance_pair, min_clearance_t and min_clearance_points "
                             "are given together or not at all")
        return cls(_f(doc["clearance_mm"]), None if least is None else _f(least),
                   None if pair is None else (str(pair[0]), str(pair[1])),
                   None if doc.get("min_clearance_t") is None else _f(doc["min_clearance_t"]),
                   None if points is None else (_point(points[0]), _point(points[1])),
                   tuple(str(b) for b in doc.get("bodies", ())), int(doc.get("pairs", 0)),
                   {str(k): int(v) for k, v in doc.get("skipped", {}).items()}, bool(doc.get("self", False)),
                   doc.get("srdf"), tuple(str(n) for n in doc.get("notes", ())), int(doc.get("distance_calls", 0)))


def _point(values: Any) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)
    return x, y, z


@dataclass(frozen=True)
class Metrics:
    """Every trajectory's figures (DESIGN.md "Metrics every trajectory carries"), trajectory.json's
    ``metrics`` (:meth:`to_json`).

    Attributes:
        max_position_error_mm: the largest TCP position deviation from the programmed path [mm].
        max_orientation_error_deg: the largest orientation deviation [deg].
        max_joint_speed_ratio, max_joint_accel_ratio: the largest |qd| / limit and |qdd| / limit of
            the samples (the limits scaled as the task says).
        duration_s: the trajectory's duration [s].
        planning_time_s: wall time of the planning [s].
        samples: the number of samples.
        method: the crossing method asked for ("auto", a method's name).
        crossings: every crossing, in time order.
        torques: the torque figures, or why there are none ("not computed: ...").
        max_stopping_distance_mm: the largest stopping distance of the samples [mm].
        max_stopping_distance_at_s: when [s].
        jerk: what a jerk limit or the quintic PTP law costs; None with neither.
        blends: every corner that asked for a fly-by.
        clearance: the collision check; None when the task and robot have nothing to check.
        max_tcp_speed_ratio: the largest TCP speed on the samples over the move's programmed speed
            (fly-by corners: the faster neighbour's); 0 for a trajectory of PTP moves only.
    """

    max_position_error_mm: float
    max_orientation_error_deg: float
    max_joint_speed_ratio: float
    max_joint_accel_ratio: float
    duration_s: float
    planning_time_s: float
    samples: int
    method: str
    crossings: tuple[CrossingReport, ...]
    torques: TorqueFigures | str
    max_stopping_distance_mm: float
    max_stopping_distance_at_s: float
    jerk: JerkFigures | None = None
    blends: tuple[BlendReport, ...] = ()
    clearance: ClearanceFigures | None = None
    max_tcp_speed_ratio: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """trajectory.json's ``metrics``: torque and jerk figures flat among the others, the closest
        approach at the top and the whole check under ``collision``, ``blends`` only when a corner asked."""
        torques = {"torques": self.torques} if isinstance(self.torques, str) else self.torques.to_json()
        out: dict[str, Any] = {
            "max_position_error_mm": self.max_position_error_mm,
            "max_orientation_error_deg": self.max_orientation_error_deg,
            "max_joint_speed_ratio": self.max_joint_speed_ratio, "max_joint_accel_ratio": self.max_joint_accel_ratio,
            "max_tcp_speed_ratio": self.max_tcp_speed_ratio,
            "duration_s": self.duration_s, "planning_time_s": self.planning_time_s, "samples": self.samples,
            "method": self.method, "crossings": [c.to_json() for c in self.crossings], **torques,
            **(self.jerk.to_json() if self.jerk is not None else {}),
            "max_stopping_distance_mm": self.max_stopping_distance_mm,
            "max_stopping_distance_at_s": self.max_stopping_distance_at_s}
        if self.clearance is not None:  # the two figures DESIGN names at the top, the rest under "collision"
            collision = self.clearance.to_json()
            out.update(min_clearance_mm=self.clearance.min_clearance_mm,
                       min_clearance_pair=collision["min_clearance_pair"], collision=collision)
        return {**out, "blends": [b.to_json() for b in self.blends]} if self.blends else out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Metrics:
        torques: TorqueFigures | str = (str(doc["torques"]) if "torques" in doc else TorqueFigures(
            _f(doc["max_torque_ratio"]), _f(doc["max_torque_at_s"]), str(doc["max_torque_joint"]),
            {str(k): float(v) for k, v in doc["peak_torque_Nm"].items()},
            {str(k): float(v) for k, v in doc["torque_limit_Nm"].items()}))
        jerk = (JerkFigures(_f(doc["acceleration_limited_duration_s"]), _f(doc["jerk_time_lost_s"]),
                            None if doc.get("max_joint_jerk_ratio") is None else _f(doc["max_joint_jerk_ratio"]))
                if "acceleration_limited_duration_s" in doc else None)
        return cls(_f(doc["max_position_error_mm"]), _f(doc["max_orientation_error_deg"]),
                   _f(doc["max_joint_speed_ratio"]), _f(doc["max_joint_accel_ratio"]), _f(doc["duration_s"]),
                   _f(doc["planning_time_s"]), int(doc["samples"]), str(doc["method"]),
                   tuple(CrossingReport.from_json(c) for c in doc.get("crossings", ())), torques,
                   _f(doc.get("max_stopping_distance_mm", 0.0)), _f(doc.get("max_stopping_distance_at_s", 0.0)),
                   jerk, tuple(BlendReport.from_json(b) for b in doc.get("blends", ())),
                   ClearanceFigures.from_json(doc["collision"]) if doc.get("collision") is not None else None,
                   _f(doc.get("max_tcp_speed_ratio", 0.0)))

    @classmethod
    def of_samples(cls, duration_s: float, samples: int) -> Metrics:
        """The figures of samples made elsewhere (tests, benchmarks): duration and count, the rest 0."""
        return cls(0.0, 0.0, 0.0, 0.0, duration_s, 0.0, samples, "exact", (), "not computed", 0.0, 0.0)

    def limit_ratios(self) -> dict[str, float]:
        """Every ``max_*_ratio`` figure (the limits a plan must keep, the torque it reports), in the file's order."""
        out = {"max_joint_speed_ratio": self.max_joint_speed_ratio, "max_joint_accel_ratio": self.max_joint_accel_ratio,
               "max_tcp_speed_ratio": self.max_tcp_speed_ratio}
        if isinstance(self.torques, TorqueFigures):
            out["max_torque_ratio"] = self.torques.max_torque_ratio
        if self.jerk is not None and self.jerk.max_joint_jerk_ratio is not None:
            out["max_joint_jerk_ratio"] = self.jerk.max_joint_jerk_ratio
        return out

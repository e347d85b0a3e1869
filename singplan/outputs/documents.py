"""What ``singplan plan``, ``check`` and ``ik`` print with ``--json``: one JSON document on stdout.

Each document names its format and version (``"format": "singplan.plan/1"``, ``singplan.check/1``,
``singplan.ik/1``); the JSON Schemas are ``singplan/outputs/schemas/<command>.schema.json``
(:func:`schema`) and docs/json-output.md describes every field. A version stays while fields
are only added; renaming, removing or changing the meaning of a field makes the next version.
Success (``"ok": true``, exit code 0) carries the results; a failure (``"ok": false``) carries the
exit code and the one-line message the command also writes to stderr. Numbers are written as
their shortest round-trip text, and a value that is not finite (a 7-joint arm's 6R distances)
as null.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from importlib import resources
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # only annotations: `singplan ik --json` need not import the planner
    from singplan.outputs.pages import PlannedFolder
    from singplan.results.detect import MoveZones

COMMANDS = ("plan", "check", "ik")
VERSION = 1


def format_name(command: str) -> str:
    """The ``format`` of a command's document: ``singplan.<command>/<version>``."""
    return f"singplan.{command}/{VERSION}"


def schema(command: str) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a command's document."""
    text = (resources.files("singplan.outputs") / "schemas" / f"{command}.schema.json").read_text()
    return dict(json.loads(text))


_NUMBER = r"(?:-?\d[\d.eE+-]*|null)"
_NUMBER_LIST = re.compile(rf"\[\s*({_NUMBER}(?:,\s*{_NUMBER})*)\s*\]")


def dumps(document: dict[str, Any]) -> str:
    """The document as indented JSON text with a final newline (NaN and infinities as null); a
    list of numbers stays on one line (``"xyz": [0.0, 0.0, 0.12]``)."""
    text = json.dumps(_finite(document), indent=2, allow_nan=False)
    return _NUMBER_LIST.sub(lambda m: "[" + re.sub(r",\s+", ", ", m.group(1)) + "]", text) + "\n"


def failure(command: str, exit_code: int, message: str) -> dict[str, Any]:
    """The document of a command that failed: its exit code and message."""
    return {"format": format_name(command), "ok": False, "exit_code": exit_code, "error": message}


def _success(command: str) -> dict[str, Any]:
    return {"format": format_name(command), "ok": True, "exit_code": 0}


def plan_document(task: str, done: PlannedFolder) -> dict[str, Any]:
    """``singplan plan --json``: what trajectory.json holds, without the per-sample series, and
    where the files went."""
    traj = done.traj
    record = traj.document()
    return {**_success("plan"), "task": task, "output": str(done.folder), "files": list(done.files),
            "not_written": dict(done.skipped), "robot": traj.robot, "urdf": traj.urdf, "tip": traj.tip,
            "tool": traj.tool, "joint_names": list(traj.joint_names), "period_s": traj.period,
            "duration_s": traj.duration_s, "samples": len(traj.t), "moves": record["moves"],
            "segments": record["segments"], "events": record["events"], "metrics": record["metrics"]}


def check_document(task: str, found: Sequence[MoveZones]) -> dict[str, Any]:
    """``singplan check --json``: the zones of every move along the programmed path and the
    stopping distance bound. A move no method plans makes it a failure (exit code 3, ``error`` the
    first such move's refusal) that still carries the zones, each move's ``no_plan`` reason and no
    bound (``stopping_distance_bound_mm`` null: there is no plan to bound)."""
    moves = []
    for m in found:
        scale_mm = m.length_m * 1e3  # path parameter u in [0, 1] -> arc length [mm]
        zones = [{"singularity": z.kind, "s_entry_mm": z.u_entry * scale_mm, "s_exit_mm": z.u_exit * scale_mm,
                  "s_closest_mm": z.u_closest * scale_mm, "min_distance": z.min_distance,
                  "min_distance_unit": z.unit, "threshold": z.threshold} for z in m.zones]
        record: dict[str, Any] = {"move": m.index, "kind": m.kind, "length_mm": scale_mm, "zones": zones,
                                  "stopping_distance_bound_mm": None}
        if m.stopping is not None:
            record["stopping_distance_bound_mm"] = m.stopping.bound_m * 1e3
            record.update({"at_fraction": m.stopping.at} if m.kind == "ptp" else {"at_s_mm": m.stopping.at * scale_mm})
        if m.no_plan is not None:
            record["no_plan"] = str(m.no_plan)
        moves.append(record)
    refusal = next((m.no_plan for m in found if m.no_plan is not None), None)
    head = _success("check") if refusal is None else failure("check", refusal.exit_code, str(refusal))
    return {**head, "task": task, "zones": sum(len(m.zones) for m in found), "moves": moves}


def ik_document(robot: str, urdf: str, tip: str, joint_names: Sequence[str], target: dict[str, list[float]],
                tool: dict[str, list[float]], held: dict[str, Any] | None,
                solutions: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """``singplan ik --json``: every solution with its label and singular distances."""
    return {**_success("ik"), "robot": robot, "urdf": urdf, "tip": tip, "joint_names": list(joint_names),
            "target": target, "tool": tool, "held": held, "solutions": list(solutions)}


def _finite(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value

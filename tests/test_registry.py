"""The crossing-method registry: the one home of the names, user methods by object or by registered name."""

from __future__ import annotations

import io
import json
import math
from dataclasses import replace
from pathlib import Path

import pytest

from singplan.cli import main
from singplan.errors import InputError, SingularityError, TaskError
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import Crossing, MoveContext
from singplan.planning.crossing.methods import WristJoint
from singplan.planning.path.zones import Zone
from singplan.results.plan import plan
from singplan.task import schema
from singplan.task.load import load_task

NEAR_MISS = Path(__file__).resolve().parents[1] / "examples" / "abb_near_miss_auto.yaml"


class WideWrist:
    """A user's method: the built-in wrist-joint crossing over twice the zone, under its own name."""

    name = "wide-wrist"
    variant = ""

    def __init__(self) -> None:
        self._inner = WristJoint(None, 2.0)

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        crossing = self._inner.cross(ctx, zone)
        return None if crossing is None else replace(crossing, method=self.name)


class GiveUp:
    """A user's method that refuses every zone (like the built-in stop), with its own message."""

    variant = ""

    def __init__(self, name: str = "give-up") -> None:
        self.name = name

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        raise SingularityError(f"move {ctx.move_index}: give-up refuses the {zone.kind} zone",
                               move=ctx.move_index, kind=zone.kind, s_m=zone.u_entry * ctx.piece.length_m)


@pytest.fixture
def clean_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    """Registrations made by a test are undone after it."""
    monkeypatch.setattr(registry, "_METHODS", dict(registry._METHODS))


def test_the_registry_names_every_method_and_gives_its_objects(clean_registry: None) -> None:
    assert registry.names() == registry.BUILT_IN == (
        "auto", "wrist-joint", "axis", "null-space", "exact", "dls", "average", "ptp", "stop")
    assert set(registry.AUTO_CANDIDATES) < set(registry.names())
    move = load_task(NEAR_MISS).moves[0]
    for name in registry.names()[1:]:  # every method a task may name has its objects, under that name
        methods = registry.candidates(name, move)
        assert methods and all(m.name == name for m in methods)
    assert registry.names()[0] == schema.AUTO_METHOD
    assert [m.name for m in registry.candidates(schema.AUTO_METHOD, move)] == [
        "exact", "wrist-joint", "wrist-joint", "wrist-joint", "axis", "null-space"]


def test_singplan_info_lists_every_method_a_task_may_name(clean_registry: None) -> None:
    registry.register(GiveUp())
    out = io.StringIO()
    assert main(["info", "so100", "--json"], out=out) == 0
    methods = {m["method"]: m for m in json.loads(out.getvalue())["crossing_methods"]}
    assert tuple(methods) == registry.names() and methods["give-up"]["applies"]
    assert not methods["wrist-joint"]["applies"] and "two-axis wrist" in methods["wrist-joint"]["note"]
    assert methods["exact"] == {"method": "exact", "applies": True, "note": ""}


def test_a_method_object_passed_to_plan_crosses_every_zone(clean_registry: None) -> None:
    traj = plan(NEAR_MISS, method=WideWrist())
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    assert crossing.method == "wide-wrist" and crossing.config_before != crossing.config_after
    assert traj.metrics.method == "wide-wrist"
    assert traj.metrics.max_position_error_mm < 1e-6  # the wrapped wrist-joint keeps the TCP position
    assert 0.0 < traj.metrics.max_orientation_error_deg <= 2.0  # within the task's tolerance
    assert "wide-wrist" not in registry.names()  # passing an object registers nothing


def test_a_registered_name_is_accepted_by_tasks_and_the_command_line(clean_registry: None, tmp_path: Path) -> None:
    with pytest.raises(TaskError, match=r"^method: unknown value 'give-up'"):
        plan(NEAR_MISS, method="give-up")
    with pytest.raises(TaskError, match=r"singularity\.method: unknown value 'give-up'"):
        plan(load_task(NEAR_MISS).with_method("give-up"))  # a task's own method name, checked before planning
    registry.register(GiveUp())
    assert registry.names()[-1] == "give-up"
    with pytest.raises(SingularityError, match="give-up refuses the wrist zone"):
        plan(load_task(NEAR_MISS).with_method("give-up"))
    err = io.StringIO()
    code = main(["plan", str(NEAR_MISS), "--method", "give-up", "-o", str(tmp_path / "out")], out=io.StringIO(),
                err=err)
    assert code == 3 and "give-up refuses" in err.getvalue()
    with pytest.raises(InputError, match="'give-up' is already registered"):
        registry.register(GiveUp())
    with pytest.raises(InputError, match="'exact' is already registered"):
        registry.register(GiveUp("exact"))


def test_the_names_are_not_changed_from_outside_by_accident(clean_registry: None) -> None:
    names = registry.names()
    assert isinstance(names, tuple)  # a copy: nothing done to it reaches the registry
    assert names == registry.BUILT_IN and isinstance(registry.BUILT_IN, tuple)


def test_capabilities_decide_which_methods_cannot_serve() -> None:
    """families.py reports what an arm offers; only the registry turns that into method names."""
    from singplan.kinematics.robot import load_robot

    for robot, capabilities, refused in (
            ("abb_irb2400", {"closed form", "wrist singularity", "square jacobian", "full pose"}, set()),
            ("so100", set(), {"wrist-joint", "axis", "null-space", "auto"}),
            ("panda", {"full pose"}, {"wrist-joint", "axis", "null-space", "auto"})):
        recognition = load_robot(robot).recognition
        assert recognition.capabilities == capabilities
        assert set(registry.refusals(recognition)) == refused


def test_auto_compares_the_pose_keeping_candidates_in_order(clean_registry: None) -> None:
    move = load_task(NEAR_MISS).moves[0]
    found = registry.candidates("auto", move)
    assert [m.name for m in found] == ["exact", "wrist-joint", "wrist-joint", "wrist-joint", "axis", "null-space"]
    assert [m.variant for m in found if m.name == "wrist-joint"] == [
        f"window x{w:g}" for w in registry.WRIST_JOINT_WINDOWS]
    assert math.isclose(registry.WRIST_JOINT_WINDOWS[0], 1.0)

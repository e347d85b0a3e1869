"""Task defaults are written once (task.schema): the records, the YAML reader and the user guide agree."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from singplan.kinematics.robot import load_robot
from singplan.task import schema
from singplan.task.load import parse_task

GUIDE = Path(__file__).resolve().parent.parent / "docs" / "user-guide.md"
MINIMAL = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
           "moves": [{"lin": {"to": {"xyz": [1.0, 0.2, 0.8]}}}, {"ptp": {"to": {"joints_deg": [0, 0, 0, 0, 30, 0]}}}]}


def test_a_task_without_optional_fields_gets_the_schema_s_defaults() -> None:
    task = parse_task(MINIMAL)
    lin, ptp = task.moves
    assert (lin.speed_m_s, lin.config, ptp.velocity_scale) == (schema.DEFAULT_SPEED_M_S, schema.DEFAULT_CONFIG,
                                                              schema.DEFAULT_VELOCITY_SCALE)
    sing = task.singularity
    assert (sing.method, sing.orientation_tolerance_deg, sing.position_tolerance_mm) == (
        schema.DEFAULT_METHOD, schema.DEFAULT_ORIENTATION_TOLERANCE_DEG, schema.DEFAULT_POSITION_TOLERANCE_MM)
    assert (sing.zone.wrist_deg, sing.zone.shoulder_mm, sing.zone.elbow_deg) == (
        schema.DEFAULT_ZONE_WRIST_DEG, schema.DEFAULT_ZONE_SHOULDER_MM, schema.DEFAULT_ZONE_ELBOW_DEG)
    assert task.limits.acceleration_rad_s2 == (schema.DEFAULT_ACCELERATION_RAD_S2,)
    assert task.limits.velocity_scale == schema.DEFAULT_VELOCITY_SCALE
    assert (task.period_s, task.tool_xyz, task.tool_rpy_deg) == (schema.DEFAULT_PERIOD_S, schema.DEFAULT_TOOL,
                                                                 schema.DEFAULT_TOOL)
    assert parse_task(task.to_mapping()) == task  # the filled-in mapping reads back to the same task


def test_the_user_guide_shows_the_schema_s_defaults() -> None:
    text = GUIDE.read_text()
    doc = yaml.safe_load(re.search(r"```yaml\n(.*?)```", text, re.S).group(1))
    sing, limits = doc["singularity"], doc["limits"]
    assert sing["method"] == schema.DEFAULT_METHOD
    assert sing["orientation_tolerance_deg"] == schema.DEFAULT_ORIENTATION_TOLERANCE_DEG
    assert sing["position_tolerance_mm"] == schema.DEFAULT_POSITION_TOLERANCE_MM
    assert sing["zone"] == {"wrist_deg": schema.DEFAULT_ZONE_WRIST_DEG, "shoulder_mm": schema.DEFAULT_ZONE_SHOULDER_MM,
                            "elbow_deg": schema.DEFAULT_ZONE_ELBOW_DEG}
    assert limits["velocity_scale"] == schema.DEFAULT_VELOCITY_SCALE
    assert limits["acceleration"] == schema.DEFAULT_ACCELERATION_RAD_S2
    assert doc["output"]["period"] == schema.DEFAULT_PERIOD_S
    assert f"`speed` defaults to {schema.DEFAULT_SPEED_M_S:g} m/s" in " ".join(text.split())


def test_a_task_without_limits_has_the_default_acceleration_on_every_joint() -> None:
    robot = load_robot("abb_irb2400")
    assert parse_task(MINIMAL).limits.joint_accelerations(robot.n_joints).tolist() == [
        schema.DEFAULT_ACCELERATION_RAD_S2] * 6

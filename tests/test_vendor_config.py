"""Vendor configuration data against the vendors' documented rules and worked examples.

Sources of the examples (facts carried over, cited per test):
* ABB RAPID reference manual, data type confdata: quadrant n of an axis is [90 n, 90 (n+1)) deg
  (quadrant -1 is 0 to -90 deg); the cfx table of serial-link robots (wrist centre relative to
  axis 1, relative to the lower arm, axis 5 angle), as quoted in the ARTE toolbox
  (arturogilaparicio/arte, compute_configuration.m).
* KUKA Turn: the worked example $AXIS_ACT = {91, -45, 37, 1, -1, 0} -> T 18 (robot-forum.com
  "how to know robot configuration from robot axes", quoting the KUKA manual's Status and Turn).
  Status bit 1 for arms whose A3 and A4 axes intersect: A3 >= 0 deg (Siemens SINUMERIK
  programming manual 6FC5398-2EP40-0BA0, STAT address for KUKA-type arms, p. 710).
* FANUC: the R-2000iB/165F example of onerobotics.com "The perils of six-axis robots"
  (2013): NUT 000 at J = (7.962, -5.284, -36.250, 77.661, -51.975, -79.273) deg and FUT 000
  at J = (7.962, -5.284, -36.250, -102.339, 51.975, 100.727) deg. The bundled R-2000iB/210F
  has the same arm (a1, a2, c1, c2, c3; shared/robots/robots.yaml), only c4 differs, which moves
  neither the wrist centre nor the letters.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from singplan.cli import main
from singplan.errors import RobotModelError
from singplan.kinematics.configuration import classify
from singplan.kinematics.robot import Robot, load_robot, robots_dir
from singplan.kinematics.vendor_config import (
    abb_confdata,
    convention_for,
    fanuc_configuration,
    fanuc_turn,
    kuka_status_turn,
    sidecar_path,
    vendor_config,
    vendor_configs,
)
from tests.conftest import random_q

VENDOR_ARMS = {"abb_irb2400": "abb", "abb_irb6700_200_260": "abb", "kuka_kr6_r700_sixx": "kuka",
               "kuka_kr6_r900_2": "kuka", "kuka_kr150_r3100_2": "kuka", "kuka_kr120_r2500_pro": "kuka",
               "fanuc_lrmate200id": "fanuc", "fanuc_m10ia": "fanuc", "fanuc_r2000ib_210f": "fanuc"}


def _at_axes(robot: Robot, axes_deg: list[float]) -> dict[str, object] | None:
    conv = convention_for(robot)
    assert conv is not None
    return vendor_config(robot, conv.joints_rad(np.radians(axes_deg)))


def test_abb_quadrants_follow_the_rapid_rule() -> None:
    # axis 1 at 100 deg: quadrant 1 (90-180); axis 4 at -45: quadrant -1 (0 to -90); axis 6 at 300: quadrant 3
    assert abb_confdata([100, 0, 0, -45, 30, 300], False, False) == (1, -1, 3, 0)
    assert abb_confdata([-90.5, 0, 0, 89.9, 30, -270.1], False, False)[:3] == (-2, 0, -4)


@pytest.mark.parametrize(("behind_axis1", "behind_lower_arm", "a5", "cfx"), [
    (False, False, 30, 0), (False, False, -30, 1), (False, True, 30, 2), (False, True, -30, 3),
    (True, False, 30, 4), (True, False, -30, 5), (True, True, 30, 6), (True, True, -30, 7)])
def test_abb_cfx_table(behind_axis1: bool, behind_lower_arm: bool, a5: float, cfx: int) -> None:
    assert abb_confdata([0, 0, 0, 0, a5, 0], behind_axis1, behind_lower_arm).cfx == cfx


def test_kuka_turn_worked_example() -> None:
    st = kuka_status_turn([91, -45, 37, 1, -1, 0], overhead=False, phi_deg=0.0)
    assert st.turn == 18  # b010010: A2 and A5 negative
    assert st.status == 0b110  # A3 37 >= phi 0 (bit 1), A5 -1 < 0 (bit 2), basic area (bit 0 clear)


def test_kuka_status_bits_one_at_a_time() -> None:
    assert kuka_status_turn([0, -90, 90, 0, 45, 0], overhead=False, phi_deg=0.0).status == 2
    assert kuka_status_turn([0, -90, 90, 0, 45, 0], overhead=True, phi_deg=0.0).status == 3
    assert kuka_status_turn([0, -90, -10, 0, 45, 0], overhead=False, phi_deg=0.0).status == 0
    assert kuka_status_turn([0, -90, 5, 0, 45, 0], overhead=False, phi_deg=5.48).status == 0  # below phi
    assert kuka_status_turn([0, -90, 90, 0, 185, 0], overhead=False, phi_deg=0.0).status == 6  # wraps to -175
    assert kuka_status_turn([0, -90, 90, 0, 0, 0], overhead=False, phi_deg=0.0).status == 6  # A5 <= 0 (DESIGN.md)


def test_fanuc_worked_example_on_the_r2000ib(robots: dict[str, Robot]) -> None:
    robot = robots["fanuc_r2000ib_210f"]
    nut = [7.962, -5.284, -36.250, 77.661, -51.975, -79.273]
    fut = [7.962, -5.284, -36.250, -102.339, 51.975, 100.727]
    assert _at_axes(robot, nut) == {"fanuc": "N U T, 0, 0, 0"}
    assert _at_axes(robot, fut) == {"fanuc": "F U T, 0, 0, 0"}


def test_fanuc_turn_numbers() -> None:
    assert [fanuc_turn(a) for a in (-79.3, 179.9, 180.0, 539.0, -180.0, -180.1, -540.1)] == [0, 0, 1, 1, 0, -1, -2]
    assert fanuc_configuration([200, 0, 0, -200, -30, 400], up=False, front=False) == "N D B, 1, -1, 1"


def test_couplings_fanuc_j3_and_abb_irb2400(robots: dict[str, Robot]) -> None:
    q = np.radians([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    fanuc = convention_for(robots["fanuc_lrmate200id"])
    abb = convention_for(robots["abb_irb2400"])
    kuka = convention_for(robots["kuka_kr6_r900_2"])
    assert fanuc is not None and abb is not None and kuka is not None
    np.testing.assert_allclose(np.degrees(fanuc.axes_rad(q)), [10, 20, 10, 40, 50, 60], atol=1e-12)  # J3 = q3 - q2
    np.testing.assert_allclose(np.degrees(abb.axes_rad(q)), [10, 20, 50, 40, 50, 60], atol=1e-12)  # A3 = q3 + q2
    np.testing.assert_allclose(kuka.axes_rad(q), q, atol=0)
    np.testing.assert_allclose(fanuc.joints_rad(fanuc.axes_rad(q)), q, atol=1e-15)


def test_conventions_of_the_bundled_arms(robots: dict[str, Robot]) -> None:
    for name, vendor in VENDOR_ARMS.items():
        conv = convention_for(robots[name])
        assert conv is not None and conv.vendor == vendor and conv.sources, name
    staubli = convention_for(robots["staubli_tx2_60"])
    assert staubli is not None and staubli.vendor == "staubli"
    assert vendor_config(robots["staubli_tx2_60"], np.zeros(6)) is None  # no Staubli form in the contract
    assert convention_for(robots["ur5"]) is None and vendor_config(robots["ur5"], np.zeros(6)) is None


def _vendor_flip(value: dict[str, object]) -> bool:
    if "abb" in value:
        return bool(value["abb"]["cfx"] & 1)  # type: ignore[index]
    if "kuka" in value:
        return bool(value["kuka"]["status"] & 4)  # type: ignore[index]
    return str(value["fanuc"]).startswith("F")


@pytest.mark.parametrize("name", sorted(VENDOR_ARMS))
def test_wrist_label_is_the_vendor_flip_on_every_arm(name: str, robots: dict[str, Robot],
                                                     rng: np.random.Generator) -> None:
    """singplan's wrist letter F is the vendor's own flip, in controller terms, on every bundled arm."""
    robot = robots[name]
    q = random_q(robot, rng, 200)
    q = q[np.abs(np.sin(q[:, 4])) > 1e-3]  # off the wrist singularity, where both are defined
    for qk, value in zip(q, vendor_configs(robot, q), strict=True):
        assert value is not None
        assert (classify(robot, qk).wrist == "F") == _vendor_flip(value), (name, np.degrees(qk))


@pytest.mark.parametrize(("name", "axes_deg"), [
    ("abb_irb2400", [0, 0, 0, 0, 60, 0]), ("abb_irb6700_200_260", [0, 0, 0, 0, 60, 0]),
    ("kuka_kr6_r900_2", [0, -90, 90, 0, 60, 0]), ("kuka_kr150_r3100_2", [0, -90, 90, 0, 60, 0]),
    ("fanuc_lrmate200id", [0, 0, 0, 0, -60, 0]), ("fanuc_m10ia", [0, 0, 0, 0, -60, 0])])
def test_tool_tilted_down_in_front_is_no_flip_everywhere(name: str, axes_deg: list[float],
                                                         robots: dict[str, Robot]) -> None:
    """The same physical pose (arm forward, tool tilted down) is "N" and the vendor's no-flip on every arm,
    though the URDF's q5 is +60 deg on ABB/KUKA and -60 deg on FANUC."""
    robot = robots[name]
    conv = convention_for(robot)
    assert conv is not None
    q = conv.joints_rad(np.radians(axes_deg))
    z_tool = robot.fk_tip(q).rotation[:, 2]
    assert z_tool[2] < -0.5  # tool axis points down
    assert classify(robot, q).label == "F U N"
    value = vendor_config(robot, q)
    assert value is not None and not _vendor_flip(value)


def test_user_urdf_sidecar(tmp_path: Path, robots: dict[str, Robot]) -> None:
    urdf = tmp_path / "my_arm.urdf"
    shutil.copy(robots_dir() / "fanuc_lrmate200id.urdf", urdf)
    q = np.radians([5.0, 10.0, 20.0, 30.0, -40.0, 50.0])
    assert vendor_config(load_robot(urdf), q) is None  # no sidecar: no convention
    sidecar_path(urdf).write_text("controller:\n  vendor: fanuc\n  axis_signs: [1, 1, 1, 1, 1, 1]\n"
                                  "  axis_offsets_deg: [0, 0, 0, 0, 0, 0]\n"
                                  "  couplings: [{axis: 3, joint: 2, factor: -1}]\n")
    assert vendor_config(load_robot(urdf), q) == vendor_config(robots["fanuc_lrmate200id"], q)


def test_bad_sidecar_is_bad_input(tmp_path: Path) -> None:
    urdf = tmp_path / "arm2.urdf"
    shutil.copy(robots_dir() / "kuka_kr6_r900_2.urdf", urdf)
    sidecar_path(urdf).write_text("controller:\n  vendor: yaskawa\n")
    with pytest.raises(RobotModelError, match="vendor: expected one of abb, kuka"):
        vendor_config(load_robot(urdf), np.zeros(6))


def test_move_records_carry_vendor_config(planned_kuka: Path) -> None:
    import json

    doc = json.loads((planned_kuka / "trajectory.json").read_text())
    assert doc["moves"], "every task move is listed"
    for m in doc["moves"]:
        # the bundled KUKA has collision shapes and an SRDF: each move also carries its closest approach
        assert set(m) == {"move", "kind", "t0", "t1", "config_end", "vendor_config", "min_clearance_mm",
                          "min_clearance_pair"}
        kuka = m["vendor_config"]["kuka"]
        assert 0 <= kuka["status"] <= 7 and 0 <= kuka["turn"] <= 63
        assert (m["config_end"].endswith("F")) == bool(kuka["status"] & 4)


def test_csv_deg_vendor_config_per_sample(planned_kuka: Path) -> None:
    assert main(["export", str(planned_kuka), "--format", "csv-deg", "--vendor-config",
                 "-o", str(planned_kuka / "v.csv")]) == 0
    lines = (planned_kuka / "v.csv").read_text().splitlines()
    assert lines[0].endswith(",vendor_config")
    assert all(line.rsplit(",", 1)[1].startswith("S ") for line in lines[1:])


@pytest.mark.parametrize("name", ["kuka_kr6_r700_sixx", "kuka_kr6_r900_2", "kuka_kr150_r3100_2",
                                  "kuka_kr120_r2500_pro"])
def test_kuka_phi_is_the_stretched_arm(name: str, robots: dict[str, Robot]) -> None:
    """Status bit 1 turns on at A3 = phi = atan2(-a2, c3): the forearm offset a2 of the OPW parameters
    (an independent formula: the wrist point on the line through A2 and A3)."""
    robot = robots[name]
    p = robot.opw
    assert p is not None
    phi_deg = np.degrees(np.arctan2(-p.a2, p.c3))
    for a3, bit in ((phi_deg - 0.01, 0), (phi_deg + 0.01, 2)):
        value = _at_axes(robot, [0.0, -90.0, float(a3), 0.0, 30.0, 0.0])
        assert value is not None and value["kuka"]["status"] & 2 == bit, (name, a3)  # type: ignore[index]

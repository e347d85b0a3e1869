"""Messages a new user met (a trial from outside): each names the option or field it is about, and says
what to do. Through ``main(argv)``; one small UR5 plan is shared."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from singplan.planning.crossing.registry import names as method_names
from tests.cli_helpers import run_cli

UR5_LIN = {"robot": "ur5", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": [0, -90, 90, -90, -90, 0]},
           "moves": [{"lin": {"to": {"xyz": [0.45, 0.3, 0.3]}, "speed": 0.3}}]}
ABB_PTP = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
           "moves": [{"ptp": {"to": {"joints_deg": [10, 10, 20, 0, 30, 0]}}}]}


def _task(tmp_path: Path, mapping: dict[str, object], name: str = "task.yaml") -> str:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(mapping))
    return str(path)


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("ur5")
    code, _, err = run_cli("plan", _task(folder, UR5_LIN), "-o", str(folder / "out"), "--no-report", "--no-replay")
    assert code == 0, err
    return folder / "out"


def test_option_errors_name_the_option(planned: Path, tmp_path: Path) -> None:
    code, _, err = run_cli("batch", _task(tmp_path, ABB_PTP), "-o", str(tmp_path / "b"), "--workers", "0")
    assert code == 2 and "--workers: 0 is not a positive number" in err, err
    code, _, err = run_cli("export", str(planned), "--format", "urscript", "--gain", "50", "-o",
                           str(tmp_path / "a.script"))
    assert code == 2 and "--gain: expected 100 to 2000, got 50" in err, err
    code, _, err = run_cli("export", str(planned), "--format", "urscript", "--lookahead-time", "1",
                       "-o", str(tmp_path / "a.script"))
    assert code == 2 and "--lookahead-time: expected" in err, err
    code, _, err = run_cli("replay", str(planned), "--serve", "--speed", "0")
    assert code == 2 and "--speed: expected a number in [0.01, 100]" in err, err


def test_speed_with_html_is_refused_and_nothing_written(planned: Path, tmp_path: Path) -> None:
    code, _, err = run_cli("replay", str(planned), "--html", str(tmp_path / "r.html"), "--speed", "2")
    assert code == 2 and "--speed goes with --serve" in err, err
    assert not (tmp_path / "r.html").exists()


def test_an_invalid_host_is_an_error_before_any_warning(planned: Path) -> None:
    code, _, err = run_cli("replay", str(planned), "--serve", "--host", "999.1.1.1")
    assert code == 2 and "not an address of this machine" in err
    assert "warning" not in err, err


def test_an_unknown_robot_names_robot_and_the_nearest(tmp_path: Path) -> None:
    code, _, err = run_cli("check", _task(tmp_path, {**ABB_PTP, "robot": "ABB_IRB2400"}))
    assert code == 2 and "robot: unknown robot 'ABB_IRB2400' (did you mean 'abb_irb2400'?); valid:" in err, err
    code, _, err = run_cli("ik", "kuka_kr6_r900", "--xyz", "0.5", "0", "0.5")
    assert code == 2 and "(did you mean 'kuka_kr6_r900_2'?)" in err, err


def test_a_tip_that_leaves_no_arm_names_tip(tmp_path: Path) -> None:
    code, _, err = run_cli("check", _task(tmp_path, {**ABB_PTP, "tip": "base_link"}))
    assert code == 2 and "0 revolute joints from base_link to base_link" in err and "(`tip`" in err, err
    code, _, err = run_cli("check", _task(tmp_path, {**ABB_PTP, "tip": "nosuch"}))
    assert code == 2 and err.startswith("singplan: error: tip: ") and "unknown tip frame 'nosuch'" in err, err


def test_help_describes_the_tool_options_and_lists_the_methods() -> None:
    from singplan.outputs.choices import CROSSING_METHODS

    methods = method_names()  # auto and the built-in methods (none registered in this test)
    assert methods == CROSSING_METHODS  # the help's list is the registry's
    _, out, _ = run_cli("ik", "--help")
    text = " ".join(out.split())
    assert "--tool-xyz X Y Z tool offset from the tip frame" in text and "--tool-rpy-deg R P Y tool orientation" in text
    for command in ("plan", "batch"):
        _, out, _ = run_cli(command, "--help")
        text = " ".join(out.split()).replace("- ", "-")  # argparse wraps null-space at its hyphen
        assert ", ".join(methods) in text, text


def test_export_of_another_file_of_the_folder_says_what_to_give(planned: Path) -> None:
    code, _, err = run_cli("export", str(planned / "trajectory.csv"), "--format", "csv-deg")
    assert code == 2 and "not a trajectory.json: give the output folder of `singplan plan`" in err, err


def test_urscript_writes_zero_not_minus_zero(planned: Path, tmp_path: Path) -> None:
    """The cb3 resampling puts joints 1 and 6 (0 at the start) a rounding below zero: -0.000000000000."""
    code, _, err = run_cli("export", str(planned), "--format", "urscript", "--ur-controller", "cb3",
                       "-o", str(tmp_path / "cb3.script"))
    assert code == 0, err
    text = (tmp_path / "cb3.script").read_text()
    assert "-0.000000000000" not in text and "0.000000000000" not in text
    assert "  movej([0, -1.5707963" in text


@pytest.mark.parametrize(("move", "hint"), [
    ({"lin": {"to": {"xyz": [50, -20, 80]}}}, "read as centimetres it would be [0.5, -0.2, 0.8] m"),
    ({"ptp": {"to": {"xyz": [50, -20, 80]}}}, "read as centimetres it would be [0.5, -0.2, 0.8] m"),
    ({"lin": {"to": {"xyz": [3, 0, 1]}}}, "(positions are in metres)\n")])
def test_a_target_far_beyond_reach_says_so_in_metres(move: dict[str, object], hint: str, tmp_path: Path) -> None:
    code, _, err = run_cli("check", _task(tmp_path, {**ABB_PTP, "moves": [move]}))
    assert code == 3 and "the target is " in err and " m from the base, beyond the arm's reach of " in err, err
    assert hint in err, err

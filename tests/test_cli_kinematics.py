"""`singplan robots` and `singplan ik` through main(argv)."""

from __future__ import annotations

import json

from tests.cli_helpers import run_cli


def test_robots_table_and_json() -> None:
    code, out, _ = run_cli("robots")
    assert code == 0
    assert "abb_irb2400" in out and "ur5" in out and "panda" in out
    code, out, _ = run_cli("robots", "--json")
    rows = {r["name"]: r for r in json.loads(out)}
    assert rows["abb_irb2400"]["dof"] == 6 and rows["abb_irb2400"]["family"] == "opw"
    assert abs(rows["abb_irb2400"]["reach_m"] - (0.1 + 0.705 + (0.135**2 + 0.755**2) ** 0.5 + 0.085)) < 1e-3
    assert rows["panda"]["dof"] == 7


def test_ik_prints_one_solution_per_branch_with_labels() -> None:
    code, out, _ = run_cli("ik", "staubli_tx2_60", "--xyz", "0.3", "0.2", "0.5", "--rpy-deg", "180", "10", "0")
    assert code == 0
    lines = out.strip().splitlines()
    count = int(lines[0].split()[0])
    labels = {" ".join(line.split()[:3]) for line in lines[2:]}
    assert count == len(lines) - 2 == len(labels) == 4  # one row per branch inside the limits
    code, out, _ = run_cli("ik", "staubli_tx2_60", "--xyz", "0.3", "0.2", "0.5", "--rpy-deg", "180", "10", "0",
                            "--all-variants")
    assert int(out.split()[0]) > 4  # joints 4 and 6 have +-270 deg ranges: more variants


def test_ik_columns_are_headed_by_the_full_joint_names() -> None:
    """panda's seven columns were all headed panda_joi, ur5's first two shoulder_ (names cut to 9)."""
    for robot, target, joints in (("panda", ["0.4", "0", "0.4"], [f"panda_joint{i}" for i in range(1, 8)]),
                                  ("ur5", ["0.4", "0.1", "0.4"], ["shoulder_pan_joint", "shoulder_lift_joint",
                                                                  "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                                                                  "wrist_3_joint"])):
        code, out, _ = run_cli("ik", robot, "--xyz", *target, "--rpy-deg", "180", "0", "0")
        assert code == 0
        header, first = out.splitlines()[1:3]
        assert header.split()[1:1 + len(joints)] == joints
        for name in joints:  # each value ends under its name's last letter
            end = header.index(name) + len(name)
            assert first[end - 1] != " " and (end == len(first) or first[end] == " "), (name, header, first)


def test_ik_errors_exit_2_and_unreachable_exit_3() -> None:
    code, _, err = run_cli("ik", "no_such_robot", "--xyz", "1", "0", "1")
    assert code == 2 and "abb_irb2400" in err
    code, _, err = run_cli("ik", "abb_irb2400", "--xyz", "1", "0")
    assert code == 2
    code, out, err = run_cli("ik", "abb_irb2400", "--xyz", "9", "0", "1")
    assert code == 3 and out == "" and err.startswith("singplan: error: no solution inside the joint limits")


def test_ik_numbers_that_are_not_finite_or_out_of_range_are_bad_input_naming_the_flag() -> None:
    for extra, named in ((["--xyz", "1", "0.2", "nan"], "--xyz[2]: must be finite"),
                         (["--xyz", "1", "0.2", "0.8", "--rpy-deg", "inf", "0", "0"], "--rpy-deg[0]: must be finite"),
                         (["--xyz", "1e300", "0.2", "0.8"], "--xyz[0]: must be at most 100 m"),
                         (["--xyz", "1", "0.2", "0.8", "--tool-xyz", "nan", "0", "0"], "--tool-xyz[0]")):
        code, out, err = run_cli("ik", "abb_irb2400", *extra)
        assert code == 2 and named in err and out == "", (extra, err)

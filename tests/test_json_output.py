"""``--json`` of plan, check and ik: one document on stdout, valid against its versioned JSON Schema,
the same facts as the text and the files; failures as documents with the exit code."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from singplan.cli import main
from singplan.outputs import documents
from singplan.results.trajectory import load
from tests.cli_helpers import run_cli

DEMO = Path(__file__).resolve().parent.parent / "singplan" / "demo_task.yaml"
KUKA_PROGRAM = Path(__file__).resolve().parent.parent / "examples" / "kuka_program.yaml"


def run_json(*argv: str) -> tuple[int, dict[str, Any], str]:
    """Exit code, the one document on stdout (validated against its command's schema), stderr."""
    code, out, err = run_cli(*argv, "--json")
    document = json.loads(out)  # the whole of stdout is one document
    jsonschema.validate(document, documents.schema(argv[0]))
    assert document["format"] == f"singplan.{argv[0]}/1" and document["exit_code"] == code
    assert document["ok"] is (code == 0)
    return code, document, err


def test_plan_json_holds_what_trajectory_json_holds_without_the_samples(tmp_path: Path) -> None:
    code, doc, err = run_json("plan", str(DEMO), "-o", str(tmp_path / "out"), "--no-replay")
    assert code == 0 and err == ""
    saved = load(tmp_path / "out").to_json()
    assert doc["files"] == ["trajectory.csv", "trajectory.json", "report.html"] and doc["not_written"] == {}
    assert doc["output"] == str(tmp_path / "out")
    assert doc["duration_s"] == saved["t"][-1] == 1.904 and doc["samples"] == len(saved["t"]) == 477
    for key in ("robot", "urdf", "tip", "tool", "joint_names", "moves", "segments", "events", "metrics"):
        assert doc[key] == saved[key], key
    assert doc["period_s"] == saved["period"]
    assert not {"t", "q", "qd", "qdd"} & set(doc) and isinstance(doc["samples"], int)  # no per-sample series


def test_plan_json_failures_are_documents_with_the_exit_code(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(DEMO.read_text().replace("speed: 0.25", "sped: 0.25"))
    code, doc, err = run_json("plan", str(bad), "-o", str(tmp_path / "a"))
    assert code == 2 and "moves[0].lin.sped: unknown key; did you mean 'speed'?" in doc["error"]
    assert err == f"singplan: error: {doc['error']}\n"  # the same message, on stderr as without --json
    code, doc, _ = run_json("plan", str(DEMO), "-o", str(tmp_path / "b"), "--method", "stop")
    assert code == 3 and "move 0" in doc["error"]
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_check_json_lists_the_zones_the_text_lists() -> None:
    code, doc, _ = run_json("check", str(KUKA_PROGRAM))
    assert code == 0
    out = io.StringIO()
    assert main(["check", str(KUKA_PROGRAM)], out=out) == 0
    text = out.getvalue()
    assert f"{doc['zones']} singular zone(s)" in text
    assert [m["kind"] for m in doc["moves"]] == ["lin", "circ", "ptp"]
    zone = doc["moves"][0]["zones"][0]
    assert zone["singularity"] == "wrist" and zone["min_distance_unit"] == "rad"
    assert f"s {zone['s_entry_mm']:8.1f} .. {zone['s_exit_mm']:8.1f} mm" in text
    assert f"at s {zone['s_closest_mm']:.1f} mm" in text
    assert 0 <= zone["s_entry_mm"] <= zone["s_closest_mm"] <= zone["s_exit_mm"] <= doc["moves"][0]["length_mm"]
    assert 0.0 <= doc["moves"][2]["at_fraction"] <= 1.0  # where the PTP's bound is largest
    worst_mm = max(m["stopping_distance_bound_mm"] for m in doc["moves"])
    assert f"stopping distance: at most {worst_mm:.3f} mm" in text


def test_ik_json_gives_the_rows_of_the_text() -> None:
    argv = ["ik", "abb_irb2400", "--xyz", "1.0", "0.2", "0.8", "--rpy-deg", "180", "10", "0"]
    code, doc, _ = run_json(*argv)
    assert code == 0 and doc["held"] is None
    assert doc["target"] == {"xyz": [1.0, 0.2, 0.8], "rpy_deg": [180.0, 10.0, 0.0]}
    out = io.StringIO()
    assert main(argv, out=out) == 0
    rows = out.getvalue().splitlines()[2:]
    assert len(rows) == len(doc["solutions"]) == 2
    for row, solution in zip(rows, doc["solutions"], strict=True):
        assert row.split()[:3] == solution["config"].split()
        assert [float(v) for v in row.split()[3:9]] == pytest.approx(solution["joints_deg"], abs=5e-4)
        assert float(row.split()[9]) == pytest.approx(solution["wrist_deg"], abs=5e-4)


def test_ik_json_of_a_seven_joint_arm_has_null_distances_and_a_held_joint() -> None:
    code, doc, _ = run_json("ik", "panda", "--xyz", "0.4", "0", "0.4", "--rpy-deg", "180", "0", "0")
    assert code == 0 and len(doc["solutions"]) == 1
    assert doc["solutions"][0]["config"] == "-" and doc["solutions"][0]["wrist_deg"] is None
    code, doc, _ = run_json("ik", "panda", "--xyz", "0.4", "0", "0.4", "--rpy-deg", "180", "0", "0",
                            "--hold", "panda_joint3=0")
    assert code == 0 and doc["held"] == {"joint": "panda_joint3", "value_deg": 0.0}
    assert all(s["joints_deg"][2] == 0.0 and s["wrist_deg"] is not None for s in doc["solutions"])


def test_ik_json_without_a_solution_is_exit_3() -> None:
    code, doc, err = run_json("ik", "abb_irb2400", "--xyz", "5", "0", "0.8")
    assert code == 3 and doc["error"].startswith("no solution inside the joint limits")
    assert err.startswith("singplan: error: no solution")


@pytest.mark.parametrize("command", documents.COMMANDS)
def test_the_schemas_are_valid_and_refuse_what_they_should(command: str) -> None:
    schema = documents.schema(command)
    jsonschema.Draft202012Validator.check_schema(schema)
    failure = documents.failure(command, 2, "moves[0]: bad")
    jsonschema.validate(failure, schema)
    for broken in ({**failure, "format": f"singplan.{command}/2"}, {**failure, "exit_code": 0},
                   {k: v for k, v in failure.items() if k != "error"}, {**failure, "ok": True}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, schema)


def test_dumps_keeps_number_lists_on_one_line_and_reads_back_the_same() -> None:
    doc = {"a": [1.0, -2.5e-07, None], "b": ["x", "y"], "c": {"d": [[0.1, 0.2], [3, 4]]}, "e": float("nan"),
           "f": "text [1, 2]"}
    text = documents.dumps(doc)
    assert '"a": [1.0, -2.5e-07, null]' in text and '"d": [\n' in text and '[0.1, 0.2]' in text
    assert json.loads(text) == {**doc, "e": None}

"""The runnable scripts of examples/ run as a user runs them (README: "a runnable script"); the
controller-program script has its own test in tests/test_programs_docs.py."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(script: str, argv: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "argv", [script, *argv])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(EXAMPLES / script), run_name="__main__")
    assert done.value.code == 0


def test_plan_and_inspect_tells_timed_untimed_and_infeasible_candidates_apart(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    _run("plan_and_inspect.py", [], monkeypatch)
    text = capsys.readouterr().out
    assert "abb_near_miss_auto.yaml: 1.032 s, 259 samples" in text, text
    assert "compared: axis 1.032 s" in text and "compared: exact >= 1.748 s, not timed:" in text, text
    assert "compared: null-space infeasible: move 0 (lin): null-space acts only" in text, text


def test_export_ros2_writes_its_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _run("export_ros2.py", [str(EXAMPLES / "abb_near_miss_auto.yaml"), str(tmp_path / "out")], monkeypatch)
    assert any((tmp_path / "out").iterdir())

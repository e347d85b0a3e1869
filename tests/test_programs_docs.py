"""docs/controller-programs.md stays true: its commands and Python blocks run, and its example
programs are what singplan writes today for the public scenarios they name.

An example block is introduced by a marker naming the scenario, the format and the lines shown::

    <!-- program: scenarios_programs/kuka_kr6_r900_2__nullspace_wrist_exact_hit krl 1-40 -->

After a change of the writers, ``python -m tests.test_programs_docs --write`` rewrites the blocks.
"""

from __future__ import annotations

import io
import os
import re
import shlex
import sys
from pathlib import Path

import pytest

from singplan.cli import main
from singplan.outputs.programs import ProgramOptions, program_texts
from singplan.results.plan import plan
from singplan.task.load import load_task
from tests.shared import SHARED, require

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "controller-programs.md"
_MARKER = re.compile(r"<!-- program: (\S+) (\S+) (\d+)-(\d+) -->\n```(\w*)\n(.*?)```", re.S)
_BLOCK = re.compile(r"```(bash|python)\n(.*?)```", re.S)
SOURCE_DATE_EPOCH = "1767225600"  # 2026-01-01: the date a FANUC /ATTR shows in the examples


def excerpt(name: str, fmt: str, first: int, last: int) -> str:
    """Lines first..last (1-based, inclusive) of the program singplan writes for a public scenario."""
    folder, stem = name.split("/")
    traj = plan(load_task(require(SHARED / folder / f"{stem}.yaml")))
    os.environ["SOURCE_DATE_EPOCH"] = SOURCE_DATE_EPOCH
    try:
        text = next(iter(program_texts(traj, fmt, ProgramOptions()).values()))
    finally:
        del os.environ["SOURCE_DATE_EPOCH"]
    lines = text.splitlines()
    shown = lines[first - 1:last]
    return "\n".join(shown + ([f"... ({len(lines) - last} more lines)"] if last < len(lines) else [])) + "\n"


def test_the_example_programs_are_what_singplan_writes() -> None:
    blocks = _MARKER.findall(PAGE.read_text())
    assert len(blocks) == 3
    for name, fmt, first, last, _, shown in blocks:
        assert shown == excerpt(name, fmt, int(first), int(last)), \
            f"{name} ({fmt}) changed: run python -m tests.test_programs_docs --write"


def commands(text: str) -> list[list[str]]:
    """The ``singplan`` command lines of a page's bash blocks (comments dropped)."""
    out = []
    for lang, body in _BLOCK.findall(text):
        if lang == "bash":
            out += [shlex.split(line, comments=True) for line in body.splitlines() if line.startswith("singplan ")]
    return out


def test_the_page_s_commands_and_python_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    text = PAGE.read_text()
    lines = commands(text)
    assert len(lines) >= 6
    printed = []
    for argv in lines:
        out, err = io.StringIO(), io.StringIO()
        assert main(argv[1:], out=out, err=err) == 0, (argv, err.getvalue())
        printed.append(out.getvalue())
    shown = re.search(r"prints, for the first one:\n\n```text\n(.*?)```", text, re.S)
    assert shown is not None and shown.group(1) == printed[1]
    python = [body for lang, body in _BLOCK.findall(text) if lang == "python"]
    assert python
    for body in python:
        exec(compile(body, str(PAGE), "exec"), {"__name__": "__docs__"})  # the page's own code


def test_the_example_script_writes_its_robot_s_program(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    import runpy

    task = ROOT / "examples" / "abb_near_miss_auto.yaml"
    monkeypatch.setattr(sys, "argv", ["controller_program.py", str(task), str(tmp_path / "out"), "0.2"])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(ROOT / "examples" / "controller_program.py"), run_name="__main__")
    assert done.value.code == 0
    assert (tmp_path / "out" / "singplan.mod").read_text().startswith("MODULE MOD_singplan")
    assert "ABB RAPID program singplan" in capsys.readouterr().out


def write() -> None:
    """Rewrite the example blocks of the page from what singplan writes now."""
    text = PAGE.read_text()

    def fill(m: re.Match[str]) -> str:
        name, fmt, first, last, lang = m.group(1, 2, 3, 4, 5)
        return (f"<!-- program: {name} {fmt} {first}-{last} -->\n```{lang}\n"
                f"{excerpt(name, fmt, int(first), int(last))}```")

    PAGE.write_text(_MARKER.sub(fill, text))


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        write()

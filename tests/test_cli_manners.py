"""The command line's manners: --version, did-you-mean, shell completion, progress on a terminal,
the overview of a long program (all through ``main(argv)``; bash completes for real)."""

from __future__ import annotations

import io
import re
import shutil
import subprocess
from importlib.metadata import version
from pathlib import Path

import pytest

import singplan
from singplan.cli import build_parser, main
from singplan.outputs.completion import SHELLS
from singplan.outputs.progress import FINISHING
from singplan.outputs.summary import LISTED_MOVES, NOTABLE_SHOWN, summary
from singplan.results.plan import plan
from singplan.results.trajectory import load
from singplan.task.load import load_task
from tests.cli_helpers import run_cli

DEMO = Path(__file__).resolve().parent.parent / "singplan" / "demo_task.yaml"


class Terminal(io.StringIO):
    """stderr as a terminal: tqdm draws its bar here."""

    def isatty(self) -> bool:
        return True


# --- --version -------------------------------------------------------------------------------------

def test_version_names_singplan_python_and_the_planning_libraries() -> None:
    code, out, err = run_cli("--version")
    assert code == 0 and err == ""
    first, second = out.splitlines()
    assert first == f"singplan {singplan.__version__}"
    assert singplan.__version__ == version("singplan")  # pyproject reads the version from _version.py
    for name in ("pin", "toppra", "numba", "numpy", "meshcat"):
        assert f"{name} {version(name)}" in second


# --- did you mean ------------------------------------------------------------------------------------

def test_a_mistyped_command_gets_the_nearest_one() -> None:
    code, out, err = run_cli("plna", "task.yaml")
    assert code == 2 and out == ""
    assert "unknown command 'plna' (did you mean plan?)" in err
    code, _, err = run_cli("frobnicate")
    assert code == 2 and "did you mean" not in err and "commands: robots, info, ik, plan" in err


def test_a_mistyped_option_is_named_before_a_missing_one() -> None:
    code, _, err = run_cli("export", "out", "--fromat", "ros2")
    assert code == 2
    assert "unrecognized option '--fromat' (did you mean --format?)" in err
    assert "required" not in err  # argparse alone said: the following arguments are required: --format
    code, _, err = run_cli("plan", "task.yaml", "--quite")
    assert code == 2 and "'--quite' (did you mean --quiet?)" in err
    code, _, err = run_cli("ik", "ur5", "--xyz", "1", "0", "0", "--banana")
    assert code == 2 and "unrecognized option '--banana'" in err and "did you mean" not in err


def test_a_mistyped_export_format_gets_the_nearest_one(planned_kuka: Path) -> None:
    code, _, err = run_cli("export", str(planned_kuka), "--format", "ros3")
    assert code == 2 and "--format: unknown format 'ros3' (did you mean ros2?); valid formats: ros2" in err


def test_the_command_line_suggests_as_before_with_the_one_helper() -> None:
    """errors.nearest, now the CLI's did-you-mean as well, names for every lower-case typo (a letter
    dropped or two swapped) of every command and option what the CLI's own difflib call did."""
    import argparse
    import difflib

    from singplan.errors import nearest

    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    groups = [list(commands)] + [[o for o in p._option_string_actions if o.startswith("--")]
                                 for p in commands.values()]
    checked = 0
    for names in groups:
        for name in names:
            typos = {name[:i] + name[i + 1:] for i in range(len(name))} | {
                name[:i] + name[i + 1] + name[i] + name[i + 2:] for i in range(len(name) - 1)}
            for typo in typos - set(names):
                before = difflib.get_close_matches(typo, names, n=1, cutoff=0.6)
                assert nearest(typo, names) == (before[0] if before else None), (typo, names)
                checked += 1
    assert checked > 500


def test_valid_spellings_still_parse(planned_kuka: Path, tmp_path: Path) -> None:
    parser = build_parser()
    assert parser.parse_args(["plan", "t.yaml", "-oDIR"]).output == "DIR"  # a short option's value attached
    assert parser.parse_args(["plan", "t.yaml", "--out=DIR"]).output == "DIR"  # an abbreviation, with =
    assert parser.parse_args(["ik", "ur5", "--xyz", "0.4", "-0.2", "-.5"]).xyz == [0.4, -0.2, -0.5]
    assert parser.parse_args(["batch", "-o", "x", "--", "-odd-name.yaml"]).tasks == ["-odd-name.yaml"]
    code, _, _ = run_cli("export", str(planned_kuka), "--form", "ros2", "-o", str(tmp_path / "t.yaml"))
    assert code == 0 and (tmp_path / "t.yaml").is_file()


# --- completion --------------------------------------------------------------------------------------

@pytest.mark.parametrize("shell", SHELLS)
def test_every_shell_gets_a_script_naming_every_command(shell: str) -> None:
    code, out, err = run_cli("completion", shell)
    assert code == 0 and err == ""
    for command in ("robots", "info", "ik", "plan", "check", "replay", "demo", "export", "batch", "completion"):
        assert command in out
    assert "format" in out and "abb_irb2400" in out  # options (tcsh lists them without --), the bundled robots


def _bash_complete(script: Path, words: list[str]) -> list[str]:
    """What bash offers for the last word of ``words`` with the script sourced (a real bash)."""
    line = " ".join(words)
    program = (f"source {script}\n"
               f"COMP_WORDS=({' '.join(repr(w) for w in words)}); COMP_CWORD={len(words) - 1}\n"
               f"COMP_LINE={line!r}; COMP_POINT={len(line)}\n"
               "_shtab_singplan singplan\n"
               "printf '%s\\n' \"${COMPREPLY[@]}\"\n")
    done = subprocess.run(["bash", "-c", program], capture_output=True, text=True, timeout=60, check=True)
    return done.stdout.split()


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash on this machine")
def test_bash_completes_commands_options_robots_and_task_files(tmp_path: Path) -> None:
    script = tmp_path / "singplan.bash"
    code, out, _ = run_cli("completion", "bash")
    assert code == 0
    script.write_text(out)
    assert _bash_complete(script, ["singplan", "pl"]) == ["plan"]
    assert "--format" in _bash_complete(script, ["singplan", "export", "out", "--f"])
    assert {"kuka_kr6_r900_2", "kuka_kr6_r700_sixx"} <= set(_bash_complete(script, ["singplan", "ik", "kuka_kr6"]))
    (tmp_path / "weld.yaml").write_text("robot: x\n")
    (tmp_path / "weld.txt").write_text("")
    offered = _bash_complete(script, ["singplan", "plan", str(tmp_path / "wel")])
    assert str(tmp_path / "weld.yaml") in offered and str(tmp_path / "weld.txt") not in offered


# --- progress ----------------------------------------------------------------------------------------

def test_progress_is_drawn_on_a_terminal_only_and_not_when_quiet(tmp_path: Path) -> None:
    options = ["--no-report", "--no-replay"]
    err = Terminal()
    assert main(["plan", str(DEMO), "-o", str(tmp_path / "a"), *options], out=io.StringIO(), err=err) == 0
    drawn = err.getvalue()
    assert "planning" in drawn and f"{FINISHING}: 100%" in drawn and "2/2" in drawn
    assert drawn.endswith("\r")  # the bar's line is cleared before the summary (leave=False)
    for argv, stream in (([], io.StringIO()), (["--quiet"], Terminal())):
        assert main(["plan", str(DEMO), "-o", str(tmp_path / "b"), *options, *argv], out=io.StringIO(),
                    err=stream) == 0
        assert stream.getvalue() == ""


# --- the summary of a long program -----------------------------------------------------------------

@pytest.fixture(scope="module")
def long_program() -> tuple[singplan.Trajectory, singplan.Task]:
    """22 moves: 11 times a LIN exactly through a wrist singularity (the demo's) and a PTP back."""
    task = load_task(Path(__file__).resolve().parent.parent / "examples" / "kuka_long_program.yaml")
    return plan(task), task


def test_a_long_program_gets_an_overview_and_full_lists_every_move(long_program) -> None:
    traj, task = long_program
    assert len(task.moves) > LISTED_MOVES
    text = summary(traj, task)
    move_lines = [line for line in text.splitlines() if re.match(r"  move \d+ ", line)]
    assert len(move_lines) == NOTABLE_SHOWN
    assert "  moves: 11 lin, 11 ptp; 22 change configuration; 0 fly-by corner(s)" in text
    assert re.search(r"  crossings: 11 \(11 wrist; methods 11 exact\), \d+\.\d{3} s lost", text)
    assert f"{NOTABLE_SHOWN} of 22 notable move(s)" in text and "--full lists every move" in text
    assert len(text.splitlines()) < 25
    full = summary(traj, task, full=True)
    assert len([line for line in full.splitlines() if re.match(r"  move \d+ ", line)]) == 22
    assert full.splitlines()[-3:] == text.splitlines()[-3:]  # the metrics the same either way


def test_a_short_program_lists_every_move_as_before(planned_kuka: Path) -> None:
    task, traj = load_task(DEMO), load(planned_kuka)
    assert summary(traj, task) == summary(traj, task, full=True)
    assert "notable" not in summary(traj, task)

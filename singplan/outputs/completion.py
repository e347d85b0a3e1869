"""Shell completion scripts for the ``singplan`` command (``singplan completion bash|zsh|tcsh``).

The scripts are written by shtab from the command's own argparse parser, so they list the
commands and options the installed version has, with no start-up cost at each Tab: the shell
completes from the static script (argcomplete instead runs the program on every Tab). Task
files complete as ``*.yaml``/``*.yml``, robots as the bundled names or a ``*.urdf`` file,
output folders as folders. shtab is imported only here, when a script is asked for.
"""

from __future__ import annotations

import argparse
from typing import Any

SHELLS = ("bash", "zsh", "tcsh")

# what an argument completes to, by its argparse ``dest`` (the same name means the same kind in every command)
_TASK_FILES = ("task", "tasks")
_FILES = ("trajectory", "out", "file", "html")
_FOLDERS = ("output",)
_ROBOTS = ("robot",)


def completion_script(parser: argparse.ArgumentParser, shell: str, robot_names: list[str]) -> str:
    """The completion script of ``parser`` for ``shell`` (one of :data:`SHELLS`)."""
    import shtab

    kinds: dict[str, Any] = {
        **dict.fromkeys(_TASK_FILES, shtab.glob("*.yaml", "*.yml")),
        **dict.fromkeys(_FILES, shtab.FILE),
        **dict.fromkeys(_FOLDERS, shtab.DIRECTORY),
        **dict.fromkeys(_ROBOTS, _robots(robot_names)),
    }
    for action in _all_actions(parser):
        if action.dest in kinds:
            action.complete = kinds[action.dest]  # type: ignore[attr-defined]  # shtab reads this attribute
    return shtab.complete(parser, shell=shell)


def _all_actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """Every argument of the parser and its commands' parsers (argparse has no public walk of them;
    shtab reads the same attributes)."""
    actions = list(parser._actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):  # aliases map to the same parser
                actions.extend(_all_actions(sub))
    return actions


def _robots(names: list[str]) -> dict[str, Any]:
    """A bundled robot name, or a URDF file (or a folder on the way to one)."""
    words = " ".join(names)
    return {
        "bash": "_singplan_compgen_robots",
        "zsh": f"_alternative 'robots:bundled robot:({words})' 'files:URDF file:_files -g \"*.urdf\"'",
        "tcsh": f"({words})",
        "preamble": {"bash": (
            "_singplan_compgen_robots() {\n"
            f"  compgen -W \"{words}\" -- \"$1\"\n"
            "  compgen -f -X '!*.urdf' -- \"$1\"\n"
            "  compgen -d -- \"$1\"\n"
            "}\n")},
    }

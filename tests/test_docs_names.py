"""Every ``singplan.X`` name the README, the docs and the examples mention resolves (docs said
``singplan.load``, which does not exist: ``singplan.results.trajectory.load`` does)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEXTS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "examples").rglob("*.py")])
FILE_NAMES = {"singplan.bash", "singplan.ls", "singplan.mod", "singplan.src"}  # files a command writes
NAME = re.compile(r"(?<![\w/.-])singplan(?:\.[A-Za-z_]\w*)+(?![\w/])")  # not a format name (singplan.plan/1)


def _mentioned() -> dict[str, str]:
    """Each dotted name and the first place it is written (file:line)."""
    found: dict[str, str] = {}
    for path in TEXTS:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for match in NAME.finditer(line):
                if match.group(0) not in FILE_NAMES:
                    found.setdefault(match.group(0), f"{path.relative_to(ROOT)}:{number}")
    return found


def _resolve(name: str) -> object:
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            value: object = importlib.import_module(".".join(parts[:k]))
        except ModuleNotFoundError:
            continue
        for attribute in parts[k:]:
            value = getattr(value, attribute)
        return value
    raise ModuleNotFoundError(name)


MENTIONED = _mentioned()


def test_the_docs_mention_names() -> None:
    assert "singplan.results.trajectory.load" in MENTIONED and len(MENTIONED) > 20


@pytest.mark.parametrize("name", sorted(MENTIONED))
def test_every_singplan_name_in_the_docs_resolves(name: str) -> None:
    try:
        value = _resolve(name)
    except (AttributeError, ModuleNotFoundError) as exc:
        pytest.fail(f"{MENTIONED[name]}: {name} does not resolve ({exc})")
    assert value is not None, f"{MENTIONED[name]}: {name} is None"

"""No circle of imports of any kind (issue 24): between modules, type-only imports included.

The ``acyclic_siblings`` contract in pyproject.toml checks the same between the packages and
modules of every package (``lint-imports``); this test reads the import graph itself, with the
imports under ``if TYPE_CHECKING:`` counted, and names a circle it finds.
"""

from __future__ import annotations

from pathlib import Path

import pytest

grimp = pytest.importorskip("grimp", reason="grimp comes with import-linter (the dev extra)")

ROOT = Path(__file__).resolve().parents[1]


def _graph() -> grimp.ImportGraph:
    return grimp.build_graph("singplan", cache_dir=None, exclude_type_checking_imports=False)


def _circle(graph: grimp.ImportGraph) -> list[str]:
    """One circle of direct imports between singplan's modules, [] when there is none (depth-first)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph.modules):
        if state.get(start):
            continue
        path, stack = [start], [iter(sorted(graph.find_modules_directly_imported_by(start)))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph.find_modules_directly_imported_by(nxt))))
    return []


def test_type_only_imports_are_in_the_graph() -> None:
    """singplan/__init__.py imports the entry module only for type checkers: the graph has it."""
    assert "singplan.entry" in _graph().find_modules_directly_imported_by("singplan")


def test_no_module_imports_itself_through_others() -> None:
    assert _circle(_graph()) == []


def test_the_circle_finder_finds_one() -> None:
    graph = _graph()
    graph.add_import(importer="singplan.errors", imported="singplan.entry")  # errors -> entry -> ... -> errors
    circle = _circle(graph)
    assert circle[0] == circle[-1] and "singplan.entry" in circle


def test_the_contracts_count_type_only_imports() -> None:
    tomllib = pytest.importorskip("tomllib", reason="tomllib is Python 3.11's")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    assert not config.get("exclude_type_checking_imports", False)
    assert any(c["type"] == "acyclic_siblings" and c["ancestors"] == ["singplan"] for c in config["contracts"])

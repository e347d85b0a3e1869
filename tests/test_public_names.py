"""Every public name of ``singplan`` resolves, from the module its table names (the entry module,
:mod:`singplan.entry`, for plan, plan_into and detect)."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import singplan


@pytest.mark.parametrize("name", singplan.__all__)
def test_every_name_in_all_resolves(name: str) -> None:
    value = getattr(singplan, name)
    if name == "__version__":
        assert isinstance(value, str)
        return
    home = singplan._HOME_OF[name]
    assert getattr(importlib.import_module(home), name) is value


def test_all_and_the_table_list_the_same_names() -> None:
    assert sorted(singplan.__all__) == sorted([*singplan._HOME_OF, "__version__"])


def test_the_type_checking_imports_match_the_table() -> None:
    """The names mypy sees (the TYPE_CHECKING block) come from the modules the table loads them from."""
    tree = ast.parse(Path(singplan.__file__).read_text())
    block = next(node for node in tree.body if isinstance(node, ast.If)
                 and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING")
    seen = {alias.name: node.module for node in block.body if isinstance(node, ast.ImportFrom)
            for alias in node.names}
    assert seen == singplan._HOME_OF


def test_dir_lists_every_public_name() -> None:
    assert set(singplan.__all__) <= set(dir(singplan))


def test_the_entry_module_gives_plan_plan_into_detect_and_the_task_readers() -> None:
    """The command line, the batch runner and ``singplan`` share one entry (issue 24)."""
    from singplan import batch, entry

    for name in ("plan", "plan_into", "detect", "load_task", "parse_task"):
        assert getattr(singplan, name) is getattr(entry, name)
    assert (batch.plan_into, batch.load_task) == (entry.plan_into, entry.load_task)


def test_a_fresh_interpreter_resolves_them_all() -> None:
    """In a new process (nothing imported yet), each name loads on first use."""
    code = "import singplan\nfor n in singplan.__all__: getattr(singplan, n)\nprint('ok')"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'detectt'"):
        singplan.detectt  # noqa: B018

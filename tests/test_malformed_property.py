"""Property: a valid task mutated into a malformed one exits 2 naming the mutated field.

Every bundled example task (singplan/demo_task.yaml, examples/*.yaml) is mutated by one
change that always makes it invalid; `singplan plan` (or `check`) must exit 2 with a
message naming the field, never 0, 1 or 3, never a traceback. Seeded (derandomize). The long run
has the `soak` marker (deselected by default, run by CI: ``python -m pytest -q -m soak``), with
10 x SINGPLAN_SOAK_EXAMPLES mutants (default 3000).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.cli_helpers import run_cli

ROOT = Path(__file__).resolve().parent.parent
SOURCES = [ROOT / "singplan" / "demo_task.yaml", *sorted((ROOT / "examples").glob("*.yaml"))]
VALID = {path.name: yaml.safe_load(path.read_text()) for path in SOURCES}
POSITIVE_KEYS = {"speed", "velocity_scale", "acceleration", "period", "orientation_tolerance_deg",
                 "position_tolerance_mm", "wrist_deg", "shoulder_mm", "elbow_deg"}
EXAMPLES = 200
SOAK_EXAMPLES = 10 * int(os.environ.get("SINGPLAN_SOAK_EXAMPLES", "300"))

Path_ = tuple[str | int, ...]


class Mutant(NamedTuple):
    """A malformed task as YAML text, and the words its error message must contain."""

    text: str
    words: tuple[str, ...]
    kind: str


def field(path: Path_) -> str:
    """``("moves", 0, "lin", "speed")`` -> ``moves[0].lin.speed`` (the messages' notation)."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
    return out


def nodes(doc: Any, path: Path_ = ()) -> list[tuple[Path_, Any]]:
    """Every node below the root with its path, parents before children."""
    found: list[tuple[Path_, Any]] = []
    children = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for key, value in children:
        found.append(((*path, key), value))
        found.extend(nodes(value, (*path, key)))
    return found


def get(doc: Any, path: Path_) -> Any:
    for part in path:
        doc = doc[part]
    return doc


def replaced(doc: Any, path: Path_, value: Any) -> Any:
    """A deep copy of ``doc`` with the node at ``path`` replaced (``...`` deletes a mapping key)."""
    copy = json.loads(json.dumps(doc))
    parent = get(copy, path[:-1])
    if value is ...:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return copy


class Raw(str):
    """Text written into the YAML as it is (a 400-digit integer, a 200-deep nesting)."""


def emit(value: Any, duplicate: Path_ | None = None, path: Path_ = ()) -> str:
    """``value`` as flow-style YAML; the mapping at ``duplicate`` repeats its first key."""
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, dict):
        items = [f"{json.dumps(str(k))}: {emit(v, duplicate, (*path, k))}" for k, v in value.items()]
        if path == duplicate:
            key = next(iter(value))
            items.append(f"{json.dumps(key)}: {emit(value[key])}")
        return "{" + ", ".join(items) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(emit(v, duplicate, (*path, i)) for i, v in enumerate(value)) + "]"
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    return json.dumps(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _leaf_key(path: Path_) -> str:
    return next(str(p) for p in reversed(path) if isinstance(p, str))


def _required(doc: dict[str, Any], path: Path_) -> bool:
    """Whether deleting the mapping key at ``path`` makes the task invalid."""
    key, parent = path[-1], path[:-1]
    if not parent:
        return key in ("robot", "start", "moves")
    if parent == ("start",):
        return key in ("joints_deg", "pose")
    if parent == ("start", "pose"):
        return True  # both xyz and rpy_deg are required for a start pose
    if len(parent) == 3 and parent[0] == "moves":  # moves[i].<kind>
        return key in ("to", "via")
    if len(parent) == 4 and parent[0] == "moves" and parent[3] in ("to", "via"):
        return key in ("xyz", "joints_deg")
    return len(parent) == 2 and parent[0] == "moves"  # the kind key of a move


def _wrong_type(value: Any) -> Any:
    if _is_number(value):
        return "fast"
    if isinstance(value, str):
        return 7
    if isinstance(value, list):
        return "abc"
    return [1, 2]


Mutation = Callable[[st.DrawFn, dict[str, Any], str], Mutant]


def delete_required(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    paths = [p for p, _ in nodes(doc) if isinstance(p[-1], str) and _required(doc, p)]
    path = draw(st.sampled_from(paths))
    words = (field(path[:-1]),) if len(path) > 1 else (str(path[0]),)
    return Mutant(emit(replaced(doc, path, ...)), words, f"delete {field(path)}")


def add_unknown_key(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    parents = [()] + [p for p, v in nodes(doc) if isinstance(v, dict)]
    parent = draw(st.sampled_from(parents))
    key = draw(st.sampled_from(["extra", "sped", "velocity", "colour", "Robot", "méthode"]))
    mutated = json.loads(json.dumps(doc))
    get(mutated, parent)[key] = 1
    return Mutant(emit(mutated), (field(parent), key), f"add {field((*parent, key))}")


def wrong_type(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    path, value = draw(st.sampled_from(nodes(doc)))
    return Mutant(emit(replaced(doc, path, _wrong_type(value))), (field(path),), f"wrong type at {field(path)}")


def bad_number(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    path, _ = draw(st.sampled_from([(p, v) for p, v in nodes(doc) if _is_number(v)]))
    bad: list[Any] = [math.nan, math.inf, -math.inf, 1e9, -1e9, Raw("9" * 400), Raw("1" + "0" * 320), 1e300]
    if _leaf_key(path) in POSITIVE_KEYS:
        bad += [0, -1, 1e-300, -0.0]
    value = draw(st.sampled_from(bad))
    return Mutant(emit(replaced(doc, path, value)), (field(path),), f"{value!s:.12} at {field(path)}")


def wrong_length(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    lists = [(p, v) for p, v in nodes(doc) if isinstance(v, list) and v and all(_is_number(x) for x in v)]
    path, value = draw(st.sampled_from(lists))
    length = draw(st.sampled_from([0, len(value) - 1, len(value) + 1, 65]))
    return Mutant(emit(replaced(doc, path, [1.0] * length)), (field(path),), f"{length} numbers at {field(path)}")


def duplicate_key(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    parents = [()] + [p for p, v in nodes(doc) if isinstance(v, dict) and v]
    parent = draw(st.sampled_from(parents))
    key = next(iter(get(doc, parent)))
    return Mutant(emit(doc, duplicate=parent), (field((*parent, key)), "twice"), f"duplicate {field((*parent, key))}")


def deep_nesting(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    path, _ = draw(st.sampled_from(nodes(doc)))
    depth = draw(st.integers(65, 3000))
    opening, closing = draw(st.sampled_from([("[", "]"), ('{"a": ', "}")]))
    nested = Raw(opening * depth + "1" + closing * depth)
    return Mutant(emit(replaced(doc, path, nested)), (field(path), "deeper than 64"), f"{depth} deep at {field(path)}")


def unknown_name(draw: st.DrawFn, doc: dict[str, Any], name: str) -> Mutant:
    choices: list[tuple[Path_, Any, str]] = [(("robot",), "abb_irb9999", "robot"),
                                             (("tip",), "flange_x", "tip frame"),
                                             (("singularity", "method"), "teleport", "singularity.method")]
    choices += [((*p, "config"), "X Y Z", field((*p, "config")))
                for p, _ in nodes(doc) if len(p) == 3 and p[0] == "moves"]
    path, value, words = draw(st.sampled_from(choices))
    mutated = json.loads(json.dumps(doc))
    parent = mutated
    for part in path[:-1]:
        parent = parent.setdefault(part, {}) if isinstance(part, str) else parent[part]
    parent[path[-1]] = value
    return Mutant(emit(mutated), (words, str(value)), f"{value} at {field(path)}")


MUTATIONS: list[Mutation] = [delete_required, add_unknown_key, wrong_type, bad_number, wrong_length,
                             duplicate_key, deep_nesting, unknown_name]


@st.composite
def mutants(draw: st.DrawFn) -> Mutant:
    name = draw(st.sampled_from(sorted(VALID)))
    mutation = draw(st.sampled_from(MUTATIONS))
    mutant = mutation(draw, VALID[name], name)
    return mutant._replace(kind=f"{name}: {mutant.kind}")


def run(mutant: Mutant, command: str) -> tuple[int, str]:
    with tempfile.TemporaryDirectory() as folder:
        task = Path(folder) / "task.yaml"
        task.write_text(mutant.text)
        shutil.copytree(ROOT / "examples" / "meshes", Path(folder) / "meshes")  # a cell's meshes, task-relative
        argv = ["plan", str(task), "-o", str(Path(folder) / "out")] if command == "plan" else ["check", str(task)]
        done = run_cli(*argv)
        assert not (Path(folder) / "out").exists()
    return done.code, done.text


def check_mutant(mutant: Mutant, command: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, text = run(mutant, command)
    captured = capsys.readouterr()
    text += captured.out + captured.err
    assert "Traceback" not in text, (mutant.kind, text)
    assert code == 2, (mutant.kind, code, text)
    for word in mutant.words:
        assert word in text, (mutant.kind, word, text)


@settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(mutant=mutants(), command=st.sampled_from(["plan", "plan", "check"]))
def test_malformed_tasks_exit_2_naming_the_field(mutant: Mutant, command: str,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    check_mutant(mutant, command, capsys)


@pytest.mark.soak
@settings(max_examples=SOAK_EXAMPLES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(mutant=mutants(), command=st.sampled_from(["plan", "check"]))
def test_malformed_tasks_soak(mutant: Mutant, command: str, capsys: pytest.CaptureFixture[str]) -> None:
    check_mutant(mutant, command, capsys)


@pytest.mark.parametrize("name", sorted(VALID))
def test_the_unmutated_tasks_are_valid(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """The starting points pass validation (`check` exits 0), so each failure above is the mutation's."""
    code, text = run(Mutant(emit(VALID[name]), (), "none"), "check")
    assert code == 0, text


@pytest.mark.parametrize("mutation", MUTATIONS, ids=lambda m: m.__name__)
def test_every_mutation_kind_is_exercised(mutation: Mutation, capsys: pytest.CaptureFixture[str]) -> None:
    """Each mutation kind on each example, with a fixed seed of draws, so none can go untested."""

    @settings(max_examples=10, derandomize=True, deadline=None, database=None,
              suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(data=st.data())
    def one(data: st.DataObject) -> None:
        name = data.draw(st.sampled_from(sorted(VALID)))
        check_mutant(mutation(data.draw, VALID[name], name), "plan", capsys)

    one()

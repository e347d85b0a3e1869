"""Every code block of README.md and docs/*.md, run as a reader would run it (sybil collects them).

pytest collects the Markdown files through sybil (the root conftest.py, ``testpaths`` in
pyproject.toml); each fenced block is one test item. What a block is, by its language:

- ``bash``: each command is run (``\\`` continues a line, ``&&`` chains, ``#`` starts a comment,
  ``*`` globs expand, a final ``> FILE`` takes stdout): ``singplan ...`` through
  :func:`singplan.cli.main` in this process, ``python ...`` as a subprocess; each must exit 0.
  Anything else must be marked not-run.
- ``python``: executed in the document's namespace (blocks of one page share it, in order);
  a block with an ``if __name__ == "__main__":`` guard is a script, run as a file in a subprocess.
- ``yaml``: a task (``robot``, ``start``, ``moves``) is planned and must exit 0 (its summary is
  what it prints); a controller
  sidecar (``controller:``) is read as singplan reads one; anything else must be an excerpt.
- ``json``: a document of singplan's ``--json`` output, valid against the schema of its format.
- ``output``: what the block right before it prints (stdout and stderr together, as a terminal
  shows them), compared after normalisation: trailing spaces dropped, the one-time note of the
  kernels' compilation left out, ``...`` inside a line matches any text on that line (paths,
  timings), a line of just ``...`` any number of lines.
- ``text``: a diagram or listing, not run. A block without a language is an error.

Directives, an HTML comment right before a block:

- ``<!-- not-run: KIND -->``: the block is not run, for a reason of :data:`NOT_RUN`; the test
  checks the marking is deliberate (every line of the block is of that kind) and, for a
  benchmark, that the script exists and takes every option the block gives it.
- ``<!-- excerpt-of: examples/FILE.yaml -->``: a YAML fragment cut from that example, which
  must contain it (the fragment cannot drift from a file that is planned elsewhere).

Each page runs in a fresh temporary folder holding links to the project's folders the pages name
(:data:`LINKED`: ``examples/``, ``bench/``, ...) and the placeholder files (:data:`PLACEHOLDERS`),
so commands write their outputs there and nothing in the project changes.
"""

from __future__ import annotations

import contextlib
import glob
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from sybil import Document, Example, Region, Sybil
from sybil.parsers.markdown.lexers import DirectiveInHTMLCommentLexer, FencedCodeBlockLexer

ROOT = Path(__file__).resolve().parent.parent
RUN = ("bash", "python", "yaml", "json")
NOT_RUN: dict[str, tuple[str, str]] = {  # kind -> (a pattern every line of the block holds, why)
    "install": (r"\bpip install\b", "installs packages; the test suite runs inside an installation"),
    "test-suite": (r"\bpython -m pytest\b", "runs the test suite, which runs this block"),
    "desktop": (r"^xdg-open\b", "opens a desktop application"),
    "server": (r"(--serve\b|serve=True)", "starts a server that runs until it is stopped"),
    "benchmark": (r"^python bench/\S+\.py\b", "a benchmark of minutes on 2 cores; bench/ is run by hand"),
}
# the project's folders the pages' commands name; not the package (a process started here would import
# singplan from the link, and a batch's long-lived worker server would lose it with the folder)
LINKED = ("examples", "bench", "docs", "robots")
PLACEHOLDERS = {  # names the docs use for the reader's own files -> the example that stands in for them
    "task.yaml": "examples/kuka_program.yaml",
    "cell/weld_a.yaml": "examples/abb_near_miss_auto.yaml",
    "cell/weld_b.yaml": "examples/kuka_program.yaml",
}
PLANNED_PLACEHOLDERS = {"OUT": "singplan/demo_task.yaml"}  # output folders the docs name: planned first


@dataclass(frozen=True)
class Block:
    """A fenced block and what comes with it."""

    language: str
    source: str
    line: int  # of the block's first source line in the page
    not_run: str | None = None  # a key of NOT_RUN
    excerpt_of: str | None = None  # the example file a YAML fragment is cut from
    expected: str | None = None  # the output block after it


def parse_blocks(document: Document) -> list[Region]:
    """sybil parser: one region per block to check, with its directive and expected output."""
    fences = list(FencedCodeBlockLexer(language=r"[^\n]*")(document))
    directives = list(DirectiveInHTMLCommentLexer(directive=r"not-run|excerpt-of", arguments=r"[^\n]*?")(document))
    items = sorted([(r.start, "fence", r) for r in fences] + [(r.start, "directive", r) for r in directives],
                   key=lambda item: item[0])
    regions: list[Region] = []
    pending: Region | None = None  # a directive waiting for its block
    previous: tuple[Region, Block] | None = None  # the last block that may take an output block
    for _, kind, region in items:
        line = document.text.count("\n", 0, region.start) + 1
        if kind == "directive":
            if pending is not None:
                raise ValueError(f"{document.path}:{line}: two directives in a row")
            pending = region
            continue
        language = region.lexemes["language"].strip()
        source = str(region.lexemes["source"])
        if language == "output":
            if previous is None or document.text[previous[0].end:region.start].strip() or pending is not None:
                raise ValueError(f"{document.path}:{line}: an output block must follow the block that prints it")
            code_region, block = previous
            code_region.parsed = Block(**{**block.__dict__, "expected": source})
            previous = None
            continue
        if language not in (*RUN, "text"):
            kinds = ", ".join((*RUN, "text", "output"))
            raise ValueError(f"{document.path}:{line}: a block needs a language ({kinds}), got {language!r}")
        if language == "text":
            if pending is not None:
                raise ValueError(f"{document.path}:{line}: a directive before a text block")
            previous = None
            continue
        block = Block(language, source, line + 1, **_directive(document, pending))
        pending = None
        code = Region(region.start, region.end, block, evaluate)
        regions.append(code)
        previous = (code, block)
    if pending is not None:
        raise ValueError(f"{document.path}: a directive with no block after it")
    return regions


def _directive(document: Document, region: Region | None) -> dict[str, str]:
    if region is None:
        return {}
    name, argument = region.lexemes["directive"], region.lexemes["arguments"].strip()
    if name == "not-run":
        if argument not in NOT_RUN:
            raise ValueError(f"{document.path}: not-run: {argument!r} is no kind of {', '.join(NOT_RUN)}")
        return {"not_run": argument}
    if not (ROOT / argument).is_file():
        raise ValueError(f"{document.path}: excerpt-of: {argument} is not a file of the project")
    return {"excerpt_of": argument}


# --- evaluation -----------------------------------------------------------------------------------

def evaluate(example: Example) -> str | None:
    block: Block = example.parsed
    where = f"{Path(example.path).name}:{block.line}"
    if block.not_run is not None:
        check_not_run(block, where)
        return None
    _plan_placeholders(block.source)
    run = {"bash": run_bash, "python": run_python, "yaml": run_yaml, "json": run_json}[block.language]
    printed = run(block, example.namespace, example.path)
    if block.expected is not None and not output_matches(block.expected, printed):
        return (f"{where}: the block printed\n{printed}\nwhich does not match the output the page shows:\n"
                f"{block.expected}")
    return None


def commands(source: str) -> list[list[str]]:
    """The commands of a shell block: continuation lines joined, comments dropped, ``&&`` split."""
    text = source.replace("\\\n", " ")
    out: list[list[str]] = []
    for line in text.splitlines():
        words = shlex.split(line, comments=True)
        while "&&" in words:
            cut = words.index("&&")
            out.append(words[:cut])
            words = words[cut + 1:]
        if words:
            out.append(words)
    return out


def run_bash(block: Block, namespace: dict[str, Any], page: str) -> str:
    from singplan.cli import main

    printed = []
    for argv in commands(block.source):
        argv, target = (argv[:-2], argv[-1]) if len(argv) > 2 and argv[-2] == ">" else (argv, None)
        args = [match for word in argv[1:] for match in (sorted(glob.glob(word)) if "*" in word else [word])]
        if argv[0] == "singplan":
            out, err = io.StringIO(), io.StringIO()
            code = main(args, out=out, err=err if target is not None else out)  # as a terminal shows them
            text, errors = out.getvalue(), err.getvalue()
        elif argv[0] == "python":
            done = subprocess.run([sys.executable, *args], stdout=subprocess.PIPE, text=True, timeout=900,
                                  check=False, stderr=subprocess.PIPE if target is not None else subprocess.STDOUT)
            code, text, errors = done.returncode, done.stdout, done.stderr or done.stdout
        else:
            raise AssertionError(f"{shlex.join(argv)}: the docs harness runs singplan and python commands only; "
                                 f"mark the block <!-- not-run: KIND --> ({', '.join(NOT_RUN)})")
        assert code == 0, f"{shlex.join(argv)} exited {code}:\n{errors}"
        if target is not None:  # `> FILE`: stdout into the file (in the page's temporary folder)
            Path(target).write_text(text)
        else:
            printed.append(text)
    return "".join(printed)


def run_python(block: Block, namespace: dict[str, Any], page: str) -> str:
    if re.search(r"^if __name__ == .__main__.:", block.source, re.MULTILINE):
        script = Path(f"docs_block_{block.line}.py")
        script.write_text(block.source)
        done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=900,
                              check=False)
        assert done.returncode == 0 and not done.stderr.strip(), (
            f"the script exited {done.returncode} and printed on stderr:\n{done.stderr}")
        return done.stdout
    code = compile("\n" * (block.line - 1) + block.source, page, "exec")  # the page's lines
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(code, namespace)
    return out.getvalue()


def run_yaml(block: Block, namespace: dict[str, Any], page: str) -> str:
    value = yaml.safe_load(block.source)
    if block.excerpt_of is not None:
        whole = yaml.safe_load((ROOT / block.excerpt_of).read_text())
        assert contains(whole, value), f"the fragment is not part of {block.excerpt_of}: {value!r}"
        return ""
    if isinstance(value, dict) and {"robot", "start", "moves"} <= set(value):
        from singplan.cli import main

        task = Path(f"docs_task_{block.line}.yaml")
        task.write_text(block.source)
        out, err = io.StringIO(), io.StringIO()
        code = main(["plan", str(task), "-o", f"docs_out_{block.line}", "--no-report", "--no-replay"], out=out,
                    err=err)
        assert code == 0, f"the task exits {code}: {err.getvalue()}"
        return out.getvalue()  # the summary: an output block may follow
    if isinstance(value, dict) and set(value) == {"controller"}:
        from singplan.kinematics.vendor_config import parse_convention

        assert parse_convention(value["controller"], "controller.yaml: controller") is not None
        return ""
    raise AssertionError("a YAML block is a task (robot, start, moves), a controller sidecar, "
                         "or marked <!-- excerpt-of: examples/FILE.yaml -->")


def run_json(block: Block, namespace: dict[str, Any], page: str) -> str:
    """A JSON document of singplan's (``format`` ``singplan.<command>/<n>``): valid against its schema."""
    import jsonschema

    from singplan.outputs import documents

    value = json.loads(block.source)
    command = re.fullmatch(r"singplan\.(\w+)/\d+", str(value.get("format", "")) if isinstance(value, dict) else "")
    assert command is not None and command.group(1) in documents.COMMANDS, "a JSON block is a document of singplan's"
    jsonschema.validate(value, documents.schema(command.group(1)))
    return ""


def contains(whole: Any, part: Any) -> bool:
    """``part`` is found in ``whole``: a sub-mapping, a run of a list's mappings (moves), or a value, at
    any depth."""
    if _within(whole, part):
        return True
    children = whole.values() if isinstance(whole, dict) else whole if isinstance(whole, list) else ()
    return any(contains(child, part) for child in children)


def _within(whole: Any, part: Any) -> bool:
    if isinstance(part, dict) and isinstance(whole, dict):
        return all(k in whole and _within(whole[k], v) for k, v in part.items())
    if isinstance(part, list) and isinstance(whole, list):
        if not all(isinstance(p, dict) for p in part):  # numbers (xyz, joints): the whole list
            return len(part) == len(whole) and all(_within(w, p) for w, p in zip(whole, part, strict=True))
        return any(all(_within(w, p) for w, p in zip(whole[i:i + len(part)], part, strict=True))  # moves: a run
                   for i in range(len(whole) - len(part) + 1))
    return bool(whole == part)


_ONCE = "singplan: first run after an install"  # the note of the kernels' one compilation: not shown


def output_matches(expected: str, printed: str) -> bool:
    """``printed`` against a page's output block: trailing spaces ignored, ``...`` matches any text."""
    pattern = []
    for line in expected.rstrip("\n").splitlines():
        line = line.rstrip()
        if line == "...":
            pattern.append(r"(?:[^\n]*\n)*?")
        else:
            pattern.append(".*?".join(re.escape(part) for part in line.split("...")) + r"[ \t]*\n")
    lines = "".join(line.rstrip() + "\n" for line in printed.splitlines() if not line.startswith(_ONCE))
    return re.fullmatch("".join(pattern), lines) is not None


def check_not_run(block: Block, where: str) -> None:
    """A block marked not-run: every line of it is of the kind named (the marking is deliberate)."""
    assert block.not_run is not None
    pattern = NOT_RUN[block.not_run][0]
    texts = ([line for line in block.source.replace("\\\n", " ").splitlines() if shlex.split(line, comments=True)]
             if block.language == "bash" else [block.source])
    assert texts, f"{where}: an empty block marked not-run"
    for text in texts:
        assert re.search(pattern, text, re.MULTILINE), (
            f"{where}: {text!r} is not of the kind not-run: {block.not_run} ({NOT_RUN[block.not_run][1]}); run it")
    if block.not_run == "benchmark":
        for argv in commands(block.source):
            _check_script_options(argv, where)


def _check_script_options(argv: list[str], where: str) -> None:
    """A benchmark command names a script that exists and whose --help lists every option given."""
    script = ROOT / argv[1]
    assert script.is_file(), f"{where}: {argv[1]} does not exist"
    done = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=300,
                          check=False, cwd=ROOT)
    assert done.returncode == 0, f"{where}: {argv[1]} --help exited {done.returncode}: {done.stderr}"
    for option in (word.split("=")[0] for word in argv[2:] if word.startswith("--")):
        assert re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", done.stdout), (
            f"{where}: {argv[1]} has no option {option}")


# --- one temporary folder per page ------------------------------------------------------------------

def setup(namespace: dict[str, Any]) -> None:
    """A fresh folder for the page: links to the project's entries, the placeholder files."""
    from singplan.planning.crossing import registry

    folder = Path(tempfile.mkdtemp(prefix="singplan-docs-"))
    for name in LINKED:
        (folder / name).symlink_to(ROOT / name)
    for name, source in PLACEHOLDERS.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / source, folder / name)
    namespace["_docs"] = {"cwd": os.getcwd(), "folder": folder, "registered": dict(registry._METHODS)}
    namespace["__name__"] = "__docs__"
    os.chdir(folder)


def _plan_placeholders(source: str) -> None:
    """The output folders a block names (``OUT``), planned before the block runs, once per page."""
    from singplan.cli import main

    for name, task in PLANNED_PLACEHOLDERS.items():
        if re.search(rf"\b{name}\b", source) and not Path(name).exists():
            assert main(["plan", str(ROOT / task), "-o", name, "--quiet"], out=io.StringIO(), err=io.StringIO()) == 0


def teardown(namespace: dict[str, Any]) -> None:
    """Back to where the tests run; the folder removed; methods a page registered forgotten."""
    from singplan.planning.crossing import registry

    state = namespace["_docs"]
    os.chdir(state["cwd"])
    shutil.rmtree(state["folder"], ignore_errors=True)
    registry._METHODS.clear()
    registry._METHODS.update(state["registered"])


DOCS = Sybil(parsers=[parse_blocks], path=str(ROOT), patterns=["README.md", "docs/*.md"], setup=setup,
             teardown=teardown, name="docs")

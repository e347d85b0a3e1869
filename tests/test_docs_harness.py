"""The harness that runs the docs' blocks (tests/docs_harness.py): it covers every page, refuses
what it cannot check, compares output as documented, and a not-run marking must be deliberate."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from sybil import Document

from singplan.results.trajectory import load
from tests.docs_harness import (
    DOCS,
    NOT_RUN,
    ROOT,
    Block,
    check_not_run,
    commands,
    contains,
    output_matches,
    parse_blocks,
)


def blocks(text: str) -> list[Block]:
    return [region.parsed for region in parse_blocks(Document(text, "page.md"))]


def test_every_page_is_collected() -> None:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    assert len(pages) >= 9
    assert all(DOCS.should_parse(page) for page in pages)
    assert 'testpaths = ["tests", "README.md", "docs"]' in (ROOT / "pyproject.toml").read_text()


def test_every_page_parses_and_the_readme_quick_start_is_the_install_it_describes() -> None:
    for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]:
        DOCS.parse(page)  # a block without a language, an orphan output block ... would raise here
    readme = blocks((ROOT / "README.md").read_text())
    assert readme[0].not_run == "install"
    assert commands(readme[0].source) == [["pip", "install", "."], ["singplan", "demo"],
                                          ["pip", "install", ".[test]"], ["python", "-m", "pytest", "-q"]]


def test_blocks_take_their_directive_and_output() -> None:
    page = ("<!-- not-run: server -->\n```bash\nsingplan replay out --serve\n```\n\n"
            "```bash\nsingplan robots\n```\n\n```output\nname ...\n...\n```\n\n"
            "<!-- excerpt-of: examples/weave_seam.yaml -->\n```yaml\nspeed: 0.012\n```\n"
            "```text\na diagram\n```\n")
    found = blocks(page)
    assert [(b.language, b.not_run, b.excerpt_of, b.expected) for b in found] == [
        ("bash", "server", None, None), ("bash", None, None, "name ...\n...\n"),
        ("yaml", None, "examples/weave_seam.yaml", None)]


@pytest.mark.parametrize("page, message", [
    ("```\nsingplan robots\n```\n", "needs a language"),
    ("```console\n$ singplan robots\n```\n", "needs a language"),
    ("Some text.\n\n```output\nx\n```\n", "must follow the block that prints it"),
    ("```bash\nsingplan robots\n```\n\nIt prints:\n\n```output\nx\n```\n", "must follow the block that prints it"),
    ("<!-- not-run: slow -->\n```bash\nsingplan robots\n```\n", "is no kind of"),
    ("<!-- excerpt-of: examples/none.yaml -->\n```yaml\na: 1\n```\n", "is not a file of the project"),
    ("<!-- not-run: install -->\n", "a directive with no block after it"),
])
def test_what_cannot_be_checked_is_refused(page: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        blocks(page)


def test_a_not_run_marking_must_be_deliberate() -> None:
    check_not_run(Block("bash", "pip install . && singplan demo\n", 1, not_run="install"), "page.md:1")
    with pytest.raises(AssertionError, match="is not of the kind not-run: install"):
        check_not_run(Block("bash", "pip install .\nsingplan robots\n", 1, not_run="install"), "page.md:1")
    with pytest.raises(AssertionError, match="is not of the kind not-run: server"):
        check_not_run(Block("python", "import singplan\nsingplan.replay('OUT', html='r.html')\n", 1,
                            not_run="server"), "page.md:1")
    assert set(NOT_RUN) == {"install", "test-suite", "desktop", "server", "benchmark"}


def test_a_benchmark_marked_not_run_must_name_real_options() -> None:
    check_not_run(Block("bash", "python bench/robots_acceptance.py --quick --markdown\n", 1, not_run="benchmark"),
                  "page.md:1")
    with pytest.raises(AssertionError, match="has no option --fast"):
        check_not_run(Block("bash", "python bench/robots_acceptance.py --fast\n", 1, not_run="benchmark"),
                      "page.md:1")
    with pytest.raises(AssertionError, match="does not exist"):
        check_not_run(Block("bash", "python bench/none.py\n", 1, not_run="benchmark"), "page.md:1")


def test_commands_join_lines_drop_comments_and_split_chains() -> None:
    source = "singplan plan a.yaml \\\n    -o out   # plan it\n# a comment\npip install . && singplan demo\n"
    assert commands(source) == [["singplan", "plan", "a.yaml", "-o", "out"], ["pip", "install", "."],
                                ["singplan", "demo"]]


def test_output_is_compared_line_by_line_with_ellipses() -> None:
    printed = "planned in 0.58 s\nwrote /tmp/x/out/a.csv\nline 3\nline 4\nlast   \n"
    assert output_matches("planned in ... s\nwrote .../out/a.csv\n...\nlast\n", printed)
    assert output_matches("planned in ... s\n...\n", printed)
    assert not output_matches("planned in ... s\nwrote .../out/b.csv\n...\n", printed)
    assert not output_matches("planned in 0.59 s\n...\n", printed)
    assert not output_matches("planned in ... s\n", printed)  # everything printed is accounted for
    assert not output_matches("planned in ... s\nwrote ...\n", "planned in 1 s\nwrote a\nwrote b\n")
    assert output_matches("x\n", "singplan: first run after an install: compiling ...\nx\n")


def test_an_excerpt_is_found_in_its_file() -> None:
    whole = {"moves": [{"a": 1}, {"b": {"c": [1, 2, 3]}}, {"d": 4}], "e": 5}
    assert contains(whole, [{"b": {"c": [1, 2, 3]}}, {"d": 4}])
    assert contains(whole, {"moves": [{"a": 1}]}) and contains(whole, {"c": [1, 2, 3]})
    assert not contains(whole, [{"a": 1}, {"d": 4}])  # not a run of consecutive moves
    assert not contains(whole, {"b": {"c": [1, 2]}})  # a vector is whole or not at all
    assert not contains(whole, {"e": 6})


def test_the_docs_folder_holds_no_stray_code(tmp_path: Path) -> None:
    """Indented (4-space) code blocks are not collected: the pages use fenced blocks only."""
    for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]:
        lines = page.read_text().splitlines()
        fenced = False
        for n, line in enumerate(lines):
            if line.startswith("```"):
                fenced = not fenced
            previous = lines[n - 1] if n else ""
            if not fenced and line.startswith("    ") and not previous.strip() and line.strip():
                raise AssertionError(f"{page.name}:{n + 1}: an indented code block; fence it with a language")


def test_the_readme_picture_is_of_the_demo_as_it_plans_now(planned_kuka: Path) -> None:
    """docs/screenshot.py stamps the demo's duration into the PNG; a plan that changes needs a new picture."""
    spec = importlib.util.spec_from_file_location("screenshot", ROOT / "docs" / "screenshot.py")
    assert spec is not None and spec.loader is not None
    screenshot = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(screenshot)
    stamped = screenshot.png_text((ROOT / "docs" / "img" / "replay.png").read_bytes())
    assert stamped[screenshot.DURATION_KEY] == f"{load(planned_kuka).duration_s:.3f}", (
        "docs/img/replay.png shows another plan than the demo's: run python docs/screenshot.py")

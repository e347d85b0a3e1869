"""pytest collects README.md and docs/*.md too (``testpaths``): sybil turns every code block into a
test item, run as a reader would run it (tests/docs_harness.py says how)."""

from tests.docs_harness import DOCS

pytest_collect_file = DOCS.pytest()

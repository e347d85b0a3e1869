"""`python -m singplan ...` runs the CLI."""

from singplan.cli import run

run()

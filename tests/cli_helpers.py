"""The command line run in-process, as the tests run it: ``singplan.cli.main(argv)`` with its two
streams captured (the CLI is ``main(argv) -> int`` so that tests need no subprocess)."""

from __future__ import annotations

import io
import os
from typing import NamedTuple

from singplan.cli import main


class CliRun(NamedTuple):
    """What one ``singplan`` command did: its exit code and what it wrote to stdout and stderr."""

    code: int
    out: str
    err: str

    @property
    def text(self) -> str:
        """Everything it printed, stdout then stderr."""
        return self.out + self.err


def run_cli(*argv: str | os.PathLike[str]) -> CliRun:
    """``singplan ARGV`` (paths given as they are): exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    code = main([os.fspath(a) for a in argv], out=out, err=err)
    return CliRun(code, out.getvalue(), err.getvalue())


def assert_no_traceback(text: str) -> None:
    """A user never sees a traceback, only a message."""
    assert "Traceback" not in text and 'File "' not in text, text

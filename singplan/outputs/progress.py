"""Progress of long work on a terminal: a tqdm bar fed by the planner's ``Progress`` callback.

``singplan plan`` calls :func:`plan_bar` around planning. On a terminal (and without
``--quiet``) the bar appears as soon as planning starts, counts the moves as the planner
finishes them (``progress(done, total)`` of :mod:`singplan.planning.orchestration.planner`) with tqdm's rate
and time left, and once every move is planned says what remains (fly-by corners timed
together, the samples checked, the files written) until the bar is closed. Anywhere else (a
pipe, a file, a CI log) nothing is drawn: the bar is for people watching.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from tqdm import tqdm


FINISHING = "corners, checks, files"


class PlanBar:
    """The bar of one plan: ``start()`` when planning begins, ``progress`` as moves are planned."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self._bar: tqdm | None = None

    def start(self) -> None:
        from tqdm import tqdm  # here, not at the top: only a plan watched on a terminal pays its import

        if self._bar is None:
            self._bar = tqdm(total=None, desc="planning", unit="move", file=self._stream, leave=False,
                             dynamic_ncols=True)

    def progress(self, done: int, total: int) -> None:
        self.start()
        assert self._bar is not None
        if self._bar.total != total:
            self._bar.reset(total=total)
        self._bar.update(done - self._bar.n)
        if done == total:
            self._bar.set_description(FINISHING)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()  # leave=False: the line is cleared, the summary follows on a clean screen
            self._bar = None


@contextlib.contextmanager
def plan_bar(stream: TextIO, quiet: bool) -> Iterator[PlanBar | None]:
    """A :class:`PlanBar` on ``stream`` when it is a terminal and not ``quiet``, else None."""
    if quiet or not _is_terminal(stream):
        yield None
        return
    bar = PlanBar(stream)
    try:
        yield bar
    finally:
        bar.close()


def _is_terminal(stream: TextIO) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())

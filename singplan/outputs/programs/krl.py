"""KUKA KRL (KR C4 / KR C5, KUKA System Software 8.x): a ``.src`` program of PTP spline blocks.

The program (no ``.dat`` file: every point is an inline E6AXIS aggregate ``{A1 .., A6 ..}``, which
KRL accepts wherever a point is expected, so there is nothing to declare)::

    DEF name( )
      BAS (#INITMOV, 0)
      $VEL_AXIS[i] = 10                    ; the first motion at 10 % axis speed (BCO run)
      SPTP {A1 .., .., A6 ..}              ; to the start point, exact stop
      $VEL_AXIS[i] = 100 / $ACC_AXIS[i] = 100
      PTP_SPLINE                           ; one block per stretch between exact stops
        SPTP {..}                          ; where the robot stands (a segment of length 0)
        TIME_BLOCK START
        SPTP {..}
        TIME_BLOCK PART = 0.048            ; the planned time of the segment before it [s]
        ...
        TIME_BLOCK END = 1.234             ; the block's planned time [s]
      ENDSPLINE                            ; the block ends in an exact stop
    END

Manual (KUKA System Software 8.x, operating and programming instructions for system integrators):
"PTP spline block" and "SPTP" (the spline passes through every point of the block, in axis space,
without stopping); "TIME_BLOCK" (the segments between ``TIME_BLOCK START`` and ``TIME_BLOCK END``
take the given total time, shared out in proportion to the ``TIME_BLOCK PART`` values; the time
block begins at the end point of the segment before ``TIME_BLOCK START``, which is why each block
first names the point the robot stands on); "Approximate positioning" (``ENDSPLINE C_SPL`` flies
into the next block); system variables ``$VEL_AXIS`` / ``$ACC_AXIS`` (percent of the machine data's
axis speed and acceleration).

A block holds at most :attr:`Krl.block_segments` segments; a stretch without an exact stop that is
longer continues in the next block (``ENDSPLINE C_SPL``), whose first segment starts in flight, so
it cannot open a time block: it is timed by axis speed instead (``WITH $VEL_AXIS[i] = p``, p the
percent at which the leading axis takes the planned time, ignoring acceleration), the one place the
program's timing is approximate beyond the controller's own spline.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TextIO

from singplan.kinematics.vendor_config import Vendor
from singplan.outputs.programs.model import (
    APPROACH_PERCENT,
    Dialect,
    Motion,
    Note,
    Part,
    ProgramModel,
    number,
    seconds,
    wrap,
)

_AXES = 6


class Krl(Dialect):
    fmt = "krl"
    title = "KUKA KRL"
    vendor: Vendor = "kuka"
    extension = ".src"
    name_max = 24
    name_pattern = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*")
    name_rule = "letters, digits, _ and $, not starting with a digit"
    axis_decimals = 4
    time_step_s = 1e-6  # printed to the microsecond: a period that is not whole milliseconds keeps its times
    max_part_lines = 4800  # below 5000 lines per .src with the block lines the count leaves out
    comment_width = 76
    block_segments = 500
    manual = ("KSS 8.x manual for system integrators: PTP spline block, SPTP, TIME_BLOCK, "
              "approximate positioning (C_SPL), $VEL_AXIS")

    def motion_lines(self, motion: Motion) -> int:
        return 2 + (5 if motion.stop else 0)  # SPTP and its TIME_BLOCK PART; a stop closes a block and opens one

    def write_main(self, stream: TextIO, model: ProgramModel) -> None:
        w = stream.write
        w(f"&ACCESS RVP\n&REL 1\nDEF {model.name}( )\n")
        for line in model.header:
            w("".join(f"; {text}\n" for text in wrap(line, self.comment_width)))
        w("  BAS (#INITMOV, 0)\n")
        w(f"  ; first motion (BCO run): to the start point at {APPROACH_PERCENT} % axis speed, exact stop\n")
        w("".join(f"  $VEL_AXIS[{i}] = {APPROACH_PERCENT}\n" for i in range(1, _AXES + 1)))
        w(f"  SPTP {_axes(model.start)}\n")
        w("  ; the planned motion: its own times, at full axis speed and acceleration allowed\n")
        w("".join(f"  $VEL_AXIS[{i}] = 100\n  $ACC_AXIS[{i}] = 100\n" for i in range(1, _AXES + 1)))
        if model.split:
            w("".join(f"  {part.name}( )\n" for part in model.parts))
        else:
            self._body(stream, model, model.parts[0])
        w("END\n")

    def write_part(self, stream: TextIO, model: ProgramModel, part: Part) -> None:
        number_ = model.parts.index(part) + 1
        stream.write(f"&ACCESS RVP\n&REL 1\nDEF {part.name}( )\n"
                     f"; part {number_} of {len(model.parts)} of {model.name}: run {model.name}, not this part alone\n")
        self._body(stream, model, part)
        stream.write("END\n")

    def notes(self, model: ProgramModel) -> list[str]:
        joins = sum(isinstance(e, _Begin) and not e.before.stop for part in model.parts
                    for e in _events(part, self.block_segments))
        if not joins:
            return []
        return [f"{joins} spline block(s) continue in flight (a block holds at most {self.block_segments} "
                "segments): the first segment of each is timed by axis speed ($VEL_AXIS), not by a time block"]

    def _body(self, stream: TextIO, model: ProgramModel, part: Part) -> None:
        w = stream.write
        timing, total_s = False, 0.0
        for event in _events(part, self.block_segments):
            if isinstance(event, Note):
                indent = "    " if timing else "  "
                w("".join(f"{indent}; {text}\n" for text in wrap(event.text, self.comment_width)))
            elif isinstance(event, _Begin):
                timing, total_s = False, 0.0
                w("  PTP_SPLINE\n")
                if event.before.stop:  # the robot stands on it: the time block starts there
                    w(f"    SPTP {_axes(event.before)} ; where the robot stands\n")
                else:
                    first = event.first
                    percent = speed_percent(event.before, first, model.axis_speed_deg_s)
                    with_ = ", ".join(f"$VEL_AXIS[{i}] = {percent}" for i in range(1, _AXES + 1))
                    w(f"    ; continued in flight: timed by axis speed (planned {seconds(first.duration_s)} s)\n"
                      f"    SPTP {_axes(first)} WITH {with_}\n")
            elif isinstance(event, _End):
                if timing:
                    w(f"    TIME_BLOCK END = {seconds(total_s)}\n")
                w("  ENDSPLINE\n" if event.stop else "  ENDSPLINE C_SPL\n")
                timing = False
            else:
                if not timing:
                    w("    TIME_BLOCK START\n")
                    timing = True
                w(f"    SPTP {_axes(event)}\n    TIME_BLOCK PART = {seconds(event.duration_s)}\n")
                total_s += event.duration_s


@dataclass(frozen=True)
class _Begin:
    """A PTP spline block opens, its first segment running from ``before`` to ``first``."""

    before: Motion
    first: Motion


@dataclass(frozen=True)
class _End:
    """A PTP spline block closes: at an exact stop, or flying on (C_SPL)."""

    stop: bool


def _events(part: Part, limit: int) -> Iterator[Note | Motion | _Begin | _End]:
    """The part as PTP spline blocks: one per stretch between exact stops, of at most ``limit`` segments.

    A block opened on a point the robot stands on names that point and times every segment after
    it; a block opened in flight (after a full one) times its first segment by axis speed, and that
    motion is written with its :class:`_Begin`, not yielded again."""
    before, count = part.before, -1  # count: segments in the open block, -1 when none is open
    for item in part.items:
        if isinstance(item, Note):
            yield item
            continue
        if count < 0:
            yield _Begin(before, item)
            if before.stop:
                yield item
            count = 1
        else:
            yield item
            count += 1
        if item.stop or count >= limit:
            yield _End(item.stop)
            count = -1
        before = item
    if count >= 0:
        yield _End(False)


def speed_percent(before: Motion, motion: Motion, axis_speed_deg_s: tuple[float, ...]) -> int:
    """The $VEL_AXIS percent (1..100) at which the leading axis covers its step in the motion's time."""
    need = max(abs(b - a) / (v * motion.duration_s) for a, b, v in zip(before.axes_deg, motion.axes_deg,
                                                                          axis_speed_deg_s, strict=True))
    return min(100, max(1, round(100.0 * need)))


def _axes(motion: Motion) -> str:
    return "{" + ", ".join(f"A{i} {number(v, 4)}" for i, v in enumerate(motion.axes_deg, start=1)) + "}"

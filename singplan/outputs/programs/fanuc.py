"""FANUC TP source (R-30iA / R-30iB): an ``.ls`` program of joint moves with times in milliseconds.

The program (ASCII source, converted to a ``.tp`` by the controller's ASCII Upload option or by
ROBOGUIDE / WinOLPC ``maketp``)::

    /PROG  NAME
    /ATTR
    ...
    /MN
       1:  !first motion to the start ;
       2:J P[1] 10% FINE    ;
       3:J P[2] 48msec CNT100    ;
       4:J P[3] 52msec FINE    ;
    /POS
    P[1]{
       GP1:
        UF : 0, UT : 1,
        J1=    10.000 deg,  J2=   -20.000 deg,  J3=    30.000 deg,
        J4=     0.000 deg,  J5=   -90.000 deg,  J6=     0.000 deg
    };
    /END

Manual (FANUC R-30iB operator's manual, basic operation, B-83284EN): "Motion instructions": joint
motion ``J``, speed in ``%`` (the first motion, 10 % of the joint speed) or as the time of the
motion in ``sec`` / ``msec`` (1 to 32000 msec), termination ``FINE`` (the robot stops at the point)
or ``CNT100`` (it does not decelerate there and rounds the corner, flying on); "Position data":
joint representation ``J1= .. deg`` (three decimals, as the controller prints them), which carries
no configuration string: the configuration each move ends in is written as a remark (``!``).
The joint values are the controller's, with J2/J3 interaction (J3 measured from the horizontal).
Programs longer than 9999 lines are split into parts the main program ``CALL``s.
"""

from __future__ import annotations

import re
import time
from typing import TextIO

from singplan.kinematics.vendor_config import Vendor
from singplan.outputs.programs.model import (
    APPROACH_PERCENT,
    Dialect,
    Motion,
    Note,
    Part,
    ProgramModel,
    clean,
    number,
    stamp,
    wrap,
)

MAX_MSEC = 32000  # the longest time a joint motion can be given in msec


class FanucLs(Dialect):
    fmt = "fanuc-ls"
    title = "FANUC TP"
    vendor: Vendor = "fanuc"
    extension = ".ls"
    name_max = 36  # R-30iA and later (the R-J3iB took 8)
    name_pattern = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
    name_rule = "letters, digits and _, starting with a letter"
    axis_decimals = 3
    time_step_s = 1e-3
    max_segment_s = MAX_MSEC / 1000.0
    max_part_lines = 9999
    comment_width = 32  # a remark (!) holds 32 characters
    manual = "FANUC R-30iB operator manual B-83284EN: motion instructions (J, msec, FINE, CNT), position data"

    def program_name(self, name: str) -> str:
        return name.upper()

    def overhead_lines(self, header: tuple[str, ...], main: bool) -> int:
        if main:  # the header's remarks, then a remark and the first motion
            return sum(len(wrap(line, self.comment_width)) for line in header) + 2
        return len(wrap(_part_remark(99999, 99999, "X" * self.name_max), self.comment_width))

    def write_main(self, stream: TextIO, model: ProgramModel) -> None:
        lines = [_remark(text, self.comment_width) for line in model.header
                 for text in wrap(line, self.comment_width)]
        lines += [_remark("first motion to the start", self.comment_width), f"J P[1] {APPROACH_PERCENT}% FINE    "]
        positions = [model.start]
        if model.split:
            lines += [f"CALL {part.name}    " for part in model.parts]
        else:
            positions += self._body(lines, model.parts[0], first=2)
        _write(stream, model.name, clean(model.name)[:16], lines, positions)

    def write_part(self, stream: TextIO, model: ProgramModel, part: Part) -> None:
        number_ = model.parts.index(part) + 1
        lines = [_remark(text, self.comment_width)
                 for text in wrap(_part_remark(number_, len(model.parts), model.name), self.comment_width)]
        positions = self._body(lines, part, first=1)
        _write(stream, part.name, f"part {number_} of {len(model.parts)}"[:16], lines, positions)

    def _body(self, lines: list[str], part: Part, first: int) -> list[Motion]:
        positions: list[Motion] = []
        for item in part.items:
            if isinstance(item, Note):
                lines += [_remark(text, self.comment_width) for text in wrap(item.text, self.comment_width)]
            else:
                msec = round(item.duration_s * 1000.0)
                lines.append(f"J P[{first + len(positions)}] {msec}msec {'FINE' if item.stop else 'CNT100'}    ")
                positions.append(item)
        return positions


def _part_remark(number: int, parts: int, name: str) -> str:
    return f"part {number} of {parts} of {name}, run {name}"


def _remark(text: str, width: int) -> str:
    return "!" + clean(text).replace(";", ",")[:width] + " "


def _write(stream: TextIO, name: str, comment: str, lines: list[str], positions: list[Motion]) -> None:
    """The whole file: /PROG, /ATTR (every program here moves group 1), /MN with line numbers, /POS, /END."""
    made = time.strftime("DATE %y-%m-%d  TIME %H:%M:%S", stamp())
    w = stream.write
    w(f"/PROG  {name}\n/ATTR\nOWNER\t\t= MNEDITOR;\nCOMMENT\t\t= \"{comment}\";\nPROG_SIZE\t= 0;\n"
      f"CREATE\t\t= {made};\nMODIFIED\t= {made};\nFILE_NAME\t= ;\nVERSION\t\t= 0;\n"
      f"LINE_COUNT\t= {len(lines)};\nMEMORY_SIZE\t= 0;\nPROTECT\t\t= READ_WRITE;\n"
      "TCD:  STACK_SIZE\t= 0,\n      TASK_PRIORITY\t= 50,\n      TIME_SLICE\t= 0,\n      BUSY_LAMP_OFF\t= 0,\n"
      "      ABORT_REQUEST\t= 0,\n      PAUSE_REQUEST\t= 0;\n"
      "DEFAULT_GROUP\t= 1,*,*,*,*;\nCONTROL_CODE\t= 00000000 00000000;\n/MN\n")
    w("".join(f"{n:4d}:{'' if line.startswith('J ') else '  '}{line};\n" for n, line in enumerate(lines, start=1)))
    w("/POS\n")
    for n, m in enumerate(positions, start=1):
        a = [f"{number(v, 3):>9}" for v in m.axes_deg]
        w(f"P[{n}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\t\n"
          f"\tJ1= {a[0]} deg,\tJ2= {a[1]} deg,\tJ3= {a[2]} deg,\n"
          f"\tJ4= {a[3]} deg,\tJ5= {a[4]} deg,\tJ6= {a[5]} deg\n}};\n")
    w("/END\n")

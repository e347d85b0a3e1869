"""ABB RAPID (IRC5 / OmniCore, RobotWare 6 and 7): a ``.mod`` module of ``MoveAbsJ`` instructions.

The module::

    MODULE MOD_name
      LOCAL CONST zonedata zSingplan := [FALSE, 0.1, 0.1, 0.1, 0.005, 0.1, 0.005];
      PROC name()
        MoveAbsJ [[a1, .., a6], [9E+09, ..]], v100, fine, tool0;             ! to the start point
        MoveAbsJ [[..], [9E+09, ..]], v1000\\T:=0.048, zSingplan, tool0;   ! fly by
        MoveAbsJ [[..], [9E+09, ..]], v1000\\T:=0.052, fine, tool0;        ! exact stop
      ENDPROC
    ENDMODULE

Manual (ABB Technical reference manual, RAPID Instructions, Functions and Data types): "MoveAbsJ"
(moves the axes to an absolute joint position; the optional argument ``\\T`` gives the time of the
movement in seconds and replaces the speed data), "jointtarget" (``robax`` in degrees, ``extax``
9E+09 for axes that do not exist), "zonedata" (``fine`` stops; a fly-by zone of pzone_tcp mm
around the point, here the export's tolerance, so the corner the controller rounds adds at most
about that much to the deviation between points), "speeddata" (the first motion's ``v100``).
Joint targets carry no confdata: the configuration each move ends in is written as a comment.
"""

from __future__ import annotations

import re
from typing import TextIO

from singplan.kinematics.vendor_config import Vendor
from singplan.outputs.programs.model import Dialect, Motion, Note, Part, ProgramModel, number, seconds, wrap

ZONE = "zSingplan"
_NO_AXIS = "9E+09"


class Rapid(Dialect):
    fmt = "rapid"
    title = "ABB RAPID"
    vendor: Vendor = "abb"
    extension = ".mod"
    name_max = 28  # RAPID identifiers hold 32 characters; the module is named MOD_<name>
    name_pattern = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
    name_rule = "letters, digits and _, starting with a letter"
    named_after_file = False  # a module file may hold any module
    axis_decimals = 4
    time_step_s = 1e-6  # printed to the microsecond: a period that is not whole milliseconds keeps its times
    max_part_lines = 5000
    comment_width = 76
    manual = "ABB RAPID reference: MoveAbsJ (argument \\T), jointtarget, zonedata, speeddata"

    def write_main(self, stream: TextIO, model: ProgramModel) -> None:
        w = stream.write
        self._open(stream, model, model.name, model.header)
        w("    ! first motion: to the start point at v100, exact stop\n")
        w(f"    MoveAbsJ {_joints(model.start)}, v100, fine, tool0;\n")
        if model.split:
            w("".join(f"    {part.name};\n" for part in model.parts))
        else:
            self._body(stream, model.parts[0])
        w("  ENDPROC\nENDMODULE\n")

    def write_part(self, stream: TextIO, model: ProgramModel, part: Part) -> None:
        number_ = model.parts.index(part) + 1
        self._open(stream, model, part.name,
                   (f"part {number_} of {len(model.parts)} of {model.name}: run {model.name}, not this part alone",))
        self._body(stream, part)
        stream.write("  ENDPROC\nENDMODULE\n")

    def _open(self, stream: TextIO, model: ProgramModel, name: str, header: tuple[str, ...]) -> None:
        w = stream.write
        w(f"MODULE MOD_{name}\n")
        for line in header:
            w("".join(f"  ! {text}\n" for text in wrap(line, self.comment_width)))
        tcp, deg = number(model.tolerance_mm, 4).rstrip("0").rstrip("."), number(model.tolerance_deg, 4)
        w(f"  LOCAL CONST zonedata {ZONE} := [FALSE, {tcp}, {tcp}, {tcp}, {deg}, {tcp}, {deg}];\n")
        w(f"  PROC {name}()\n")

    def _body(self, stream: TextIO, part: Part) -> None:
        for item in part.items:
            if isinstance(item, Note):
                stream.write("".join(f"    ! {text}\n" for text in wrap(item.text, self.comment_width)))
            else:
                zone = "fine" if item.stop else ZONE
                stream.write(f"    MoveAbsJ {_joints(item)}, v1000\\T:={seconds(item.duration_s)}, {zone}, tool0;\n")


def _joints(motion: Motion) -> str:
    robax = ",".join(number(v, 4) for v in motion.axes_deg)
    return f"[[{robax}],[{','.join([_NO_AXIS] * 6)}]]"

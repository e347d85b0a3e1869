"""Independent readers of the controller programs singplan writes (KUKA KRL, ABB RAPID, FANUC LS).

Each reader parses a program file (and the part files its main program calls) the way the
controller's language defines it, and returns the timed points the controller is told to move
through: the start point (reached by the first, untimed motion, at t = 0), then every point with its
time from the start and whether the robot stops there. Nothing here imports singplan's program
writers: the controller axis conventions are read from robots.yaml (or a URDF's sidecar) directly,
and the joint values are stored as the controllers store them (KRL REAL, RAPID num and FANUC
positions are single precision).

* KRL: ``SPTP {A1 .., A6 ..}`` inside ``PTP_SPLINE`` blocks; a block's time block covers the
  segments after ``TIME_BLOCK START``, ``TIME_BLOCK END = total`` shared out in proportion to the
  ``TIME_BLOCK PART`` values; a segment outside a time block but inside a block (one continuing in
  flight) is timed by ``WITH $VEL_AXIS[i] = p``: the leading axis at p percent of its speed.
* RAPID: ``MoveAbsJ [[a1..a6],[..]], speed\\T:=time, zone, tool`` (``fine``: stop), calls of
  part procedures by name.
* FANUC: ``J P[n] <ms>msec CNT100|FINE ;`` in /MN, ``CALL NAME ;``, the positions in /POS.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

ROBOTS_YAML = Path(__file__).resolve().parents[1] / "robots" / "urdf" / "robots.yaml"


@dataclass
class Reading:
    """Timed points of a program: t [s] (P,), controller axes [deg] (P, 6), stop (P,), and for a point
    reached by a motion timed by speed rather than time, that speed (``speed_percent``, else None)."""

    t: list[float] = field(default_factory=list)
    axes_deg: list[list[float]] = field(default_factory=list)
    stop: list[bool] = field(default_factory=list)
    speed_percent: list[float | None] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)

    def add(self, t: float, axes: list[float], stop: bool, speed_percent: float | None = None) -> None:
        self.t.append(t)
        self.axes_deg.append([float(np.float32(a)) for a in axes])  # the controller's single precision
        self.stop.append(stop)
        self.speed_percent.append(speed_percent)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.array(self.t), np.array(self.axes_deg), np.array(self.stop)


def read_program(path: Path, axis_speed_deg_s: list[float] | None = None) -> Reading:
    """The timed points of the program at ``path`` (its parts read from its folder)."""
    reading = Reading()
    suffix = path.suffix.lower()
    if suffix == ".src":
        _Krl(path.parent, reading, axis_speed_deg_s).program(path)
    elif suffix == ".mod":
        _Rapid(path.parent, reading).program(path)
    elif suffix == ".ls":
        _Fanuc(path.parent, reading).program(path)
    else:
        raise ValueError(f"not a program file: {path}")
    return reading


# --- KRL -----------------------------------------------------------------------------------------

_KRL_AXES = re.compile(r"\{\s*" + r",\s*".join(rf"A{i}\s+(\S+?)" for i in range(1, 7)) + r"\s*\}")


class _Krl:
    def __init__(self, folder: Path, reading: Reading, speed: list[float] | None) -> None:
        self.folder, self.reading, self.speed = folder, reading, speed
        self.block: list[tuple[str, list[float], float]] | None = None  # (kind, axes, part or percent)

    def program(self, path: Path) -> None:
        self.reading.files.append(path)
        lines = [line.split(";", 1)[0].strip() for line in path.read_text().splitlines()]
        name = next(line.split()[1].split("(")[0] for line in lines if line.upper().startswith("DEF "))
        if name.lower() != path.stem.lower():
            raise ValueError(f"{path}: DEF {name} is not the file's name")
        for line in lines:
            self.statement(line)

    def statement(self, line: str) -> None:
        upper = line.upper()
        ignored = ("&", "DEF ", "BAS ", "BAS(", "$VEL_AXIS", "$ACC_AXIS")
        if not line or upper.startswith(ignored) or upper == "END":
            return
        if upper == "PTP_SPLINE":
            self.block = []
            self.timed, self.total = False, 0.0
        elif upper.startswith("SPTP"):
            axes = [float(v) for v in _KRL_AXES.search(line).groups()]  # type: ignore[union-attr]
            if self.block is None:  # a motion on its own: the first motion, to the start point
                if self.reading.t:
                    raise ValueError("a second SPTP outside a spline block")
                self.reading.add(0.0, axes, True)
            elif "WITH" in upper:
                percent = float(re.search(r"\$VEL_AXIS\[1\]\s*=\s*([\d.]+)", line).group(1))  # type: ignore[union-attr]
                self.block.append(("speed", axes, percent))
            else:
                self.block.append(("timed" if self.timed else "first", axes, 0.0))
        elif upper == "TIME_BLOCK START":
            self.timed = True
        elif upper.startswith("TIME_BLOCK PART"):
            kind, axes, _ = self.block[-1]  # type: ignore[index]
            self.block[-1] = (kind, axes, float(upper.split("=")[1]))  # type: ignore[index]
        elif upper.startswith("TIME_BLOCK END"):
            self.total = float(upper.split("=")[1])
        elif upper.startswith("ENDSPLINE"):
            self.close(stop="C_SPL" not in upper)
        elif re.fullmatch(r"[A-Za-z_$][\w$]*\(\s*\)", line):  # a call of a part
            self.program(self.folder / (line.split("(")[0] + ".src"))
        else:
            raise ValueError(f"KRL statement not expected: {line!r}")

    def close(self, stop: bool) -> None:
        block, self.block = self.block or [], None
        timed = [part for kind, _, part in block if kind == "timed"]
        scale = self.total / sum(timed) if timed else 1.0
        for n, (kind, axes, value) in enumerate(block):
            last = n == len(block) - 1
            if kind == "first":  # the block names where the robot stands: no motion
                if not np.allclose(axes, self.reading.axes_deg[-1], atol=1e-4) or not self.reading.stop[-1]:
                    raise ValueError("a block opens on a point the robot is not standing on")
                continue
            if kind == "speed":
                before = np.array(self.reading.axes_deg[-1])
                step = np.abs(np.array(axes) - before) / (np.array(self.speed) * value / 100.0)  # type: ignore[arg-type]
                self.reading.add(self.reading.t[-1] + float(step.max()), axes, stop and last, speed_percent=value)
            else:
                self.reading.add(self.reading.t[-1] + value * scale, axes, stop and last)


# --- RAPID ---------------------------------------------------------------------------------------

_MOVE_ABS_J = re.compile(r"MoveAbsJ\s*\[\[([^\]]*)\],\s*\[[^\]]*\]\]\s*,\s*(\w+)\s*(?:\\T\s*:=\s*([\d.]+))?\s*,"
                         r"\s*(\w+)\s*,\s*(\w+)\s*;")


class _Rapid:
    def __init__(self, folder: Path, reading: Reading) -> None:
        self.folder, self.reading = folder, reading
        self.procs: dict[str, list[str]] = {}

    def program(self, path: Path) -> None:
        self.load(path)
        main = next(iter(self.procs))
        self.run(main)

    def load(self, path: Path) -> None:
        self.reading.files.append(path)
        proc = None
        for raw in path.read_text().splitlines():
            line = raw.split("!", 1)[0].strip()
            if line.startswith("PROC "):
                proc = line.split()[1].split("(")[0]
                self.procs[proc] = []
            elif line == "ENDPROC":
                proc = None
            elif line and proc is not None:
                self.procs[proc].append(line)

    def run(self, proc: str) -> None:
        for line in self.procs[proc]:
            move = _MOVE_ABS_J.fullmatch(line)
            if move:
                axes = [float(v) for v in move.group(1).split(",")]
                if move.group(3) is None:  # no \T: the first motion, to the start point
                    if self.reading.t or move.group(4) != "fine":
                        raise ValueError(f"an untimed MoveAbsJ other than the first: {line!r}")
                    self.reading.add(0.0, axes, True)
                else:
                    self.reading.add(self.reading.t[-1] + float(move.group(3)), axes, move.group(4) == "fine")
            elif re.fullmatch(r"[A-Za-z]\w*;", line):  # a call of a part procedure in its own module
                called = line[:-1]
                if called not in self.procs:
                    self.load(self.folder / (called + ".mod"))
                self.run(called)
            else:
                raise ValueError(f"RAPID statement not expected: {line!r}")


# --- FANUC LS ------------------------------------------------------------------------------------

_FANUC_MOTION = re.compile(r"J P\[(\d+)\] (?:(\d+)msec|(\d+)%) (FINE|CNT100)")
_FANUC_POS = re.compile(r"P\[(\d+)\]\{.*?J1=\s*(\S+) deg,\s*J2=\s*(\S+) deg,\s*J3=\s*(\S+) deg,\s*"
                        r"J4=\s*(\S+) deg,\s*J5=\s*(\S+) deg,\s*J6=\s*(\S+) deg\s*\};", re.S)


class _Fanuc:
    def __init__(self, folder: Path, reading: Reading) -> None:
        self.folder, self.reading = folder, reading

    def program(self, path: Path) -> None:
        self.reading.files.append(path)
        text = path.read_text()
        name = re.search(r"^/PROG\s+(\S+)", text, re.M).group(1)  # type: ignore[union-attr]
        if name.upper() != path.stem.upper():
            raise ValueError(f"{path}: /PROG {name} is not the file's name")
        main = text.split("/MN\n", 1)[1].split("/POS\n", 1)
        positions = {int(m.group(1)): [float(v) for v in m.groups()[1:]] for m in _FANUC_POS.finditer(main[1])}
        lines = [re.sub(r"^\s*\d+:\s*", "", line).rstrip(";").strip() for line in main[0].splitlines()]
        count = int(re.search(r"LINE_COUNT\s*=\s*(\d+);", text).group(1))  # type: ignore[union-attr]
        if count != len(lines):
            raise ValueError(f"{path}: LINE_COUNT {count}, but {len(lines)} lines")
        for line in lines:
            motion = _FANUC_MOTION.fullmatch(line)
            if line.startswith("!"):
                continue
            if motion:
                axes, stop = positions[int(motion.group(1))], motion.group(4) == "FINE"
                if motion.group(3) is not None:  # a speed in %: the first motion, to the start point
                    if self.reading.t or not stop:
                        raise ValueError(f"a % motion other than the first: {line!r}")
                    self.reading.add(0.0, axes, True)
                else:
                    self.reading.add(self.reading.t[-1] + int(motion.group(2)) / 1000.0, axes, stop)
            elif line.startswith("CALL "):
                self.program(self.folder / (line.split()[1] + ".ls"))
            else:
                raise ValueError(f"FANUC line not expected: {line!r}")


# --- the controller convention, undone ----------------------------------------------------------

def convention(robot: str, urdf: str) -> tuple[np.ndarray, np.ndarray]:
    """(matrix (6, 6), offsets [deg] (6,)) with controller axes = matrix @ joints + offsets, read from
    robots.yaml for a bundled arm, else from the URDF's ``.controller.yaml`` sidecar."""
    robots = yaml.safe_load(ROBOTS_YAML.read_text())["robots"]
    spec = robots.get(robot, {}).get("controller") if Path(urdf).name == robots.get(robot, {}).get("urdf") else None
    if spec is None:
        side = Path(urdf).with_name(Path(urdf).stem + ".controller.yaml")
        spec = yaml.safe_load(side.read_text())["controller"]
    matrix = np.diag(np.array(spec.get("axis_signs", [1] * 6), dtype=float))
    for c in spec.get("couplings") or []:
        matrix[c["axis"] - 1, c["joint"] - 1] += c["factor"]
    return matrix, np.array(spec.get("axis_offsets_deg", [0] * 6), dtype=float)


def urdf_joints_deg(axes_deg: np.ndarray, matrix: np.ndarray, offsets_deg: np.ndarray) -> np.ndarray:
    """URDF joint values [deg] (P, 6) of controller axis values [deg] (P, 6)."""
    return np.linalg.solve(matrix, (np.asarray(axes_deg) - offsets_deg).T).T


def radians(values_deg: np.ndarray) -> np.ndarray:
    return np.asarray(values_deg) * (math.pi / 180.0)

"""Vendor configuration data: ABB confdata, KUKA Status and Turn, FANUC configuration strings.

A pose target on an industrial controller names its IK branch in the vendor's own terms,
computed from the **controller's** axis values. Those differ from the URDF joint values by
signs, offsets and couplings (FANUC J2/J3, the ABB IRB 2400 parallel linkage), which
``robots/urdf/robots.yaml`` records per bundled arm under ``controller`` (with sources)::

    axis_i = axis_signs[i] * joint_i + axis_offsets_deg[i] + sum(f * joint_j for {axis: i, joint: j, factor: f})

A user URDF declares its convention in a sidecar file next to it, ``<name>.controller.yaml``,
holding the same ``controller:`` mapping; without one its vendor configuration is null. The
sidecar is read like every file singplan reads (:mod:`singplan.kinematics.files`,
:mod:`singplan.kinematics.yamldoc`): a regular UTF-8 file of at most
:data:`MAX_SIDECAR_BYTES`, no aliases, shallow nesting, each value checked for type and range;
anything else is bad input naming the file and the field.

The forms (degrees of the controller axes ``a1..a6``):

* ABB ``confdata`` (RAPID reference, data type confdata): ``cf1, cf4, cf6 = floor(a / 90)``
  of axes 1, 4, 6; ``cfx = 4 * behind_axis1 + 2 * behind_lower_arm + (a5 < 0)``: the wrist
  centre behind axis 1, behind the lower arm (the line through axes 2 and 3), axis 5 negative.
* KUKA ``Status`` bit 0: wrist point overhead (x < 0 in the A1 frame); bit 1: ``A3 >= phi``,
  phi the A3 value where the arm is stretched (wrist point on the line through A2 and A3);
  bit 2: ``A5 <= 0`` (wrapped to (-180, 180]; DESIGN.md's wording of KUKA's table);
  ``Turn`` bit i set when axis i+1 < 0.
* FANUC configuration string ``"F|N U|D T|B, t1, t4, t6"``: flip when J5 > 0 (no flip
  otherwise), elbow up/down, wrist centre in front of (T) or behind (B) J1; turn numbers
  ``floor((a + 180) / 360)`` of J1, J4, J6.

The wrist letter of singplan's own labels (:mod:`singplan.kinematics.configuration`) is geometric: it
is the vendor's flip indicator on every bundled arm, in controller terms: ``N`` is ABB axis 5
>= 0, KUKA Status bit 2 clear (A5 > 0), FANUC ``N`` (J5 <= 0), whatever the URDF's q5 sign (tested;
at exactly A5 = 0, the singularity itself, KUKA's bit is set while the label says ``N``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path
from typing import Any, Literal, NamedTuple, cast

import numpy as np

from singplan.errors import InputError, RobotModelError
from singplan.kinematics.angles import wrap_deg
from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.files import FileFieldError, display_path, read_bounded_text
from singplan.kinematics.robot import Robot, registry_specs, robots_dir
from singplan.kinematics.yamldoc import YamlLimits, load_yaml, shorten

Vendor = Literal["abb", "kuka", "fanuc", "staubli", "none"]
VENDORS: tuple[Vendor, ...] = ("abb", "kuka", "fanuc", "staubli", "none")
SIDECAR_SUFFIX = ".controller.yaml"
MAX_SIDECAR_BYTES = 64 * 1024  # a convention is a few lines; sources may quote a manual or two
_SIDECAR_YAML = YamlLimits("a controller sidecar", max_depth=6, max_nodes=2000, max_key_chars=64,
                           max_scalar_chars=2000)
_N_AXES = 6
_CONVENTION_KEYS = ("vendor", "axis_signs", "axis_offsets_deg", "couplings", "sources")
MAX_OFFSET_DEG = 720.0  # an axis offset beyond two turns is a unit mistake
MAX_COUPLING_FACTOR = 100.0


@dataclass(frozen=True)
class ControllerConvention:
    """How a robot's controller axes relate to its URDF joints: ``axes = matrix @ q + offsets_rad``."""

    vendor: Vendor
    matrix: tuple[tuple[float, ...], ...]  # (6, 6)
    offsets_rad: tuple[float, ...]  # (6,)
    sources: tuple[str, ...] = ()

    def axes_rad(self, q: np.ndarray) -> np.ndarray:
        """Controller axis values [rad] of URDF joint values q, (6,) or (N, 6)."""
        return np.asarray(q, dtype=float) @ np.asarray(self.matrix).T + np.asarray(self.offsets_rad)

    def joints_rad(self, axes_rad: np.ndarray) -> np.ndarray:
        """URDF joint values [rad] of controller axis values, (6,) or (N, 6)."""
        rhs = np.asarray(axes_rad, dtype=float) - np.asarray(self.offsets_rad)
        return cast(np.ndarray, np.linalg.solve(np.asarray(self.matrix), rhs.T).T)


class AbbConfdata(NamedTuple):
    cf1: int
    cf4: int
    cf6: int
    cfx: int


class KukaStatusTurn(NamedTuple):
    status: int
    turn: int


def abb_confdata(axes_deg: Sequence[float], behind_axis1: bool, behind_lower_arm: bool) -> AbbConfdata:
    """ABB confdata of one set of controller axis values [deg] and the two geometric flags."""
    a = np.asarray(axes_deg, dtype=float)
    cf = np.floor(a[[0, 3, 5]] / 90.0).astype(int)
    cfx = 4 * int(behind_axis1) + 2 * int(behind_lower_arm) + int(a[4] < 0.0)
    return AbbConfdata(int(cf[0]), int(cf[1]), int(cf[2]), cfx)


def kuka_status_turn(axes_deg: Sequence[float], overhead: bool, phi_deg: float) -> KukaStatusTurn:
    """KUKA Status and Turn of controller axis values [deg]; ``phi_deg`` is the A3 of the stretched arm."""
    a = np.asarray(axes_deg, dtype=float)
    status = int(overhead) | (int(a[2] >= phi_deg) << 1) | (int(wrap_deg(a[4:5])[0] <= 0.0) << 2)
    turn = sum(1 << i for i in range(_N_AXES) if a[i] < 0.0)
    return KukaStatusTurn(status, turn)


def fanuc_turn(angle_deg: float) -> int:
    """FANUC turn number: 0 for [-180, 180), 1 for [180, 540), -1 for [-540, -180) ..."""
    return math.floor((angle_deg + 180.0) / 360.0)


def fanuc_configuration(axes_deg: Sequence[float], up: bool, front: bool) -> str:
    """FANUC configuration string, e.g. ``"N U T, 0, 0, 0"``, of controller axis values [deg]."""
    a = [float(v) for v in axes_deg]
    flip = "F" if wrap_deg(np.array([a[4]]))[0] > 0.0 else "N"
    return (f"{flip} {'U' if up else 'D'} {'T' if front else 'B'}, "
            f"{fanuc_turn(a[0])}, {fanuc_turn(a[3])}, {fanuc_turn(a[5])}")


# --- conventions: bundled registry and user sidecars -------------------------------------------

@cache
def _registry_conventions() -> dict[str, ControllerConvention | None]:
    """Bundled URDF file path (resolved) -> convention, from robots.yaml."""
    out: dict[str, ControllerConvention | None] = {}
    for name, spec in registry_specs().items():
        convention = parse_convention(spec.get("controller"), f"robots.yaml: robots.{name}.controller")
        if "urdf" in spec:  # the example-robot-data arms (UR5, Panda) have vendor none
            out[str((robots_dir() / spec["urdf"]).resolve())] = convention
    return out


def parse_convention(spec: object, where: str) -> ControllerConvention | None:
    """A ``controller:`` mapping -> convention (None for vendor ``none`` or no mapping)."""
    if spec is None:
        return None
    if not isinstance(spec, Mapping):
        raise RobotModelError(where, f"expected a mapping with {', '.join(_CONVENTION_KEYS)}, got {_shown(spec)}")
    vendor = spec.get("vendor")
    if not isinstance(vendor, str) or vendor not in VENDORS:
        raise RobotModelError(f"{where}.vendor", f"expected one of {', '.join(VENDORS)}, got {_shown(vendor)}")
    if vendor == "none":
        return None
    unknown = [str(k) for k in spec if k not in _CONVENTION_KEYS]
    if unknown:
        raise RobotModelError(where, f"unknown key(s) {shorten(', '.join(sorted(unknown)))}; valid: "
                                     f"{', '.join(_CONVENTION_KEYS)}")
    signs = _numbers(spec.get("axis_signs", [1] * _N_AXES), f"{where}.axis_signs", 1.0)
    bad = next((i for i, s in enumerate(signs) if s not in (1.0, -1.0)), None)
    if bad is not None:
        raise RobotModelError(f"{where}.axis_signs[{bad}]", f"must be 1 or -1, got {signs[bad]:g}")
    offsets = _numbers(spec.get("axis_offsets_deg", [0] * _N_AXES), f"{where}.axis_offsets_deg", MAX_OFFSET_DEG)
    matrix = np.diag(signs)
    for k, c in enumerate(_list(spec.get("couplings"), f"{where}.couplings")):
        axis, joint, factor = _coupling(c, f"{where}.couplings[{k}]")
        matrix[axis - 1, joint - 1] += factor
    if abs(np.linalg.det(matrix)) < 1e-9:
        raise RobotModelError(f"{where}.couplings", "the axes would not determine the joints (singular mapping)")
    sources = _list(spec.get("sources"), f"{where}.sources")
    if not all(isinstance(text, str) for text in sources):
        raise RobotModelError(f"{where}.sources", "expected a list of texts (where each figure comes from)")
    return ControllerConvention(cast(Vendor, vendor), tuple(map(tuple, matrix.tolist())),
                                tuple(math.radians(v) for v in offsets), tuple(sources))


def _shown(value: object) -> str:
    """A value for a message: its type and a short repr (a huge list is never printed whole)."""
    text = repr(value) if not isinstance(value, (list, dict)) or len(value) <= 12 else f"{len(value)} items"
    return f"{type(value).__name__} {shorten(text, 60)}"


def _list(value: object, where: str) -> list[Any]:
    """An optional list (None: empty)."""
    if value is None:
        return []
    if not isinstance(value, list):
        raise RobotModelError(where, f"expected a list, got {_shown(value)}")
    return value


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _numbers(value: object, where: str, bound: float) -> list[float]:
    """Six finite numbers of magnitude at most ``bound``."""
    if not isinstance(value, list) or len(value) != _N_AXES:
        raise RobotModelError(where, f"expected {_N_AXES} numbers, got {_shown(value)}")
    for i, v in enumerate(value):
        if not _is_number(v) or not abs(v) <= bound:  # also NaN; an int too large for a float compares fine
            raise RobotModelError(f"{where}[{i}]", f"expected a finite number of magnitude at most {bound:g}, "
                                                   f"got {_shown(v)}")
    return [float(v) for v in value]


def _coupling(c: object, where: str) -> tuple[int, int, float]:
    if not isinstance(c, Mapping) or set(c) != {"axis", "joint", "factor"}:
        raise RobotModelError(where, f"expected {{axis: i, joint: j, factor: f}}, got {_shown(c)}")
    axis, joint, factor = c["axis"], c["joint"], c["factor"]
    for key, value in (("axis", axis), ("joint", joint)):
        if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= _N_AXES:
            raise RobotModelError(f"{where}.{key}", f"expected a whole number 1..{_N_AXES}, got {_shown(value)}")
    if axis == joint:
        raise RobotModelError(where, f"axis and joint must differ (the sign is axis_signs[{axis - 1}]), got {axis}")
    if not _is_number(factor) or not abs(factor) <= MAX_COUPLING_FACTOR:
        raise RobotModelError(f"{where}.factor", f"expected a finite number of magnitude at most "
                                                 f"{MAX_COUPLING_FACTOR:g}, got {_shown(factor)}")
    return int(axis), int(joint), float(factor)


def sidecar_path(urdf_path: str | Path) -> Path:
    """Where a user URDF's convention is looked for: ``arm.urdf`` -> ``arm.controller.yaml``."""
    p = Path(urdf_path)
    return p.with_name(p.stem + SIDECAR_SUFFIX)


def _convention_of_file(urdf_path: str) -> ControllerConvention | None:
    bundled = _registry_conventions()
    if urdf_path in bundled:
        return bundled[urdf_path]
    side = sidecar_path(urdf_path)
    try:
        stamp = side.stat().st_mtime_ns
    except OSError:
        return None
    return _read_sidecar(str(side), stamp)


@lru_cache(maxsize=64)
def _read_sidecar(side: str, mtime_ns: int) -> ControllerConvention | None:
    """A sidecar's convention, cached per modification time (an edited sidecar is read again).

    Raises:
        FileRefusedError: not a regular UTF-8 file within :data:`MAX_SIDECAR_BYTES` (a FIFO, a
            link to a device, a folder ...).
        FileFieldError: YAML that is malformed or breaks the scan's limits, naming the field.
        RobotModelError: a field of the convention is wrong (``<file>: controller.couplings[0].axis: ...``).
    """
    name = display_path(side)
    text = read_bounded_text(side, MAX_SIDECAR_BYTES, "controller sidecar")
    doc = load_yaml(text, _SIDECAR_YAML, lambda field, reason: FileFieldError(name, field, reason))
    if not isinstance(doc, Mapping) or "controller" not in doc:
        raise FileFieldError(name, "", f"expected a mapping with the key 'controller', got {_shown(doc)}")
    unknown = [str(k) for k in doc if k != "controller"]
    if unknown:
        raise FileFieldError(name, shorten(unknown[0], 64), "unknown key; a sidecar holds `controller:` only")
    return parse_convention(doc["controller"], f"{name}: controller")


def convention_for(robot: Robot) -> ControllerConvention | None:
    """The robot's controller convention: robots.yaml for a bundled URDF, else its sidecar, else None."""
    if robot.n_joints != _N_AXES:
        return None
    return _convention_of_file(str(Path(robot.urdf_path).resolve()))


def require_convention(robot: Robot, vendor: Vendor, what: str,
                       hint: Mapping[str, str] | None = None) -> ControllerConvention:
    """The robot's convention, which must be ``vendor``'s; else InputError naming what is missing.

    ``what`` names the output that needs it (e.g. ``"--format krl (KUKA KRL)"``); ``hint`` adds to the
    message of a robot of another vendor (vendor -> text, e.g. ``" (use --format rapid)"``).
    """
    hint = hint or {}
    if robot.n_joints != _N_AXES:
        raise InputError(f"{what}: robot {robot.name!r} has {robot.n_joints} joints; controller programs are "
                         f"written for {_N_AXES}-axis arms")
    conv = convention_for(robot)
    if conv is None:
        bundled = robot.entry is not None or str(Path(robot.urdf_path).resolve()) in _registry_conventions()
        where = ("robots.yaml records none for this bundled arm" if bundled else
                 f"add {sidecar_path(robot.urdf_path)} with a 'controller:' mapping "
                 "(vendor, axis_signs, axis_offsets_deg, couplings; docs/controller-programs.md)")
        raise InputError(f"{what}: robot {robot.name!r} has no controller convention (the {vendor.upper()} "
                         f"controller's axis offsets, signs and couplings); {where}")
    if conv.vendor != vendor:
        raise InputError(f"{what}: robot {robot.name!r} has the controller convention of {conv.vendor.upper()}, "
                         f"not {vendor.upper()}{hint.get(conv.vendor, '')}")
    return conv


def printed_axes_deg(conv: ControllerConvention, q: np.ndarray, decimals: int) -> np.ndarray:
    """Controller axis values [deg] (N, 6) of URDF joint values q (N, 6) [rad], rounded to ``decimals``
    so that the joint values they stand for are as near q as that many decimals allow.

    Rounding each axis on its own is not enough where axes are coupled: a FANUC J3 printed with
    3 decimals stands for ``joint_3 = J3 + J2``, whose error is the sum of both roundings (up to a
    whole unit, 0.001 deg). Each axis is rounded down or up, and of the 2^6 choices the one whose
    decoded joints (:meth:`ControllerConvention.joints_rad`) are nearest q (largest error over the
    joints) is kept: with one coupling that is within half a unit per joint, as uncoupled axes are.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    scale = 10.0**decimals
    exact = np.degrees(conv.axes_rad(q)) * scale  # in units of the last printed digit
    matrix = np.asarray(conv.matrix)
    if np.count_nonzero(matrix - np.diag(np.diag(matrix))) == 0:
        return np.round(exact) / scale
    low = np.floor(exact)
    choices = (np.arange(2**_N_AXES)[:, None] >> np.arange(_N_AXES)) & 1  # (64, 6) of 0 / 1
    out = np.empty_like(exact)
    for c in range(0, len(q), _ROUNDING_CHUNK):
        candidates = low[None, c:c + _ROUNDING_CHUNK] + choices[:, None, :]  # (64, m, 6)
        decoded = conv.joints_rad(np.radians(candidates / scale).reshape(-1, _N_AXES)).reshape(candidates.shape)
        error = np.max(np.abs(decoded - q[None, c:c + _ROUNDING_CHUNK]), axis=2)  # (64, m)
        best = np.argmin(error, axis=0)
        out[c:c + _ROUNDING_CHUNK] = candidates[best, np.arange(len(best))]
    return out / scale


_ROUNDING_CHUNK = 4096  # samples rounded at once (64 candidates each: a few MB)


# --- per robot and joint values ------------------------------------------------------------------

def vendor_configs(robot: Robot, q: np.ndarray) -> list[dict[str, Any] | None]:
    """The trajectory.json ``vendor_config`` of each row of q (N, n) [rad]; None without a convention."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    conv = convention_for(robot)
    if conv is None or conv.vendor == "staubli":  # the contract has no Staubli form
        return [None] * len(q)
    axes = np.degrees(conv.axes_rad(q))
    d = distances_batch(robot, q)  # (wrist, shoulder, elbow)
    behind_axis1 = d[:, 1] < 0.0
    elbow_up = d[:, 2] >= 0.0
    if conv.vendor == "abb":
        return [{"abb": abb_confdata(a, b, not u)._asdict()} for a, b, u in zip(axes, behind_axis1, elbow_up,
                                                                                strict=True)]
    if conv.vendor == "kuka":
        # A3 - phi is +-(elbow angle): A3 >= phi exactly where the arm is on the vendor's "up" side
        phi = axes[:, 2] - _kuka_elbow_direction(robot, conv) * np.degrees(d[:, 2])
        return [{"kuka": kuka_status_turn(a, b, p)._asdict()} for a, b, p in zip(axes, behind_axis1, phi, strict=True)]
    return [{"fanuc": fanuc_configuration(a, u, not b)} for a, b, u in zip(axes, behind_axis1, elbow_up, strict=True)]


def vendor_config(robot: Robot, q: np.ndarray) -> dict[str, Any] | None:
    """``vendor_config`` of one joint vector q (n,) [rad]."""
    return vendor_configs(robot, np.asarray(q, dtype=float)[None, :])[0]


@lru_cache(maxsize=64)
def _kuka_elbow_direction(robot: Robot, conv: ControllerConvention) -> float:
    """+1 when the elbow angle grows with A3 (KUKA's A3 >= phi is elbow up), else -1."""
    q0 = np.zeros((2, _N_AXES))
    step = math.radians(1.0)
    q0[1] = conv.joints_rad(conv.axes_rad(q0[0]) + np.array([0, 0, step, 0, 0, 0]))
    d = distances_batch(robot, q0)[:, 2]
    return 1.0 if d[1] > d[0] else -1.0


def format_vendor_config(value: dict[str, Any] | None) -> str:
    """One-line text form: ``[cf1,cf4,cf6,cfx]``, ``S 2 T 18``, the FANUC string, or empty."""
    if value is None:
        return ""
    if "abb" in value:
        c = value["abb"]
        return f"[{c['cf1']},{c['cf4']},{c['cf6']},{c['cfx']}]"
    if "kuka" in value:
        return f"S {value['kuka']['status']} T {value['kuka']['turn']}"
    return str(value["fanuc"])

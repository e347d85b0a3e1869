"""Kinematic families recognised from the chain itself, whatever the URDF's conventions.

A 6R chain is ``opw`` (ortho-parallel with a spherical wrist, Brandstoetter, Angerer and
Hofbaur 2014) or ``ur`` (axes 2-4 parallel, the ur_description layout of
:mod:`singplan.kinematics.closedform.ur`) when that closed form reproduces the URDF's forward kinematics,
else ``general6``; 7R chains are ``seven``, 5R chains ``five``.

The OPW parameters are read from the joint axes and origins in the base frame at q = 0 and
the tip pose, in the conventions of :class:`OpwParameters`: the zero pose of the file, its
axis directions and any fixed joints become the offsets and sign corrections. Every
recognition is then verified: for seeded random joint values inside the limits, the
closed form solves the tip pose Pinocchio computes, and its branch nearest the sample must
reproduce that pose to :data:`VERIFY_TOL_M` / :data:`VERIFY_TOL_RAD`. A closed form that does
not reproduce the URDF is rejected (the record says why) and the arm is ``general6``.

Recognition costs a few ms; it is cached per chain (joint placements, kinds, limits, tip).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
import pinocchio as pin

from singplan.kinematics.angles import wrap_to_pi
from singplan.kinematics.closedform import opw
from singplan.kinematics.closedform.ur import UrParameters, ur_batch

Family = Literal["opw", "ur", "general6", "five", "seven"]
# What an arm's kinematics offer the planner (the crossing methods' needs are the registry's,
# singplan.planning.crossing.registry; this module names no method):
#   "closed form": every branch of a pose in closed form (OPW, UR);
#   "wrist singularity": a wrist singularity to cross (axes 4, 5, 6 can become coplanar);
#   "square jacobian": six joints for the six pose components, a 6 x 6 Jacobian;
#   "full pose": position and orientation are both kept (a five-axis arm keeps the tool axis only).
Capability = Literal["closed form", "wrist singularity", "square jacobian", "full pose"]
_SIX_AXES: frozenset[Capability] = frozenset({"wrist singularity", "square jacobian", "full pose"})
_CAPABILITIES: dict[str, frozenset[Capability]] = {
    "opw": _SIX_AXES | {"closed form"}, "ur": _SIX_AXES | {"closed form"}, "general6": _SIX_AXES,
    "five": frozenset(), "seven": frozenset({"full pose"})}
# FK of the closed form's branch against Pinocchio [m] and [rad]: a tenth of the tightest position
# tolerance a task can give (0.0001 mm), for the flange and for a TCP up to 1 m beyond it (an
# orientation miss of the flange moves the TCP by the tool's length times it). The float error of an
# FK is ~1e-15 m; what this admits is the URDF's own rounding: ur_description's *_gripper files write
# pi/2 as 1.570796325 (1.8e-9 rad short), four such joints miss by 7.2e-9 rad / 1.8e-9 m; pi/2
# written to 6 decimals (3.3e-7 rad short) is refused.
VERIFY_TOL_M = 1e-8
VERIFY_TOL_RAD = 1e-8
VERIFY_SAMPLES = 50
_VERIFY_SEED = 20261123
_BRANCH_TOL_RAD = 1e-6  # the sample's own joints must be among the closed form's branches
_AXIS_TOL = 1e-9  # |sin| or |cos| of an angle taken as 0 (parallel, perpendicular) [-]
_POINT_TOL_M = 1e-9  # a distance taken as 0 (axes meet, a point on an axis) [m]
_CACHE_SIZE = 64


@dataclass(frozen=True)
class OpwParameters:
    """Ortho-parallel wrist geometry (Brandstoetter, Angerer, Hofbaur 2014) [m, rad].

    Joint conversion: ``q_robot = (q_opw + offsets_rad) * sign_corrections``.
    """

    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    offsets_rad: tuple[float, ...]
    sign_corrections: tuple[float, ...]

    @cached_property
    def offsets(self) -> np.ndarray:
        """``offsets_rad`` as an array (6,), for the joint conversions of many samples."""
        return np.array(self.offsets_rad, dtype=float)

    @cached_property
    def signs(self) -> np.ndarray:
        """``sign_corrections`` as an array (6,)."""
        return np.array(self.sign_corrections, dtype=float)


@dataclass(frozen=True)
class Recognition:
    """What :func:`recognise` found.

    Attributes:
        family: the kinematic family the planner uses.
        opw: OPW parameters when ``family == "opw"``.
        ur: UR parameters when ``family == "ur"``.
        residual_m, residual_rad: the worst FK error of the verification (0.0 when no closed
            form was verified).
        rejected: why each closed form tried was not taken, e.g. ``{"opw": "axes 4 and 5 do
            not meet ..."}``; empty for an accepted first try.
        no_wrist: why a general 6R arm has no wrist singularity, e.g. "axis 4 is parallel to axis 5"
            ("" when it has one).
        T_base_closed: the closed form's base frame in the URDF's base frame (4, 4): z along
            axis 1, wherever the file's base link sits (identity for a base on axis 1).
        T_flange_tip: the tip in the closed form's flange frame (4, 4): a tip turned about
            or set off axis 6 (identity for a tip whose z is axis 6, its origin on it).
        T_joint3_closed: a UR arm's joint-3 frame of the closed form (ur_description's) in the
            URDF's joint-3 frame (4, 4), both fixed to link 3 (identity in that layout).
    """

    family: Family
    opw: OpwParameters | None = None
    ur: UrParameters | None = None
    residual_m: float = 0.0
    residual_rad: float = 0.0
    rejected: tuple[tuple[str, str], ...] = ()
    no_wrist: str = ""
    T_base_closed: np.ndarray = field(default_factory=lambda: np.eye(4), compare=False)
    T_flange_tip: np.ndarray = field(default_factory=lambda: np.eye(4), compare=False)
    T_joint3_closed: np.ndarray = field(default_factory=lambda: np.eye(4), compare=False)

    def to_closed_form(self, T_base_tip: np.ndarray) -> np.ndarray:
        """Tip poses (N, 4, 4) in the base frame as the closed form's flange poses in its own base frame."""
        return _to_closed_form(T_base_tip, *self._inverses)

    @cached_property
    def _inverses(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The inverses of T_base_closed and T_flange_tip, None for an identity (IK calls this per pose)."""
        return _inverse_unless_identity(self.T_base_closed), _inverse_unless_identity(self.T_flange_tip)

    def closed_points(self, points_m: np.ndarray) -> np.ndarray:
        """Points (N, 3) [m] of the base frame in the closed form's base frame."""
        points = np.asarray(points_m, dtype=float)
        B = self.T_base_closed
        return points if _is_identity(B) else (points - B[:3, 3]) @ B[:3, :3]

    def flange_point(self, point_tip_m: np.ndarray) -> np.ndarray:
        """A point (3,) [m] of the tip frame in the closed form's flange frame."""
        F = self.T_flange_tip
        return np.asarray(point_tip_m, dtype=float) if _is_identity(F) else F[:3, :3] @ point_tip_m + F[:3, 3]

    @property
    def capabilities(self) -> frozenset[Capability]:
        """What this arm's kinematics offer (:data:`Capability`): its family's, without a wrist
        singularity where the wrist has none (``no_wrist``)."""
        found = _CAPABILITIES[self.family]
        return found - {"wrist singularity"} if self.no_wrist else found

    @property
    def reason(self) -> str:
        """The rejections as one sentence ("" when none)."""
        return "; ".join(f"not {name}: {why}" for name, why in self.rejected)


class _NotFamilyError(Exception):
    """The chain does not have a family's structure (the message says what is missing)."""


_cache: dict[bytes, Recognition] = {}


def recognise(model: pin.Model, tip_frame_id: int) -> Recognition:
    """The family of the chain ``model`` (reduced to base -> tip) with the tip frame ``tip_frame_id``."""
    key = _fingerprint(model, tip_frame_id)
    found = _cache.get(key)
    if found is None:
        if len(_cache) >= _CACHE_SIZE:
            _cache.clear()
        found = _cache[key] = _recognise(model, tip_frame_id)
    return found


def _fingerprint(model: pin.Model, tip_frame_id: int) -> bytes:
    h = hashlib.blake2b(digest_size=20)
    for j in range(1, model.njoints):
        h.update(model.joints[j].shortname().encode())
        h.update(np.ascontiguousarray(model.jointPlacements[j].homogeneous).tobytes())
    h.update(np.ascontiguousarray(model.frames[tip_frame_id].placement.homogeneous).tobytes())
    h.update(str(model.frames[tip_frame_id].parentJoint).encode())
    h.update(np.asarray(model.lowerPositionLimit, dtype=float).tobytes())
    h.update(np.asarray(model.upperPositionLimit, dtype=float).tobytes())
    if any(model.joints[j].shortname() == "JointModelRevoluteUnaligned" for j in range(1, model.njoints)):
        h.update(np.asarray(_axes_and_origins(model, tip_frame_id)[0]).tobytes())
    return h.digest()


def _recognise(model: pin.Model, tip_frame_id: int) -> Recognition:
    n = model.nq
    if n != 6:
        return Recognition("seven" if n == 7 else "five" if n == 5 else "general6")
    rejected: list[tuple[str, str]] = []
    for name, derive in (("opw", _derive_opw), ("ur", _derive_ur), ("ur", _derive_ur_geometric)):
        try:
            params, B, F = derive(model, tip_frame_id)
            residual_m, residual_rad = _verify(model, tip_frame_id, params, B, F)
        except _NotFamilyError as exc:
            rejected.append((name, str(exc)))
            continue
        except ArithmeticError as exc:  # a degenerate chain (zero-length links) the checks let through
            rejected.append((name, f"degenerate geometry ({type(exc).__name__})"))
            continue
        if isinstance(params, OpwParameters):
            return Recognition("opw", opw=params, residual_m=residual_m, residual_rad=residual_rad,
                               rejected=tuple(rejected), T_base_closed=B, T_flange_tip=F)
        return Recognition("ur", ur=params, residual_m=residual_m, residual_rad=residual_rad,
                           rejected=tuple(rejected[:1]), T_base_closed=B, T_flange_tip=F,
                           T_joint3_closed=_ur_joint3(model, params, B))
    return Recognition("general6", rejected=tuple(rejected), no_wrist=_no_wrist(model, tip_frame_id))


def _no_wrist(model: pin.Model, tip_frame_id: int) -> str:
    """Why the chain has no wrist singularity ("" when it has one).

    The wrist singularity is where axes 4, 5 and 6 are coplanar (the angular velocities of the
    wrist span only a plane; for perpendicular axes: axes 4 and 6 aligned). Turning joint 5
    sweeps axis 6 around axis 5, through the plane of axes 4 and 5, unless axis 4 or axis 6 is
    parallel to axis 5.
    """
    a = _axes_and_origins(model, tip_frame_id)[0]
    for k in (3, 5):
        if np.linalg.norm(np.cross(a[k], a[4])) <= _AXIS_TOL:
            return f"axis {k + 1} is parallel to axis 5"
    return ""


def _axes_and_origins(model: pin.Model, tip_frame_id: int,
                      q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, pin.SE3]:
    """Unit joint axes (n, 3), joint origins (n, 3) and the tip pose, in the base frame at ``q`` (default 0)."""
    data = model.createData()
    q = np.zeros(model.nq) if q is None else q
    J = pin.computeJointJacobians(model, data, q)  # WORLD frame: the angular rows are the joint axes
    pin.updateFramePlacements(model, data)
    axes = np.array([J[3:, model.joints[j].idx_v] for j in range(1, model.njoints)])
    origins = np.array([data.oMi[j].translation for j in range(1, model.njoints)])
    return axes, origins, data.oMf[tip_frame_id].copy()


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _require(condition: bool | np.bool_, why: str) -> None:
    if not bool(condition):
        raise _NotFamilyError(why)


def _meet(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray | None:
    """The point where two non-parallel lines meet, or None when they pass by each other."""
    w = p1 - p2
    b = float(d1 @ d2)
    denom = 1.0 - b * b
    if denom < _AXIS_TOL:
        return None  # parallel
    t1 = (b * float(d2 @ w) - float(d1 @ w)) / denom
    t2 = (float(d2 @ w) - b * float(d1 @ w)) / denom
    x1, x2 = p1 + t1 * d1, p2 + t2 * d2
    return (x1 + x2) / 2 if np.linalg.norm(x1 - x2) <= _POINT_TOL_M else None


def _ry(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _sign(x: float) -> float:
    return 1.0 if x >= 0 else -1.0


def _offset(angle_at_zero: float) -> float:
    """The OPW offset of a joint whose OPW angle is ``angle_at_zero`` at the robot's zero, in (-pi, pi]."""
    return _wrap(-angle_at_zero)


def _wrap(angle_rad: float) -> float:
    """One angle wrapped to (-pi, pi] by the numpy formula (calling the compiled scalar ``angles.wrap``
    from Python would load its kernel from the disk cache, ~10 ms, for six numbers)."""
    return float(wrap_to_pi(np.array(angle_rad)))


def _snap(x: float) -> float:
    """Round-off of a derived length or angle removed (1e-15 of the composed placements)."""
    return float(round(x, 12))


def _derive_opw(model: pin.Model, tip_frame_id: int) -> tuple[OpwParameters, np.ndarray, np.ndarray]:
    """OPW parameters of the chain at q = 0 (see the module docstring and :mod:`singplan.kinematics.closedform.opw`).

    OPW frame: z along axis 1 through the base origin, y along axis 2 (oriented so that the
    shoulder offset a1 >= 0), the forearm frame ``c = Rz(t1) Ry(t2 + t3)`` with z along axis 4
    pointing out to the wrist centre; each joint's sign is its axis against the OPW axis it
    plays, its offset minus its OPW angle at the robot's zero. A base link off axis 1 and a tip
    off axis 6 are first moved there (:func:`_base_frame`, :func:`_flange_frame`); the
    returned transforms carry them (``T_base_closed``, ``T_flange_tip`` of :class:`Recognition`).
    """
    a, p, tip = _axes_and_origins(model, tip_frame_id)
    B = _base_frame(a[0], p[0])
    a, p, tip = a @ B.rotation, (p - B.translation) @ B.rotation, B.actInv(tip)  # in the OPW base frame
    z = np.array([0.0, 0.0, 1.0])
    _require(abs(a[1] @ a[0]) <= _AXIS_TOL, "axis 2 is not perpendicular to axis 1")
    _require(np.linalg.norm(np.cross(a[1], a[2])) <= _AXIS_TOL, "axes 2 and 3 are not parallel")
    wrist = _meet(p[3], a[3], p[4], a[4])
    _require(wrist is not None, "axes 4 and 5 do not meet (no spherical wrist)")
    assert wrist is not None
    _require(np.linalg.norm(np.cross(a[5], wrist - p[5])) <= _POINT_TOL_M,
             "axis 6 does not pass through the wrist centre")
    _require(np.linalg.norm(np.cross(a[2], a[3])) > _AXIS_TOL and abs(a[3] @ a[2]) <= _AXIS_TOL,
             "axis 4 is not perpendicular to axis 3")
    y = _unit(a[1])
    if float(p[1] @ np.cross(y, z)) < -_POINT_TOL_M:
        y = -y  # the shoulder in front of axis 1: a1 >= 0
    x = np.cross(y, z)
    t1 = math.atan2(x[1], x[0])
    a1, c1 = float(p[1] @ x), float(p[1, 2])
    upper = p[2] - p[1]
    t2 = math.atan2(float(upper @ x), float(upper @ z))
    c2 = math.hypot(float(upper @ x), float(upper @ z))
    _require(c2 > _POINT_TOL_M, "axes 2 and 3 coincide")
    fore_axis = a[3] * _sign(float(a[3] @ (wrist - p[2])))  # axis 4 pointing out to the wrist centre
    t23 = math.atan2(float(fore_axis @ x), float(fore_axis @ z))
    R_0c = _rz(t1) @ _ry(t23)
    fore = R_0c.T @ (wrist - p[2])
    _require(math.hypot(fore[0], fore[2]) > _POINT_TOL_M, "the wrist centre is on axis 3")
    flange = _flange_frame(tip, a[5], wrist)
    F = flange.actInv(tip).homogeneous  # the tip in the flange frame
    tip = flange
    tip_z = tip.rotation[:, 2]
    c4 = float((tip.translation - wrist) @ tip_z)
    axis5_c = R_0c.T @ a[4]  # = +-Rz(t4) e_y: take the sign that keeps |t4| <= 90 deg
    t4 = math.atan2(-axis5_c[0], axis5_c[1])
    s5 = 1.0
    if abs(t4) > math.pi / 2:
        t4, s5 = _wrap(t4 + math.pi), -1.0
    R_c4 = R_0c @ _rz(t4)
    w = R_c4.T @ tip_z
    t5 = math.atan2(w[0], w[2])
    M = (R_c4 @ _ry(t5)).T @ tip.rotation
    t6 = math.atan2(M[1, 0], M[0, 0])
    signs = [_sign(float(a[0] @ z)), _sign(float(a[1] @ y)), _sign(float(a[2] @ y)), _sign(float(a[3] @ fore_axis)),
             s5, _sign(float(a[5] @ tip_z))]
    angles = (t1, t2, t23 - t2, t4, t5, t6)
    params = OpwParameters(a1=_snap(a1), a2=_snap(float(fore[0])), b=_snap(float(wrist @ y)), c1=_snap(c1),
                           c2=_snap(c2), c3=_snap(float(fore[2])), c4=_snap(c4),
                           offsets_rad=tuple(_snap_angle(_offset(t)) for t in angles),
                           sign_corrections=tuple(signs))
    return params, B.homogeneous, F


def _base_frame(axis1: np.ndarray, origin1: np.ndarray) -> pin.SE3:
    """The OPW base frame in the URDF's base frame: z along axis 1 (the side of the base z), origin
    the foot of the base origin on axis 1, x the base x made perpendicular; the identity (no
    round-off) when axis 1 already is the base z axis through the origin."""
    z = np.array([0.0, 0.0, 1.0])
    foot = origin1 - float(origin1 @ axis1) * axis1
    if np.linalg.norm(np.cross(axis1, z)) <= _AXIS_TOL and np.linalg.norm(foot) <= _POINT_TOL_M:
        return pin.SE3.Identity()
    z_b = axis1 if float(axis1 @ z) >= 0 else -axis1
    x_b = next(v - float(v @ z_b) * z_b for v in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
               if np.linalg.norm(v - float(v @ z_b) * z_b) > 0.1)
    x_b = _unit(x_b)
    return pin.SE3(np.column_stack([x_b, np.cross(z_b, x_b), z_b]), foot)


def _flange_frame(tip: pin.SE3, axis6: np.ndarray, wrist: np.ndarray) -> pin.SE3:
    """A frame on axis 6 fixed to link 6: z along axis 6 (the tip's z side, else away from the
    wrist centre), origin the tip origin's foot on axis 6, x the tip's x made perpendicular; the
    tip itself when its z is axis 6 and its origin on it."""
    tip_z, out = tip.rotation[:, 2], tip.translation - wrist
    on_axis = np.linalg.norm(out - float(out @ tip_z) * tip_z) <= _POINT_TOL_M
    if np.linalg.norm(np.cross(tip_z, axis6)) <= _AXIS_TOL and on_axis:
        return tip.copy()
    side = float(tip_z @ axis6) if abs(float(tip_z @ axis6)) > _AXIS_TOL else float(out @ axis6)
    z_f = axis6 if side >= 0 else -axis6
    x_f = next(v - float(v @ z_f) * z_f for v in (tip.rotation[:, 0], tip.rotation[:, 1])
               if np.linalg.norm(v - float(v @ z_f) * z_f) > 0.1)
    x_f = _unit(x_f)
    return pin.SE3(np.column_stack([x_f, np.cross(z_f, x_f), z_f]), wrist + float(out @ z_f) * z_f)


def _snap_angle(angle_rad: float) -> float:
    """An offset within round-off of a multiple of 90 deg made exactly that multiple."""
    quarter = round(angle_rad / (math.pi / 2))
    return math.radians(90.0 * quarter) if abs(angle_rad - quarter * math.pi / 2) < 1e-12 else angle_rad


def _derive_ur(model: pin.Model, tip_frame_id: int) -> tuple[UrParameters, np.ndarray, np.ndarray]:
    """UR parameters from the joint placements (the ur_description layout; verified afterwards).

    A base link placed anywhere around axis 1 (e.g. ROS-Industrial's ``base_link``, turned 180
    deg about z from ur_description's) is folded into ``T_base_closed``: the parameters are
    read with joint 1's placement reduced to its height along its axis."""
    a, _p, _tip = _axes_and_origins(model, tip_frame_id)
    _require(all(np.linalg.norm(np.cross(a[1], a[k])) <= _AXIS_TOL for k in (2, 3)), "axes 2, 3 and 4 are not parallel")
    _require(abs(a[1] @ a[0]) <= _AXIS_TOL, "axis 2 is not perpendicular to axis 1")
    _require(abs(a[4] @ a[3]) <= _AXIS_TOL and abs(a[5] @ a[4]) <= _AXIS_TOL,
             "axes 4, 5 and 6 are not successively perpendicular")
    canonical, B = _ur_canonical(model)
    params = UrParameters.from_model(canonical, tip_frame_id)
    _require(min(abs(params.l2), abs(params.l3)) > _POINT_TOL_M, "an arm link of zero length")
    return params, B, np.eye(4)


def _ur_canonical(model: pin.Model) -> tuple[pin.Model, np.ndarray]:
    """The model with joint 1 placed on the base z axis (turned and shifted only about and across
    it), and that placement as ``T_base_closed``; the model itself when joint 1 already is."""
    placement = model.jointPlacements[1]
    kind = model.joints[1].shortname().removeprefix("JointModel")
    z = np.array([0.0, 0.0, 1.0])
    if kind != "RZ" or np.linalg.norm(placement.rotation @ z - z) > _AXIS_TOL:
        return model, np.eye(4)  # the layout check and the verification decide
    height = float(placement.translation[2])
    B = pin.SE3(placement.rotation, placement.translation - height * z)
    if np.linalg.norm(B.translation) <= _POINT_TOL_M and np.linalg.norm(B.rotation - np.eye(3)) <= _AXIS_TOL:
        return model, np.eye(4)
    canonical = model.copy()
    canonical.jointPlacements[1] = pin.SE3(np.eye(3), height * z)
    return canonical, B.homogeneous


# ur_description's tool0 orientation at q = 0 in its base frame: the zero pose the UR closed form assumes
_UR_TOOL_AT_ZERO = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def _derive_ur_geometric(model: pin.Model, tip_frame_id: int) -> tuple[UrParameters, np.ndarray, np.ndarray]:
    """UR parameters from the axes and origins at q = 0, whatever the joint frames (e.g. the
    DH-style layout of newer ur_description files, all joints turning about their own z).

    The closed form's base frame has z along axis 1 and y along axis 2 at q = 0; in it the
    lengths are what the closed form needs: the height of axis 2 (d1), the distances between
    axes 2, 3 and 4 in the arm plane (l2, l3), the lateral offset of the wrist point P where
    axes 5 and 6 meet, P's drop below axis 4 (d5) and the tool's distance along axis 6 (d6); the
    tool frame is ur_description's (the tip folded in as ``T_flange_tip``). The zero pose and
    axis directions must be ur_description's: the verification rejects any other.
    """
    a, p, tip = _axes_and_origins(model, tip_frame_id)
    _require(all(np.linalg.norm(np.cross(a[1], a[k])) <= _AXIS_TOL for k in (2, 3)), "axes 2, 3 and 4 are not parallel")
    B = _base_frame(a[0], p[0])
    y_b = B.rotation.T @ a[1]
    yaw = math.atan2(-y_b[0], y_b[1])  # turn the base about axis 1 until axis 2 is its y
    B = B * pin.SE3(_rz(yaw), np.zeros(3))
    a, p, tip = a @ B.rotation, (p - B.translation) @ B.rotation, B.actInv(tip)
    wrist = _meet(p[4], a[4], p[5], a[5])
    _require(wrist is not None, "axes 5 and 6 do not meet")
    assert wrist is not None
    upper, fore = p[2] - p[1], p[3] - p[2]
    d6 = float((tip.translation - wrist) @ a[5]) * _sign(float(a[5] @ _UR_TOOL_AT_ZERO[:, 2]))
    flange = pin.SE3(_UR_TOOL_AT_ZERO, wrist + d6 * _UR_TOOL_AT_ZERO[:, 2])
    params = UrParameters(d1=_snap(float(p[1, 2])), shoulder_y=_snap(float(p[1, 1])), lateral=_snap(float(wrist[1])),
                          l2=_snap(math.hypot(upper[0], upper[2])), l3=_snap(math.hypot(fore[0], fore[2])),
                          wrist_y=_snap(float(wrist[1] - p[3, 1])), d5=_snap(float(p[3, 2] - wrist[2])), d6=_snap(d6),
                          elbow_y=_snap(float(upper[1])), shoulder_turn=math.atan2(upper[0], upper[2]))
    _require(min(abs(params.l2), abs(params.l3)) > _POINT_TOL_M, "an arm link of zero length")
    return params, B.homogeneous, flange.actInv(tip).homogeneous


def _ur_joint3(model: pin.Model, params: UrParameters, T_base_closed: np.ndarray) -> np.ndarray:
    """The closed form's joint-3 frame in the URDF's (both on link 3), identity within round-off."""
    data = model.createData()
    pin.forwardKinematics(model, data, np.zeros(model.nq))
    B = pin.SE3(T_base_closed)
    origin = B.actInv(data.oMi[3]).translation
    closed = B * pin.SE3(_ry(params.shoulder_turn), origin)
    C = data.oMi[3].actInv(closed).homogeneous
    return np.eye(4) if np.allclose(C, np.eye(4), rtol=0.0, atol=1e-12) else C


def closed_form_batch(params: OpwParameters | UrParameters, T_closed: np.ndarray) -> np.ndarray:
    """All eight closed-form branches (N, 8, 6) [rad] of flange poses (N, 4, 4) in the closed form's
    base frame (:meth:`Recognition.to_closed_form`); NaN rows unreachable."""
    T = np.ascontiguousarray(T_closed, dtype=float).reshape(-1, 4, 4)
    if isinstance(params, UrParameters):
        return ur_batch(params, T)
    zeros = np.zeros(len(T))
    p = params
    return opw.branches(T, p.a1, p.a2, p.b, p.c1, p.c2, p.c3, p.c4, p.offsets, p.signs, zeros, zeros)


def _to_closed_form(T_base_tip: np.ndarray, closed_base_inv: np.ndarray | None,
                    tip_flange_inv: np.ndarray | None) -> np.ndarray:
    T = np.asarray(T_base_tip, dtype=float).reshape(-1, 4, 4)
    if closed_base_inv is not None:
        T = closed_base_inv @ T
    if tip_flange_inv is not None:
        T = T @ tip_flange_inv
    return np.ascontiguousarray(T)


def _inverse_unless_identity(T: np.ndarray) -> np.ndarray | None:
    return None if _is_identity(T) else np.linalg.inv(T)


def _is_identity(T: np.ndarray) -> bool:
    return bool(np.array_equal(T, np.eye(4)))


def verification_samples(model: pin.Model) -> np.ndarray:
    """The seeded joint samples (VERIFY_SAMPLES, n) of the verification, inside the limits."""
    rng = np.random.default_rng(_VERIFY_SEED)
    lower = np.maximum(np.asarray(model.lowerPositionLimit, dtype=float), -math.pi)
    upper = np.minimum(np.asarray(model.upperPositionLimit, dtype=float), math.pi)
    return rng.uniform(lower, upper, size=(VERIFY_SAMPLES, model.nq))


def _verify(model: pin.Model, tip_frame_id: int, params: OpwParameters | UrParameters, T_base_closed: np.ndarray,
            T_flange_tip: np.ndarray) -> tuple[float, float]:
    """Worst (position [m], rotation [rad]) FK error of the closed form's branch nearest each sample.

    Raises _NotFamilyError when the closed form loses a sample's branch or misses its pose.
    """
    data = model.createData()
    samples = verification_samples(model)
    poses = []
    for q in samples:
        pin.framesForwardKinematics(model, data, q)
        poses.append(data.oMf[tip_frame_id].homogeneous)
    branches = closed_form_batch(params, _to_closed_form(np.array(poses), _inverse_unless_identity(T_base_closed),
                                                           _inverse_unless_identity(T_flange_tip)))
    worst_m = worst_rad = 0.0
    for q, T, sols in zip(samples, poses, branches, strict=True):
        diff = np.abs(np.angle(np.exp(1j * (sols - q))))  # per joint, modulo whole turns
        dist = np.where(np.isnan(diff).any(axis=1), np.inf, diff.max(axis=1))
        k = int(np.argmin(dist))
        if not dist[k] <= _BRANCH_TOL_RAD:
            raise _NotFamilyError(f"the closed form does not recover the joints {np.round(q, 4).tolist()} "
                             f"(nearest branch {float(dist[k]):.3g} rad away)")
        pin.framesForwardKinematics(model, data, sols[k])
        error = pin.SE3(T).actInv(data.oMf[tip_frame_id])
        worst_m = max(worst_m, float(np.linalg.norm(error.translation)))
        worst_rad = max(worst_rad, float(np.linalg.norm(pin.log3(error.rotation))))
    if not (worst_m <= VERIFY_TOL_M and worst_rad <= VERIFY_TOL_RAD):
        raise _NotFamilyError(f"the closed form misses the URDF's FK by {worst_m:.3g} m / {worst_rad:.3g} rad")
    return worst_m, worst_rad

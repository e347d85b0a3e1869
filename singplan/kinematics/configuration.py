"""Configuration labels (shoulder F/B, elbow U/D, wrist N/F) and signed singularity distances.

The labels are defined from geometry, not from joint values, so one definition serves every
arm whatever its joint signs and offsets. With the joint frames of Pinocchio:

* ``up`` is axis 1, oriented from the base towards the shoulder; ``forward`` is, for an OPW
  arm, the x axis of its OPW frame turning with joint 1 (whatever the URDF's zero pose), else
  the direction perpendicular to axes 1 and 2, turning with joint 1 and pointing along link 1's
  x axis (the direction the arm points at its zero pose in ROS-Industrial URDFs);
  ``n = up x forward`` is the normal of the arm plane.
* The **wrist point** ``w`` is where axes 5 and 6 meet (the wrist centre of a spherical
  wrist; for a UR arm the origin of the wrist-3 joint).
* **Shoulder** distance [m]: ``(w - o1) . forward``, the signed distance of the wrist point
  from axis 1 measured in the arm plane. Where the arm has a lateral offset (OPW ``b``, the
  UR ``d4``) this is the distance from that offset cylinder. ``F`` (front) when positive.
* **Elbow** distance [rad]: signed angle, about ``n``, from the upper arm ``o3 - o2`` to the
  forearm ``e - o3`` (both projected onto the arm plane); 0 when the arm is stretched. ``e``
  is the wrist point, or where axes 2, 3 and 4 are parallel (UR-type arms) the origin of
  joint 4, which the planar arm positions.
  ``U`` (up) when positive.
* **Wrist** distance [rad]: signed angle from axis 4 to axis 6 about axis 5. Axis 4 is
  oriented outwards from the elbow, axis 6 outwards to the flange, and axis 5 is oriented at
  the zero configuration along the first of (n, up, forward) it is not perpendicular to.
  ``N`` (no flip) when positive; 0 where axes 4 and 6 are collinear.

Each label is the sign of its distance, so a label flips exactly where its distance
crosses zero, and there the Jacobian loses rank (tested). On the singularity itself the sign
is round-off (the UR5 at q = 0 is wrist-, elbow- and nearly shoulder-singular): a distance
within :data:`LABEL_ZERO` of zero (an angle also within it of +-pi, where the wrapped value
jumps) counts as on it, and a configuration on a singularity takes the positive letter (F, U,
N). :func:`positive_sides` is that rule; every label singplan prints or records (``classify``,
the IK's list, the planner's configuration checks, trajectory.json) comes from it.

A 7-joint arm (family ``seven``) has none of these: its self-motion joins what would be
branches of a 6R arm, and its singularities are not the 6R wrist, shoulder and elbow. Its
distances are NaN and its label is ``-`` (:data:`NO_LABEL`). Holding one joint
(:mod:`singplan.kinematics.held`) makes it a 6R chain, labelled by the definitions above.

Five-joint arms have their own shoulder and elbow definitions and no wrist flip
(:mod:`singplan.kinematics.reduced`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError
from singplan.kinematics import reduced
from singplan.kinematics.angles import wrap
from singplan.kinematics.compiled import jit
from singplan.kinematics.geometry import cross3
from singplan.kinematics.robot import Robot

# [rad] or [m]: a signed distance this close to its singular value is on it. The closed forms
# are exact to round-off in the pose, but an angle solved where two branches meet carries its
# square root: the UR5's q3 at q = 0 comes out +-2.6e-8 rad (elbow up and down, one pose to
# 1e-16 m), and up to 1.2e-6 rad on random stretched-elbow poses of the UR5 and UR10.
LABEL_ZERO = 1e-5
SHOULDER_LABELS = ("F", "B")
ELBOW_LABELS = ("U", "D")
WRIST_LABELS = ("N", "F")
NO_LABEL = "-"  # an arm without configuration labels (7 joints)


@dataclass(frozen=True)
class Configuration:
    """A branch of the inverse kinematics, as integrators name it."""

    shoulder: str  # "F" front | "B" back
    elbow: str  # "U" up | "D" down
    wrist: str  # "N" no flip | "F" flip

    @property
    def label(self) -> str:
        """String form, e.g. ``"F U N"``; ``"-"`` for :data:`UNLABELLED`."""
        if self == UNLABELLED:
            return NO_LABEL
        return f"{self.shoulder} {self.elbow} {self.wrist}"

    def __str__(self) -> str:
        return self.label


UNLABELLED = Configuration(NO_LABEL, NO_LABEL, NO_LABEL)  # the configuration of an arm without labels


def _unlabelled(robot: Robot) -> bool:
    return robot.family == "seven"


def parse_configuration(text: str, field: str = "config") -> Configuration:
    """Parse ``"F U N"`` (spaces optional) into a :class:`Configuration`."""
    letters = text.replace(" ", "").upper()
    if (len(letters) != 3 or letters[0] not in SHOULDER_LABELS or letters[1] not in ELBOW_LABELS
            or letters[2] not in WRIST_LABELS):
        raise TaskError(field, f"expected a configuration like 'F U N' (shoulder F|B, elbow U|D, "
                               f"wrist N|F), got {text!r}")
    return Configuration(letters[0], letters[1], letters[2])


class SingularityDistances(NamedTuple):
    """Signed distances to the three singularities; each label is the sign of its distance."""

    wrist_rad: float  # angle between axes 4 and 6 [rad], signed: > 0 no flip
    shoulder_m: float  # wrist point from axis 1 in the arm plane [m], signed: > 0 front
    elbow_rad: float  # forearm angle from the stretched arm [rad], signed: > 0 up
    sigma_min: float  # smallest singular value of the TCP Jacobian


class _Reference(NamedTuple):
    """Per-robot constants of the definitions above (computed at the zero configuration)."""

    up: np.ndarray  # (3,) axis 1 in the base frame, oriented base -> shoulder
    sign4: float
    sign5: float
    sign6: float
    wrist_in_link5: np.ndarray  # (3,) wrist point in joint 5's frame
    forward_in_link1: np.ndarray  # (3,) the arm's forward direction in joint 1's frame
    elbow_joint: int  # 0: elbow point is the wrist point; k: origin of joint k
    has_wrist: bool  # axes 4 and 6 both off axis 5: turning joint 5 makes axes 4, 5, 6 coplanar somewhere


class _Chain(NamedTuple):
    """The joints at one configuration, in the base frame."""

    origins: list[np.ndarray]  # joint frames' origins 1..n
    axes: list[np.ndarray]  # unit joint axes 1..n
    frame1: pin.SE3  # joint 1's frame
    frame5: pin.SE3  # joint 5's frame


@dataclass(frozen=True)
class _Frames:
    """Joint origins and axes (base frame) at one configuration."""

    origins: list[np.ndarray]
    axes: list[np.ndarray]
    wrist: np.ndarray
    forward: np.ndarray


def _chain(robot: Robot, q: np.ndarray) -> _Chain:
    model, data = robot.model, robot.data
    J = pin.computeJointJacobians(model, data, q)  # WORLD frame: columns carry joint axes
    origins = [np.array(data.oMi[i].translation) for i in range(1, model.njoints)]
    axes = [np.array(J[3:, model.joints[i].idx_v]) for i in range(1, model.njoints)]
    return _Chain(origins, axes, data.oMi[1].copy(), data.oMi[5].copy())  # copies: data changes on the next call


def _closest_point_on_first(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Point of line (p1, d1) closest to line (p2, d2); p1 when they are parallel."""
    w = p1 - p2
    b = float(d1 @ d2)
    denom = 1.0 - b * b
    if denom < 1e-12:
        return p1
    t = (b * float(d2 @ w) - float(d1 @ w)) / denom
    return p1 + t * d1


@lru_cache(maxsize=64)
def _reference(robot: Robot) -> _Reference:
    q0 = np.zeros(robot.n_joints)
    chain = _chain(robot, q0)
    origins, axes = chain.origins, chain.axes
    z1 = axes[0]
    up = z1 if float(z1 @ origins[1]) >= 0 else -z1  # origins are relative to the base origin
    wrist = _closest_point_on_first(origins[4], axes[4], origins[5], axes[5])
    wrist_in_link5 = np.array(chain.frame5.actInv(wrist))
    forward_in_link1 = _forward_in_link1(robot, chain, up)
    # the signs are read at the OPW zero where there is one: the same arm pose whatever the file's zero
    q_ref = q0 if robot.opw is None else robot.opw.offsets * robot.opw.signs
    if robot.opw is not None:
        chain = _chain(robot, q_ref)
        origins, axes = chain.origins, chain.axes
        wrist = np.array(chain.frame5.act(wrist_in_link5))
    forward = _forward(chain, up, forward_in_link1)
    tool0 = robot.fk_tip(q_ref).translation
    elbow_joint = 4 if _parallel(axes[1], axes[3]) and _parallel(axes[2], axes[3]) else 0
    sign4 = 1.0 if float(axes[3] @ (wrist - origins[2])) >= 0 else -1.0
    sign6 = 1.0 if float(axes[5] @ (tool0 - wrist)) >= 0 else -1.0
    normal = cross3(up, forward)
    sign5 = 1.0
    for ref in (normal, up, forward):
        dot = float(axes[4] @ ref)
        if abs(dot) > 0.5:
            sign5 = 1.0 if dot > 0 else -1.0
            break
    has_wrist = not (_parallel(axes[3], axes[4]) or _parallel(axes[5], axes[4]))
    return _Reference(up, sign4, sign5, sign6, wrist_in_link5, forward_in_link1, elbow_joint, has_wrist)


def _forward_in_link1(robot: Robot, chain: _Chain, up: np.ndarray) -> np.ndarray:
    """The arm's forward direction in joint 1's frame (``chain`` at q = 0).

    For an OPW arm the OPW x axis (the arm plane at q1_opw = 0), for a UR arm its closed form's
    x axis (ur_description's base x at q1 = 0). Otherwise the direction
    perpendicular to axes 1 and 2 (the arm plane's in-plane horizontal, whatever the file's
    frames), pointing along joint 1's x axis as ROS-Industrial files do, or where that x is
    perpendicular to it, towards the shoulder joint's offset from axis 1 (else either way).
    """
    R1 = chain.frame1.rotation
    R_base_closed = robot.recognition.T_base_closed[:3, :3]
    if robot.opw is not None:
        t1 = -robot.opw.offsets_rad[0]  # OPW angle of joint 1 at the robot's zero
        return R1.T @ R_base_closed @ np.array([math.cos(t1), math.sin(t1), 0.0])
    if robot.ur is not None:  # the closed form's x at q = 0, whatever the file's joint-1 frame
        return R1.T @ R_base_closed @ np.array([1.0, 0.0, 0.0])
    across = cross3(chain.axes[1], up)
    if float(np.linalg.norm(across)) < 1e-9:  # axis 2 along axis 1: keep joint 1's x
        return np.array([1.0, 0.0, 0.0])
    across = across / np.linalg.norm(across)
    offset = chain.origins[1] - chain.origins[0]
    for hint in (R1[:, 0], offset):
        dot = float(across @ hint)
        if abs(dot) > 1e-9:
            return R1.T @ (across if dot > 0 else -across)
    return R1.T @ across


def _parallel(a: np.ndarray, b: np.ndarray) -> bool:
    return float(np.linalg.norm(cross3(a, b))) < 1e-9


def _forward(chain: _Chain, up: np.ndarray, forward_in_link1: np.ndarray) -> np.ndarray:
    x1 = chain.frame1.rotation @ forward_in_link1
    f = x1 - float(x1 @ up) * up
    return f / np.linalg.norm(f)


def _frames(robot: Robot, q: np.ndarray) -> tuple[_Reference, _Frames]:
    ref = _reference(robot)
    chain = _chain(robot, q)
    wrist = np.array(chain.frame5.act(ref.wrist_in_link5))
    return ref, _Frames(chain.origins, chain.axes, wrist, _forward(chain, ref.up, ref.forward_in_link1))


def _signed_distances(ref: _Reference, fr: _Frames) -> tuple[float, float, float]:
    o, z = fr.origins, fr.axes
    shoulder = float((fr.wrist - o[0]) @ fr.forward)
    n = cross3(ref.up, fr.forward)
    elbow_point = fr.wrist if ref.elbow_joint == 0 else o[ref.elbow_joint - 1]
    upper, fore = o[2] - o[1], elbow_point - o[2]
    upper = upper - float(upper @ n) * n
    fore = fore - float(fore @ n) * n
    elbow = float(np.arctan2(cross3(upper, fore) @ n, upper @ fore))
    z4, z5, z6 = ref.sign4 * z[3], ref.sign5 * z[4], ref.sign6 * z[5]
    # no wrist singularity (axis 4 or 6 along axis 5): never in a wrist zone, label N
    wrist = float(np.arctan2(cross3(z4, z6) @ z5, z4 @ z6)) if ref.has_wrist else math.pi
    return wrist, shoulder, elbow


def positive_sides(d: np.ndarray) -> np.ndarray:
    """Which signed (wrist [rad], shoulder [m], elbow [rad]) distances (..., 3) take the positive
    letter (N, F, U): those above ``-LABEL_ZERO`` (on the singularity counts as positive), and the
    wrapped angles within ``LABEL_ZERO`` of -pi (the same angle as +pi). NaN is not positive."""
    d = np.asarray(d, dtype=float)
    positive = d >= -LABEL_ZERO
    positive[..., [0, 2]] |= d[..., [0, 2]] <= -math.pi + LABEL_ZERO
    return positive


def _label(wrist: float, shoulder: float, elbow: float) -> Configuration:
    w, s, e = positive_sides(np.array([wrist, shoulder, elbow])).tolist()
    return Configuration(SHOULDER_LABELS[0 if s else 1], ELBOW_LABELS[0 if e else 1], WRIST_LABELS[0 if w else 1])


def classify(robot: Robot, q: np.ndarray) -> Configuration:
    """The configuration (shoulder, elbow, wrist) of joint values ``q`` (n,) [rad]; UNLABELLED for 7 joints."""
    if _unlabelled(robot):
        return UNLABELLED
    if reduced.is_reduced(robot):
        return _label(*reduced.distances(robot, q))
    ref, fr = _frames(robot, np.asarray(q, dtype=float))
    return _label(*_signed_distances(ref, fr))


def singularity_distances(robot: Robot, q: np.ndarray) -> SingularityDistances:
    """Signed distances of ``q`` to the wrist, shoulder and elbow singularities.

    Also the smallest singular value of the 6 x n TCP Jacobian, a unit-mixed but
    method-independent measure of how close ``q`` is to any singularity.
    """
    q = np.asarray(q, dtype=float)
    if _unlabelled(robot):
        wrist, shoulder, elbow = (math.nan,) * 3
    elif reduced.is_reduced(robot):
        return SingularityDistances(*reduced.distances(robot, q), reduced.sigma_min(robot, q))
    else:
        wrist, shoulder, elbow = _signed_distances(*_frames(robot, q))
    sigma = float(np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1])
    return SingularityDistances(wrist, shoulder, elbow, sigma)


def label_and_distances(robot: Robot, q: np.ndarray) -> tuple[Configuration, SingularityDistances]:
    """Both at once (one forward kinematics), for sampling along paths."""
    d = singularity_distances(robot, q)
    return _label(d.wrist_rad, d.shoulder_m, d.elbow_rad), d


def distances_batch(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Signed (wrist [rad], shoulder [m], elbow [rad]) distances of many samples q (N, n).

    For OPW arms this is closed form, one compiled loop, from the OPW joint angles: the wrist
    distance is q5 (axes 4 and 6 meet at the wrist centre at that angle), the shoulder
    distance is the wrist centre's forward coordinate in the arm plane,
    ``a1 + c2 sin q2 + k sin(q2 + q3 + psi)`` with ``k = hypot(a2, c3)``, ``psi = atan2(a2, c3)``,
    and the elbow distance is ``q3 + psi``, the angle from the upper arm to the forearm.
    For UR arms (the ur_description layout of :mod:`singplan.kinematics.closedform.ur`) they are ``-q5``, the
    wrist point's forward coordinate in frame 1, ``l2 cos q2 + l3 cos(q2 + q3) - d5 sin(q2 + q3 + q4)``,
    and ``q3``. These equal the frame-based definitions above (tested); other arms use those,
    per sample.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if _unlabelled(robot):
        return np.full((len(q), 3), np.nan)
    if reduced.is_reduced(robot):
        return reduced.distances_batch(robot, q)
    if robot.opw is None and robot.ur is None:
        return np.array([_signed_distances(*_frames(robot, qk)) for qk in q]).reshape(-1, 3)
    return _closed_form_distances(robot, q)


def _closed_form_distances(robot: Robot, q: np.ndarray) -> np.ndarray:
    """:func:`distances_batch` of an OPW or UR arm's samples q (N, n)."""
    p = robot.opw
    if p is None:
        ur = robot.ur
        assert ur is not None
        return _ur_distances(np.ascontiguousarray(q), ur.l2, ur.l3, ur.d5)
    return _opw_distances(np.ascontiguousarray(q), p.signs, p.offsets, p.a1, p.c2, math.hypot(p.a2, p.c3),
                          math.atan2(p.a2, p.c3))


def _closed_form_labelled(robot: Robot) -> bool:
    """Whether :func:`distances_batch` is a closed form (OPW, UR) rather than classify's own computation."""
    return not (_unlabelled(robot) or reduced.is_reduced(robot)) and (robot.opw is not None or robot.ur is not None)


@jit
def _opw_distances(q: np.ndarray, signs: np.ndarray, offsets: np.ndarray, a1: float, c2: float, k: float,
                   psi: float) -> np.ndarray:
    """:func:`distances_batch` of an OPW arm: (q5, shoulder, q3 + psi), angles wrapped to (-pi, pi]."""
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        t2, t3, t5 = (q[i, 1] * signs[1] - offsets[1], q[i, 2] * signs[2] - offsets[2],
                      q[i, 4] * signs[4] - offsets[4])
        out[i, 0] = wrap(t5)
        out[i, 1] = a1 + c2 * math.sin(t2) + k * math.sin(t2 + t3 + psi)
        out[i, 2] = wrap(t3 + psi)
    return out


# The OPW and UR closed forms of distances_batch agree with the frame-based distances of classify
# to ~5e-12 (m or rad, measured on the bundled arms); within this margin of where a label changes
# (+-LABEL_ZERO about 0, or +-pi for the wrapped angles) a row is classified on its own so the two
# never disagree on a label.
_LABEL_BOUNDARY = 10 * LABEL_ZERO


def labels_batch(robot: Robot, q: np.ndarray) -> list[str]:
    """``classify(robot, qk).label`` of every row of q (N, n) [rad], from one :func:`distances_batch` call."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    d = distances_batch(robot, q)
    labels = labels_from_distances(d)
    if not _closed_form_labelled(robot):
        return labels  # distances_batch is classify's own computation, row by row
    for k in _near_sign_change(d, _LABEL_BOUNDARY):
        labels[k] = classify(robot, q[k]).label
    return labels


# [m or rad]: how far the distances of a whole-turn variant of a row, moved by at most 1e-9 rad into
# the limits (:mod:`singplan.kinematics.ik.turns`), can be from the row's own: the clip times the arm's
# reach (under 1e-8 for any arm under 10 m) and round-off, with room to spare
_VARIANT_SLACK = 1e-6


def labels_of_variants(robot: Robot, rows: np.ndarray, origin: np.ndarray, q: np.ndarray) -> list[str]:
    """:func:`labels_batch` of rows q (M, n) [rad], each a whole-turn variant of ``rows[origin]``
    (``rows`` (B, n), ``origin`` (M,)) moved by at most 1e-9 rad into the joint limits.

    The singular distances are periodic in every joint, so a variant's are its row's to round-off
    and the clip: each of the B rows is labelled once, and only the rows of a branch within
    :data:`_VARIANT_SLACK` of :func:`labels_batch`'s own margin of a sign change are labelled one
    by one, as :func:`labels_batch` labels them (for a UR arm's 256 variants of 8 branches, 8 rows
    to compute instead of 256).
    """
    if not _closed_form_labelled(robot):
        return labels_batch(robot, q)
    codes = _codes_off_sign_change(_closed_form_distances(robot, rows), LABEL_ZERO, _LABEL_BOUNDARY + _VARIANT_SLACK)
    by_row = codes[origin]
    labels: list[str] = _LABELS[by_row].tolist()
    if -1 in codes.tolist():
        near = np.flatnonzero(by_row < 0)
        for k, label in zip(near.tolist(), labels_batch(robot, q[near]), strict=True):
            labels[k] = label
    return labels


@jit
def _codes_off_sign_change(d: np.ndarray, zero: float, margin: float) -> np.ndarray:
    """:func:`_label_codes` of distance rows d (N, 3), -1 for the rows :func:`_near_sign_change` finds
    within ``margin`` of a sign change."""
    codes = _label_codes(d, zero)
    codes[_near_sign_change(d, margin)] = -1
    return codes


@jit
def _near_sign_change(d: np.ndarray, margin: float) -> np.ndarray:
    """The rows of distances d (N, 3) with one within ``margin`` of 0, or an angle (wrist, elbow)
    within it of +-pi: where a closed form's sign may disagree with classify's."""
    near = np.zeros(d.shape[0], dtype=np.bool_)
    for i in range(d.shape[0]):
        for j in range(3):
            near[i] |= abs(d[i, j]) < margin or (j != 1 and abs(d[i, j]) > math.pi - margin)
    return np.flatnonzero(near)


def labels_from_distances(d: np.ndarray) -> list[str]:
    """Configuration labels of distance rows (N, 3): each distance's side (the rule of
    :func:`positive_sides`, compiled); NO_LABEL for an all-NaN row."""
    labels: list[str] = _LABELS[_label_codes(np.ascontiguousarray(d, dtype=float), LABEL_ZERO)].tolist()
    return labels


# the label of each code of _label_codes (front 4, up 2, no flip 1; 8 none), as objects: one take a call
_LABELS = np.array([*(f"{s} {e} {w}" for s in SHOULDER_LABELS[::-1] for e in ELBOW_LABELS[::-1]
                      for w in WRIST_LABELS[::-1]), NO_LABEL], dtype=object)


@jit
def _label_codes(d: np.ndarray, zero: float) -> np.ndarray:
    """Each distance row's (N, 3) index in _LABELS: which side of ``zero`` each distance is on, as
    :func:`positive_sides` says (an angle within ``zero`` of -pi is +pi's; NaN counts as negative)."""
    codes = np.empty(d.shape[0], dtype=np.int64)
    for i in range(d.shape[0]):
        wrist, shoulder, elbow = d[i, 0], d[i, 1], d[i, 2]
        if math.isnan(wrist) and math.isnan(shoulder) and math.isnan(elbow):
            codes[i] = 8
        else:
            codes[i] = (4 * (shoulder >= -zero) + 2 * (elbow >= -zero or elbow <= -math.pi + zero)
                        + (wrist >= -zero or wrist <= -math.pi + zero))
    return codes


@jit
def _ur_distances(q: np.ndarray, l2: float, l3: float, d5: float) -> np.ndarray:
    """:func:`distances_batch` of a UR arm: (-q5, shoulder, q3), angles wrapped to (-pi, pi]."""
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        out[i, 0] = wrap(-q[i, 4])
        q2, q23 = q[i, 1], q[i, 1] + q[i, 2]
        out[i, 1] = l2 * math.cos(q2) + l3 * math.cos(q23) - d5 * math.sin(q23 + q[i, 3])
        out[i, 2] = wrap(q[i, 2])
    return out

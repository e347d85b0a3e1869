"""A URDF read and scanned before Pinocchio sees it: counts, depths and every joint's axis and mimic.

Pinocchio (urdfdom underneath) builds the kinematic tree recursively: a chain of a few thousand
joints overflows the C stack and kills the process (SIGSEGV, no message), and a joint axis of
``0 0 0`` becomes a joint that does not move, which planning then reports as an unreachable pose.
So the file is read through :func:`~singplan.kinematics.files.read_bounded` and scanned first with
Python's expat parser (iteratively; expat refuses entity-expansion bombs itself), and refused,
naming the file and the element, when it has

* more than :data:`MAX_ELEMENTS` XML elements or nesting deeper than :data:`MAX_XML_DEPTH`;
* more than :data:`MAX_JOINTS` joints or :data:`MAX_LINKS` links, or a kinematic tree deeper
  than :data:`MAX_TREE_DEPTH` joints;
* a joint or link name that is empty, over :data:`MAX_NAME_CHARS` characters or holds a control
  character (outputs and other tools could not name it);
* a movable joint whose axis is not three finite numbers of non-zero length;
* a ``<mimic>`` naming no joint, or with a multiplier or offset that is not a finite number.

The scan also records each joint's ``<mimic>``: singplan plans independent joints, so a joint on
the planned chain that mimics another is refused by name (:func:`check_no_mimic`), while mimic
joints off the chain (a gripper's fingers) are locked with the rest of the tree, as before.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

from singplan.errors import RobotModelError
from singplan.kinematics.files import FileRefusedError, display_path, read_bounded

MAX_URDF_BYTES = 32 * 1024 * 1024
MAX_ELEMENTS = 200_000  # a detailed humanoid has a few thousand
MAX_XML_DEPTH = 32  # URDF nests robot > link > visual > geometry > mesh: 5 levels
MAX_JOINTS = 1000
MAX_LINKS = MAX_JOINTS + 1
MAX_TREE_DEPTH = 256  # joints from the root to the deepest link; Pinocchio's parser crashed past ~3000
MAX_NAME_CHARS = 256
MIN_AXIS_NORM = 1e-6
_MOVABLE = ("revolute", "continuous", "prismatic", "planar")


@dataclass(frozen=True)
class Mimic:
    """A joint's ``<mimic>``: its value is ``multiplier * leader + offset``."""

    leader: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class UrdfScan:
    """What the scan found: the document's text, for Pinocchio, and each joint's mimic."""

    text: str
    joints: tuple[str, ...]
    mimics: dict[str, Mimic] = field(default_factory=dict)  # follower joint -> its leader and law


def read_urdf(path: Path) -> UrdfScan:
    """The URDF at ``path``, read and scanned (see the module's docstring).

    Raises:
        RobotModelError: not a regular file within :data:`MAX_URDF_BYTES` (missing, a folder, a
            FIFO, a device ...), or what the scan refuses, naming the file and the element.
    """
    try:
        data = read_bounded(path, MAX_URDF_BYTES, "URDF")
    except FileRefusedError as exc:
        raise RobotModelError(exc.path, exc.reason) from None
    name = display_path(path)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RobotModelError(name, f"cannot be read as URDF: not UTF-8 text (byte {exc.start} is invalid)") from None
    return _Scanner(name).scan(data, text)


class _Scanner:
    def __init__(self, name: str) -> None:
        self.name = name
        self.joints: list[str] = []
        self.links: set[str] = set()
        self.parent_of: dict[str, str] = {}  # child link -> parent link
        self.mimics: dict[str, Mimic] = {}
        self.mimic_elements: dict[str, ET.Element] = {}

    def fail(self, reason: str) -> RobotModelError:
        return RobotModelError(self.name, reason)

    def scan(self, data: bytes, text: str) -> UrdfScan:
        depth = elements = 0
        parser: ET.XMLPullParser[ET.Element] = ET.XMLPullParser(events=("start", "end"))
        try:
            for start in range(0, max(len(data), 1), 1 << 20):  # fed a MiB at a time: events as they come
                parser.feed(data[start:start + (1 << 20)])
                for event, element in cast(Iterator[tuple[str, ET.Element]], parser.read_events()):
                    if event == "start":
                        depth += 1
                        elements += 1
                        self._check_size(depth, elements, element)
                        continue
                    depth -= 1
                    if depth == 1:
                        self._top_level(element)
                        element.clear()  # the scan keeps names, not the tree
            parser.close()
        except ET.ParseError as exc:
            raise self.fail(f"cannot be read as URDF: not well-formed XML ({exc})") from None
        self._check_tree()
        return UrdfScan(text, tuple(self.joints), dict(self.mimics))

    def _check_size(self, depth: int, elements: int, element: ET.Element) -> None:
        if depth == 1 and element.tag != "robot":
            raise self.fail(f"cannot be read as URDF: the root element is <{_tag(element.tag)}>, not <robot>")
        if depth > MAX_XML_DEPTH:
            raise self.fail(f"XML nested deeper than {MAX_XML_DEPTH} levels (at <{_tag(element.tag)}>); "
                            "a URDF nests 5 or 6")
        if elements > MAX_ELEMENTS:
            raise self.fail(f"more than {MAX_ELEMENTS} XML elements; singplan reads URDFs up to that")

    def _top_level(self, element: ET.Element) -> None:
        if element.tag == "link":
            link = self._name("link", element)
            self.links.add(link)
            if len(self.links) > MAX_LINKS:
                raise self.fail(f"more than {MAX_LINKS} links; singplan reads URDFs of up to {MAX_JOINTS} joints")
        elif element.tag == "joint":
            self._joint(element)

    def _name(self, kind: str, element: ET.Element) -> str:
        text = element.get("name")
        if not text:
            raise self.fail(f"a <{kind}> without a name")
        shown = repr(text[:60])
        if len(text) > MAX_NAME_CHARS:
            raise self.fail(f"{kind} {shown}...: a name of {len(text)} characters is over the cap of {MAX_NAME_CHARS}")
        if not text.isprintable():
            raise self.fail(f"{kind} {shown}: the name holds a control character; outputs could not name it")
        return text

    def _joint(self, element: ET.Element) -> None:
        name = self._name("joint", element)
        self.joints.append(name)
        if len(self.joints) > MAX_JOINTS:
            raise self.fail(f"more than {MAX_JOINTS} joints; singplan reads URDFs of up to {MAX_JOINTS}")
        parent, child = element.find("parent"), element.find("child")
        if parent is not None and child is not None and parent.get("link") and child.get("link"):
            self.parent_of.setdefault(str(child.get("link")), str(parent.get("link")))
        if element.get("type") in _MOVABLE:
            self._axis(name, element.find("axis"))
        mimic = element.find("mimic")
        if mimic is not None:
            self.mimics[name] = Mimic(str(mimic.get("joint", "")), self._number(name, mimic, "multiplier", 1.0),
                                      self._number(name, mimic, "offset", 0.0))

    def _axis(self, joint: str, axis: ET.Element | None) -> None:
        """A movable joint's axis: three finite numbers of non-zero length (urdfdom's default 1 0 0 if absent)."""
        if axis is None or axis.get("xyz") is None:
            return
        text = str(axis.get("xyz"))
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise self.fail(f"joint {joint!r}: axis xyz={text[:60]!r} is not three finite numbers")
        if math.hypot(*values) < MIN_AXIS_NORM:
            raise self.fail(f"joint {joint!r}: axis xyz={text[:60]!r} has no direction (length "
                            f"{math.hypot(*values):.3g}); give the unit vector it turns or slides along")

    def _number(self, joint: str, element: ET.Element, key: str, default: float) -> float:
        text = element.get(key)
        try:
            value = default if text is None else float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or abs(value) > 1e6:
            raise self.fail(f"joint {joint!r}: mimic {key}={str(text)[:40]!r} is not a finite number")
        return value

    def _check_tree(self) -> None:
        """Every mimic names a joint; no chain of links deeper than :data:`MAX_TREE_DEPTH` (or a loop)."""
        for follower, mimic in self.mimics.items():
            if mimic.leader not in self.joints:
                raise self.fail(f"joint {follower!r}: mimic joint={mimic.leader[:60]!r} names no joint of the URDF")
        depth: dict[str, int] = {}
        for link in self.parent_of:
            self._depth(link, depth)

    def _depth(self, link: str, depth: dict[str, int]) -> None:
        """Record the depth of ``link`` and of the links on its way to one of known depth (or the root)."""
        path = []
        while link in self.parent_of and link not in depth:
            path.append(link)
            if len(path) > MAX_TREE_DEPTH:
                raise self.fail(f"a chain of more than {MAX_TREE_DEPTH} joints from the root to {link!r} "
                                "(or a loop of links); singplan reads trees up to that depth")
            link = self.parent_of[link]
        known = depth.get(link, 0)
        for k, step in enumerate(reversed(path), start=1):
            depth[step] = known + k
            if known + k > MAX_TREE_DEPTH:
                raise self.fail(f"a chain of more than {MAX_TREE_DEPTH} joints from the root to {step!r}; "
                                "singplan reads trees up to that depth")


def check_no_mimic(scan: UrdfScan, chain: Iterable[str], path: str) -> None:
    """Refuse a planned-chain joint that mimics another (named, with its leader and law)."""
    for joint in chain:
        mimic = scan.mimics.get(joint)
        if mimic is not None:
            raise RobotModelError(path, f"joint {joint!r} mimics {mimic.leader!r} (multiplier {mimic.multiplier:g}, "
                                        f"offset {mimic.offset:g}); singplan plans independent joints, so a mimic "
                                        "joint on the chain from the base to the tip is not supported (mimic "
                                        "joints off the chain, e.g. a gripper's fingers, are)")


def _tag(tag: str) -> str:
    return tag[:40]

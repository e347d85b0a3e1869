"""A YAML document read with bounded work: its event stream scanned before anything is built.

PyYAML builds a document recursively and follows aliases, so a document written to hurt (a
billion-laughs alias bomb, nesting thousands deep, half a million nodes, a 5000-digit integer)
costs gigabytes or a crash before any value can be checked. Every YAML file singplan reads (the
task, a URDF's controller sidecar) goes through :func:`load_yaml`: the event stream is scanned
first, iteratively (no input can exhaust the stack), and refused with the key path and line on
nesting deeper than :attr:`YamlLimits.max_depth`, more than :attr:`YamlLimits.max_nodes` nodes,
any alias or merge key, a key given twice in one mapping, a key or scalar over its length cap,
an integer longer than any float holds, or a second document. Only then does the safe loader
(libyaml's when installed) build the document.

Errors are made by the caller's ``error(field, reason)`` (the task's :class:`TaskError`, a file's
:class:`~singplan.kinematics.files.FileFieldError`), so each names the file and field its own way;
``field`` is empty for what concerns the whole document.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import yaml

from singplan.errors import InputError

FieldError = Callable[[str, str], InputError]  # (field path or "", reason) -> the error to raise

# more digits than any float can hold: decimal (and YAML 1.1 octal), hexadecimal, binary
_LONG_INTEGER = re.compile(r"[-+]?(?:[0-9][0-9_:]{399,}|0[xX][0-9a-fA-F_]{256,}|0[bB][01_]{1024,})")


@dataclass(frozen=True)
class YamlLimits:
    """What one kind of YAML file may hold; ``kind`` names it in messages ("a task")."""

    kind: str
    max_depth: int  # nesting levels of mappings and sequences
    max_nodes: int  # scalars, mappings and sequences together
    max_key_chars: int
    max_scalar_chars: int


if TYPE_CHECKING:  # the stubs' CSafeLoader is not a SafeLoader; both read the same documents
    _SafeLoader = yaml.SafeLoader
else:
    _SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class Loader(_SafeLoader):
    """The safe loader (libyaml's when installed); reached only after the scan passed.

    It also reads ``1e-3`` and ``2E5`` as numbers (YAML 1.2, JSON), which YAML 1.1 leaves as
    strings; a user writing them means numbers.
    """


Loader.add_implicit_resolver("tag:yaml.org,2002:float",
                             re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"), list("-+0123456789"))


def join_field(prefix: str, key: str) -> str:
    """A key path one level down: ``moves[0].lin`` + ``speed``."""
    return f"{prefix}.{key}" if prefix else key


def shorten(text: str, limit: int = 80) -> str:
    """``text`` cut to ``limit`` characters for a message."""
    return text if len(text) <= limit else f"{text[:limit - 3]}..."


def key_text(key: Any) -> str:
    """A key as it appears in a field path: plain when it is a short printable name."""
    text = str(key)
    if isinstance(key, str) and text.isprintable() and 0 < len(text) <= 64:
        return text
    return shorten(repr(key), 40)


def load_yaml(text: str, limits: YamlLimits, error: FieldError) -> Any:
    """The document of ``text``, after :func:`scan` found it within ``limits``.

    Raises ``error(field, reason)``: a limit broken (the field and line named), not valid YAML
    (line and column), or a scalar PyYAML cannot convert.
    """
    try:
        scan(text, limits, error)
        return yaml.load(text, Loader=Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise error("", f"not valid YAML{where}: {shorten(str(problem))}") from None
    except (ValueError, OverflowError) as exc:  # a scalar PyYAML itself cannot convert
        raise error("", f"a value cannot be read: {shorten(str(exc))}") from None


def scan(text: str, limits: YamlLimits, error: FieldError) -> None:
    """Refuse what the YAML event stream shows is unsafe or ambiguous (see the module's docstring).

    libyaml reads ahead of the events it hands out and, since PyYAML 6.0.4, stops deep flow
    nesting with its own error before this scan sees the level that passes the depth limit.
    So a document libyaml refuses is scanned again with PyYAML's own parser, which reads ahead
    by one token only: the guard's message (which names the limit) comes first whatever the
    release, and a document that is really malformed still raises the parser's error.
    """
    try:
        _Scan(limits, error).run(yaml.parse(text, Loader=Loader))
    except yaml.YAMLError:
        if _SafeLoader is yaml.SafeLoader:  # PyYAML without libyaml: the error is already the Python parser's
            raise
        _Scan(limits, error).run(yaml.parse(text, Loader=yaml.SafeLoader))


@dataclass
class _Open:
    """A mapping or sequence the event scan is inside of."""

    path: str
    is_mapping: bool
    key_lines: dict[str, int] = field(default_factory=dict)  # mapping: key -> line it was given on
    count: int = 0  # sequence: items so far; mapping: keys and values so far
    key: str = ""  # mapping: the key whose value comes next


@dataclass
class _Scan:
    """One pass over a document's events."""

    limits: YamlLimits
    error: FieldError
    stack: list[_Open] = field(default_factory=list)

    def run(self, events: Iterator[Any]) -> None:
        documents = nodes = 0
        for event in events:
            line = event.start_mark.line + 1 if event.start_mark is not None else 0  # the parser always marks
            if isinstance(event, yaml.DocumentStartEvent):
                documents += 1
                if documents > 1:
                    raise self.error("", f"holds more than one YAML document (the second starts "
                                         f"at line {line}); {self.limits.kind} file holds one")
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                self.stack.pop()
            elif isinstance(event, yaml.NodeEvent):
                nodes += 1
                if nodes > self.limits.max_nodes:
                    raise self.error("", f"more than {self.limits.max_nodes} YAML nodes (at line {line})")
                where = self._place(event, line)
                if where is not None:
                    self._check_node(event, where, line)

    def _place(self, event: Any, line: int) -> str | None:
        """The key path of a value node; None (after checking it) when the node is a mapping key."""
        if not self.stack:
            return ""
        top = self.stack[-1]
        top.count += 1
        if not top.is_mapping:
            return f"{top.path}[{top.count - 1}]"
        if top.count % 2 == 0:
            return join_field(top.path, key_text(top.key))
        if not isinstance(event, yaml.ScalarEvent):
            raise self.error(top.path, f"a key must be a plain name, not a list, mapping or alias (line {line})")
        key_path = join_field(top.path, key_text(event.value))
        if event.value == "<<" and event.implicit[0]:
            raise self.error(key_path, f"YAML merge keys are not allowed in {self.limits.kind} (line {line})")
        if event.value in top.key_lines:
            raise self.error(key_path, f"given twice in one mapping (lines {top.key_lines[event.value]} and "
                                       f"{line}); a key may appear once")
        if len(event.value) > self.limits.max_key_chars:
            raise self.error(key_path, f"a key of {len(event.value)} characters is over the cap of "
                                       f"{self.limits.max_key_chars} (line {line})")
        top.key_lines[event.value] = line
        top.key = event.value
        return None

    def _check_node(self, event: Any, where: str, line: int) -> None:
        if isinstance(event, yaml.AliasEvent):
            raise self.error(where, f"YAML aliases are not allowed in {self.limits.kind} (line {line})")
        if isinstance(event, yaml.ScalarEvent):
            if _LONG_INTEGER.fullmatch(event.value):  # quoted too: `!!int "9...9"` would reach int() otherwise
                raise self.error(where, f"number too large ({len(event.value)} characters, line {line})")
            if len(event.value) > self.limits.max_scalar_chars:
                raise self.error(where, f"a value of {len(event.value)} characters is over the cap of "
                                        f"{self.limits.max_scalar_chars} (line {line})")
            return
        if len(self.stack) >= self.limits.max_depth:
            raise self.error(shorten(where, 120), f"nesting deeper than {self.limits.max_depth} levels (line {line})")
        self.stack.append(_Open(where, isinstance(event, yaml.MappingStartEvent)))

"""Did-you-mean for the command line: an unknown command or option is named, with the nearest valid one.

argparse on its own reports ``singplan plna`` as an invalid choice without a hint, and
``singplan export out --fromat ros2`` as a missing ``--format`` without naming ``--fromat``
(its check of required options runs before the one of unknown ones). :class:`SuggestingParser`
looks at its own arguments first: each parser of the tree (``singplan``, then the command's)
checks the tokens it is handed, the top level the command name, a command its options, and
refuses the first unknown one through ``error()`` (usage, message, exit code 2) with the
closest name (:func:`singplan.errors.nearest`, as every unknown name). Everything else is argparse's own.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from singplan.errors import nearest


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


class SuggestingParser(argparse.ArgumentParser):
    """An ArgumentParser that names an unknown command or option and suggests the closest valid one.

    Subparsers are made of the same class (argparse's default ``parser_class``), so each
    command's parser checks its own options.
    """

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]  # typeshed's overloads
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        tokens = list(sys.argv[1:] if args is None else args)
        self._refuse_unknown(tokens)
        return super().parse_known_args(tokens, namespace)

    def _refuse_unknown(self, tokens: list[str]) -> None:
        commands = self._commands()
        for token in tokens:
            if token == "--":
                return
            if token.startswith("-") and len(token) > 1 and not _is_number(token):
                self._check_option(token)
            elif commands is not None:  # the first word is the command; the rest is its parser's
                if token not in commands:
                    self._unknown_command(token, list(commands))
                return

    def _commands(self) -> dict[str, Any] | None:
        """The command names of a parser with commands (argparse keeps them on a private action class)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return dict(action.choices)
        return None

    def _check_option(self, token: str) -> None:
        name = token.split("=", 1)[0]
        known = list(self._option_string_actions)
        if name in known:
            return
        if token.startswith("--") and self.allow_abbrev and any(o.startswith(name) for o in known):
            return  # an abbreviation: argparse resolves it (or names the ambiguity)
        if not token.startswith("--") and token[:2] in known:
            return  # a short option with its value attached: -oDIR
        near = nearest(name, [o for o in known if o.startswith("--") == name.startswith("--")] or known)
        self.error(f"unrecognized option {name!r}" + (f" (did you mean {near}?)" if near else "")
                   + f"; see {self.prog} --help")

    def _unknown_command(self, token: str, commands: list[str]) -> NoReturn:
        near = nearest(token, commands)
        hint = f" (did you mean {near}?)" if near else ""
        self.error(f"unknown command {token!r}{hint}; commands: {', '.join(commands)}")

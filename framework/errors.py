"""Errors a user can act on.

A :class:`UserError` carries one sentence that names the file, the field and what was expected;
the CLI prints it without a traceback and exits with code 2.
"""

from __future__ import annotations

import reprlib
from typing import Any

#: How much of a value an error message quotes: a few items of each container, two levels deep.
_QUOTE = reprlib.Repr()
_QUOTE.maxlevel = 2
_QUOTE.maxtuple = _QUOTE.maxlist = _QUOTE.maxdict = _QUOTE.maxset = _QUOTE.maxfrozenset = 4
_QUOTE.maxstring = _QUOTE.maxother = 60
QUOTE_LIMIT = 100


class UserError(Exception):
    """Bad input from the user: printed as one line per problem, exit code 2."""

    def __init__(self, *lines: str) -> None:
        super().__init__("\n".join(lines))
        self.lines: list[str] = list(lines)


class PluginError(Exception):
    """A plugin misbehaved (bad registration, wrong API version)."""


def quoted(value: Any, limit: int = QUOTE_LIMIT) -> str:
    """``repr(value)`` cut to about ``limit`` characters, for error messages.

    A value comes from the user's file and may be huge (a long list, an alias-expanded
    structure); formatting it whole could take minutes and gigabytes. Only a few items of each
    container are visited.

    >>> quoted(list(range(1000)))
    '[0, 1, 2, 3, ...]'
    >>> quoted("x" * 300, limit=20)
    "'xxxxxxxxxxxxxxxx..."
    """
    text = _QUOTE.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."

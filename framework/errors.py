"""Errors a user can act on.

A :class:`UserError` carries one sentence that names the file, the field and what was expected;
the CLI prints it without a traceback and exits with code 2.
"""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user: printed as one line per problem, exit code 2."""

    def __init__(self, *lines: str) -> None:
        super().__init__("\n".join(lines))
        self.lines: list[str] = list(lines)


class PluginError(Exception):
    """A plugin misbehaved (bad registration, wrong API version)."""

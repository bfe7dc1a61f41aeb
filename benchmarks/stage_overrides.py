"""``--set KEY=VALUE`` for the detector benchmarks: stage parameters from the command line.

Values are read as YAML scalars (``3`` is an int, ``0.05`` a float, ``true`` a bool), as in a
pipeline file, and the stage's pydantic parameters validate them.
"""

from __future__ import annotations

import argparse

from trackfw.errors import UserError
from trackfw.pipeline import parse_assignments


def add_set_option(parser: argparse.ArgumentParser, stage: str) -> None:
    """Add a repeatable ``--set KEY=VALUE`` option for ``stage``'s parameters."""
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"a {stage} parameter, as in a pipeline file (repeatable)",
    )


def parse_overrides(pairs: list[str]) -> dict[str, object]:
    """The ``--set`` pairs as parameters; a malformed pair ends the program with one sentence."""
    try:
        return parse_assignments(pairs, "--set")
    except UserError as error:
        raise SystemExit(str(error)) from None

"""``--set KEY=VALUE`` for the benchmarks: stage parameters from the command line.

Values are read as YAML scalars (``3`` is an int, ``0.05`` a float, ``true`` a bool), as in a
pipeline file, and the stage's pydantic parameters validate them.
"""

from __future__ import annotations

import argparse

import yaml


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
    """``["a=3", "b=0.05"]`` -> ``{"a": 3, "b": 0.05}``; a pair without ``=`` is an error.

    >>> parse_overrides(["blob_scales_per_octave=3", "blob_threshold=0.05"])
    {'blob_scales_per_octave': 3, 'blob_threshold': 0.05}
    """
    overrides: dict[str, object] = {}
    for pair in pairs:
        key, separator, value = pair.partition("=")
        if not separator or not key.strip():
            raise SystemExit(f"--set {pair!r}: expected KEY=VALUE, e.g. blob_threshold=0.05.")
        overrides[key.strip()] = yaml.safe_load(value)
    return overrides

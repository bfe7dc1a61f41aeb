"""Evaluation: ``trackfw eval`` (CLEAR MOT, -In variants, IDF1, HOTA, info-less recognition)."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw eval``."""
    from trackfw_plugins.evaluation.cli import register

    register(app)

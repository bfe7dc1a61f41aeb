"""Evaluation: ``trackfw eval`` (CLEAR MOT, -In variants, IDF1, HOTA, info-less recognition)."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Evaluation registers no stage."""

"""Built-in detectors."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in detectors."""
    from trackfw_plugins.detectors.oracle import OracleDetector

    registry.add_detector(OracleDetector)

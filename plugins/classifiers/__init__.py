"""Built-in info-less classifiers."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in classifiers."""
    from trackfw_plugins.classifiers.oracle import OracleClassifier

    registry.add_classifier(OracleClassifier)

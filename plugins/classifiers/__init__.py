"""Built-in info-less classifiers."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in classifiers."""
    from trackfw_plugins.classifiers.flow_threshold import FlowThresholdClassifier
    from trackfw_plugins.classifiers.oracle import OracleClassifier
    from trackfw_plugins.classifiers.scene_check import SceneCheckClassifier
    from trackfw_plugins.classifiers.svm import SvmClassifier

    registry.add_classifier(OracleClassifier)
    registry.add_classifier(SvmClassifier)
    registry.add_classifier(FlowThresholdClassifier)
    registry.add_classifier(SceneCheckClassifier)


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw train classifier``."""
    from trackfw.cli import command_group
    from trackfw_plugins.classifiers.cli import register

    register(command_group(app, "train", "Train the info-less classifier or the head detector."))

"""Built-in info-less classifiers."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl
from trackfw.registry import stage_modules

TRACKFW_PLUGIN_API = 1

trackfw_register_stages = stage_modules(__name__, "oracle", "svm", "flow_threshold", "scene_check")


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw train classifier``."""
    from trackfw.cli import command_group
    from trackfw_plugins.classifiers.cli import register

    register(command_group(app, "train", "Train the info-less classifier or the head detector."))

"""Built-in detectors."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl
from trackfw.registry import stage_modules

TRACKFW_PLUGIN_API = 1

trackfw_register_stages = stage_modules(
    __name__, "oracle", "edgebox_cnn", "hog", "onnx_detector", "mot_file", "yolox"
)


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw train detector``."""
    from trackfw.cli import command_group
    from trackfw_plugins.detectors.cli import register

    register(command_group(app, "train", "Train the info-less classifier or the head detector."))

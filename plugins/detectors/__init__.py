"""Built-in detectors."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in detectors."""
    from trackfw_plugins.detectors.edgebox_cnn import EdgeBoxCnnDetector
    from trackfw_plugins.detectors.hog import HogDetector
    from trackfw_plugins.detectors.mot_file import MotFileDetector
    from trackfw_plugins.detectors.onnx_detector import OnnxDetector
    from trackfw_plugins.detectors.oracle import OracleDetector
    from trackfw_plugins.detectors.yolox import YoloxDetector

    registry.add_detector(OracleDetector)
    registry.add_detector(EdgeBoxCnnDetector)
    registry.add_detector(HogDetector)
    registry.add_detector(OnnxDetector)
    registry.add_detector(MotFileDetector)
    registry.add_detector(YoloxDetector)


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw train detector``."""
    from trackfw.cli import command_group
    from trackfw_plugins.detectors.cli import register

    register(command_group(app, "train", "Train the info-less classifier or the head detector."))

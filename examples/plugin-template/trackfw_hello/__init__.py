"""A minimal trackfw plugin: one detector, registered through the ``trackfw`` entry point."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from trackfw.hookspecs import hookimpl
from trackfw.records import Detections, FrameData
from trackfw.registry import Registry
from trackfw.stages import Detector, StageParams

TRACKFW_PLUGIN_API = 1


class CentreParams(StageParams):
    """Parameters of the centre detector."""

    count: int = Field(1, ge=0, description="how many detections to put at the image centre")


class CentreDetector(Detector[CentreParams]):
    """Detects ``count`` heads at the image centre (a toy to copy from)."""

    name = "centre"
    uses_pixels = False

    def detect(self, frame: FrameData) -> Detections:
        # self.params is the validated CentreParams (the type argument of Detector).
        video = frame.video
        points = np.tile([video.width / 2, video.height / 2], (self.params.count, 1))
        return Detections.from_points(points)


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the centre detector."""
    registry.add_detector(CentreDetector)

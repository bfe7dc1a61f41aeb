"""The ``mot-file`` detector: precomputed detections in MOTChallenge det.txt format.

See docs/algorithms/detectors.md#mot-file.

Rows are ``frame,id,left,top,width,height,score,...`` with 1-based frames, read by
:func:`trackfw.formats.read_mot_detections`. The file path is a
template: ``{video}`` is the video's folder, ``{name}`` its name; a relative path is taken from the
video's folder. No pixels are read.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from trackfw.errors import UserError
from trackfw.formats import detections_by_frame, read_mot_detections
from trackfw.records import Detections, FrameData, VideoContext
from trackfw.stages import Detector, StageParams
from trackfw_plugins.detectors.boxes import detections_from_boxes


class MotFileParams(StageParams):
    """Parameters of the ``mot-file`` detector."""

    path: str = Field(
        "{video}/det/det.txt",
        description="det.txt path; {video} = the video folder, {name} = its name; relative"
        " paths start at the video folder.",
    )
    point: Literal["body", "centre", "top"] = Field(
        "body",
        description="Head point of a box: body = the head-point rule (left + w/2, top + 0.08 h),"
        " centre, top.",
    )
    score_threshold: float | None = Field(
        None, description="Drop rows whose raw score is below this; null = keep every row."
    )
    score_transform: Literal["clip", "sigmoid"] = Field(
        "clip", description="Map raw scores to [0, 1]: clip, or the logistic function."
    )


class MotFileDetector(Detector[MotFileParams]):
    """Precomputed detections from a MOTChallenge det.txt file."""

    name = "mot-file"
    uses_pixels = False

    def __init__(self, params: MotFileParams | None = None) -> None:
        super().__init__(params)
        self.table: dict[int, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}

    def resolve(self, video: VideoContext) -> Path:
        """The det.txt path for ``video``."""
        folder = Path(video.path)
        if folder.is_file():
            folder = folder.parent
        text = self.params.path.replace("{video}", str(folder)).replace("{name}", video.name)
        path = Path(text).expanduser()
        return path if path.is_absolute() else folder / path

    def start(self, video: VideoContext) -> None:
        """Read the video's det.txt."""
        path = self.resolve(video)
        if not path.is_file():
            raise UserError(
                f"{path}: detections file not found (mot-file path {self.params.path!r});"
                " expected a MOTChallenge det.txt."
            )
        self.table = detections_by_frame(read_mot_detections(path))

    def detect(self, frame: FrameData) -> Detections:
        """The rows of frame ``frame.t`` above the score threshold."""
        boxes, raw = self.table.get(frame.t, (np.zeros((0, 4)), np.zeros(0)))
        if self.params.score_threshold is not None:
            keep = raw >= self.params.score_threshold
            boxes, raw = boxes[keep], raw[keep]
        if self.params.score_transform == "sigmoid":
            scores = 1.0 / (1.0 + np.exp(-raw))
        else:
            scores = np.clip(raw, 0.0, 1.0)
        return detections_from_boxes(boxes, scores, self.params.point)

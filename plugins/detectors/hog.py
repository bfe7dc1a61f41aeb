"""The ``hog`` detector: OpenCV's HOG people detector, head point taken from the body box.

See docs/algorithms/detectors.md#hog-people-detector.

Dalal-Triggs HOG with OpenCV's default linear SVM for 64×128 pedestrians. The head point of a
body box follows the project's head-point rule (:mod:`trackfw.formats.head_point`,
``(left + w/2, top + head_offset · h)``); scores are the sigmoid of the SVM margin.
"""

from __future__ import annotations

import cv2
import numpy as np
from pydantic import Field

from trackfw.formats import HEAD_FRACTION
from trackfw.records import Detections, FrameData
from trackfw.stages import Detector, StageParams
from trackfw_plugins.detectors.boxes import detections_from_boxes, frame_pixels


class HogParams(StageParams):
    """Parameters of the ``hog`` detector."""

    work_width: int = Field(
        0, ge=0, description="Resize frames to this width before detection (px); 0 = as is."
    )
    scale: float = Field(1.05, gt=1, description="Scale step of the image pyramid.")
    hit_threshold: float = Field(0.0, description="SVM margin threshold of a window.")
    win_stride: int = Field(8, ge=8, multiple_of=8, description="Window stride (px).")
    padding: int = Field(8, ge=0, description="Padding around the image (px).")
    group_threshold: int = Field(
        2, ge=0, description="Rectangle grouping threshold (0 = no grouping)."
    )
    score_threshold: float = Field(
        0.0, ge=0, le=1, description="Drop detections whose sigmoid(margin) is below this."
    )
    head_offset: float = Field(
        HEAD_FRACTION,
        ge=0,
        le=1,
        description="Head point below the box top, as a share of the box height (HOG's padded"
        " 64x128 windows fit 0.15 better on TUD-Stadtmitte).",
    )


class HogDetector(Detector[HogParams]):
    """OpenCV HOG people detector; the head point is near the top of each body box."""

    name = "hog"
    uses_pixels = True

    def __init__(self, params: HogParams | None = None) -> None:
        super().__init__(params)
        self.hog = cv2.HOGDescriptor()
        self.hog.setSVMDetector(
            np.asarray(cv2.HOGDescriptor.getDefaultPeopleDetector(), dtype=np.float32)
        )

    def detect_image(self, image: np.ndarray) -> Detections:
        """Detect people on a ``(H, W, 3)`` uint8 BGR image; points are head points."""
        width = image.shape[1]
        scale = self.params.work_width / width if self.params.work_width else 1.0
        resized = (
            image
            if scale == 1.0
            else cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
        )
        window_width, window_height = self.hog.winSize
        if resized.shape[0] < window_height or resized.shape[1] < window_width:
            # OpenCV's detectMultiScale crashes the process (no exception) on an image smaller
            # than its detection window; nobody of the window's size fits in it anyway.
            return Detections.empty()
        stride = self.params.win_stride
        boxes, weights = self.hog.detectMultiScale(
            resized,
            hitThreshold=self.params.hit_threshold,
            winStride=(stride, stride),
            padding=(self.params.padding, self.params.padding),
            scale=self.params.scale,
            groupThreshold=self.params.group_threshold,
        )
        if len(boxes) == 0:
            return Detections.empty()
        boxes_array = np.asarray(boxes, dtype=np.float64).reshape(-1, 4) / scale
        scores = 1.0 / (1.0 + np.exp(-np.asarray(weights, dtype=np.float64).reshape(-1)))
        keep = scores >= self.params.score_threshold
        return detections_from_boxes(
            boxes_array[keep], scores[keep], "body", self.params.head_offset
        )

    def detect(self, frame: FrameData) -> Detections:
        """Detect people on ``frame`` (its image must be decoded)."""
        return self.detect_image(frame_pixels(frame, self.name))

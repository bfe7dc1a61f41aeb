"""The ``flow-threshold`` classifier: info-less when the camera moves fast (a baseline) [OURS].

Looking away from the group (sky, a building, the path) makes the head-worn camera turn quickly,
so the mean optical-flow magnitude ``M_t``
(docs/algorithms/infoless-classifier.md#per-frame-measurements) alone already separates many
info-less frames. A hysteresis keeps the label from flickering: an interval starts when ``M_t``
rises above ``high`` and ends when it falls below ``low``.

Thresholds are in percent of the frame width per frame (``100 * M_t / flow_width``), so that they
do not depend on the working width. The defaults (1.6 and 0.33) are the pair with the best
pooled frame F1 on the synthetic ``paper`` dataset (seed 2018, 30 videos, oracle detections, DIS
ultrafast at 320 pixels; ``training.fit_flow_thresholds``): there, 99 % of the informative frames
move less than 1.31 % of the width per frame, while the median info-less frame moves 1.14 %
(turning away is fast, the view while looking away is often still, so recall stays near 65 %).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from trackfw.records import ClassifierDecision, Detections, FrameData, VideoContext
from trackfw.stages import Classifier, StageParams
from trackfw_plugins.classifiers.infoless_features import DisPreset, FlowMethod, OpticalFlowMeter

#: Default thresholds, percent of the frame width per frame, chosen on the synthetic data.
DEFAULT_HIGH = 1.6
DEFAULT_LOW = 0.33


class FlowThresholdParams(StageParams):
    """Parameters of the ``flow-threshold`` classifier."""

    high: float = Field(
        default=DEFAULT_HIGH,
        gt=0.0,
        description="An interval starts when the mean flow exceeds this, in percent of the frame"
        " width per frame.",
    )
    low: float = Field(
        default=DEFAULT_LOW,
        gt=0.0,
        description="An interval ends when the mean flow falls below this (percent of the width"
        " per frame); at most 'high'.",
    )
    flow: FlowMethod = Field(default="dis", description="Optical flow: 'dis' or 'farneback'.")
    flow_width: int = Field(
        default=320, ge=16, le=4096, description="Working width of the optical flow in pixels."
    )
    dis_preset: DisPreset = Field(
        default="ultrafast", description="DIS preset: 'ultrafast', 'fast' or 'medium'."
    )

    @model_validator(mode="after")
    def _low_not_above_high(self) -> FlowThresholdParams:
        if self.low > self.high:
            raise ValueError(f"low ({self.low}) must not exceed high ({self.high})")
        return self


def hysteresis_step(motion: float, inside: bool, high: float, low: float) -> bool:
    """Next label: enter above ``high``, stay while at least ``low``.

    >>> hysteresis_step(2.0, False, 1.5, 0.75), hysteresis_step(1.0, False, 1.5, 0.75)
    (True, False)
    >>> hysteresis_step(1.0, True, 1.5, 0.75), hysteresis_step(0.5, True, 1.5, 0.75)
    (True, False)
    """
    return motion >= low if inside else motion > high


def motion_score(motion: float, high: float, low: float) -> float:
    """Map the motion to [0, 1]: 0 at or below ``low``, 1 at or above ``high``, linear between.

    >>> motion_score(0.5, 2.0, 1.0), motion_score(1.5, 2.0, 1.0), motion_score(3.0, 2.0, 1.0)
    (0.0, 0.5, 1.0)
    """
    if high <= low:
        return 1.0 if motion > high else 0.0
    return float(min(max((motion - low) / (high - low), 0.0), 1.0))


class FlowThresholdClassifier(Classifier[FlowThresholdParams]):
    """Info-less while the mean optical flow is high, with hysteresis (a baseline)."""

    name = "flow-threshold"
    uses_pixels = True

    def __init__(self, params: FlowThresholdParams | None = None) -> None:
        super().__init__(params)
        self.meter = OpticalFlowMeter(
            self.params.flow, self.params.flow_width, self.params.dis_preset
        )
        self.inside = False

    def start(self, video: VideoContext) -> None:
        """Forget the previous video."""
        self.meter.reset()
        self.inside = False

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """Label ``frame`` from its flow against the previous frame."""
        if frame.image is None:
            raise ValueError("the flow-threshold classifier needs frame pixels")
        params = self.params
        motion = 100.0 * self.meter.measure(frame.image) / params.flow_width
        # The first frame is informative, so the hysteresis starts outside an interval.
        inside = hysteresis_step(motion, self.inside, params.high, params.low)
        self.inside = inside and not frame.first
        return ClassifierDecision(
            probability=motion_score(motion, params.high, params.low),
            infoless=self.inside,
            features=np.array([motion]),
        )

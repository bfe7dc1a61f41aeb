"""Tests of the ``flow-threshold`` classifier stage."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from pydantic import ValidationError

from trackfw.records import Detections, FrameData, VideoContext
from trackfw_plugins.classifiers.flow_threshold import (
    FlowThresholdClassifier,
    FlowThresholdParams,
    hysteresis_step,
    motion_score,
)

VIDEO = VideoContext(name="toy", path="toy", n_frames=20, width=640, height=360)


def test_turning_camera_is_infoless(make_frames: Callable[..., list[np.ndarray]]) -> None:
    steps = [0, 1, 1, 1, 30, 30, 30, 3, 1, 1, 1]  # pixels moved at 640 px: 30 px = 4.7 %
    shifts = list(np.cumsum(steps))
    classifier = FlowThresholdClassifier(FlowThresholdParams(high=2.0, low=0.5))
    classifier.start(VIDEO)
    labels = []
    for t, image in enumerate(make_frames(shifts)):
        decision = classifier.classify(FrameData(t, image, VIDEO, t == 0), Detections.empty())
        assert 0.0 <= decision.probability <= 1.0
        labels.append(decision.infoless)
    # The step of 3 px (0.47 %) after the turn is below low: the interval ends there.
    assert labels == [False] * 4 + [True] * 3 + [False] * 4


def test_hysteresis_keeps_the_label_between_thresholds() -> None:
    assert hysteresis_step(1.0, inside=True, high=2.0, low=0.5)
    assert not hysteresis_step(1.0, inside=False, high=2.0, low=0.5)
    assert motion_score(1.25, high=2.0, low=0.5) == pytest.approx(0.5)


def test_low_above_high_is_rejected() -> None:
    with pytest.raises(ValidationError, match="must not exceed"):
        FlowThresholdParams(high=1.0, low=2.0)

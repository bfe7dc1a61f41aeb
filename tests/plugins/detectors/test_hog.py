"""Tests of the hog people detector."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from pydantic import ValidationError

from trackfw_plugins.detectors.hog import HogDetector, HogParams


def test_params_are_validated() -> None:
    with pytest.raises(ValidationError):
        HogParams(win_stride=12)
    with pytest.raises(ValidationError):
        HogParams(scale=1.0)


def test_blank_frame_gives_nothing() -> None:
    detections = HogDetector().detect_image(np.full((240, 320, 3), 120, dtype=np.uint8))
    assert len(detections) == 0


@pytest.mark.parametrize("work_width", [0, 32])
def test_frame_smaller_than_the_window_gives_nothing(work_width: int) -> None:
    # OpenCV's detectMultiScale ends the process on an image smaller than its 64x128 window.
    image = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    assert len(HogDetector(HogParams(work_width=work_width)).detect_image(image)) == 0


def test_finds_pedestrians_on_a_real_frame(shared_data: Path) -> None:
    image = cv2.imread(str(shared_data / "TUD-Stadtmitte" / "img1" / "000001.jpg"))
    assert image is not None
    detections = HogDetector(HogParams(win_stride=8, scale=1.1)).detect_image(image)
    assert len(detections) >= 2 and detections.boxes is not None
    assert ((detections.scores > 0) & (detections.scores < 1)).all()
    expected = detections.boxes[:, 1] + 0.08 * detections.boxes[:, 3]
    assert np.allclose(detections.points[:, 1], expected)
    # Upright pedestrians: boxes taller than wide, head points in the upper half of the frame.
    assert (detections.boxes[:, 3] > detections.boxes[:, 2]).all()
    assert (detections.points[:, 1] < image.shape[0] / 2).mean() > 0.5
    lower = HogDetector(HogParams(win_stride=8, scale=1.1, head_offset=0.15)).detect_image(image)
    assert lower.boxes is not None
    assert np.allclose(lower.points[:, 1], lower.boxes[:, 1] + 0.15 * lower.boxes[:, 3])

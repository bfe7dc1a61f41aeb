"""Tests of the svm-scene classifier: the SVM overruled when the scene still registers."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from trackfw.records import Detections, FrameData, VideoContext
from trackfw_plugins.classifiers.scene_check import (
    SceneCheckClassifier,
    SceneCheckParams,
    small_motion,
)
from trackfw_plugins.maths.scene_registration import SceneRegistration

VIDEO = VideoContext(name="v", path="v", n_frames=10, width=640, height=480)


def _registration(angle: float, scale: float, shift: float) -> SceneRegistration:
    matrix = np.vstack([cv2.getRotationMatrix2D((320.0, 240.0), angle, scale), [0, 0, 1]])
    matrix[0, 2] += shift
    return SceneRegistration(matrix, True, 100, 80, 0.5)


@pytest.mark.parametrize(
    ("angle", "scale", "shift", "small"),
    [
        (2.0, 1.02, 10.0, True),
        (20.0, 1.0, 0.0, False),
        (0.0, 1.5, 0.0, False),
        (0.0, 1.0, 200.0, False),
    ],
)
def test_small_motion_limits(angle: float, scale: float, shift: float, small: bool) -> None:
    assert small_motion(_registration(angle, scale, shift), 640, 480, SceneCheckParams()) is small


def test_failed_registration_is_not_small() -> None:
    failed = SceneRegistration(np.eye(3), False, 3, 0, float("nan"), "too few matches")
    assert not small_motion(failed, 640, 480, SceneCheckParams())


def test_svm_calls_are_overruled_only_on_the_same_scene(
    monkeypatch: pytest.MonkeyPatch, textured_frame: Callable[..., np.ndarray]
) -> None:
    classifier = SceneCheckClassifier()
    classifier.start(VIDEO)
    # Every frame after the first is "info-less" to the SVM: the scene check alone decides.
    monkeypatch.setattr(classifier.svm.decider, "decide", lambda probability, features: True)
    none = Detections(points=np.zeros((0, 2)), scores=np.zeros(0))
    frames = [textured_frame(1), textured_frame(1, 8.0), textured_frame(2), textured_frame(1, 4.0)]
    decisions = [
        classifier.classify(FrameData(t, image, VIDEO, t == 0), none).infoless
        for t, image in enumerate(frames)
    ]
    assert decisions == [False, False, True, False]

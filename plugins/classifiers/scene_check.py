"""The info-less SVM with a scene check: a frame that still registers to the last informative
frame with a small camera motion is not info-less [OURS, issue 18].

See docs/algorithms/infoless-classifier.md#scene-check.

The SVM's false intervals are mostly one to three frames of a camera that barely moved (a jolt,
a blur, people briefly hidden); each one costs a full re-link across a "gap" in which nothing
changed. A real interval turns the camera to the sky, another group or the path, and those
frames no longer register to the scene before it. The check runs only on frames the SVM calls
info-less, so informative frames cost nothing extra.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field

from trackfw.records import ClassifierDecision, Detections, FrameData, VideoContext
from trackfw.stages import Classifier, StageParams
from trackfw_plugins.classifiers.svm import SvmClassifier, SvmParams
from trackfw_plugins.maths.scene_registration import (
    RegistrationSettings,
    SceneRegistration,
    register_scene,
)


class SceneCheckParams(StageParams):
    """The scene check's parameters (docs/algorithms/infoless-classifier.md#scene-check)."""

    svm: SvmParams = Field(default_factory=SvmParams, description="the svm classifier's parameters")
    scene: RegistrationSettings = Field(
        default_factory=RegistrationSettings, description="scene registration settings"
    )
    max_shift: float = Field(
        0.1, ge=0, description="largest image motion of the frame centre, times the frame width"
    )
    max_rotation_deg: float = Field(6.0, ge=0, description="largest rotation in degrees")
    max_scale_change: float = Field(0.15, ge=0, description="largest |log scale| of the motion")


def small_motion(
    registration: SceneRegistration, width: int, height: int, params: SceneCheckParams
) -> bool:
    """Whether a successful registration moves the image by at most the allowed motion."""
    if not registration.ok:
        return False
    matrix = registration.matrix
    centre = np.array([[width / 2, height / 2]])
    shift = float(np.linalg.norm(registration.apply(centre) - centre))
    linear = matrix[:2, :2] / matrix[2, 2]
    scale = float(np.sqrt(abs(np.linalg.det(linear))))
    rotation = float(
        np.degrees(np.arctan2(linear[1, 0] - linear[0, 1], linear[0, 0] + linear[1, 1]))
    )
    return bool(
        shift <= params.max_shift * width
        and abs(rotation) <= params.max_rotation_deg
        and scale > 0
        and abs(np.log(scale)) <= params.max_scale_change
    )


class SceneCheckClassifier(Classifier[SceneCheckParams]):
    """The info-less SVM; a frame it calls info-less that registers to the last informative
    frame with a small motion is informative."""

    name = "svm-scene"
    uses_pixels = True

    @classmethod
    def resource_files(cls, params: SceneCheckParams) -> list[Path]:
        """The SVM's model files."""
        return SvmClassifier.resource_files(params.svm)

    def __init__(self, params: SceneCheckParams | None = None) -> None:
        super().__init__(params)
        self.svm = SvmClassifier(self.params.svm)
        self._anchor: np.ndarray | None = None
        self._anchor_boxes: np.ndarray | None = None

    @property
    def hindsight_frames(self) -> int:
        """The SVM's ``hindsight_frames``."""
        return self.svm.hindsight_frames

    @property
    def onset_frames(self) -> int:
        """The SVM's ``onset_frames``."""
        return self.svm.onset_frames

    def start(self, video: VideoContext) -> None:
        """Forget the previous video's frames, reference, interval state and anchor."""
        self.svm.start(video)
        self._anchor = None
        self._anchor_boxes = None

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """The SVM's decision, overruled to informative when the scene check passes."""
        if frame.image is None:
            raise ValueError("the svm-scene classifier needs frame pixels (uses_pixels is True)")
        svm = self.svm
        features = svm.extractor.update(frame.t, frame.image, detections.points)
        probability = float(svm.model.probability(features)[0])
        infoless = svm.decider.decide(probability, features) and not frame.first
        if infoless and self._anchor is not None:
            registration = register_scene(
                self._anchor, frame.image, self._anchor_boxes, detections.boxes, self.params.scene
            )
            height, width = frame.image.shape[:2]
            infoless = not small_motion(registration, width, height, self.params)
        # Settling with the final decision moves the SVM's reference of C_t as well.
        svm.decider.settle(frame.t, infoless, features)
        if not infoless:
            self._anchor = frame.image.copy()
            self._anchor_boxes = detections.boxes
        return svm.decision(frame, probability, infoless, features)


__all__ = ["SceneCheckClassifier", "SceneCheckParams", "small_motion"]

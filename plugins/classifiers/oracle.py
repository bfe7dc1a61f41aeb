"""The ``oracle`` classifier: ground-truth info-less intervals.

Isolates tracking from interval recognition; see
docs/algorithms/infoless-classifier.md#oracle-classifier.
"""

from __future__ import annotations

from trackfw.records import ClassifierDecision, Detections, FrameData, VideoContext
from trackfw.stages import Classifier


class OracleClassifier(Classifier):
    """Labels a frame info-less exactly when it lies inside a ground-truth interval."""

    name = "oracle"
    needs_ground_truth = True

    def start(self, video: VideoContext) -> None:
        truth = video.ground_truth
        self.infoless_frames = truth.infoless_frames() if truth is not None else set()

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        infoless = frame.t in self.infoless_frames
        return ClassifierDecision(probability=1.0 if infoless else 0.0, infoless=infoless)

"""Tests of detection precision/recall."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw.records import Detections
from trackfw_plugins.detectors.training.evaluate import DetectionScore, evaluate
from trackfw_plugins.detectors.training.sampling import AnnotatedFrame


def test_evaluate_counts_precision_recall_and_ignores_tiny_heads() -> None:
    image = np.zeros((10, 10, 3), dtype=np.uint8)
    frames = [
        AnnotatedFrame(image, np.array([[10.0, 10.0, 20.0], [50.0, 50.0, 2.0]]), "a"),
        AnnotatedFrame(image, np.array([[80.0, 10.0, 20.0]]), "b"),
    ]
    answers = iter(
        [
            Detections(points=np.array([[12.0, 10.0], [50.0, 50.0]]), scores=np.ones(2)),
            Detections(points=np.array([[0.0, 90.0]]), scores=np.ones(1)),
        ]
    )
    score = evaluate(lambda _image: next(answers), frames, min_head_size=5.0)
    assert (score.true_positives, score.detections, score.heads) == (1, 2, 2)
    assert score.precision == pytest.approx(0.5) and score.recall == pytest.approx(0.5)
    assert "precision 0.500" in score.summary()
    assert DetectionScore().precision == 1.0 and DetectionScore().recall == 1.0

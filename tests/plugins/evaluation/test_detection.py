"""Head-point detection precision / recall."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.evaluation.detection import DetectionCounts, frame_detection_counts


def test_one_to_one_matching_within_half_a_head() -> None:
    heads = np.array([[100.0, 100.0, 80.0], [300.0, 100.0, 80.0], [900.0, 900.0, 80.0]])
    detections = np.array([[105.0, 100.0], [110.0, 100.0], [300.0, 130.0], [600.0, 600.0]])
    counts = frame_detection_counts(detections, heads)
    # Two detections near head 1: only one may match; head 3 has none within 40 px (half of 80).
    assert (counts.tp, counts.fp, counts.fn) == (2, 2, 1)
    assert counts.distance_sum == 35.0
    assert counts.precision == 0.5
    assert counts.recall == 2 / 3


def test_the_rule_scales_with_the_head() -> None:
    detections = np.array([[112.0, 100.0]])
    assert frame_detection_counts(detections, np.array([[100.0, 100.0, 30.0]])).tp == 1
    assert frame_detection_counts(detections, np.array([[100.0, 100.0, 20.0]])).tp == 0
    assert frame_detection_counts(detections, np.array([[100.0, 100.0, 20.0]]), ratio=0.7).tp == 1


def test_empty_sides() -> None:
    nothing = np.zeros((0, 2))
    assert frame_detection_counts(nothing, np.array([[1.0, 1.0, 9.0]])).fn == 1
    assert frame_detection_counts(np.array([[1.0, 1.0]]), np.zeros((0, 3))).fp == 1
    pooled = DetectionCounts(1, 0, 1, 2.0) + DetectionCounts(1, 1, 0, 4.0)
    assert (pooled.tp, pooled.fp, pooled.fn, pooled.mean_distance) == (2, 1, 1, 3.0)

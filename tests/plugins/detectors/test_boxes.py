"""Tests of the detectors' box helpers."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.detectors.boxes import non_maximum_suppression, suppress_nested_centres


def test_a_small_box_on_the_edge_of_a_larger_head_box_is_dropped() -> None:
    # IoU 0.11 keeps both under IoU NMS; the small box's centre is 0.42 of the large side from
    # the large box's centre (1.25 of its own side), so it is a second point on the same head.
    boxes = np.array([[100.0, 100.0, 24.0, 24.0], [117.0, 112.0, 8.0, 8.0]])
    order = non_maximum_suppression(boxes, np.array([0.95, 0.9]), 0.5, 0.3)
    assert order.tolist() == [0, 1]
    assert suppress_nested_centres(boxes, order, 0.7).tolist() == [0]


def test_neighbouring_heads_of_similar_size_survive() -> None:
    # Touching heads: centres one side apart.
    boxes = np.array([[100.0, 100.0, 12.0, 12.0], [112.0, 100.0, 12.0, 12.0], [100, 113, 11, 11]])
    order = np.array([0, 1, 2])
    assert suppress_nested_centres(boxes, order, 0.7).tolist() == [0, 1, 2]


def test_ratio_zero_keeps_every_box_and_order_is_kept() -> None:
    boxes = np.array([[0.0, 0.0, 10.0, 10.0], [1.0, 1.0, 10.0, 10.0], [40.0, 0.0, 10.0, 10.0]])
    assert suppress_nested_centres(boxes, np.array([2, 0, 1]), 0.0).tolist() == [2, 0, 1]
    assert suppress_nested_centres(boxes, np.array([2, 0, 1]), 0.7).tolist() == [2, 0]


def test_a_higher_threshold_keeps_the_same_boxes_above_it() -> None:
    # benchmarks/detector_accuracy.py reads several thresholds off one low-threshold run: boxes
    # scoring below a threshold must never have removed a box above it.
    rng = np.random.default_rng(3)
    for _ in range(50):
        count = 60
        corners = rng.uniform(0, 100, (count, 2))
        sides = rng.uniform(5, 20, (count, 1))
        boxes = np.hstack([corners, sides, sides])
        scores = rng.uniform(0, 1, count)
        low = non_maximum_suppression(boxes, scores, 0.3, 0.3)
        low = suppress_nested_centres(boxes, low, 0.7)
        high = non_maximum_suppression(boxes, scores, 0.6, 0.3)
        high = suppress_nested_centres(boxes, high, 0.7)
        assert sorted(low[scores[low] >= 0.6].tolist()) == sorted(high.tolist())

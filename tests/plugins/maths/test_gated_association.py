"""Tests of the gated association of positioned candidates."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.datasets.points import gap_scene
from trackfw_plugins.maths.gated_association import associate_gated, bending_of_pairs
from trackfw_plugins.maths.window_association import WindowAssociationParams, associate_window


def _group() -> np.ndarray:
    return np.array([[100.0, 100.0], [160.0, 110.0], [220.0, 95.0], [130.0, 170.0], [200.0, 180.0]])


def test_drifted_prediction_matches_every_target() -> None:
    group = _group()
    clutter = np.array([[600.0, 400.0], [650.0, 420.0], [40.0, 400.0]])
    detections = np.vstack([clutter, group + np.array([30.0, -20.0])])
    result, _ = associate_gated(group, detections, 60.0, None, WindowAssociationParams())
    assert result.matched_detection.tolist() == [3, 4, 5, 6, 7]
    assert result.unmatched == 0
    # A pure shift has no bending: the cost is zero.
    assert result.cost < 1e-6


def test_nothing_inside_the_gate_loses() -> None:
    detections = _group() + 500.0
    result, evidence = associate_gated(_group(), detections, 40.0, None, WindowAssociationParams())
    assert evidence == 1.0
    assert result.cost == float("inf")
    assert (result.matched_detection == -1).all()


def test_bending_agrees_with_tps_rpm_scale() -> None:
    # A deformed pattern bends; an affine copy of it does not.
    group = _group()
    affine = group @ np.array([[1.1, 0.2], [-0.1, 0.9]]).T + 40.0
    params = WindowAssociationParams()
    assert bending_of_pairs(group, affine, params) < 1e-9
    deformed = affine.copy()
    deformed[2] += [40.0, 35.0]
    assert bending_of_pairs(group, deformed, params) > 1e-3


def test_positioned_candidate_cost_compares_with_window_cost() -> None:
    # On a gap scene whose prediction is placed where the group is, the gated candidate finds
    # every target and its psi is no worse than the window search's.
    candidates, detections, truth = gap_scene(30, seed=3)
    placed = detections[truth]
    params = WindowAssociationParams()
    gated, evidence = associate_gated(placed + 5.0, detections, 50.0, None, params)
    assert 0.1 < evidence < 0.2  # 7 px of 50
    window = associate_window(candidates[0], detections, None, params)
    assert (gated.matched_detection == truth).all()
    assert gated.cost <= window.cost + 1e-6

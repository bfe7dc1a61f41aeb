"""The Kalman tracker with its three associations (Kalman1, Kalman2, Kalman3)."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw.records import Detections, VideoContext
from trackfw.registry import load_registry

VIDEO = VideoContext(name="v", path="v", n_frames=50, width=1280, height=720)


@pytest.mark.parametrize("association", ["hungarian", "nearest", "tps-rpm"])
def test_tracks_a_moving_group_with_shuffled_detections(association: str) -> None:
    tracker = load_registry().build_stage(
        "tracker", {"type": "kalman", "params": {"association": association}}
    )
    tracker.start(VIDEO)
    random = np.random.default_rng(0)
    start = random.uniform([300, 200], [900, 500], (6, 2))
    velocity = random.normal(0, 2, (6, 2))
    tracker.initialise(0, np.arange(1, 7), start)
    for t in range(1, 25):
        truth = start + velocity * t
        order = random.permutation(6)
        tracker.step(t, Detections.from_points(truth[order] + random.normal(0, 0.5, (6, 2))))
        matched = np.array([state.matched_detection for state in tracker.states()])
        assert (order[matched] == np.arange(6)).all(), t
    assert np.abs(tracker.positions() - (start + velocity * 24)).max() < 2.0


def test_gate_leaves_far_detections_unassigned() -> None:
    tracker = load_registry().build_stage("tracker", {"type": "kalman"})
    tracker.start(VIDEO)  # 720p: gate = 50 * 720 / 1080 = 33.3 px
    tracker.initialise(0, np.array([1]), np.array([[100.0, 100.0]]))
    tracker.step(1, Detections.from_points([[160.0, 100.0]]))
    assert tracker.states()[0].matched_detection == -1
    assert np.allclose(tracker.positions(), [[100.0, 100.0]])


def test_reinitialise_restarts_with_zero_velocity() -> None:
    tracker = load_registry().build_stage("tracker", {"type": "kalman"})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([1]), np.array([[100.0, 100.0]]))
    for t in range(1, 6):
        tracker.step(t, Detections.from_points([[100.0 + 5 * t, 100.0]]))
    assert tracker.states()[0].velocity[0] > 4
    tracker.reinitialise(6, np.array([[400.0, 300.0]]), np.array([-1]))
    state = tracker.states()[0]
    assert np.allclose(state.position, [400, 300]) and np.allclose(state.velocity, 0)

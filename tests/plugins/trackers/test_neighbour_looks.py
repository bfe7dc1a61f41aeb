"""Tests of the looks kept of the people seen beside a lost target."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.trackers.neighbour_looks import NEIGHBOURS_KEPT, NeighbourLooks


def _euclidean(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    return np.linalg.norm(first[:, None, :] - second[None, :, :], axis=2)


def test_only_a_target_tracked_on_the_previous_frame_is_just_lost() -> None:
    looks = NeighbourLooks.start(3)
    every = np.ones(3, dtype=bool)
    # All given tracked; all three lost on the first frame count.
    assert looks.end_frame(~every, every).tolist() == [0, 1, 2]
    # Lost (or out of view, or placed at b) on the frame before: it may be anywhere now.
    assert (
        looks.end_frame(np.array([False, True, False]), np.array([True, False, True])).tolist()
        == []
    )
    looks.remember(1, np.ones((2, 3)))
    looks.remember(1, np.zeros((0, 3)))  # nobody seen apart: nothing added
    looks.remember(1, np.zeros((1, 3)))  # a second loss adds
    assert looks.descriptors[1] is not None and looks.descriptors[1].shape == (3, 3)


def test_only_the_latest_are_kept() -> None:
    looks = NeighbourLooks.start(1)
    for loss in range(NEIGHBOURS_KEPT):
        looks.remember(0, np.full((2, 1), float(loss)))
    kept = looks.descriptors[0]
    assert kept is not None and kept.shape == (NEIGHBOURS_KEPT, 1)
    assert kept[0, 0] == NEIGHBOURS_KEPT / 2 and kept[-1, 0] == NEIGHBOURS_KEPT - 1


def test_forgotten_when_tracked_again() -> None:
    looks = NeighbourLooks.start(2)
    looks.remember(0, np.ones((1, 2)))
    looks.remember(1, np.ones((1, 2)))
    looks.end_frame(np.array([True, False]), np.array([False, True]))
    assert looks.descriptors[0] is None
    distance = looks.distances(np.array([0, 1]), np.array([[1.0, 1.0], [4.0, 5.0]]), _euclidean)
    assert np.isinf(distance[0]).all()
    assert distance[1].tolist() == [0.0, 5.0]

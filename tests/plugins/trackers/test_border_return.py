"""The border geometry of a target's return: the edge it left by, the cost of coming back."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.trackers.border_return import border_return_cost, image_edge


def test_image_edge_is_the_one_farthest_beyond() -> None:
    positions = np.array([[-5.0, 50.0], [150.0, 50.0], [50.0, -1.0], [120.0, 200.0]])
    assert image_edge(positions, 100, 100).tolist() == [0, 1, 2, 3]
    assert image_edge(np.zeros((0, 2)), 100, 100).tolist() == []


def test_a_return_costs_its_distance_to_the_door_over_the_gate_near_an_edge_only() -> None:
    # Left through the right edge (1), expected at (130, 40): the door is (99, 40).
    points = np.array([[95.0, 40.0], [50.0, 40.0], [2.0, 60.0]])
    cost = border_return_cost(
        np.array([1, -1]),
        np.array([[130.0, 40.0], [0.0, 0.0]]),
        np.array([10.0, 10.0]),
        points,
        5.0,
        100,
        100,
    )
    assert cost[0, 0] == 0.4  # 4 px from the door, gate 10
    assert np.isinf(cost[0, 1])  # not near an edge
    assert np.isclose(cost[0, 2], np.hypot(97.0, 20.0) / 10.0)  # round the corner: any edge
    assert np.isinf(cost[1]).all()  # never left

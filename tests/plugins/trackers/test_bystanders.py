"""Anonymous bystander tracks: when they start, compete, end."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.trackers.bystanders import Bystanders, BystanderSettings


def _frame(
    bystanders: Bystanders,
    points: list[list[float]],
    taken: list[int] | None = None,
    target_sides: float = 10.0,
) -> None:
    """One frame: predict, then close it with the targets holding the rows ``taken``."""
    array = np.array(points, dtype=np.float64).reshape(-1, 2)
    held = np.array(taken or [], dtype=np.int64)
    bystanders.predict()
    bystanders.update(array, held, array[held], np.full(len(held), target_sides), 30.0)


def test_a_track_competes_after_confirm_frames_and_ends_after_misses() -> None:
    bystanders = Bystanders.start(BystanderSettings(confirm_frames=3, end_after_frames=2), 10, 1, 1)
    competing = []
    for t in range(4):
        _frame(bystanders, [[100.0 + t, 100.0]])
        competing.append(len(bystanders.competing()))
    assert competing == [0, 0, 1, 1]
    _frame(bystanders, [])
    assert len(bystanders) == 1 and len(bystanders.competing()) == 0  # coasting: no claims
    _frame(bystanders, [])
    assert len(bystanders) == 0


def test_an_unconfirmed_track_ends_at_its_first_miss() -> None:
    bystanders = Bystanders.start(BystanderSettings(), 10, 1, 1)
    _frame(bystanders, [[100.0, 100.0]])
    _frame(bystanders, [])
    assert len(bystanders) == 0


def test_no_track_starts_on_a_second_detection_of_a_targets_head() -> None:
    bystanders = Bystanders.start(BystanderSettings(near_target=0.5), 10, 1, 1)
    # Row 0 is the target's detection (10 px head); row 1 lies 4 px off it, row 2 far away.
    _frame(bystanders, [[100.0, 100.0], [104.0, 100.0], [200.0, 100.0]], taken=[0])
    assert len(bystanders) == 1
    assert np.allclose(bystanders.bank.positions, [[200.0, 100.0]])


def test_a_track_whose_detection_a_target_took_ends() -> None:
    bystanders = Bystanders.start(BystanderSettings(confirm_frames=1), 10, 1, 1)
    _frame(bystanders, [[100.0, 100.0]])
    bystanders.predict()
    bystanders.claim(np.array([0]))
    # A re-acquired target took the claimed detection after the association.
    point = np.array([[100.0, 100.0]])
    bystanders.update(point, np.array([0]), point, np.array([np.nan]), 30.0)
    assert len(bystanders) == 0


def test_rival_cost_is_gated() -> None:
    bystanders = Bystanders.start(BystanderSettings(confirm_frames=1), 10, 1, 1)
    _frame(bystanders, [[100.0, 100.0]])
    bystanders.predict()
    cost = bystanders.rival_cost(np.array([[103.0, 104.0], [200.0, 100.0]]), 30.0)
    assert cost[0, 0] == 5.0 and np.isinf(cost[0, 1])

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


def _held_frame(bystanders: Bystanders, points: list[list[float]], holders: list[int]) -> None:
    """One frame whose first ``len(holders)`` rows are the targets ``holders``' detections."""
    array = np.array(points, dtype=np.float64).reshape(-1, 2)
    held = np.arange(len(holders))
    bystanders.predict()
    bystanders.update(array, held, array[held], np.full(len(held), 10.0), 30.0, np.array(holders))


def test_a_track_seen_apart_from_a_target_stays_so_until_it_comes_near_or_is_missed() -> None:
    settings = BystanderSettings(confirm_frames=1, apart_gates=1.0)
    bystanders = Bystanders.start(settings, 10, 1, 1, targets=2)
    # Target 1 at x=100; a bystander 60 px away (beyond the 30 px gate); target 0 unseen.
    _held_frame(bystanders, [[100.0, 100.0], [160.0, 100.0]], holders=[1])
    assert bystanders.apart.tolist() == [[False, True]]
    # Target 1 lost: the bystander's apartness from it is kept while the track keeps its head.
    _held_frame(bystanders, [[160.0, 100.0]], holders=[])
    assert bystanders.apart.tolist() == [[False, True]]
    # The track walking within the gate of the target's detection may be it: no longer apart.
    for x in (150.0, 140.0, 132.0, 125.0):
        _held_frame(bystanders, [[100.0, 100.0], [x, 100.0]], holders=[1])
    assert len(bystanders) == 1 and bystanders.apart.tolist() == [[False, False]]
    _held_frame(bystanders, [[60.0, 100.0], [125.0, 100.0]], holders=[1])
    assert bystanders.apart.tolist() == [[False, True]]
    # A frame without a detection: the track may come back on someone else.
    bystanders.predict()
    bystanders.update(
        np.zeros((0, 2)),
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 2)),
        np.zeros(0),
        30.0,
        np.zeros(0, dtype=np.int64),
    )
    assert bystanders.apart.tolist() == [[False, False]]


def test_claim_alone_takes_only_detections_no_target_holds() -> None:
    bystanders = Bystanders.start(BystanderSettings(confirm_frames=1), 10, 1, 1)
    _frame(bystanders, [[100.0, 100.0]])
    bystanders.predict()
    points = np.array([[101.0, 100.0]])
    bystanders.claim_alone(points, np.array([0]), 30.0)  # a target holds the only detection
    assert bystanders.claimed_rows().tolist() == []
    bystanders.predict()
    bystanders.claim_alone(points, np.zeros(0, dtype=np.int64), 30.0)
    assert bystanders.claimed_rows().tolist() == [0]


def test_apart_is_measured_in_association_gates() -> None:
    near = Bystanders.start(BystanderSettings(confirm_frames=1, apart_gates=2.0), 10, 1, 1, 1)
    # 45 px from the target's detection: beyond one 30 px gate, within two.
    _held_frame(near, [[100.0, 100.0], [145.0, 100.0]], holders=[0])
    assert near.apart.tolist() == [[False]]
    _held_frame(near, [[100.0, 100.0], [165.0, 100.0]], holders=[0])
    assert near.apart.tolist() == [[True]]

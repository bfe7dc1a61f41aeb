"""A target given on a box it shares with a passer-by (``start_split``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.records import Detections, VideoContext
from trackfw.registry import load_registry
from trackfw_plugins.trackers.bystanders import Bystanders, BystanderSettings
from trackfw_plugins.trackers.start_split import StartSplit, StartSplitSettings

FPS = 25.0
VIDEO = VideoContext(name="v", path="v", n_frames=60, width=320, height=240, fps=FPS)
SIDE = 16.0
STANDER = np.array([100.0, 120.0])
#: The passer-by starts 14 px right of the stander and walks right at 4 px per frame.
WALKER_START, WALKER_SPEED = np.array([114.0, 120.0]), np.array([4.0, 0.0])


def _detections(points: list[np.ndarray], sides: list[float] | None = None) -> Detections:
    array = np.array(points, dtype=np.float64).reshape(-1, 2)
    side = np.full(len(array), SIDE) if sides is None else np.array(sides, dtype=np.float64)
    boxes = np.column_stack([array - side[:, None] / 2, side, side])
    return Detections.from_points(array, boxes=boxes)


def _passing(t: int) -> Detections:
    """One box on the passer-by until frame 3 (the stander's head hidden in it), then both."""
    walker = WALKER_START + WALKER_SPEED * t
    return _detections([walker] if t < 3 else [walker, STANDER])


def _run(
    given: np.ndarray,
    split: bool,
    frames: int = 12,
    detections: Callable[[int], Detections] = _passing,
) -> tuple[np.ndarray, list]:
    """The target given at ``given`` tracked through ``detections(t)`` for t = 1..frames-1;
    its last position and the withdrawals."""
    params: dict[str, object] = {"bystanders": {}, "start_gate_px_at_1080": 100.0}
    if split:
        params["start_split"] = {}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([3]), given[None, :])
    withdrawn = []
    for t in range(1, frames):
        tracker.step(t, detections(t))
        withdrawn += tracker.withdrawn()
    return tracker.positions()[0], withdrawn


def test_a_stander_given_behind_a_passer_by_is_found_when_the_box_splits() -> None:
    position, withdrawn = _run(STANDER, split=True)
    assert np.hypot(*(position - STANDER)) < 3.0
    # Reports from the first step on were the passer-by's: taken back, once.
    assert withdrawn == [(0, 1)]


def test_without_the_check_the_stander_follows_the_passer_by() -> None:
    position, withdrawn = _run(STANDER, split=False)
    assert position[0] > 130.0
    assert withdrawn == []


def test_a_passer_by_given_on_its_own_box_keeps_it() -> None:
    # The walker is the target: the stander's head appearing beside the given point traces back
    # to where the stander stood, further from the given point than the walker's first box.
    position, withdrawn = _run(WALKER_START, split=True)
    walker_now = WALKER_START + WALKER_SPEED * 11
    assert np.hypot(*(position - walker_now)) < 6.0
    assert withdrawn == []


def _sliding(t: int, offset: np.ndarray, own_side: float) -> Detections:
    """The box is the stander's on the first step, slides onto the passer-by walking out of it
    over the next frames, and from frame 5 the stander's own head (box side ``own_side``) is
    found ``offset`` from its given point."""
    walker = WALKER_START + WALKER_SPEED * t
    if t >= 5:
        return _detections([walker, STANDER + offset], [SIDE, own_side])
    share = (0.05, 0.2, 0.45, 0.75)[t - 1]
    return _detections([STANDER + share * (walker - STANDER)])


def _run_sliding(offset: np.ndarray, own_side: float, split: bool) -> tuple[np.ndarray, list]:
    return _run(STANDER, split, 14, lambda t: _sliding(t, offset, own_side))


def test_a_stander_whose_box_slid_onto_the_passer_by_takes_its_own_head() -> None:
    # Its first box lay 1 px from the given point, nearer than its own head now does: what
    # tells is that the track has walked off the given point while the new head leads back.
    offset = np.array([4.0, 2.0])
    position, withdrawn = _run_sliding(offset, SIDE, split=True)
    assert np.hypot(*(position - STANDER)) < 6.0
    assert withdrawn == [(0, 1)]
    position, withdrawn = _run_sliding(offset, SIDE, split=False)
    assert position[0] > 130.0  # without the check it went with the passer-by
    assert withdrawn == []


def test_a_half_hidden_head_is_measured_by_the_targets_first_box() -> None:
    # Coming free of the passer-by, the stander's box is small (10 px) and its head point 6 px
    # off: more than half its own side, less than half the 16 px box the target started on.
    position, withdrawn = _run_sliding(np.array([6.0, 0.0]), 10.0, split=True)
    assert np.hypot(*(position - STANDER)) < 8.0
    assert withdrawn == [(0, 1)]
    # Twice as far off, beyond half of either side: no trade.
    position, withdrawn = _run_sliding(np.array([12.0, 0.0]), 10.0, split=True)
    assert withdrawn == []


def _track_frames(tracks: Bystanders, frames: list[list[list[float]]]) -> np.ndarray:
    """Feed bystander-only frames (no target holds anything); the last frame's points."""
    points = np.zeros((0, 2))
    for frame in frames:
        points = np.array(frame, dtype=np.float64).reshape(-1, 2)
        tracks.predict()
        none = np.zeros(0, dtype=np.int64)
        tracks.update(points, none, np.zeros((0, 2)), np.zeros(0), 30.0)
    return points


def test_only_a_track_followed_long_enough_and_born_after_the_start_trades() -> None:
    settings = StartSplitSettings(within_s=0.4, follow_s=0.12)  # 10 and 3 frames at 25 fps
    split = StartSplit.begin(settings, FPS, (320, 240), 0, np.array([[50.0, 50.0]]))
    split.first_step(1, np.array([0]), np.array([[62.0, 50.0]]), np.array([SIDE]))
    assert split.first_error.tolist() == [12.0]
    tracks = Bystanders.start(BystanderSettings(), 10.0, 1.0, 1.0)
    sides = np.array([SIDE])
    drifted = np.array([[75.0, 50.0]])
    points = _track_frames(tracks, [[[51.0, 50.0]]] * 2)
    assert split.due(2, np.array([0]), drifted, tracks, points, sides) == []  # followed 1 frame
    points = _track_frames(tracks, [[[51.0, 50.0]]] * 2)
    assert split.due(4, np.array([0]), drifted, tracks, points, sides) == [(0, 0)]
    assert split.due(5, np.array([0]), drifted, tracks, points, sides) == []  # traded once


def test_no_trade_after_the_window() -> None:
    settings = StartSplitSettings(within_s=0.12, follow_s=0.04)  # 3 and 1 frames
    split = StartSplit.begin(settings, FPS, (320, 240), 0, np.array([[50.0, 50.0]]))
    split.first_step(1, np.array([0]), np.array([[62.0, 50.0]]), np.array([SIDE]))
    tracks = Bystanders.start(BystanderSettings(), 10.0, 1.0, 1.0)
    _track_frames(tracks, [[]] * 2)
    points = _track_frames(tracks, [[[51.0, 50.0]]] * 3)
    drifted = np.array([[75.0, 50.0]])
    assert split.due(5, np.array([0]), drifted, tracks, points, np.array([SIDE])) == []


def _split_beside_the_border(first_side: float) -> StartSplit:
    """A target given 45 px from the left border whose first box lay 40 px from it."""
    settings = StartSplitSettings(within_s=0.4, follow_s=0.12)
    split = StartSplit.begin(settings, FPS, (320, 240), 0, np.array([[45.0, 50.0]]))
    split.first_step(1, np.array([0]), np.array([[85.0, 50.0]]), np.array([first_side]))
    return split


def test_no_trade_for_a_head_that_walked_in_at_the_border() -> None:
    drifted, sides = np.array([[90.0, 50.0]]), np.array([36.0])
    tracks = Bystanders.start(BystanderSettings(), 10.0, 1.0, 1.0)
    # First seen 28 px from the border, within its own box's side: somebody walking in.
    points = _track_frames(tracks, [[[28.0, 50.0]]] * 4)
    split = _split_beside_the_border(20.0)
    assert split.due(4, np.array([0]), drifted, tracks, points, sides) == []
    tracks = Bystanders.start(BystanderSettings(), 10.0, 1.0, 1.0)
    points = _track_frames(tracks, [[[38.0, 50.0]]] * 4)  # 38 px in: a split
    split = _split_beside_the_border(20.0)
    assert split.due(4, np.array([0]), drifted, tracks, points, sides) == [(0, 0)]


def test_a_target_given_on_a_head_cut_by_the_border_never_trades() -> None:
    assert _split_beside_the_border(20.0).open[0]
    assert not _split_beside_the_border(50.0).open[0]  # its box's side reaches the border


def test_the_check_needs_bystander_tracks() -> None:
    with pytest.raises(UserError, match="start_split needs bystanders"):
        load_registry().build_stage("tracker", {"type": "kalman", "params": {"start_split": {}}})


def test_no_trade_after_an_interval() -> None:
    params = {"bystanders": {}, "start_gate_px_at_1080": 100.0, "start_split": {}}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([3]), STANDER[None, :])
    tracker.step(1, _passing(1))
    # A look-away on frames 2-3: at b the camera pose has changed, so no new head's path leads
    # back to the start frame's given point any more.
    at_b = _passing(4)
    tracker.reinitialise(4, at_b.points[:1], np.array([0]), at_b)
    withdrawn = []
    for t in range(5, 12):
        tracker.step(t, _passing(t))
        withdrawn += tracker.withdrawn()
    assert withdrawn == []


def test_the_first_step_may_come_after_info_less_frames() -> None:
    split = _split_beside_the_border(20.0)  # first step on frame 1
    assert split.first_error.tolist() == [40.0]
    late = StartSplit.begin(StartSplitSettings(), FPS, (320, 240), 0, np.array([[45.0, 50.0]]))
    late.first_step(6, np.array([0]), np.array([[55.0, 50.0]]), np.array([20.0]))
    late.first_step(7, np.array([0]), np.array([[95.0, 50.0]]), np.array([20.0]))
    assert late.first_error.tolist() == [10.0]  # the first step's, not a later one's

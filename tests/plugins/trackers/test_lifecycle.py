"""Target lifecycle of the kalman tracker: every state change, and re-acquisition after a gap."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from trackfw.records import Detections, VideoContext
from trackfw.registry import load_registry

# 25 fps, 720p: the association gate is 33.3 px, lost_after 1.0 s = 25 frames.
VIDEO = VideoContext(name="v", path="v", n_frames=500, width=1280, height=720, fps=25.0)
GROUP = np.array([[400.0, 300.0], [460.0, 310.0], [520.0, 300.0]])


def _tracker_at(positions: np.ndarray, **lifecycle: Any) -> Any:
    params = {"lifecycle": lifecycle} if lifecycle else {}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.arange(1, len(positions) + 1), positions)
    return tracker


def _tracker(**lifecycle: Any) -> Any:
    return _tracker_at(GROUP, **lifecycle)


def _seen(points: np.ndarray, sizes: list[float] | None = None) -> Detections:
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    sides = np.full(len(points), 30.0) if sizes is None else np.asarray(sizes)
    boxes = np.column_stack([points - sides[:, None] / 2, sides, sides])
    return Detections.from_points(points, boxes=boxes)


def test_tracked_then_lost_after_the_set_time_and_not_before() -> None:
    tracker = _tracker(lost_after_s=1.0)
    for t in range(1, 26):  # 25 frames = 1.0 s without target 2
        tracker.step(t, _seen(GROUP[[0, 2]]))
    assert tracker.statuses() == ["tracked", "tracked", "tracked"]
    tracker.step(26, _seen(GROUP[[0, 2]]))
    assert tracker.statuses() == ["tracked", "lost", "tracked"]
    assert tracker.states()[1].status == "lost"


# Target 2 stands 25 px (under one 30-px head) behind target 1; target 3 is far from both.
CROSSING = np.array([[400.0, 300.0], [425.0, 300.0], [700.0, 300.0]])


@pytest.mark.parametrize("hold", [None, 0.5])
def test_a_target_hidden_behind_another_stays_tracked_for_the_hold(hold: float | None) -> None:
    tracker = _tracker_at(CROSSING, lost_after_s=0.2, hidden_hold_s=hold)
    last_tracked = 0
    for t in range(1, 20):  # one detection for targets 1 and 2 (target 1 takes it); 3 unseen
        tracker.step(t, _seen(CROSSING[[0]]))
        if tracker.statuses()[1] == "tracked":
            last_tracked = t
        assert tracker.statuses()[0] == "tracked"
    # 0.2 s = 5 frames at 25 fps; 0.5 s = 12.5 frames
    assert last_tracked == (5 if hold is None else 12)


def test_a_missing_target_far_from_every_detection_is_lost_as_before() -> None:
    tracker = _tracker_at(CROSSING, lost_after_s=0.2, hidden_hold_s=0.5)
    for t in range(1, 7):
        tracker.step(t, _seen(CROSSING[[0, 1]]))
    assert tracker.statuses() == ["tracked", "tracked", "lost"]


@pytest.mark.parametrize("start_gate", [None, 100.0])
def test_a_start_position_off_the_detectors_head_is_taken_with_the_start_gate(
    start_gate: float | None,
) -> None:
    # Given start positions 45 px above the heads the detector finds (gate 33.3 px at 720p,
    # start gate 66.7 px); a bystander 80 px below target 3's head is 125 px from its start, not
    # three times as far as its head: that head is not clearly its own.
    tracker = load_registry().build_stage(
        "tracker", {"type": "kalman", "params": {"start_gate_px_at_1080": start_gate}}
    )
    tracker.start(VIDEO)
    starts = np.array([[200.0, 300.0], [500.0, 300.0], [800.0, 300.0]])
    tracker.initialise(0, np.array([1, 2, 3]), starts)
    heads = starts + np.array([0.0, 45.0])
    bystander = heads[2] + np.array([0.0, 80.0])
    tracker.step(1, _seen(np.vstack([heads, bystander])))
    matched = [state.matched_detection for state in tracker.states()]
    assert matched == ([0, 1, -1] if start_gate else [-1, -1, -1])


def _started_pair(starts: list[list[float]], hold: bool) -> Any:
    """Targets 1 and 2 given at ``starts``, the start gate of the real pipelines, and the hold."""
    params = {"start_gate_px_at_1080": 100.0, "start_shared_hold": hold}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([1, 2]), np.array(starts))
    return tracker


@pytest.mark.parametrize("hold", [False, True])
def test_two_targets_given_on_one_detection_wait_until_it_splits(hold: bool) -> None:
    # A stander given at (400, 300) and a walker at (430, 310): the detector gives one box
    # between them that moves with the walker for three frames (nearest to the stander), then
    # a box each. Whoever took the shared box took the walker's motion.
    tracker = _started_pair([[400.0, 300.0], [430.0, 310.0]], hold)
    for t, x in enumerate([408.0, 418.0, 428.0], start=1):
        tracker.step(t, _seen([[x, 304.0]]))
        held = [state.matched_detection for state in tracker.states()]
        assert held == ([-1, -1] if hold else [0, -1])
    tracker.step(4, _seen([[446.0, 310.0], [401.0, 300.0]]))
    matched = [state.matched_detection for state in tracker.states()]
    assert matched == ([1, 0] if hold else [0, 1])
    assert tracker.statuses() == ["tracked", "tracked"]


@pytest.mark.parametrize("hold", [False, True])
def test_a_walker_whose_neighbour_shows_up_takes_its_own_detection(hold: bool) -> None:
    # A stander given at (316, 119) and a walker at (330, 119) (at 720p): the walker's head is
    # the nearest detection of both until the stander's is found on frame 4; by then each has
    # a detection nearer to it than to the other, and the usual association takes over.
    tracker = _started_pair([[316.0, 119.0], [330.0, 119.0]], hold)
    for t, x in enumerate([342.0, 345.0, 347.0], start=1):
        tracker.step(t, _seen([[x, 115.0]]))
    tracker.step(4, _seen([[350.0, 110.0], [321.0, 118.0]]))
    assert [state.matched_detection for state in tracker.states()] == [1, 0]
    for t in range(5, 10):
        tracker.step(t, _seen([[350.0 + 3 * (t - 4), 110.0], [321.0, 118.0]]))
    states = tracker.states()
    assert [state.matched_detection for state in states] == [1, 0]
    assert states[1].position[0] > 360.0


def test_lost_target_is_reacquired_with_its_old_id_where_the_group_says() -> None:
    # Target 2 vanishes for 3 s while the camera pans: the whole group drifts 120 px right.
    # It comes back where its offset to the group puts it, 120 px from where it was last
    # seen; a bystander of another head size stands exactly where it vanished.
    tracker = _tracker(lost_after_s=0.2)
    pan = np.array([1.6, 0.0])  # px per frame
    for t in range(1, 76):
        tracker.step(t, _seen(GROUP[[0, 2]] + pan * t))
    assert tracker.statuses()[1] == "lost"
    back = GROUP + pan * 76
    bystander = GROUP[1]
    tracker.step(76, _seen(np.vstack([back, bystander]), [30.0, 30.0, 30.0, 60.0]))
    states = tracker.states()
    assert [s.status for s in states] == ["tracked"] * 3
    assert states[1].target_id == 2 and states[1].matched_detection == 1
    assert np.allclose(states[1].position, back[1], atol=1.0)


def test_a_target_not_yet_detected_is_also_looked_for_where_it_was_given() -> None:
    # Target 2's head was given on the start frame, but the detector has not found it yet. Its
    # neighbours walk 120 px right in 3 s while it stands; its head, detected at last where it
    # was given, is taken there, far from where the offsets to the walkers put it.
    tracker = _tracker(lost_after_s=0.2)
    walk = np.array([1.6, 0.0])  # px per frame
    for t in range(1, 76):
        tracker.step(t, _seen(GROUP[[0, 2]] + walk * t))
    assert tracker.statuses()[1] == "lost"
    tracker.step(76, _seen(np.vstack([GROUP[[0, 2]] + walk * 76, GROUP[1]])))
    states = tracker.states()
    assert [s.status for s in states] == ["tracked"] * 3
    assert states[1].matched_detection == 2
    assert np.allclose(states[1].position, GROUP[1])


def test_without_neighbours_the_gate_grows_with_time_lost() -> None:
    # Alone, a lost target waits where it was last seen. 55 px away is beyond the first
    # re-acquisition gate (60 px at 1080p = 40 px at 720p) and the tracker's 33 px gate, and
    # within it after 1 s (+ 30 px at 720p).
    lifecycle = {
        "lost_after_s": 0.1,
        "reacquire_gate_px_at_1080": 60.0,
        "reacquire_growth_px_per_s_at_1080": 45.0,
        "reacquire_max_px_at_1080": 300.0,
    }
    tracker = load_registry().build_stage(
        "tracker", {"type": "kalman", "params": {"lifecycle": lifecycle}}
    )
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([7]), np.array([[600.0, 300.0]]))
    far = _seen([[655.0, 300.0]])
    for t in range(1, 5):
        tracker.step(t, Detections.empty())
    tracker.step(5, far)
    assert tracker.statuses() == ["lost"]
    for t in range(6, 30):
        tracker.step(t, Detections.empty())
    tracker.step(30, far)
    assert tracker.statuses() == ["tracked"]
    assert tracker.states()[0].target_id == 7


def test_out_of_view_then_tracked_again() -> None:
    tracker = load_registry().build_stage("tracker", {"type": "kalman"})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([1, 2]), np.array([[1200.0, 300.0], [600.0, 300.0]]))
    x = 1200.0
    t = 0
    while x < 1279:  # target 1 walks right, 8 px per frame, to the edge
        t, x = t + 1, x + 8.0
        tracker.step(t, _seen([[x, 300.0], [600.0, 300.0]]) if x < 1280 else _seen([[600, 300]]))
    for _ in range(3):  # then it is gone; its prediction leaves the image
        t += 1
        tracker.step(t, _seen([[600.0, 300.0]]))
    assert tracker.statuses() == ["out-of-view", "tracked"]
    for _ in range(20):
        t += 1
        tracker.step(t, _seen([[600.0, 300.0]]))
    assert tracker.statuses() == ["out-of-view", "tracked"]
    # It walks back in where it left (the neighbour has not moved).
    t += 1
    tracker.step(t, _seen([[1270.0, 300.0], [600.0, 300.0]]))
    assert tracker.statuses() == ["tracked", "tracked"]
    assert tracker.states()[0].matched_detection == 0


def test_tentative_confirmed_by_a_detection() -> None:
    tracker = _tracker(confirm_within_s=0.5)
    tracker.reinitialise(10, GROUP + 50.0, np.array([0, -1, 2]))
    assert tracker.statuses() == ["tracked", "tentative", "tracked"]
    for t in range(11, 16):
        tracker.step(t, _seen((GROUP + 50.0)[[0, 2]]))
    assert tracker.statuses()[1] == "tentative"
    tracker.step(16, _seen(GROUP + 50.0))
    assert tracker.statuses() == ["tracked"] * 3


def test_tentative_lost_when_nothing_confirms_it() -> None:
    tracker = _tracker(confirm_within_s=0.5)
    tracker.reinitialise(10, GROUP + 50.0, np.array([0, -1, 2]))
    for t in range(11, 23):  # 12 frames = 0.48 s
        tracker.step(t, _seen((GROUP + 50.0)[[0, 2]]))
    assert tracker.statuses()[1] == "tentative"
    tracker.step(23, _seen((GROUP + 50.0)[[0, 2]]))
    assert tracker.statuses()[1] == "lost"


def test_lost_targets_stay_lost_through_a_reinitialisation() -> None:
    tracker = _tracker(lost_after_s=0.2)
    for t in range(1, 10):
        tracker.step(t, _seen(GROUP[[0, 2]]))
    assert tracker.statuses()[1] == "lost"
    before = tracker.positions()[1].copy()
    tracker.reinitialise(20, GROUP + 200.0, np.array([0, -1, 1]))
    assert tracker.statuses() == ["tracked", "lost", "tracked"]
    assert np.allclose(tracker.positions()[1], before)


def test_a_bystander_of_another_head_size_is_not_taken() -> None:
    tracker = _tracker()
    tracker.step(1, _seen(GROUP, [30.0, 30.0, 30.0]))
    tracker.step(2, _seen(GROUP, [30.0, 80.0, 30.0]))
    assert [s.matched_detection for s in tracker.states()] == [0, -1, 2]


def _painted(spots: list[tuple[float, float, tuple[int, int, int]]]) -> np.ndarray:
    """A grey 720p frame with a 60 px square of colour (BGR) at each spot."""
    image = np.full((720, 1280, 3), 128, dtype=np.uint8)
    for x, y, colour in spots:
        image[int(y) - 30 : int(y) + 30, int(x) - 30 : int(x) + 30] = colour
    return image


def test_appearance_refuses_a_bystander_that_looks_different() -> None:
    # Target 1 (red) vanishes; 2 s later a green bystander stands 10 px from where it is
    # expected and the red person 30 px away. By position alone the bystander is taken;
    # with the patch descriptor the red person is.
    red, green = (0, 0, 255), (0, 255, 0)
    chosen = {}
    for descriptor in ("none", "patch"):
        tracker = load_registry().build_stage(
            "tracker",
            {
                "type": "kalman",
                "params": {
                    "lifecycle": {"lost_after_s": 0.2, "reacquire_max_px_at_1080": 120.0},
                    "appearance": {"descriptor": descriptor, "max_distance": 0.3},
                },
            },
        )
        assert tracker.needs_pixels == (descriptor != "none")
        tracker.start(VIDEO)
        tracker.initialise(0, np.array([1]), np.array([[400.0, 300.0]]))
        tracker.see(_painted([(400, 300, red)]))
        tracker.step(1, _seen([[400.0, 300.0]]))
        empty = _painted([])
        for t in range(2, 52):
            tracker.see(empty)
            tracker.step(t, Detections.empty())
        assert tracker.statuses() == ["lost"]
        tracker.see(_painted([(410, 300, green), (430, 300, red)]))
        tracker.step(52, _seen([[410.0, 300.0], [430.0, 300.0]]))
        assert tracker.statuses() == ["tracked"]
        chosen[descriptor] = tracker.states()[0].matched_detection
    assert chosen == {"none": 0, "patch": 1}


def test_matches_at_b_are_judged_after_the_cameras_change_of_scale() -> None:
    # After the look-away the camera stands nearer: every head is 1.6 times larger. The size
    # check compares with the rescaled sizes, so the three correct matches stay tracked, also
    # on the frames after b; without the rescale each would exceed size_ratio_max 1.5.
    tracker = _tracker()
    tracker.step(1, _seen(GROUP, [30.0, 30.0, 30.0]))
    at_b = GROUP * 1.6
    tracker.reinitialise(40, at_b, np.array([0, 1, 2]), _seen(at_b, [48.0, 48.0, 48.0]))
    assert tracker.statuses() == ["tracked"] * 3
    for t in range(41, 60):
        tracker.step(t, _seen(at_b, [48.0, 48.0, 48.0]))
    assert tracker.statuses() == ["tracked"] * 3
    assert [s.matched_detection for s in tracker.states()] == [0, 1, 2]


@pytest.mark.parametrize("scale_offsets_at_b", [False, True])
def test_a_target_lost_before_a_is_expected_where_the_zoomed_pattern_puts_it(
    scale_offsets_at_b: bool,
) -> None:
    # Three targets 300 px apart; the third is lost before a. After the look-away the camera
    # stands nearer (every head and every offset 1.5 times larger, about the image centre). On
    # the frame after b the third head is detected where the zoomed pattern puts it: 225 px
    # right of where the old offsets expect it, beyond its re-acquisition gate.
    group = np.array([[300.0, 300.0], [600.0, 300.0], [900.0, 300.0]])
    tracker = _tracker_at(group, lost_after_s=0.2, scale_offsets_at_b=scale_offsets_at_b)
    for t in range(1, 4):
        tracker.step(t, _seen(group))
    for t in range(4, 12):
        tracker.step(t, _seen(group[:2]))
    assert tracker.statuses() == ["tracked", "tracked", "lost"]
    centre = np.array([640.0, 360.0])
    zoomed = centre + 1.5 * (group - centre)
    at_b = np.vstack([zoomed[:2], tracker.positions()[2:]])
    tracker.reinitialise(40, at_b, np.array([0, 1, -1]), _seen(zoomed[:2], [45.0, 45.0]))
    tracker.step(41, _seen(zoomed, [45.0, 45.0, 45.0]))
    expected = "tracked" if scale_offsets_at_b else "lost"
    assert tracker.statuses() == ["tracked", "tracked", expected]
    if scale_offsets_at_b:
        assert np.allclose(tracker.positions()[2], zoomed[2], atol=1.0)


def test_a_match_at_b_out_of_line_with_the_groups_scale_is_tentative() -> None:
    tracker = _tracker()
    tracker.step(1, _seen(GROUP, [30.0, 30.0, 30.0]))
    at_b = GROUP * 1.6
    tracker.reinitialise(40, at_b, np.array([0, 1, 2]), _seen(at_b, [48.0, 48.0, 100.0]))
    assert tracker.statuses() == ["tracked", "tracked", "tentative"]


RED, GREEN, BLUE = (0, 0, 255), (0, 255, 0), (255, 0, 0)


def _looked_at(
    gap_max_distance: float | None, rematch_ratio: float | None = 0.8, **lifecycle: Any
) -> Any:
    """Three targets (red, green, blue) seen once with the patch descriptor on."""
    appearance = {
        "descriptor": "patch",
        "max_distance": 0.3,
        "gap_max_distance": gap_max_distance,
        "gap_rematch_ratio": rematch_ratio,
    }
    params = {"appearance": appearance, "lifecycle": lifecycle}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([1, 2, 3]), GROUP)
    colours = (RED, GREEN, BLUE)
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(GROUP, colours, strict=True)]))
    tracker.step(1, _seen(GROUP))
    return tracker


@pytest.mark.parametrize("limit", [None, 0.3])
def test_a_swap_at_b_is_undone_by_look(limit: float | None) -> None:
    # The group reappears 200 px lower; the window match swapped targets 1 and 2. With the
    # look check each refuses the other's head and takes its own again by appearance.
    tracker = _looked_at(limit)
    at_b = GROUP + np.array([0.0, 200.0])
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(at_b, (RED, GREEN, BLUE), strict=True)]))
    swapped = np.array([1, 0, 2])
    tracker.reinitialise(40, at_b[swapped], swapped, _seen(at_b))
    states = tracker.states()
    assert [s.status for s in states] == ["tracked"] * 3
    expected = [1, 0, 2] if limit is None else [0, 1, 2]
    assert [s.matched_detection for s in states] == expected
    assert np.allclose(tracker.positions(), at_b[expected])


def test_a_match_at_b_that_looks_like_someone_else_is_lost() -> None:
    # Target 1 (red) walked away during the look-away; the window match put it on a cyan
    # bystander. It is lost, not reported on the bystander; the others stay tracked.
    tracker = _looked_at(0.3)
    at_b = GROUP + np.array([0.0, 200.0])
    tracker.see(
        _painted([(at_b[0, 0], at_b[0, 1], (255, 255, 0)), (*at_b[1], GREEN), (*at_b[2], BLUE)])
    )
    tracker.reinitialise(40, at_b, np.array([0, 1, 2]), _seen(at_b))
    assert tracker.statuses() == ["lost", "tracked", "tracked"]
    tracker.step(41, _seen(at_b))
    assert tracker.statuses()[0] == "lost"


@pytest.mark.parametrize("ratio", [None, 0.8])
def test_a_refused_target_is_not_rematched_between_two_heads_that_look_alike(
    ratio: float | None,
) -> None:
    # Target 1 (red) walked away; the window match put it on a cyan bystander and two red
    # bystanders stand elsewhere. Re-matched by look alone it would take one of them; when
    # neither stands out from the other it is lost instead.
    tracker = _looked_at(0.3, ratio)
    at_b = GROUP + np.array([0.0, 200.0])
    reds = np.array([[900.0, 200.0], [1100.0, 250.0]])
    spots = [(*at_b[0], (255, 255, 0)), (*at_b[1], GREEN), (*at_b[2], BLUE)]
    tracker.see(_painted([*spots, *((x, y, RED) for x, y in reds)]))
    tracker.reinitialise(40, at_b, np.array([0, 1, 2]), _seen(np.vstack([at_b, reds])))
    first = "tracked" if ratio is None else "lost"
    assert tracker.statuses() == [first, "tracked", "tracked"]
    if ratio is None:
        assert tracker.states()[0].matched_detection in (3, 4)


@pytest.mark.parametrize("size_refused_at_b", ["tentative", "lost"])
def test_a_match_at_b_refused_for_size_is_rematched_by_look_or_left_tentative(
    size_refused_at_b: str,
) -> None:
    # The window match put target 1 (red) on a yellow head three times its size, while its
    # own red head stands free 300 px away. Left tentative, it sits on the yellow head; refused
    # as by the look check, it takes its own head back by look.
    tracker = _looked_at(0.3, size_refused_at_b=size_refused_at_b)
    at_b = GROUP + np.array([0.0, 200.0])
    red_head, yellow_head = np.array([800.0, 150.0]), at_b[0]
    spots = [(*red_head, RED), (*yellow_head, (0, 255, 255)), (*at_b[1], GREEN), (*at_b[2], BLUE)]
    tracker.see(_painted(spots))
    heads = _seen(np.vstack([red_head, yellow_head, at_b[1:]]), [30.0, 90.0, 30.0, 30.0])
    tracker.reinitialise(40, at_b, np.array([1, 2, 3]), heads)
    states = tracker.states()
    if size_refused_at_b == "lost":
        assert [s.status for s in states] == ["tracked"] * 3
        assert states[0].matched_detection == 0
        assert np.allclose(tracker.positions()[0], red_head)
    else:
        assert [s.status for s in states] == ["tentative", "tracked", "tracked"]
        assert np.allclose(tracker.positions()[0], yellow_head)


def test_a_match_at_b_refused_for_size_with_no_look_check_is_lost() -> None:
    tracker = _tracker(size_refused_at_b="lost")
    tracker.step(1, _seen(GROUP, [30.0, 30.0, 30.0]))
    at_b = GROUP + np.array([0.0, 200.0])
    tracker.reinitialise(40, at_b, np.array([0, 1, 2]), _seen(at_b, [30.0, 30.0, 100.0]))
    assert tracker.statuses() == ["tracked", "tracked", "lost"]


def _walk_out_right(tracker: Any, group: np.ndarray, sizes: list[float]) -> int:
    """Target 1 (row 0) walks out through the right edge; the others stay. Returns the frame."""
    x, t = float(group[0, 0]), 0
    while x < 1279:
        t, x = t + 1, x + 8.0
        shown = np.vstack([[x, group[0, 1]], group[1:]]) if x < 1280 else group[1:]
        tracker.step(t, _seen(shown, sizes if x < 1280 else sizes[1:]))
    for _ in range(3):
        t += 1
        tracker.step(t, _seen(group[1:], sizes[1:]))
    assert tracker.statuses()[0] == "out-of-view"
    return t


def _left_for_4_s(
    tracker: Any,
    group: np.ndarray,
    sizes: list[float] | None = None,
    extra: np.ndarray | None = None,
) -> int:
    """Start on ``group``, walk target 1 out through the right edge, then show the others (and
    ``extra`` 30 px heads) for 100 frames (4 s). Returns the frame."""
    sizes = sizes or [30.0] * len(group)
    tracker.initialise(0, np.arange(1, len(group) + 1), group)
    t = _walk_out_right(tracker, group, sizes)
    shown = group[1:] if extra is None else np.vstack([group[1:], extra])
    shown_sizes = sizes[1:] + [30.0] * (len(shown) - len(group) + 1)
    for _ in range(100):
        t += 1
        tracker.step(t, _seen(shown, shown_sizes))
    return t


class _AgreeingLooks:
    """An appearance memory whose descriptors always agree (the border rule needs one)."""

    active = True

    def remember(self, *args: Any) -> Any:
        return np.zeros(0, dtype=np.int64)  # never a swap

    def veto(
        self,
        image: Any,
        targets: Any,
        detections: Any,
        columns: Any,
        candidates: Any,
        entering: Any,
    ) -> Any:
        return np.zeros(candidates.shape, dtype=bool)


def _edge_tracker(looks: bool = True, **lifecycle: Any) -> Any:
    params = {"lifecycle": {"reentry_margin_px_at_1080": 60.0, **lifecycle}}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    original = tracker.initialise

    def initialise(*args: Any) -> None:
        original(*args)
        if looks:
            tracker.memory = tracker.reacquisition.memory = _AgreeingLooks()
            tracker.image = np.zeros((720, 1280, 3), dtype=np.uint8)

    tracker.initialise = initialise
    return tracker


def test_returner_reacquired_through_its_exit_edge_far_from_the_exit_point() -> None:
    # Target 1 leaves through the right edge at y = 300 and comes back 4 s later through the
    # same edge 200 px lower (the camera has tilted meanwhile; its neighbours did not move):
    # far beyond the 80 px gate around where it left, within the re-entry gate along that edge.
    tracker = _edge_tracker()
    group = np.array([[1200.0, 300.0], [600.0, 300.0], [700.0, 320.0]])
    t = _left_for_4_s(tracker, group)
    assert tracker.statuses()[0] == "out-of-view"
    t += 1
    tracker.step(t, _seen(np.vstack([group[1:], [[1275.0, 500.0]]])))
    assert tracker.statuses() == ["tracked"] * 3
    assert tracker.states()[0].target_id == 1 and tracker.states()[0].matched_detection == 2


def test_reentry_needs_the_border_near_the_door() -> None:
    # After the same exit, a bystander standing 100 px inside the right edge, and one entering
    # through the left edge (1270 px from the door), are not target 1: it stays out of view.
    tracker = _edge_tracker()
    group = np.array([[1200.0, 300.0], [600.0, 300.0], [700.0, 320.0]])
    _left_for_4_s(tracker, group, extra=np.array([[1180.0, 400.0], [3.0, 300.0]]))
    assert tracker.statuses() == ["out-of-view", "tracked", "tracked"]
    with_margin = _edge_tracker(reentry_margin_px_at_1080=200.0)
    _left_for_4_s(with_margin, group, extra=np.array([[1180.0, 400.0]]))
    assert with_margin.statuses()[0] == "tracked"  # 100 px inside is within a 133 px margin


def test_returner_size_compared_with_the_size_expected_at_its_place() -> None:
    # Heads grow with the image row: 20 px at y = 200, 40 px at y = 600 (line 10 + 0.05 y).
    # Target 1 leaves through the right edge at y = 200 with a 20 px head and returns at
    # y = 600: a 40 px head fits there (2x its exit size), a 20 px one does not.
    group = np.array([[1200.0, 200.0], [600.0, 200.0], [700.0, 600.0]])
    sizes = [20.0, 20.0, 40.0]
    returns = {}
    for side in (40.0, 20.0):
        tracker = _edge_tracker(reentry_max_px_at_1080=1200.0)
        t = _left_for_4_s(tracker, group, sizes)
        t += 1
        tracker.step(t, _seen(np.vstack([group[1:], [[1275.0, 600.0]]]), [*sizes[1:], side]))
        returns[side] = tracker.statuses()[0]
    assert returns == {40.0: "tracked", 20.0: "out-of-view"}


def test_size_line_flat_for_one_head_and_fitted_for_several() -> None:
    from trackfw_plugins.trackers.lifecycle import size_line

    assert np.isnan(size_line(np.array([]), np.array([]))[0])
    assert size_line(np.array([100.0]), np.array([30.0])).tolist() == [30.0, 0.0]
    a, b = size_line(np.array([100.0, 200.0, 300.0, 400.0]), np.array([15.0, 20.0, 25.0, np.nan]))
    assert np.isclose(a, 10.0) and np.isclose(b, 0.05)


def test_returner_reacquired_round_the_corner() -> None:
    # Out through the right edge at y = 650, back 4 s later through the bottom edge 150 px left.
    tracker = _edge_tracker()
    group = np.array([[1200.0, 650.0], [600.0, 300.0], [700.0, 320.0]])
    t = _left_for_4_s(tracker, group)
    t += 1
    tracker.step(t, _seen(np.vstack([group[1:], [[1130.0, 715.0]]])))
    assert tracker.statuses() == ["tracked"] * 3


def test_no_reentry_through_the_border_without_a_look() -> None:
    # The same return as above with appearance 'none': on TUD virtual-wearer videos people keep
    # entering through the edge a target left by, so position alone never brings it back there.
    tracker = _edge_tracker(looks=False)
    group = np.array([[1200.0, 300.0], [600.0, 300.0], [700.0, 320.0]])
    t = _left_for_4_s(tracker, group)
    t += 1
    tracker.step(t, _seen(np.vstack([group[1:], [[1275.0, 500.0]]])))
    assert tracker.statuses()[0] == "out-of-view"


def _patch_tracker(**appearance: Any) -> Any:
    """A tracker with the patch descriptor (limit 0.3) and ``appearance`` settings, lost at 0.2 s."""
    params = {
        "appearance": {"descriptor": "patch", "max_distance": 0.3, **appearance},
        "lifecycle": {"lost_after_s": 0.2},
    }
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.initialise(0, np.array([1, 2, 3]), GROUP)
    return tracker


def _searching_anywhere(anywhere: float | None) -> Any:
    """A tracker with the patch descriptor and the search anywhere at ``anywhere``, lost at 0.2 s."""
    return _patch_tracker(anywhere_max_distance=anywhere)


def _lose_red(tracker: Any, frames: int) -> Any:
    """Red, green and blue seen on frame 1; red then gone for ``frames`` frames (and lost)."""
    colours = (RED, GREEN, BLUE)
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(GROUP, colours, strict=True)]))
    tracker.step(1, _seen(GROUP))
    for t in range(2, 2 + frames):
        tracker.see(_painted([(*GROUP[1], GREEN), (*GROUP[2], BLUE)]))
        tracker.step(t, _seen(GROUP[1:]))
    assert tracker.statuses() == ["lost", "tracked", "tracked"]
    return tracker


def _lost_red(anywhere: float | None) -> Any:
    """Red, green and blue targets seen with the patch descriptor; red then gone for 1 s."""
    return _lose_red(_searching_anywhere(anywhere), 25)


@pytest.mark.parametrize("anywhere", [None, 0.3])
def test_a_lost_target_is_found_anywhere_by_a_look_that_stands_out(anywhere: float | None) -> None:
    # Red comes back 500 px from where the group puts it (far outside any gate), beside a
    # cyan bystander: only a search by look finds it there.
    tracker = _lost_red(anywhere)
    red, cyan = np.array([1000.0, 600.0]), np.array([1000.0, 450.0])
    spots = [(*GROUP[1], GREEN), (*GROUP[2], BLUE), (*red, RED), (*cyan, (255, 255, 0))]
    tracker.see(_painted(spots))
    tracker.step(30, _seen(np.vstack([GROUP[1:], red, cyan])))  # 30: a frame the search runs
    if anywhere is None:
        assert tracker.statuses()[0] == "lost"
    else:
        assert tracker.statuses()[0] == "tracked"
        assert np.allclose(tracker.positions()[0], red, atol=1.0)


def test_no_find_anywhere_between_two_heads_that_look_alike() -> None:
    # Two red heads far away: neither stands out from the other, so the target stays lost.
    tracker = _lost_red(0.3)
    reds = np.array([[1000.0, 600.0], [1100.0, 450.0]])
    spots = [(*GROUP[1], GREEN), (*GROUP[2], BLUE), *((x, y, RED) for x, y in reds)]
    tracker.see(_painted(spots))
    tracker.step(30, _seen(np.vstack([GROUP[1:], reds])))
    assert tracker.statuses()[0] == "lost"


def test_search_anywhere_with_a_target_never_described() -> None:
    # Target 3 is never seen, so it has no descriptor (NaN looks): the search by look must pass
    # it over, not hand NaN to the assignment, and still find red.
    tracker = _searching_anywhere(0.3)
    tracker.see(_painted([(*GROUP[0], RED), (*GROUP[1], GREEN)]))
    tracker.step(1, _seen(GROUP[:2]))
    for t in range(2, 27):
        tracker.see(_painted([(*GROUP[1], GREEN)]))
        tracker.step(t, _seen(GROUP[1:2]))
    assert tracker.statuses() == ["lost", "tracked", "lost"]
    red, cyan = np.array([1000.0, 600.0]), np.array([1000.0, 450.0])
    tracker.see(_painted([(*GROUP[1], GREEN), (*red, RED), (*cyan, (255, 255, 0))]))
    tracker.step(30, _seen(np.vstack([GROUP[1:2], red, cyan])))
    assert tracker.statuses()[:2] == ["tracked", "tracked"]
    assert np.allclose(tracker.positions()[0], red, atol=1.0)


# Patch-descriptor distances to RED: DARK_RED 0.147 (beyond the 0.12 limit below), its lit
# version LIT_RED 0.089 (0.059 from DARK_RED), DEEP_RED 0.086 (0.078 from DARK_RED).
DARK_RED, LIT_RED, DEEP_RED = (0, 40, 150), (0, 30, 190), (0, 0, 170)


def _lost_red_beside(neighbour_margin: float | None) -> Any:
    """Red lost while a dark-red bystander stands far off (and a deep-red one, as like red as
    the search's 0.12 limit allows); the search anywhere on at 0.12."""
    tracker = _patch_tracker(anywhere_max_distance=0.12, neighbour_margin=neighbour_margin)
    colours = (RED, GREEN, BLUE)
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(GROUP, colours, strict=True)]))
    tracker.step(1, _seen(GROUP))
    dark, deep = np.array([1000.0, 450.0]), np.array([200.0, 600.0])
    for t in range(2, 27):
        spots = [(*GROUP[1], GREEN), (*GROUP[2], BLUE), (*dark, DARK_RED), (*deep, DEEP_RED)]
        tracker.see(_painted(spots))
        tracker.step(t, _seen(np.vstack([GROUP[1:], dark, deep])))
    assert tracker.statuses() == ["lost", "tracked", "tracked"]
    return tracker


@pytest.mark.parametrize("neighbour_margin", [None, 0.0])
def test_a_lost_target_is_not_found_on_a_person_seen_beside_it(
    neighbour_margin: float | None,
) -> None:
    # The dark-red bystander, lit now, comes back alone: it stands out as the most red-like head
    # (0.089), but it looks more like the person seen apart from red when red was lost (0.059).
    tracker = _lost_red_beside(neighbour_margin)
    lit = np.array([1000.0, 600.0])
    tracker.see(_painted([(*GROUP[1], GREEN), (*GROUP[2], BLUE), (*lit, LIT_RED)]))
    tracker.step(30, _seen(np.vstack([GROUP[1:], lit])))
    assert tracker.statuses()[0] == ("tracked" if neighbour_margin is None else "lost")


def test_a_head_the_search_would_take_for_the_target_is_not_kept_as_a_neighbour() -> None:
    # Deep red lies within the search's limit of red (it might be red, moved off its expected
    # place): only dark red is kept; red itself coming back is found.
    tracker = _lost_red_beside(0.0)
    assert tracker.reacquisition.neighbours.descriptors[0].shape[0] == 1
    red = np.array([1000.0, 600.0])
    tracker.see(_painted([(*GROUP[1], GREEN), (*GROUP[2], BLUE), (*red, RED)]))
    tracker.step(30, _seen(np.vstack([GROUP[1:], red])))
    assert tracker.statuses()[0] == "tracked"
    tracker.step(31, _seen(np.vstack([GROUP[1:], red])))
    assert tracker.reacquisition.neighbours.descriptors[0] is None  # followed again: forgotten


@pytest.mark.parametrize("neighbour_margin", [None, 0.0])
def test_a_match_at_b_on_a_person_seen_beside_the_target_at_a_is_refused(
    neighbour_margin: float | None,
) -> None:
    # Dark red stood far from red on frame a; at b the gap matcher hands red a lit-red head,
    # nearer in look to dark red (0.059) than to red (0.089): two heads seen at once on frame a
    # are two people, so red is lost rather than placed on it.
    tracker = _patch_tracker(anywhere_max_distance=0.12, neighbour_margin=neighbour_margin)
    dark = np.array([1000.0, 450.0])
    spots = [(*GROUP[0], RED), (*GROUP[1], GREEN), (*GROUP[2], BLUE), (*dark, DARK_RED)]
    for t in (1, 2, 3):
        tracker.see(_painted(spots))
        tracker.step(t, _seen(np.vstack([GROUP, dark])))
    assert tracker.statuses() == ["tracked"] * 3
    at_b = GROUP + np.array([0.0, 200.0])
    tracker.see(_painted([(*at_b[0], LIT_RED), (*at_b[1], GREEN), (*at_b[2], BLUE)]))
    tracker.reinitialise(40, at_b.copy(), np.array([0, 1, 2]), _seen(at_b))
    assert tracker.statuses() == [
        "tracked" if neighbour_margin is None else "lost",
        "tracked",
        "tracked",
    ]


def _lost_red_before_a(rematch_inactive: bool) -> Any:
    """Red, green and blue seen with the patch descriptor; red then lost before an interval."""
    tracker = _patch_tracker(gap_max_distance=0.3, gap_rematch_inactive=rematch_inactive)
    return _lose_red(tracker, 10)


@pytest.mark.parametrize("rematch_inactive", [False, True])
def test_a_target_lost_before_the_interval_is_found_at_b_by_look(rematch_inactive: bool) -> None:
    # After the look-away the group stands 200 px lower and red is back in it, with a cyan
    # bystander beside. Red took no part in the gap match (it was lost); only with
    # gap_rematch_inactive does it take its own head at b, and never the bystander's.
    tracker = _lost_red_before_a(rematch_inactive)
    at_b = GROUP + np.array([0.0, 200.0])
    cyan = np.array([700.0, 500.0])
    tracker.see(
        _painted([(*at_b[0], RED), (*at_b[1], GREEN), (*at_b[2], BLUE), (*cyan, (255, 255, 0))])
    )
    positions = np.vstack([tracker.positions()[0], at_b[1:]])
    tracker.reinitialise(40, positions, np.array([-1, 1, 2]), _seen(np.vstack([at_b, cyan])))
    if rematch_inactive:
        assert tracker.statuses() == ["tracked"] * 3
        assert tracker.states()[0].matched_detection == 0
        assert np.allclose(tracker.positions()[0], at_b[0])
    else:
        assert tracker.statuses() == ["lost", "tracked", "tracked"]


def test_a_target_lost_before_the_interval_stays_lost_between_two_heads_that_look_alike() -> None:
    tracker = _lost_red_before_a(True)
    at_b = GROUP + np.array([0.0, 200.0])
    reds = np.array([[900.0, 500.0], [1100.0, 550.0]])
    tracker.see(_painted([(*at_b[1], GREEN), (*at_b[2], BLUE), *((x, y, RED) for x, y in reds)]))
    positions = np.vstack([tracker.positions()[0], at_b[1:]])
    detections = _seen(np.vstack([at_b[1:], reds]))
    tracker.reinitialise(40, positions, np.array([-1, 0, 1]), detections)
    assert tracker.statuses() == ["lost", "tracked", "tracked"]


def test_the_group_places_a_target_that_missed_the_last_frame() -> None:
    tracker = _tracker()
    tracker.step(1, _seen(GROUP))
    tracker.step(2, _seen(GROUP[[0, 2]]))  # the middle target's head is missed on frame 2
    rows = np.arange(3)
    shifted = tracker.bank.positions + np.array([10.0, -5.0])  # the group's predictions on frame 3
    coasting, places = tracker.life.group_places(3, rows, shifted)
    assert coasting.tolist() == [1]
    # Its offsets to the two others, measured on frame 1, carried by their predictions.
    assert np.allclose(places, [GROUP[1] + np.array([10.0, -5.0])], atol=1.0)
    # With only one other target seen there is no group to place it.
    tracker.step(3, _seen(GROUP[[0]]))
    assert len(tracker.life.group_places(4, rows, tracker.bank.positions)[0]) == 0


@pytest.mark.parametrize("edge_exit_sides", [None, 1.0])
def test_a_target_lost_at_the_image_edge_walked_out_through_it(
    edge_exit_sides: float | None,
) -> None:
    # Target 1's last head lay 20 px inside the right edge (30 px heads), target 2's in the
    # middle; both vanish. With edge_exit_sides the first has walked out (out of view, right
    # edge); the second is lost inside the image either way.
    group = np.array([[1259.0, 300.0], [600.0, 300.0], [700.0, 320.0]])
    tracker = _tracker_at(group, lost_after_s=0.2, edge_exit_sides=edge_exit_sides)
    tracker.step(1, _seen(group))
    for t in range(2, 10):
        tracker.step(t, _seen(group[2:]))
    if edge_exit_sides is None:
        assert tracker.statuses() == ["lost", "lost", "tracked"]
    else:
        assert tracker.statuses() == ["out-of-view", "lost", "tracked"]
        assert tracker.life.exit_side[0] == 1  # the right edge
        assert not tracker.life.inside(tracker.positions()[:1])[0]


@pytest.mark.parametrize("out_of_view", [True, False])
def test_a_target_that_walked_out_before_the_interval_joins_the_look_rematch_only_if_asked(
    out_of_view: bool,
) -> None:
    # Red leaves through the right edge before a; at b a red head stands in the group. With
    # gap_rematch_out_of_view (the default) red takes it by look; without, a target that walked
    # out is not looked for at b (on TUD it took a bystander that looked alike).
    params = {
        "appearance": {
            "descriptor": "patch",
            "max_distance": 0.3,
            "gap_max_distance": 0.3,
            "gap_rematch_inactive": True,
            "gap_rematch_out_of_view": out_of_view,
        },
        "lifecycle": {"lost_after_s": 0.2, "edge_exit_sides": 1.5},
    }
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    group = np.array([[1230.0, 300.0], [600.0, 300.0], [700.0, 320.0]])
    tracker.initialise(0, np.array([1, 2, 3]), group)
    colours = (RED, GREEN, BLUE)
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(group, colours, strict=True)]))
    tracker.step(1, _seen(group, [40.0, 30.0, 30.0]))
    for t in range(2, 12):
        tracker.see(_painted([(*group[1], GREEN), (*group[2], BLUE)]))
        tracker.step(t, _seen(group[1:]))
    assert tracker.statuses() == ["out-of-view", "tracked", "tracked"]
    at_b = np.array([[800.0, 500.0], [600.0, 500.0], [700.0, 520.0]])
    tracker.see(_painted([(x, y, c) for (x, y), c in zip(at_b, colours, strict=True)]))
    positions = np.vstack([tracker.positions()[0], at_b[1:]])
    tracker.reinitialise(40, positions, np.array([-1, 1, 2]), _seen(at_b))
    expected = "tracked" if out_of_view else "out-of-view"
    assert tracker.statuses() == [expected, "tracked", "tracked"]

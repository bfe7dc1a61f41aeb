"""The matches at b checked by the walk after them (``walk_check``)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from trackfw.records import Detections, VideoContext
from trackfw.registry import load_registry
from trackfw_plugins.trackers.walk_check import Snapshot, WalkCheck, WalkCheckSettings

HEIGHT, WIDTH, FPS = 240, 320, 25.0
#: 1 px per frame at 240 rows and 25 fps.
ONE_PX_PER_FRAME = 1.0 * FPS * 1080.0 / HEIGHT
VIDEO = VideoContext(name="v", path="v", n_frames=60, width=WIDTH, height=HEIGHT, fps=FPS)


def _scene() -> np.ndarray:
    """A wide textured street the camera pans over (blocks of colour: corners to register)."""
    random = np.random.default_rng(5)
    scene = cv2.GaussianBlur(
        random.integers(0, 255, (HEIGHT, 3 * WIDTH, 3), dtype=np.uint8), (3, 3), 0
    )
    for _ in range(200):
        x, y = int(random.integers(0, 3 * WIDTH - 20)), int(random.integers(0, HEIGHT - 20))
        colour = tuple(int(c) for c in random.integers(0, 255, 3))
        cv2.rectangle(scene, (x, y), (x + 14, y + 11), colour, -1)
    return scene


SCENE = _scene()


def _view(pan: float) -> np.ndarray:
    """The frame the camera sees when it has panned ``pan`` pixels to the right of the middle."""
    shift = np.array([[1.0, 0.0, -(WIDTH + pan)], [0.0, 1.0, 0.0]])
    return cv2.warpAffine(SCENE, shift, (WIDTH, HEIGHT))


def _walk(
    check: WalkCheck, start: int, frames: int, world: np.ndarray, speed: np.ndarray, pan: float
) -> None:
    """Remember ``frames`` frames from ``start``: people walking ``speed`` px per frame in the
    street, the camera panning ``pan`` px per frame (so that in the image they walk less)."""
    for step in range(frames):
        camera = pan * step
        positions = world + speed * step - [camera, 0.0]
        check.remember(Snapshot(start + step, _view(camera), None, positions))


def test_a_person_who_walks_back_is_found_through_the_camera_s_pan() -> None:
    settings = WalkCheckSettings(after_s=0.4, min_speed_px_s_at_1080=ONE_PX_PER_FRAME)
    check = WalkCheck(settings, FPS, HEIGHT)
    assert check.frames == 10
    people = np.array([[100.0, 120.0], [200.0, 120.0]])
    # Before a both targets walk 2 px per frame to the right; the camera follows at 1.5, so in
    # the image they move 0.5 px per frame: under the limit, unless the pan is registered out.
    _walk(check, 0, 11, people, np.array([[2.0, 0.0], [2.0, 0.0]]), 1.5)
    # At b (the camera back at its start) target 0's person walks left, target 1's right, while
    # the camera pans left by 1.5 px per frame.
    check.arm(
        Snapshot(30, _view(0.0), None, people), np.array([0, 1]), [None, None], np.zeros(2, int)
    )
    late = 30 + check.frames
    camera = -1.5 * check.frames
    walked = people + np.array([[-2.0, 0.0], [2.0, 0.0]]) * check.frames - [camera, 0.0]
    early = Snapshot(late - 1, _view(camera), None, walked)
    assert check.due(early, np.array([0, 1])) == []  # the walk is not long enough yet
    back = check.due(Snapshot(late, _view(camera), None, walked), np.array([0, 1]))
    assert [row for row, _ in back] == [0]
    assert abs(back[0][1].before[0] - 2.0) < 0.3
    # Each check is made once.
    assert check.due(Snapshot(late + 1, _view(camera), None, walked), np.array([0, 1])) == []


def test_standing_people_under_a_swaying_camera_are_kept() -> None:
    settings = WalkCheckSettings(after_s=0.4, min_speed_px_s_at_1080=ONE_PX_PER_FRAME)
    check = WalkCheck(settings, FPS, HEIGHT)
    people = np.array([[100.0, 120.0], [200.0, 120.0]])
    # The camera pans 2 px per frame one way before a and the other way after b: in the image
    # the standing people "walk" 2 px per frame, and back.
    _walk(check, 0, 11, people, np.zeros((2, 2)), 2.0)
    check.arm(
        Snapshot(30, _view(0.0), None, people), np.array([0, 1]), [None, None], np.zeros(2, int)
    )
    camera = -2.0 * check.frames
    now = Snapshot(30 + check.frames, _view(camera), None, people - [camera, 0.0])
    assert check.due(now, np.array([0, 1])) == []


def test_without_pixels_nothing_is_checked() -> None:
    check = WalkCheck(WalkCheckSettings(after_s=0.4), FPS, HEIGHT)
    people = np.array([[100.0, 120.0]])
    for t in range(11):
        check.remember(Snapshot(t, None, None, people + np.array([3.0 * t, 0.0])))
    check.arm(Snapshot(30, None, None, people), np.array([0]), [None], np.zeros(1, int))
    assert check.pending == {}
    assert check.due(Snapshot(40, None, None, people - np.array([30.0, 0.0])), np.array([0])) == []


def test_the_tracker_loses_a_target_matched_to_someone_walking_back() -> None:
    params = {"walk_check": {"after_s": 0.4, "min_speed_px_s_at_1080": ONE_PX_PER_FRAME}}
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    assert tracker.needs_pixels  # the walks are measured against the scene
    tracker.start(VIDEO)
    people = np.array([[100.0, 120.0], [200.0, 120.0]])
    tracker.see(_view(0.0))
    tracker.initialise(0, np.array([4, 7]), people)
    for t in range(1, 11):  # both walk right, 2 px per frame, under a still camera
        tracker.see(_view(0.0))
        tracker.step(t, Detections.from_points(people + np.array([2.0 * t, 0.0])))
    assert tracker.withdrawn() == []
    # At b each is matched to a head: target 4 to someone who then walks left.
    at_b = np.array([[150.0, 120.0], [250.0, 120.0]])
    tracker.see(_view(0.0))
    tracker.reinitialise(30, at_b, np.array([0, 1]), Detections.from_points(at_b))
    for t in range(31, 41):
        tracker.see(_view(0.0))
        tracker.step(
            t, Detections.from_points(at_b + np.array([[-2.0, 0.0], [2.0, 0.0]]) * (t - 30))
        )
        if t < 40:
            assert tracker.statuses() == ["tracked", "tracked"], t
    assert tracker.statuses() == ["lost", "tracked"]
    assert tracker.withdrawn() == [(0, 30)]
    assert tracker.withdrawn() == []  # handed over once


def test_a_target_found_by_look_soon_after_b_is_checked_from_its_find() -> None:
    settings = WalkCheckSettings(after_s=0.4, min_speed_px_s_at_1080=ONE_PX_PER_FRAME)
    check = WalkCheck(settings, FPS, HEIGHT)
    people = np.array([[100.0, 120.0], [200.0, 120.0]])
    _walk(check, 0, 11, people, np.array([[2.0, 0.0], [2.0, 0.0]]), 0.0)
    # At b neither target is matched; target 0 is found by look 3 frames later on someone who
    # walks left, target 1 only after the half second, on someone who walks left as well.
    check.arm(
        Snapshot(30, _view(0.0), None, people),
        np.zeros(0, int),
        [None, None],
        np.zeros(2, int),
        np.array([0, 1]),
    )
    assert check.pending == {}
    check.found(Snapshot(33, _view(0.0), None, people), np.array([0]))
    assert list(check.pending) == [0]
    walked = people + np.array([-2.0, 0.0]) * check.frames
    # Its walk is measured from its find: not long enough on frame b + frames.
    assert check.due(Snapshot(30 + check.frames, _view(0.0), None, walked), np.array([0])) == []
    check.found(Snapshot(30 + check.frames + 1, _view(0.0), None, people), np.array([1]))
    assert list(check.pending) == [0]  # found too late: a find, not a match at b
    back = check.due(Snapshot(33 + check.frames, _view(0.0), None, walked), np.array([0, 1]))
    assert [row for row, _ in back] == [0]
    assert check.pending == {}


def _frame(people: list[tuple[float, int, int]]) -> np.ndarray:
    """The still street with each person ``(x, colour channel, seed)`` an 80 px square of their
    own noise in one colour channel."""
    image = _view(0.0).copy()
    for x, channel, seed in people:
        left = int(x) - 40
        image[80:160, left : left + 80] = 0
        noise = np.random.default_rng(seed).integers(100, 255, size=(80, 80))
        image[80:160, left : left + 80, channel] = noise
    return image


@pytest.mark.parametrize("neighbour_margin", [None, 0.0])
def test_a_target_found_soon_after_b_on_someone_walking_back_is_lost_again(
    neighbour_margin: float | None,
) -> None:
    params = {
        "walk_check": {"after_s": 0.4, "min_speed_px_s_at_1080": ONE_PX_PER_FRAME},
        "appearance": {
            "descriptor": "patch",
            "refresh_s": 0.04,
            # The two red people lie 0.18 apart: near its place the target needs a closer look,
            # anywhere a clear one (as real.yaml's person-reid limits, 0.25 and 0.4).
            "max_distance": 0.15,
            "gap_max_distance": 0.4,
            "anywhere_max_distance": 0.4,
            "neighbour_margin": neighbour_margin,
        },
    }
    tracker = load_registry().build_stage("tracker", {"type": "kalman", "params": params})
    tracker.start(VIDEO)
    tracker.see(_frame([(100.0, 2, 0), (260.0, 1, 1)]))
    tracker.initialise(0, np.array([4]), np.array([[100.0, 120.0]]))
    for t in range(1, 11):  # the red target walks right, 2 px per frame; a green one stands
        x = 100.0 + 2.0 * t
        tracker.see(_frame([(x, 2, 0), (260.0, 1, 1)]))
        tracker.step(t, Detections.from_points(np.array([[x, 120.0], [260.0, 120.0]])))
    # At b the gap matcher hands it the green one (refused by look); another red person comes
    # into view two frames later and walks left: the search by look finds the target on them.
    tracker.see(_frame([(260.0, 1, 1)]))
    tracker.reinitialise(
        30,
        np.array([[260.0, 120.0]]),
        np.array([0]),
        Detections.from_points(np.array([[260.0, 120.0]])),
    )
    assert tracker.statuses() == ["lost"]
    statuses = {}
    for t in range(31, 61):
        people = [(260.0, 1, 1)] if t < 32 else [(200.0 - 2.0 * (t - 32), 2, 2), (260.0, 1, 1)]
        tracker.see(_frame(people))
        tracker.step(t, Detections.from_points(np.array([[x, 120.0] for x, _, _ in people])))
        statuses[t] = tracker.statuses()[0]
    found = min(t for t, status in statuses.items() if status == "tracked")
    assert found <= 30 + 10  # within the half second after b: a late match at b
    lost_again = [t for t in statuses if t > found and statuses[t] == "lost"]
    assert lost_again and lost_again[0] == found + 10  # its walk after the find is checked
    undone = lost_again[0]
    assert tracker.withdrawn() == [(0, 30)]
    # Without the people seen apart, nothing says the walker is not the target.
    again = [t for t in statuses if t > undone and statuses[t] == "tracked"]
    assert bool(again) == (neighbour_margin is None)


def test_a_find_is_checked_only_for_a_target_whose_walk_before_a_held_detections() -> None:
    check = WalkCheck(WalkCheckSettings(after_s=0.4), FPS, HEIGHT)
    people = np.array([[100.0, 120.0], [200.0, 120.0], [300.0, 120.0]])
    for t in range(11):
        # Target 1 missed one frame of the walk; target 2 coasted through most of it.
        held = np.array([True, t != 0, t >= 8])
        check.remember(Snapshot(t, _view(0.0), None, people + np.array([2.0 * t, 0.0]), held))
    check.arm(
        Snapshot(30, _view(0.0), None, people),
        np.zeros(0, int),
        [None, None, None],
        np.zeros(3, int),
        np.array([0, 1, 2]),
    )
    assert sorted(check.late) == [0, 1]  # target 2's walk before a was mostly its prediction

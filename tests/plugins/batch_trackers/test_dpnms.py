"""DPNMS: the brief's sanity tests (parallel targets, jump, gap, crossing, short tracks)."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.batch_trackers.dpnms import DpnmsParams, track_dpnms
from trackfw_plugins.batch_trackers.tracks import VideoDetections

from .conftest import line_path, path_detections


def test_two_parallel_targets_give_two_full_tracks() -> None:
    paths = [line_path((100, 100), (3, 0), 30), line_path((100, 300), (3, 0), 30)]
    tracks = track_dpnms(path_detections(paths, 30), DpnmsParams(legacy_last_track=False))
    assert tracks.track_ids().tolist() == [1, 2]
    for track_id in (1, 2):
        frames, points, observed = tracks.track(track_id)
        assert frames.tolist() == list(range(30)) and observed.all()
        # Each track follows one path only.
        assert np.ptp(points[:, 1]) == 0.0


def test_legacy_quirk_appends_the_first_track_over_the_stop_cost() -> None:
    paths = [line_path((100, 100), (3, 0), 30), line_path((100, 300), (3, 0), 2)]
    paths[1] = np.vstack([paths[1], np.full((28, 2), np.nan)])
    detections = path_detections(paths, 30)
    # The 2-detection track costs 20 - 0.8 * 2 = 18.4 >= 18: only the quirk keeps it.
    assert len(track_dpnms(detections, DpnmsParams(legacy_last_track=False)).track_ids()) == 1
    legacy = track_dpnms(detections, DpnmsParams())
    assert len(legacy.track_ids()) == 2
    assert len(legacy.track(2)[0]) == 2


def test_three_detections_are_the_shortest_track_kept_at_score_one() -> None:
    # 20 - 0.8 * 3 = 17.6 < 18 keeps three detections; with score 0.5 it takes seven.
    three = [np.vstack([line_path((100, 100), (1, 0), 3), np.full((7, 2), np.nan)])]
    assert len(track_dpnms(path_detections(three, 10), DpnmsParams(legacy_last_track=False))) == 3
    half = track_dpnms(path_detections(three, 10, 0.5), DpnmsParams(legacy_last_track=False))
    assert len(half) == 0


@pytest.mark.parametrize(("jump", "expected_tracks"), [(26.0, 1), (27.0, 2)])
def test_a_jump_links_at_26_px_and_breaks_at_27_px(jump: float, expected_tracks: int) -> None:
    path = line_path((200, 200), (0, 0), 20)
    path[10:, 0] += jump
    tracks = track_dpnms(path_detections([path], 20), DpnmsParams(legacy_last_track=False))
    assert len(tracks.track_ids()) == expected_tracks
    assert len(tracks) == 20


@pytest.mark.parametrize("gap", [1, 3])
def test_a_missed_detection_splits_the_track(gap: int) -> None:
    path = line_path((200, 200), (2, 1), 30)
    path[12 : 12 + gap] = np.nan
    tracks = track_dpnms(path_detections([path], 30), DpnmsParams(legacy_last_track=False))
    assert len(tracks.track_ids()) == 2
    spans = sorted(
        (int(frames.min()), int(frames.max()))
        for frames in (tracks.track(track_id)[0] for track_id in tracks.track_ids())
    )
    assert spans == [(0, 11), (12 + gap, 29)]


def test_nms_removes_the_other_target_where_two_heads_overlap() -> None:
    # Two heads crossing: in frames 14-16 their boxes overlap with IoU > 0.5.
    a = line_path((100, 200), (10, 0), 31)
    b = line_path((400, 210), (-10, 0), 31)
    tracks = track_dpnms(path_detections([a, b], 31), DpnmsParams(legacy_last_track=False))
    # A frame where the boxes overlap keeps one detection only.
    close = np.flatnonzero(np.abs(a[:, 0] - b[:, 0]) < 20)
    assert len(close) > 0
    for frame in close:
        assert (tracks.frames == frame).sum() == 1
    without = track_dpnms(
        path_detections([a, b], 31), DpnmsParams(nms=False, legacy_last_track=False)
    )
    assert len(without) == 62


def test_max_tracks_caps_the_number_of_tracks() -> None:
    paths = [line_path((100, 100 + 150 * k), (2, 0), 10) for k in range(4)]
    tracks = track_dpnms(path_detections(paths, 10), DpnmsParams(max_tracks=2))
    assert len(tracks.track_ids()) == 2


def test_no_detections_gives_no_tracks() -> None:
    empty = VideoDetections.from_points(np.zeros(0), np.zeros((0, 2)), 5)
    assert len(track_dpnms(empty)) == 0

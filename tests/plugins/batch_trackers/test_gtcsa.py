"""GTCSA-like: rigid group translation without identity switches, and m != n frames."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.batch_trackers.gtcsa import GtcsaParams, associate_frame, kmeans, track_gtcsa
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections

# A 5-target group 45 px apart and a 2-target group far away: a 30 px step is more than half
# the spacing, so a zero-velocity nearest-neighbour start would be tempted to swap.
BIG = np.array([[300.0, 400], [345, 400], [390, 400], [322, 440], [367, 440]])
SMALL = np.array([[900.0, 300], [945, 300]])


def _video(paths: np.ndarray, seed: int = 0) -> VideoDetections:
    """``(F, T, 2)`` paths, every frame's observations in a shuffled order."""
    random = np.random.default_rng(seed)
    frames, points = [], []
    for frame, positions in enumerate(paths):
        keep = positions[np.isfinite(positions).all(axis=1)]
        for point in keep[random.permutation(len(keep))]:
            frames.append(frame)
            points.append(point)
    return VideoDetections.from_points(np.array(frames), np.array(points), len(paths))


def _truth_of(tracks: Tracks, paths: np.ndarray, track_id: int) -> set[int]:
    """The true targets whose exact positions this track's observed points take."""
    frames, points, observed = tracks.track(track_id)
    owners = set()
    for frame, point in zip(frames[observed], points[observed], strict=True):
        hits = np.flatnonzero(np.all(paths[frame] == point, axis=1))
        owners.update(hits.tolist())
    return owners


@pytest.mark.parametrize("groups", [2, 1])
def test_two_groups_translating_rigidly_keep_every_identity(groups: int) -> None:
    start = np.vstack([BIG, SMALL])
    paths = start[None] + np.arange(20)[:, None, None] * np.array([30.0, 0.0])
    tracks = track_gtcsa(_video(paths), height=1080, params=GtcsaParams(groups=groups))
    assert len(tracks.track_ids()) == len(start)
    for track_id in tracks.track_ids():
        frames, _, observed = tracks.track(track_id)
        assert frames.tolist() == list(range(20)) and observed.all()
        assert len(_truth_of(tracks, paths, int(track_id))) == 1


def test_a_missing_observation_coasts_and_clutter_starts_a_short_track() -> None:
    paths = BIG[None] + np.arange(20)[:, None, None] * np.array([10.0, 5.0])
    observed_paths = paths.copy()
    observed_paths[10, 2] = np.nan  # target 2 is not seen on frame 10
    video = _video(observed_paths)
    clutter = np.array([[10, 700.0, 900.0]])
    table = np.column_stack([video.frames, video.points, video.sizes, video.scores])
    table = np.vstack([table, [[10, 700.0, 900.0, 80.0, 80.0, 1.0]]])
    tracks = track_gtcsa(VideoDetections.from_array(table, 20), height=1080)
    assert len(tracks.track_ids()) == 6
    lengths = sorted(len(tracks.track(int(i))[0]) for i in tracks.track_ids())
    assert lengths == [1, 20, 20, 20, 20, 20]
    for track_id in tracks.track_ids():
        frames, points, observed = tracks.track(int(track_id))
        if len(frames) == 1:
            assert points[0].tolist() == clutter[0, 1:].tolist()
            continue
        owners = _truth_of(tracks, paths, int(track_id))
        assert len(owners) == 1  # no swap
        if owners == {2}:
            assert observed.tolist() == [frame != 10 for frame in range(20)]
            assert np.allclose(points[10], paths[10, 2], atol=1.0)  # coasted on its velocity
        else:
            assert observed.all()


def test_more_observations_than_targets_match_one_to_one() -> None:
    predicted = BIG + 5.0
    points = np.vstack([BIG[::-1] + 30.0, [[800.0, 800.0], [100.0, 100.0]]])
    matched = associate_frame(predicted, points, GtcsaParams(), gate=50.0, join=150.0)
    assert matched.tolist() == [4, 3, 2, 1, 0]


def test_a_target_dies_after_max_miss_frames() -> None:
    paths = np.full((15, 1, 2), np.nan)
    paths[:5, 0] = [[100.0, 100.0]] * 5
    paths[12:, 0] = [[100.0, 100.0]] * 3
    for max_miss, expected in [(3, 2), (8, 1)]:
        tracks = track_gtcsa(_video(paths), height=1080, params=GtcsaParams(max_miss=max_miss))
        assert len(tracks.track_ids()) == expected


def test_kmeans_is_deterministic_and_separates_far_groups() -> None:
    points = np.vstack([BIG, SMALL])
    labels = kmeans(points, 2)
    assert labels.tolist() == kmeans(points, 2).tolist()
    assert len(set(labels[:5].tolist())) == 1 and len(set(labels[5:].tolist())) == 1
    assert labels[0] != labels[5]


def test_one_group_follows_a_smoothly_warped_grid() -> None:
    # A 3 x 4 grid, 40 px apart, moved by 35 px and bent: the spline explains it as one group.
    grid = np.stack(np.meshgrid(np.arange(4) * 40.0, np.arange(3) * 40.0), -1).reshape(-1, 2)
    grid += 300.0
    relative = (grid - grid.mean(axis=0)) / 60.0
    bend = np.column_stack([8 * relative[:, 1] ** 2, 6 * relative[:, 0] * relative[:, 1]])
    order = np.random.default_rng(1).permutation(len(grid))
    observed = (grid + np.array([35.0, 0.0]) + bend)[order]
    matched = associate_frame(grid, observed, GtcsaParams(groups=1), gate=50.0, join=150.0)
    assert (order[matched] == np.arange(len(grid))).all()

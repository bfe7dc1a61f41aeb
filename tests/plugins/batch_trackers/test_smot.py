"""SMOT: the authors' two-target demo, the rank test, the assignment with slack."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.batch_trackers.smot import (
    SmotParams,
    Tracklet,
    generalised_assignment,
    initial_tracklets,
    join,
    track_smot,
    trajectory_rank,
)
from trackfw_plugins.batch_trackers.tracks import VideoDetections


def _demo(noise: float = 0.2, seed: int = 0) -> tuple[VideoDetections, np.ndarray]:
    """The authors' demo: two targets on frames 1-20 and 25-35 (a 4-frame gap), shuffled."""
    random = np.random.default_rng(seed)
    t = np.arange(1, 36, dtype=float)
    paths = np.stack(
        [np.column_stack([5 * t + 33, 2 * t + 20]), np.column_stack([9 * t + 2, 4 * t - 4])], axis=1
    )
    frames, points = [], []
    for index in range(35):
        if 20 <= index <= 23:  # frames 21-24 of the demo, 0-based here
            continue
        for target in random.permutation(2):
            frames.append(index)
            points.append(paths[index, target] + random.normal(0, noise, 2))
    return VideoDetections.from_points(np.array(frames), np.array(points), 35), paths


def test_the_demo_gives_two_tracks_spanning_every_frame() -> None:
    detections, paths = _demo()
    tracks = track_smot(detections, SmotParams(horizon=20, eta_max=2.0, min_similarity=0.01))
    assert len(tracks.track_ids()) == 2
    for track_id in tracks.track_ids():
        frames, points, observed = tracks.track(int(track_id))
        assert frames.tolist() == list(range(35))
        assert observed.tolist() == [not 20 <= frame <= 23 for frame in range(35)]
        # One target throughout, the gap filled on the line between its ends.
        target = int(np.argmin(np.abs(paths[0] - points[0]).sum(axis=1)))
        assert np.abs(points - paths[:, target]).max() < 2.0


def test_rank_of_a_line_is_two_and_two_velocities_raise_it() -> None:
    params = SmotParams(eta_max=0.01)
    t = np.arange(12, dtype=float)
    line = np.vstack([3 * t + 10, -2 * t + 50])
    assert trajectory_rank(line, np.ones(12, dtype=bool), params) == 2
    # The same line with frames 5-7 missing is still rank 2: the gap is free to fill.
    mask = np.ones(12, dtype=bool)
    mask[5:8] = False
    assert trajectory_rank(line, mask, params) == 2
    bent = line.copy()
    bent[:, 6:] = line[:, 5:6] + np.vstack([7.0, 4.0]) * np.arange(1, 7)
    assert trajectory_rank(bent, np.ones(12, dtype=bool), params) > 2


def test_same_dynamics_join_with_similarity_one() -> None:
    # The rank test of the brief: two pieces of one line, joint rank 2 -> S = 2 / 2 - 1 = 1.
    params = SmotParams(eta_max=0.01)
    t = np.arange(20, dtype=float)
    line = np.column_stack([4 * t + 5, 1.5 * t])
    first = Tracklet(0, line[:8], np.ones(8, dtype=bool))
    second = Tracklet(11, line[11:], np.ones(9, dtype=bool))
    joined = join(first, second)
    assert joined.omega.sum() == 17 and np.allclose(joined.points, line)
    rank = trajectory_rank(joined.points.T, joined.omega, params)
    assert rank == 2
    other = np.column_stack([-6 * t + 300, 3 * t + 10])
    mixed = join(first, Tracklet(11, other[11:], np.ones(9, dtype=bool)))
    assert trajectory_rank(mixed.points.T, mixed.omega, params) > 2


def test_assignment_links_only_above_the_slack() -> None:
    similarity = np.array([[-np.inf, 0.5, 0.005], [-np.inf, -np.inf, 1.0], [-np.inf] * 3])
    assert generalised_assignment(similarity, 0.01).tolist() == [1, 2, -1]
    assert generalised_assignment(similarity, 0.8).tolist() == [-1, 2, -1]


def test_ambiguous_links_do_not_form_tracklets() -> None:
    # Two detections 4 px and 8 px from a frame-0 detection: the ratio test (8 < 3 * 4) fails.
    points = np.array(
        [[100.0, 100.0], [104.0, 100.0], [108.0, 100.0], [300.0, 300.0], [301.0, 300.0]]
    )
    detections = VideoDetections.from_points(np.array([0, 1, 1, 0, 1]), points, 2)
    tracklets = initial_tracklets(detections, 3.0)
    lengths = sorted(len(piece.points) for piece in tracklets)
    assert lengths == [1, 1, 1, 2]


def test_a_gap_of_half_the_mean_tracklet_length_is_not_stitched() -> None:
    # A target seen 12 frames, unseen, seen 12 frames; a far static one keeps the ratio test
    # defined (it needs two detections a frame). max_gap is half the mean tracklet length
    # (of the tracklets cropped to the window).
    t = np.arange(40, dtype=float)
    path = np.column_stack([6 * t + 50, 3 * t + 40])
    for gap, expected in ((2, 1), (12, 2)):
        frames = [*range(12), *range(12 + gap, 24 + gap)]
        still = list(range(24 + gap))
        detections = VideoDetections.from_points(
            np.array(frames + still),
            np.vstack([path[frames], np.tile([900.0, 600.0], (len(still), 1))]),
            40,
        )
        tracks = track_smot(detections, SmotParams(horizon=20))
        moving = [i for i in tracks.track_ids() if tracks.track(int(i))[1][0, 0] < 800]
        # 2 frames are well under half a 12-frame tracklet, 12 frames are not.
        assert len(moving) == expected, gap

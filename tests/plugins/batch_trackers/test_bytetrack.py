"""ByteTrack: two-stage association by score, the lost buffer in seconds, unconfirmed births."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.batch_trackers.bytetrack import ByteTrackParams, track_bytetrack
from trackfw_plugins.batch_trackers.tracks import VideoDetections


def _video(paths: list[np.ndarray], scores: list[np.ndarray]) -> VideoDetections:
    """Detections from ``(F, 2)`` paths with ``(F,)`` scores; NaN rows are missed detections."""
    frames, points, values = [], [], []
    for path, score in zip(paths, scores, strict=True):
        for frame, (point, value) in enumerate(zip(path, score, strict=True)):
            if np.isfinite(point).all():
                frames.append(frame)
                points.append(point)
                values.append(value)
    n_frames = max(len(path) for path in paths)
    return VideoDetections.from_points(
        np.array(frames), np.array(points), n_frames, np.array(values)
    )


def _line(start: tuple[float, float], step: tuple[float, float], n_frames: int) -> np.ndarray:
    return np.array(start, dtype=float) + np.arange(n_frames)[:, None] * np.array(step, dtype=float)


def test_parallel_targets_keep_one_identity_each() -> None:
    paths = [_line((100, 100), (6, 2), 40), _line((100, 260), (6, -1), 40)]
    tracks = track_bytetrack(_video(paths, [np.ones(40), np.ones(40)]), fps=25)
    assert tracks.track_ids().tolist() == [1, 2]
    for track_id, path in zip((1, 2), paths, strict=True):
        frames, points, observed = tracks.track(track_id)
        assert frames.tolist() == list(range(40)) and observed.all()
        assert np.allclose(points, path)


def test_low_score_detections_continue_a_track_in_the_second_stage() -> None:
    path = _line((300, 300), (4, 0), 30)
    scores = np.ones(30)
    scores[10:16] = 0.3  # low: never starts a track, but extends a tracked one
    video = _video([path], [scores])
    tracks = track_bytetrack(video, fps=25)
    assert tracks.track_ids().tolist() == [1]
    assert tracks.track(1)[0].tolist() == list(range(30))
    # Without the second stage (low detections dropped) those frames are missing.
    strict = track_bytetrack(video, fps=25, params=ByteTrackParams(low_threshold=0.5))
    assert sorted(set(range(30)) - set(strict.frames.tolist())) == list(range(10, 16))


def test_low_score_clutter_starts_no_track() -> None:
    clutter = _line((800, 500), (0, 0), 20)
    tracks = track_bytetrack(_video([clutter], [np.full(20, 0.4)]), fps=25)
    assert len(tracks) == 0


def test_a_one_frame_high_detection_is_never_confirmed() -> None:
    target = _line((100, 100), (3, 0), 20)
    blip = np.full((20, 2), np.nan)
    blip[8] = (700, 400)
    tracks = track_bytetrack(_video([target, blip], [np.ones(20), np.ones(20)]), fps=25)
    assert tracks.track_ids().tolist() == [1]
    assert not (tracks.frames == 8).sum() > 1


@pytest.mark.parametrize(
    ("buffer_s", "fps", "same_identity"),
    [(1.0, 25.0, True), (0.5, 25.0, False), (1.0, 10.0, False), (2.0, 10.0, True)],
)
def test_the_lost_buffer_is_in_seconds(buffer_s: float, fps: float, same_identity: bool) -> None:
    path = _line((200, 200), (0, 0), 60)
    path[20:38] = np.nan  # 18 frames unseen
    params = ByteTrackParams(lost_buffer_s=buffer_s)
    tracks = track_bytetrack(_video([path], [np.ones(60)]), fps=fps, params=params)
    # A new identity is output from its confirmation: the re-birth frame 38 is not reported.
    assert len(tracks) == (42 if same_identity else 41)
    assert len(tracks.track_ids()) == (1 if same_identity else 2)


@pytest.mark.parametrize("report_birth", [False, True])
def test_a_track_is_output_from_its_confirmation_unless_report_birth(report_birth: bool) -> None:
    first = _line((100, 100), (3, 0), 30)
    late = _line((400, 300), (0, 3), 30)
    late[:10] = np.nan  # born on frame 10, confirmed on frame 11
    video = _video([first, late], [np.ones(30), np.ones(30)])
    tracks = track_bytetrack(video, fps=25, params=ByteTrackParams(report_birth=report_birth))
    assert tracks.track_ids().tolist() == [1, 2]
    # Tracks born on the first frame with detections are confirmed at once (the reference's rule).
    assert tracks.track(1)[0].tolist() == list(range(30))
    assert tracks.track(2)[0].tolist() == list(range(10 if report_birth else 11, 30))


def test_first_frame_tracks_wait_for_confirmation_without_confirm_first_frame() -> None:
    path = _line((100, 100), (3, 0), 20)
    params = ByteTrackParams(confirm_first_frame=False)
    tracks = track_bytetrack(_video([path], [np.ones(20)]), fps=25, params=params)
    assert tracks.track(1)[0].tolist() == list(range(1, 20))

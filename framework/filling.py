"""Short absences of a target filled in after the video (``engine.fill_missing_s``, ``engine.fill_after_b_s``).

A detector misses a person for a few frames when someone walks in front of them; the tracker
then stops reporting the target (docs/algorithms/segment-tracker.md#target-lifecycle) and takes
it up again a moment later on its next detection. Offline, both ends of such an absence are
known, so the frames between can be reported on the straight line from one end to the other, as
ByteTrack and BoT-SORT interpolate their tracks. Only absences inside one segment are filled: on
either side of an info-less interval the camera points elsewhere, and a straight line between
the two would cross the view for nothing.

The first frames of a segment are an absence with one end (``engine.fill_after_b_s``): a target
the tracker takes up a few frames after b (re-acquired once the detector finds it again, or once
its look is clear) was there at b as well. When its first report in the segment comes within
that limit after b, it is reported from b on, on the straight line fitted to its reports of the
same length of time from its first one, carried back (held at its first point when it has only
one, unless ``engine.fill_after_b_min_reports`` asks for more: a single report, such as a lost
target re-found on someone else on a video's last frame, is little evidence that it was there
at b). The camera is often still settling just after b and moves the image by several pixels a
frame; the place where the tracker kept the target during the interval (a lost target's expected
place) would be a guess. Nothing is carried forward into an interval: a target that stopped
being reported just before a may have left.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from trackfw.arrays import BoolArray, FloatArray


def fill_missing(
    frames: Sequence[int],
    segments: Sequence[int],
    positions: Sequence[FloatArray],
    reported: Sequence[BoolArray],
    max_frames: int,
    after_b_frames: int = 0,
    after_b_min_reports: int = 1,
) -> tuple[list[FloatArray], list[BoolArray]]:
    """Report each target on the frames of its short absences.

    Args:
        frames: ``(F,)`` increasing frame indices of the frames the loop recorded.
        segments: ``(F,)`` the segment (counted from 0) each of those frames belongs to.
        positions: per frame, ``(K, 2)`` the position of every target.
        reported: per frame, ``(K,)`` True where the target is reported.
        max_frames: longest absence filled between two reports, in frames of the video; 0
            fills none.
        after_b_frames: longest absence filled at the start of a segment that follows an
            interval, in frames of the video; 0 fills none.
        after_b_min_reports: fewest reports, within ``after_b_frames`` of its first one, a
            target needs for that fill.

    Returns:
        New positions and reported flags per frame: an absence of at most ``max_frames`` video
        frames between two reported frames of one segment is reported, each frame at the point
        that divides the two ends' points in proportion to the frames between; a target first
        reported at most ``after_b_frames`` video frames after the first frame of a later segment
        is reported from that first frame on, on the line fitted to its reports of the
        ``after_b_frames`` frames from its first one, carried back.

    >>> import numpy as np
    >>> points = [np.array([[0.0, 0.0]]), np.array([[9.0, 9.0]]), np.array([[4.0, 8.0]])]
    >>> shown = [np.array([True]), np.array([False]), np.array([True])]
    >>> filled, flags = fill_missing([10, 11, 12], [0, 0, 0], points, shown, 1)
    >>> filled[1].tolist(), flags[1].tolist()
    ([[2.0, 4.0]], [True])
    >>> fill_missing([10, 11, 12], [0, 0, 1], points, shown, 1)[1][1].tolist()
    [False]

    After an interval (frames 11-19 not recorded), a target first reported one frame after b:

    >>> points = [np.array([[0.0, 0.0]]), np.array([[50.0, 50.0]]), np.array([[7.0, 3.0]])]
    >>> shown = [np.array([True]), np.array([False]), np.array([True])]
    >>> filled, flags = fill_missing([10, 20, 21], [0, 1, 1], points, shown, 1, 1)
    >>> filled[1].tolist(), flags[1].tolist()
    ([[7.0, 3.0]], [True])

    With two reports the line through them is carried back:

    >>> points.append(np.array([[9.0, 3.0]]))
    >>> shown.append(np.array([True]))
    >>> np.round(fill_missing([10, 20, 21, 22], [0, 1, 1, 1], points, shown, 1, 1)[0][1], 6).tolist()
    [[5.0, 3.0]]

    Asking for two reports, a lone first report is not carried back:

    >>> fill_missing([10, 20, 21], [0, 1, 1], points[:3], shown[:3], 1, 1, 2)[1][1].tolist()
    [False]
    """
    filled = [np.array(p, dtype=np.float64, copy=True) for p in positions]
    flags = [np.array(r, dtype=bool, copy=True) for r in reported]
    if (max_frames <= 0 and after_b_frames <= 0) or not frames:
        return filled, flags
    table = np.stack([np.asarray(r, dtype=bool) for r in reported])  # (F, K)
    frame_index = np.asarray(frames, dtype=np.int64)
    segment_index = np.asarray(segments, dtype=np.int64)
    for target in range(table.shape[1]):
        rows = np.flatnonzero(table[:, target])
        for before, after in pairwise(rows.tolist()):
            absent = int(frame_index[after] - frame_index[before] - 1)
            if absent > max_frames or segment_index[before] != segment_index[after]:
                continue
            start = positions[before][target]
            end = positions[after][target]
            span = float(frame_index[after] - frame_index[before])
            for row in range(before + 1, after):
                share = float(frame_index[row] - frame_index[before]) / span
                filled[row][target] = (1.0 - share) * start + share * end
                flags[row][target] = True
    if after_b_frames > 0:
        _fill_segment_starts(
            frame_index,
            segment_index,
            positions,
            table,
            after_b_frames,
            after_b_min_reports,
            filled,
            flags,
        )
    return filled, flags


def _fill_segment_starts(
    frame_index: np.ndarray,
    segment_index: np.ndarray,
    positions: Sequence[FloatArray],
    table: np.ndarray,
    after_b_frames: int,
    min_reports: int,
    filled: list[FloatArray],
    flags: list[BoolArray],
) -> None:
    """Report from b on each target first reported at most ``after_b_frames`` after the first
    frame b of a segment that follows an interval, on the line fitted to its reports of the
    ``after_b_frames`` frames from its first, when those reports number at least
    ``min_reports`` (``table``: ``(F, K)`` reported flags before any filling; ``filled`` and
    ``flags`` are updated)."""
    starts = np.flatnonzero(np.diff(segment_index) != 0) + 1
    for first in starts.tolist():
        rows = np.flatnonzero(segment_index == segment_index[first])
        for target in np.flatnonzero(~table[first]).tolist():
            shown = rows[table[rows, target]]
            if len(shown) == 0 or frame_index[shown[0]] - frame_index[first] > after_b_frames:
                continue
            early = shown[frame_index[shown] - frame_index[shown[0]] <= after_b_frames]
            if len(early) < min_reports:
                continue
            times = frame_index[early].astype(np.float64)
            points = np.stack([positions[row][target] for row in early.tolist()])
            if len(early) >= 2:
                slope, intercept = np.polyfit(times, points, 1)
            else:
                slope, intercept = np.zeros(2), points[0]
            for row in range(first, int(shown[0])):
                filled[row][target] = intercept + slope * float(frame_index[row])
                flags[row][target] = True


__all__ = ["fill_missing"]

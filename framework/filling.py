"""Short absences of a target inside a segment, filled in after the video (``engine.fill_missing_s``).

A detector misses a person for a few frames when someone walks in front of them; the tracker
then stops reporting the target (docs/algorithms/segment-tracker.md#target-lifecycle) and takes
it up again a moment later on its next detection. Offline, both ends of such an absence are
known, so the frames between can be reported on the straight line from one end to the other, as
ByteTrack and BoT-SORT interpolate their tracks. Only absences inside one segment are filled: on
either side of an info-less interval the camera points elsewhere, and a straight line between
the two would cross the view for nothing.
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
) -> tuple[list[FloatArray], list[BoolArray]]:
    """Report each target on the frames of its short absences, interpolated linearly.

    Args:
        frames: ``(F,)`` increasing frame indices of the frames the loop recorded.
        segments: ``(F,)`` the segment (counted from 0) each of those frames belongs to.
        positions: per frame, ``(K, 2)`` the position of every target.
        reported: per frame, ``(K,)`` True where the target is reported.
        max_frames: longest absence filled, in frames of the video; 0 fills nothing.

    Returns:
        New positions and reported flags per frame: an absence of at most ``max_frames`` video
        frames between two reported frames of one segment is reported, each frame at the point
        that divides the two ends' points in proportion to the frames between.

    >>> import numpy as np
    >>> points = [np.array([[0.0, 0.0]]), np.array([[9.0, 9.0]]), np.array([[4.0, 8.0]])]
    >>> shown = [np.array([True]), np.array([False]), np.array([True])]
    >>> filled, flags = fill_missing([10, 11, 12], [0, 0, 0], points, shown, 1)
    >>> filled[1].tolist(), flags[1].tolist()
    ([[2.0, 4.0]], [True])
    >>> fill_missing([10, 11, 12], [0, 0, 1], points, shown, 1)[1][1].tolist()
    [False]
    """
    filled = [np.array(p, dtype=np.float64, copy=True) for p in positions]
    flags = [np.array(r, dtype=bool, copy=True) for r in reported]
    if max_frames <= 0 or not frames:
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
    return filled, flags


__all__ = ["fill_missing"]

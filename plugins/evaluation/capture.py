""" "Captured by a non-target": how often a reported target sits on a bystander.

The failure the people-of-interest setting fears most is a target that takes over a bystander's
detection and follows the wrong person. CLEAR MOT counts such a point as a false positive and a
miss, like any other error; this diagnostic names it. On each frame:

* the bystanders are the heads of heads.csv that are no target's head: a head whose centre lies
  within ``ratio`` of its size of some ground-truth target point belongs to that target;
* a reported point is *captured* when it is farther than ``distance_px`` from every target point
  and within ``ratio`` of a bystander head's size of that head's centre.

Only datasets with heads.csv (every visible head, targets and bystanders) can be scored.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from trackfw.arrays import BoolArray, FloatArray
from trackfw_plugins.evaluation.clear_mot import FrameObservations
from trackfw_plugins.maths.confusion import PooledCounts, ratio
from trackfw_plugins.maths.head_matching import MATCH_RATIO


@dataclass
class CaptureCounts(PooledCounts):
    """Reported points and those of them on a bystander, pooled with ``+``.

    >>> total = CaptureCounts(reported=10, captured=1) + CaptureCounts(reported=10, captured=3)
    >>> total.reported, total.captured, total.share
    (20, 4, 0.2)
    """

    reported: int = 0
    captured: int = 0

    @property
    def share(self) -> float:
        """Captured / reported; NaN when nothing was reported."""
        return ratio(self.captured, self.reported)


def bystander_heads(
    heads: FloatArray, targets: FloatArray, match_ratio: float = MATCH_RATIO
) -> FloatArray:
    """The ``(B, 3)`` rows of ``(M, 3)`` ``heads`` that are no target's head: no ground-truth
    target point of ``(N, 2)`` ``targets`` lies within ``match_ratio`` of the head's size.

    >>> import numpy as np
    >>> heads = np.array([[0.0, 0.0, 40.0], [200.0, 0.0, 40.0]])
    >>> bystander_heads(heads, np.array([[5.0, 0.0]])).tolist()
    [[200.0, 0.0, 40.0]]
    """
    if len(targets) == 0 or len(heads) == 0:
        return heads
    to_targets = np.linalg.norm(heads[None, :, :2] - targets[:, None, :], axis=2)
    return heads[~(to_targets <= match_ratio * heads[None, :, 2]).any(axis=0)]


def on_heads(points: FloatArray, heads: FloatArray, match_ratio: float = MATCH_RATIO) -> BoolArray:
    """``(K,)``: whether each of ``(K, 2)`` ``points`` lies on one of ``(M, 3)`` ``heads``
    (within ``match_ratio`` of that head's size of its centre).

    >>> import numpy as np
    >>> on_heads(np.array([[198.0, 3.0], [400.0, 0.0]]), np.array([[200.0, 0.0, 40.0]])).tolist()
    [True, False]
    """
    if len(points) == 0 or len(heads) == 0:
        return np.zeros(len(points), dtype=bool)
    distance = np.linalg.norm(points[:, None, :] - heads[None, :, :2], axis=2)
    return np.asarray((distance <= match_ratio * heads[None, :, 2]).any(axis=1), dtype=bool)


def frame_captured(
    reported: FloatArray,
    targets: FloatArray,
    heads: FloatArray,
    distance_px: float,
    match_ratio: float = MATCH_RATIO,
    target_distances: FloatArray | None = None,
) -> int:
    """How many reported points of one frame sit on a bystander.

    Args:
        reported: ``(K, 2)`` points the run reported.
        targets: ``(N, 2)`` ground-truth target points of the frame.
        heads: ``(M, 3)`` every visible head ``(x, y, head_size)``.
        distance_px: a reported point this close to a target point is that target's.
        match_ratio: a point within this share of a head's size of its centre is on that head.
        target_distances: ``(N, K)`` target-to-reported distances when already computed.

    >>> import numpy as np
    >>> heads = np.array([[0.0, 0.0, 40.0], [200.0, 0.0, 40.0]])
    >>> frame_captured(np.array([[5.0, 0.0], [198.0, 3.0], [400.0, 0.0]]),
    ...                np.array([[0.0, 0.0]]), heads, distance_px=40.0)
    1
    """
    if len(reported) == 0 or len(heads) == 0:
        return 0
    bystanders = bystander_heads(heads, targets, match_ratio)
    if len(targets):
        if target_distances is None:
            target_distances = np.linalg.norm(targets[:, None, :] - reported[None, :, :], axis=2)
        reported = reported[~(target_distances <= distance_px).any(axis=0)]
    return int(on_heads(reported, bystanders, match_ratio).sum())


def capture_counts(
    sequence: Sequence[FrameObservations],
    heads: Mapping[int, FloatArray],
    distance_px: float,
    match_ratio: float = MATCH_RATIO,
) -> CaptureCounts:
    """Counts over a video.

    Args:
        sequence: the evaluated frames (points), whose target-to-hypothesis distances the CLEAR
            MOT pass has already computed.
        heads: frame -> ``(M, 3)`` heads.csv rows ``(x, y, head_size)``.
        distance_px: the evaluation's match threshold.
        match_ratio: the head-matching ratio of the detection evaluation.
    """
    reported = captured = 0
    for observation in sequence:
        reported += len(observation.hyp_ids)
        frame_heads = heads.get(observation.frame)
        if frame_heads is not None:
            captured += frame_captured(
                observation.hyp_positions[:, :2],
                observation.gt_positions[:, :2],
                frame_heads,
                distance_px,
                match_ratio,
                observation.distances("point"),
            )
    return CaptureCounts(reported=reported, captured=captured)

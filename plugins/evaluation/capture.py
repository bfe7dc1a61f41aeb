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
from dataclasses import dataclass, fields
from typing import Self

import numpy as np

from trackfw.arrays import FloatArray
from trackfw_plugins.maths.head_matching import MATCH_RATIO


@dataclass
class CaptureCounts:
    """Reported points and those of them on a bystander, pooled with ``+``.

    >>> total = CaptureCounts(reported=10, captured=1) + CaptureCounts(reported=10, captured=3)
    >>> total.reported, total.captured, total.share
    (20, 4, 0.2)
    """

    reported: int = 0
    captured: int = 0

    def __add__(self, other: Self) -> Self:
        """Pool two videos' counts."""
        return type(self)(
            **{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)}
        )

    @property
    def share(self) -> float:
        """Captured / reported; NaN when nothing was reported."""
        return self.captured / self.reported if self.reported else float("nan")


def _points(positions: Mapping[int, Sequence[float]]) -> FloatArray:
    if not positions:
        return np.zeros((0, 2))
    return np.asarray([position[:2] for position in positions.values()], dtype=np.float64)


def frame_captured(
    reported: FloatArray,
    targets: FloatArray,
    heads: FloatArray,
    distance_px: float,
    ratio: float = MATCH_RATIO,
) -> int:
    """How many reported points of one frame sit on a bystander.

    Args:
        reported: ``(K, 2)`` points the run reported.
        targets: ``(N, 2)`` ground-truth target points of the frame.
        heads: ``(M, 3)`` every visible head ``(x, y, head_size)``.
        distance_px: a reported point this close to a target point is that target's.
        ratio: a point within this share of a head's size of its centre is on that head.

    >>> import numpy as np
    >>> heads = np.array([[0.0, 0.0, 40.0], [200.0, 0.0, 40.0]])
    >>> frame_captured(np.array([[5.0, 0.0], [198.0, 3.0], [400.0, 0.0]]),
    ...                np.array([[0.0, 0.0]]), heads, distance_px=40.0)
    1
    """
    if len(reported) == 0 or len(heads) == 0:
        return 0
    sizes = heads[:, 2]
    if len(targets):
        to_targets = np.linalg.norm(heads[None, :, :2] - targets[:, None, :], axis=2)
        bystanders = heads[~(to_targets <= ratio * sizes[None, :]).any(axis=0)]
        near_target = (
            np.linalg.norm(reported[:, None, :] - targets[None, :, :], axis=2) <= distance_px
        ).any(axis=1)
        reported = reported[~near_target]
    else:
        bystanders = heads
    if len(reported) == 0 or len(bystanders) == 0:
        return 0
    to_bystanders = np.linalg.norm(reported[:, None, :] - bystanders[None, :, :2], axis=2)
    return int((to_bystanders <= ratio * bystanders[None, :, 2]).any(axis=1).sum())


def capture_counts(
    hypotheses: Mapping[int, Mapping[int, Sequence[float]]],
    targets: Mapping[int, Mapping[int, Sequence[float]]],
    heads: Mapping[int, FloatArray],
    distance_px: float,
    ratio: float = MATCH_RATIO,
) -> CaptureCounts:
    """Counts over a video.

    Args:
        hypotheses: frame -> ``{track id: (x, y, ...)}`` as the run reported them.
        targets: frame -> ``{target id: (x, y)}``, the evaluated ground truth.
        heads: frame -> ``(M, 3)`` heads.csv rows ``(x, y, head_size)``.
        distance_px: the evaluation's match threshold.
        ratio: the head-matching ratio of the detection evaluation.
    """
    counts = CaptureCounts()
    for frame, positions in hypotheses.items():
        reported = _points(positions)
        frame_heads = heads.get(frame)
        captured = 0
        if frame_heads is not None:
            captured = frame_captured(
                reported, _points(targets.get(frame, {})), frame_heads, distance_px, ratio
            )
        counts = counts + CaptureCounts(reported=len(reported), captured=captured)
    return counts

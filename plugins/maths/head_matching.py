"""Detected head points against annotated heads: the one rule behind detection precision/recall.

A detection matches a head when it lies within ``ratio × head_size`` of the head's centre
[OURS: ``ratio`` = 0.5, half a head, by default]. Detections and heads are paired one-to-one by
the Hungarian method on the distance divided by the head size, so one detection never counts for
two heads and a large head does not lose its detection to a small neighbour. The rule scales with
the picture: at 1080p a head of about 80 px gives 40 px, the CLEAR MOT distance, while a distant
head of 20 px needs its detection within 10 px. Both ``trackfw eval --detections`` and the
detector training/benchmarks (``detectors.training.evaluate``) score with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.assignment import distance_matrix, hungarian

#: A detection matches a head when closer than this share of the head size.
MATCH_RATIO = 0.5


@dataclass(frozen=True)
class HeadMatches:
    """The one-to-one pairs of one frame.

    Attributes:
        heads: ``(K,)`` index of each matched head.
        detections: ``(K,)`` index of the detection matched to it.
        distances: ``(K,)`` their distance in pixels.
        n_heads: heads on the frame.
        n_detections: detections on the frame.
    """

    heads: IntArray
    detections: IntArray
    distances: FloatArray
    n_heads: int
    n_detections: int

    @property
    def n_matched(self) -> int:
        """Matched pairs (true positives)."""
        return len(self.heads)


def match_heads(points: ArrayLike, heads: ArrayLike, ratio: float = MATCH_RATIO) -> HeadMatches:
    """Pair detected points with heads within ``ratio`` head sizes.

    Args:
        points: ``(N, 2)`` detected head points ``(x, y)``.
        heads: ``(M, 3)`` annotated heads ``(x, y, head_size)``.
        ratio: the largest distance of a match, as a share of the head's size.

    >>> heads = np.array([[10.0, 10.0, 20.0], [50.0, 10.0, 20.0]])
    >>> matches = match_heads(np.array([[12.0, 10.0], [13.0, 11.0], [90.0, 10.0]]), heads)
    >>> matches.n_matched, matches.heads.tolist(), matches.detections.tolist()
    (1, [0], [0])
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    heads = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0 or len(heads) == 0:
        empty = np.zeros(0, dtype=np.int64)
        return HeadMatches(empty, empty, np.zeros(0), len(heads), len(points))
    distances = distance_matrix(heads[:, :2], points)
    relative = distances / np.maximum(heads[:, 2:3], 1e-9)
    assignment = hungarian(relative, gate=ratio)
    matched = np.flatnonzero(assignment >= 0)
    return HeadMatches(
        heads=matched.astype(np.int64),
        detections=assignment[matched].astype(np.int64),
        distances=distances[matched, assignment[matched]],
        n_heads=len(heads),
        n_detections=len(points),
    )

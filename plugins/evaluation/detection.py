"""Head-point detection precision and recall.

On each frame the detected points are matched one-to-one to the ground-truth heads by the
project's one detection rule (:func:`trackfw_plugins.maths.head_matching.match_heads`): within
half a head size of the head's centre by default, paired by a Hungarian assignment on the distance
divided by the head size. Matched pairs are true positives, unmatched detections false positives,
unmatched heads false negatives.
"""

from __future__ import annotations

from dataclasses import dataclass

from trackfw.arrays import FloatArray
from trackfw_plugins.maths.confusion import ConfusionCounts, ratio
from trackfw_plugins.maths.head_matching import MATCH_RATIO, match_heads


@dataclass
class DetectionCounts(ConfusionCounts):
    """Detection counts over frames (pool with ``+``)."""

    distance_sum: float = 0.0

    @property
    def mean_distance(self) -> float:
        """Mean distance of the matched pairs in pixels."""
        return ratio(self.distance_sum, self.tp)


def frame_detection_counts(
    detections: FloatArray, heads: FloatArray, ratio: float = MATCH_RATIO
) -> DetectionCounts:
    """Counts of one frame.

    Args:
        detections: ``(K, 2)`` detected head points.
        heads: ``(M, 3)`` ground-truth heads ``(x, y, head_size)``.
        ratio: the largest distance of a true positive, as a share of the head's size.

    >>> import numpy as np
    >>> counts = frame_detection_counts(np.array([[0.0, 0.0], [500.0, 0.0]]), np.array([[3.0, 4.0, 80.0]]))
    >>> counts.tp, counts.fp, counts.fn, counts.distance_sum
    (1, 1, 0, 5.0)
    """
    matches = match_heads(detections, heads, ratio)
    return DetectionCounts(
        tp=matches.n_matched,
        fp=matches.n_detections - matches.n_matched,
        fn=matches.n_heads - matches.n_matched,
        distance_sum=float(matches.distances.sum()),
    )

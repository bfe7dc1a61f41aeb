"""Head-point detection precision and recall.

On each frame the detected points are matched one-to-one to the ground-truth heads by a Hungarian
assignment on Euclidean distance, forbidding pairs farther than ``max_distance_px`` [OURS: the
CLEAR MOT threshold, 40 px, by default]. Matched pairs are true positives, unmatched detections
false positives, unmatched heads false negatives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackfw.arrays import FloatArray
from trackfw_plugins.evaluation.counts import ConfusionCounts
from trackfw_plugins.maths.assignment import distance_matrix, hungarian


@dataclass
class DetectionCounts(ConfusionCounts):
    """Detection counts over frames (pool with ``+``)."""

    distance_sum: float = 0.0

    @property
    def mean_distance(self) -> float:
        """Mean distance of the matched pairs in pixels."""
        return self.distance_sum / self.tp if self.tp else float("nan")


def frame_detection_counts(
    detections: FloatArray, heads: FloatArray, max_distance_px: float = 40.0
) -> DetectionCounts:
    """Counts of one frame.

    Args:
        detections: ``(K, 2)`` detected head points.
        heads: ``(M, 2)`` or ``(M, 3)`` ground-truth heads (x, y[, size]); only x, y are used.
        max_distance_px: the largest distance of a true positive.

    >>> counts = frame_detection_counts(np.array([[0.0, 0.0], [500.0, 0.0]]), np.array([[3.0, 4.0, 80.0]]))
    >>> counts.tp, counts.fp, counts.fn, counts.distance_sum
    (1, 1, 0, 5.0)
    """
    detections = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
    heads = np.asarray(heads, dtype=np.float64)
    head_points = heads.reshape(len(heads), -1)[:, :2] if heads.size else np.zeros((0, 2))
    if len(detections) == 0 or len(head_points) == 0:
        return DetectionCounts(tp=0, fp=len(detections), fn=len(head_points))
    distances = distance_matrix(head_points, detections)
    assignment = hungarian(distances, gate=max_distance_px)
    matched = assignment >= 0
    n_matched = int(matched.sum())
    distance_sum = float(distances[np.flatnonzero(matched), assignment[matched]].sum())
    return DetectionCounts(
        tp=n_matched,
        fp=len(detections) - n_matched,
        fn=len(head_points) - n_matched,
        distance_sum=distance_sum,
    )

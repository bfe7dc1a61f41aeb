"""Frame-level evaluation of the info-less classifier: precision, recall, F1, misclassified frames.

The positive class is "info-less". A frame is a true positive when the classifier called it
info-less and it lies strictly inside a ground-truth interval (frames ``a+1 .. b-1``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from trackfw.arrays import BoolArray, IntArray
from trackfw_plugins.maths.confusion import LabelCounts


@dataclass
class InfolessCounts(LabelCounts):
    """Confusion counts of the info-less label over frames (pool with ``+``).

    Attributes:
        tp: info-less frames called info-less.
        fp: informative frames called info-less.
        fn: info-less frames called informative.
        tn: informative frames called informative.
    """


def infoless_truth(intervals: Iterable[tuple[int, int]], frames: IntArray) -> BoolArray:
    """``(F,)`` True where a frame lies strictly inside one of the ``(a, b)`` intervals.

    >>> infoless_truth([(2, 5)], np.arange(7)).astype(int).tolist()
    [0, 0, 0, 1, 1, 0, 0]
    """
    frames = np.asarray(frames, dtype=np.int64)
    truth = np.zeros(len(frames), dtype=bool)
    for a, b in intervals:
        truth |= (frames > a) & (frames < b)
    return truth


def infoless_counts(predicted: BoolArray, truth: BoolArray) -> InfolessCounts:
    """Confusion counts of ``(F,)`` predicted labels against ``(F,)`` true labels.

    >>> counts = infoless_counts(np.array([1, 1, 0, 0], bool), np.array([1, 0, 1, 0], bool))
    >>> counts.tp, counts.fp, counts.fn, counts.tn, counts.f1
    (1, 1, 1, 1, 0.5)
    """
    return InfolessCounts.of(predicted, truth)

"""Counts of a decision against the truth, pooled with ``+``: precision, recall and F1.

The one place these rates are computed: the evaluation's detection, info-less and identity
scores and the classifier training's frame scores all build on these counts. A rate whose
denominator is zero is NaN (nothing to measure), never 0 or 1.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Self

import numpy as np

from trackfw.arrays import BoolArray


def ratio(part: float, whole: float) -> float:
    """``part / whole``; NaN when ``whole`` is 0.

    >>> ratio(3, 4), ratio(0, 0)
    (0.75, nan)
    """
    return part / whole if whole else float("nan")


@dataclass
class PooledCounts:
    """Counts that pool field by field with ``+`` (frames, videos or sequences are distinct)."""

    def __add__(self, other: Self) -> Self:
        """Pool two count sets of the same kind."""
        return type(self)(
            **{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)}
        )


@dataclass
class ConfusionCounts(PooledCounts):
    """True/false positives and false negatives.

    >>> total = ConfusionCounts(tp=3, fp=1, fn=0) + ConfusionCounts(tp=1, fp=0, fn=4)
    >>> total.precision, total.recall, round(total.f1, 4)
    (0.8, 0.5, 0.6154)
    """

    tp: int = 0
    fp: int = 0
    fn: int = 0

    @property
    def precision(self) -> float:
        """TP / (TP + FP); NaN when nothing was called positive."""
        return ratio(self.tp, self.tp + self.fp)

    @property
    def recall(self) -> float:
        """TP / (TP + FN); NaN when the ground truth has no positive."""
        return ratio(self.tp, self.tp + self.fn)

    @property
    def f1(self) -> float:
        """2 TP / (2 TP + FP + FN); NaN when neither side has a positive."""
        return ratio(2 * self.tp, 2 * self.tp + self.fp + self.fn)


@dataclass
class LabelCounts(ConfusionCounts):
    """Confusion counts of a boolean label given to every frame, true negatives included.

    >>> counts = LabelCounts.of(np.array([1, 1, 0, 0], bool), np.array([1, 0, 1, 0], bool))
    >>> counts.tp, counts.fp, counts.fn, counts.tn, counts.f1, counts.misclassified
    (1, 1, 1, 1, 0.5, 2)
    """

    tn: int = 0

    @classmethod
    def of(cls, predicted: BoolArray, truth: BoolArray) -> Self:
        """Count ``(F,)`` predicted labels against ``(F,)`` true labels."""
        predicted = np.asarray(predicted, dtype=bool)
        truth = np.asarray(truth, dtype=bool)
        return cls(
            tp=int(np.sum(predicted & truth)),
            fp=int(np.sum(predicted & ~truth)),
            fn=int(np.sum(~predicted & truth)),
            tn=int(np.sum(~predicted & ~truth)),
        )

    @property
    def misclassified(self) -> int:
        """Frames whose label is wrong (FP + FN)."""
        return self.fp + self.fn

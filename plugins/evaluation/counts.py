"""Confusion counts shared by the detection and info-less evaluations."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Self


@dataclass
class ConfusionCounts:
    """True/false positives and false negatives, pooled with ``+``.

    >>> total = ConfusionCounts(tp=3, fp=1, fn=0) + ConfusionCounts(tp=1, fp=0, fn=4)
    >>> total.precision, total.recall, round(total.f1, 4)
    (0.8, 0.5, 0.6154)
    """

    tp: int = 0
    fp: int = 0
    fn: int = 0

    def __add__(self, other: Self) -> Self:
        """Pool two count sets of the same kind."""
        return type(self)(
            **{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)}
        )

    @property
    def precision(self) -> float:
        """TP / (TP + FP); NaN when nothing was called positive."""
        total = self.tp + self.fp
        return self.tp / total if total else float("nan")

    @property
    def recall(self) -> float:
        """TP / (TP + FN); NaN when the ground truth has no positive."""
        total = self.tp + self.fn
        return self.tp / total if total else float("nan")

    @property
    def f1(self) -> float:
        """2 TP / (2 TP + FP + FN); NaN when neither side has a positive."""
        total = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / total if total else float("nan")

"""Frame-level info-less precision / recall / F1."""

from __future__ import annotations

import math

import numpy as np

from trackfw_plugins.evaluation.infoless import InfolessCounts, infoless_counts, infoless_truth


def test_truth_is_strictly_inside_intervals() -> None:
    truth = infoless_truth([(2, 6), (8, 10)], np.arange(12))
    assert np.flatnonzero(truth).tolist() == [3, 4, 5, 9]


def test_counts_and_scores() -> None:
    truth = infoless_truth([(2, 6)], np.arange(10))  # 3, 4, 5
    predicted = np.zeros(10, dtype=bool)
    predicted[[4, 5, 6, 7]] = True
    counts = infoless_counts(predicted, truth)
    assert (counts.tp, counts.fp, counts.fn, counts.tn) == (2, 2, 1, 5)
    assert counts.precision == 0.5
    assert counts.recall == 2 / 3
    assert counts.f1 == 4 / 7
    assert counts.misclassified == 3


def test_undefined_scores_are_nan_and_pooling_adds() -> None:
    counts = infoless_counts(np.zeros(5, dtype=bool), np.zeros(5, dtype=bool))
    assert math.isnan(counts.precision) and math.isnan(counts.recall) and math.isnan(counts.f1)
    assert counts.misclassified == 0
    pooled = counts + InfolessCounts(tp=1, fp=0, fn=1, tn=0)
    assert (pooled.tp, pooled.fn, pooled.tn) == (1, 1, 5)

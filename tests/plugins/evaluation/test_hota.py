"""HOTA in point mode (the box mode is checked against py-motmetrics in test_motmetrics_reference)."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.evaluation.clear_mot import build_sequence
from trackfw_plugins.evaluation.hota import ALPHAS, HotaCounts, hota_counts, similarity_matrix


def test_alphas_are_trackeval_thresholds() -> None:
    assert len(ALPHAS) == 19
    assert ALPHAS[0] == pytest.approx(0.05) and ALPHAS[-1] == pytest.approx(0.95)


def test_point_similarity() -> None:
    similarity = similarity_matrix(
        np.array([[0.0, 0.0]]), np.array([[0.0, 0.0], [40.0, 0.0], [100.0, 0.0]]), "point", 80.0
    )
    assert similarity.tolist() == [[1.0, 0.5, 0.0]]


def test_ground_truth_against_itself() -> None:
    ground_truth = {t: {1: (0.0, 0.0), 2: (300.0, 0.0)} for t in range(8)}
    summary = hota_counts(build_sequence(ground_truth, ground_truth)).summary()
    for name in ("HOTA", "DetA", "AssA", "LocA", "DetRe", "DetPr"):
        assert summary[name] == pytest.approx(1.0)


def test_constant_offset_lowers_detection_and_localisation_only() -> None:
    # Every hypothesis is 20 px off: similarity 0.75, accepted for alpha <= 0.75 (15 of 19).
    ground_truth = {t: {1: (0.0, 0.0)} for t in range(5)}
    hypotheses = {t: {9: (20.0, 0.0)} for t in range(5)}
    counts = hota_counts(build_sequence(ground_truth, hypotheses), "point", 80.0)
    accepted = ALPHAS <= 0.75 + 1e-12
    assert np.array_equal(counts.tp, np.where(accepted, 5.0, 0.0))
    per_alpha = counts.per_alpha()
    assert np.allclose(per_alpha["AssA"][accepted], 1.0)
    summary = counts.summary()
    assert summary["DetA"] == pytest.approx(accepted.sum() / len(ALPHAS))
    assert summary["HOTA"] == pytest.approx(accepted.sum() / len(ALPHAS))
    assert per_alpha["LocA"][0] == pytest.approx(0.75)


def test_swap_halves_association() -> None:
    ground_truth = {t: {1: (0.0, 0.0), 2: (300.0, 0.0)} for t in range(10)}
    hypotheses = {
        t: {1: (0.0, 0.0), 2: (300.0, 0.0)} if t < 5 else {1: (300.0, 0.0), 2: (0.0, 0.0)}
        for t in range(10)
    }
    summary = hota_counts(build_sequence(ground_truth, hypotheses)).summary()
    assert summary["DetA"] == pytest.approx(1.0)
    # Each GT id is matched to two hypotheses for 5 of its 10 frames: A = 5 / (10 + 10 - 5).
    assert summary["AssA"] == pytest.approx(1.0 / 3.0)
    assert summary["HOTA"] == pytest.approx(np.sqrt(1.0 / 3.0))


def test_pooling_weights_association_by_true_positives() -> None:
    ground_truth = {t: {1: (0.0, 0.0)} for t in range(4)}
    perfect = hota_counts(build_sequence(ground_truth, ground_truth))
    empty = hota_counts(build_sequence(ground_truth, {}))
    pooled = perfect + empty
    assert isinstance(pooled, HotaCounts)
    summary = pooled.summary()
    assert summary["AssA"] == pytest.approx(1.0)
    assert summary["DetA"] == pytest.approx(0.5)

"""IDF1 / IDP / IDR: py-motmetrics' empty cases and small hand-checked sequences."""

from __future__ import annotations

import math

import pytest

from trackfw_plugins.evaluation.clear_mot import build_sequence
from trackfw_plugins.evaluation.identity import IdentityCounts, identity_counts

FOUR = {i: (100.0 * i, 0.0) for i in (1, 2, 3, 4)}


def test_empty_ground_truth_gives_only_false_positives() -> None:
    counts = identity_counts(build_sequence({}, {t: FOUR for t in range(4)}))
    assert (counts.idtp, counts.idfp, counts.idfn) == (0, 16, 0)


def test_empty_predictions_give_only_false_negatives() -> None:
    counts = identity_counts(build_sequence({t: FOUR for t in range(4)}, {}))
    assert (counts.idtp, counts.idfp, counts.idfn) == (0, 0, 16)
    nothing = identity_counts(build_sequence({}, {}))
    assert (nothing.idtp, nothing.idfp, nothing.idfn) == (0, 0, 0)
    assert math.isnan(nothing.idf1)


def test_ground_truth_against_itself_is_perfect() -> None:
    ground_truth = {t: FOUR for t in range(10)}
    counts = identity_counts(build_sequence(ground_truth, ground_truth))
    assert counts.idf1 == 1.0 and counts.idp == 1.0 and counts.idr == 1.0


def test_swap_halfway_loses_half_of_the_identity_matches() -> None:
    ground_truth = {t: {1: (0.0, 0.0), 2: (200.0, 0.0)} for t in range(10)}
    hypotheses = {
        t: {1: (0.0, 0.0), 2: (200.0, 0.0)} if t < 5 else {1: (200.0, 0.0), 2: (0.0, 0.0)}
        for t in range(10)
    }
    counts = identity_counts(build_sequence(ground_truth, hypotheses))
    assert (counts.idtp, counts.idfp, counts.idfn) == (10, 10, 10)
    assert counts.idf1 == pytest.approx(0.5)


def test_one_hypothesis_cannot_serve_two_objects() -> None:
    # Hypothesis 5 follows object 1 for 6 frames then object 2 for 4 frames: only 6 count.
    ground_truth = {t: {1: (0.0, 0.0), 2: (300.0, 0.0)} for t in range(10)}
    hypotheses = {t: {5: (0.0, 0.0) if t < 6 else (300.0, 0.0)} for t in range(10)}
    counts = identity_counts(build_sequence(ground_truth, hypotheses))
    assert (counts.idtp, counts.idfp, counts.idfn) == (6, 4, 14)
    assert counts.idf1 == pytest.approx(12 / 30)
    assert counts.idp == pytest.approx(0.6)
    assert counts.idr == pytest.approx(0.3)


def test_pooling_adds_counts() -> None:
    total = IdentityCounts(3, 1, 2) + IdentityCounts(1, 0, 1)
    assert (total.idtp, total.idfp, total.idfn) == (4, 1, 3)

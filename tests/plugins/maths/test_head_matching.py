"""The one detection rule: one-to-one matches within half a head."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.maths.head_matching import match_heads


def test_match_heads_is_one_to_one_within_half_a_head() -> None:
    heads = np.array([[0.0, 0.0, 10.0], [100.0, 0.0, 40.0]])
    assert match_heads(np.array([[4.0, 0.0]]), heads).n_matched == 1
    assert match_heads(np.array([[6.0, 0.0]]), heads).n_matched == 0  # 0.6 head sizes away
    assert match_heads(np.array([[115.0, 0.0]]), heads).n_matched == 1  # big head, 0.375 away
    assert (
        match_heads(np.array([[1.0, 0.0], [2.0, 0.0]]), heads).n_matched == 1
    )  # duplicates count once
    assert match_heads(np.zeros((0, 2)), heads).n_matched == 0


def test_matches_name_their_pairs_and_distances() -> None:
    heads = np.array([[0.0, 0.0, 10.0], [100.0, 0.0, 40.0]])
    matches = match_heads(np.array([[103.0, 4.0], [50.0, 50.0], [1.0, 0.0]]), heads)
    assert matches.heads.tolist() == [0, 1] and matches.detections.tolist() == [2, 0]
    assert matches.distances.tolist() == [1.0, 5.0]
    assert (matches.n_heads, matches.n_detections) == (2, 3)

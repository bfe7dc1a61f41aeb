"""Tests of the candidate windows (docs/algorithms/gap-matchers.md#candidate-windows)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from trackfw_plugins.maths.candidate_windows import build_windows


def _naive_windows(points: np.ndarray, template_size: int) -> list[frozenset[int]]:
    seen: list[frozenset[int]] = []
    for combo in itertools.combinations(range(len(points)), 4):
        low, high = points[list(combo)].min(axis=0), points[list(combo)].max(axis=0)
        inside = frozenset(
            int(i) for i in np.nonzero(np.all((points >= low) & (points <= high), axis=1))[0]
        )
        if inside not in seen:
            seen.append(inside)
    low_size, high_size = math.ceil(0.9 * template_size), math.floor(1.2 * template_size)
    return [w for w in seen if low_size <= len(w) <= high_size]


def test_windows_match_a_naive_enumeration() -> None:
    points = np.random.default_rng(0).uniform(0, 100, (13, 2))
    windows = build_windows(points, 6)
    expected = _naive_windows(points, 6)
    found = [frozenset(np.nonzero(row)[0].tolist()) for row in windows.members]
    assert found == expected
    assert windows.total == math.comb(13, 4)
    assert windows.after_size == len(expected) <= windows.after_dedup <= windows.total


def test_window_bounds_are_inclusive() -> None:
    grid = np.array([[x, y] for x in range(3) for y in range(3)], dtype=float)
    windows = build_windows(grid, 4)
    sizes = windows.members.sum(axis=1)
    # The 2x2 corner squares hold exactly four points when the borders count as inside.
    assert (sizes == 4).sum() >= 4

"""Interval placement, swings and the look-away views of the virtual wearer."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.datasets.wear_intervals import (
    InfolessView,
    compose_swing,
    place_intervals,
    swing_progress,
)


@pytest.mark.parametrize("n_intervals", [1, 2, 3])
def test_intervals_respect_lengths_and_informative_segments(n_intervals: int) -> None:
    for seed in range(40):
        spans = place_intervals(179, n_intervals, 15, 60, 12, np.random.default_rng(seed))
        assert len(spans) == n_intervals
        assert spans[0][0] >= 12  # frames 0..11 informative (frame 0 carries the annotation)
        assert spans[-1][1] <= 179 - 1 - 12
        for first, last in spans:
            assert 15 <= last - first + 1 <= 60
        assert sum(last - first + 1 for first, last in spans) <= 179 / 2
        for (_, previous_last), (next_first, _) in itertools.pairwise(spans):
            assert next_first - previous_last - 1 >= 12


def test_intervals_shrink_to_fit_and_refuse_impossible_requests() -> None:
    spans = place_intervals(40, 1, 15, 60, 12, np.random.default_rng(0))
    first, last = spans[0]
    assert first >= 12 and 40 - 1 - last >= 12 and last - first + 1 >= 15
    with pytest.raises(UserError, match="fewer --intervals"):
        place_intervals(40, 3, 15, 60, 12, np.random.default_rng(0))


def test_same_generator_state_same_intervals() -> None:
    first = place_intervals(300, 3, 15, 60, 12, np.random.default_rng(5))
    again = place_intervals(300, 3, 15, 60, 12, np.random.default_rng(5))
    assert first == again


def _view(first: int = 10, last: int = 29) -> InfolessView:
    return InfolessView("sky", first, last, 4, 4, "top", 3.0, (0.0, 0.0), (0.0, 0.0))


def test_swing_progress_rises_then_falls_and_holds_in_between() -> None:
    view = _view()
    swing_in = [swing_progress(view, frame) for frame in range(10, 14)]
    hold = [swing_progress(view, frame) for frame in range(14, 26)]
    swing_out = [swing_progress(view, frame) for frame in range(26, 30)]
    assert all(item is None for item in hold)
    rising = [item[0] for item in swing_in if item is not None]
    falling = [item[0] for item in swing_out if item is not None]
    assert len(rising) == len(falling) == 4
    assert all(0 < value < 1 for value in rising + falling)
    assert rising == sorted(rising) and falling == sorted(falling, reverse=True)
    steps = [item[1] for item in swing_in if item is not None]
    assert all(step > 0 for step in steps)
    assert sum(steps) == pytest.approx(rising[-1])


@pytest.mark.parametrize("enter_from", ["top", "bottom", "left", "right"])
def test_compose_swing_slides_the_other_view_in(enter_from: str) -> None:
    real = np.full((40, 60, 3), 10, np.uint8)
    other = np.full((40, 60, 3), 200, np.uint8)
    assert np.array_equal(compose_swing(real, other, 0.0, 0.0, enter_from), real)
    assert np.array_equal(compose_swing(real, other, 1.0, 0.0, enter_from), other)
    half = compose_swing(real, other, 0.5, 0.0, enter_from)
    edge = {
        "top": half[0, 30],
        "bottom": half[-1, 30],
        "left": half[20, 0],
        "right": half[20, -1],
    }[enter_from]
    assert int(edge[0]) == 200
    assert int((half == 200).all(axis=2).sum()) == 40 * 60 // 2


def test_fast_swing_blurs_along_its_direction_only() -> None:
    real = np.zeros((40, 60, 3), np.uint8)
    real[:, ::4] = 255  # vertical stripes: a vertical blur keeps them, a horizontal one smears
    other = real.copy()
    vertical = compose_swing(real, other, 0.5, 0.4, "top")
    horizontal = compose_swing(real, other, 0.5, 0.4, "left")
    assert np.array_equal(vertical, real)
    assert horizontal.std() < 0.5 * real.std()

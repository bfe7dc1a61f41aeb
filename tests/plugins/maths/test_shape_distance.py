"""Tests of the hull shape distance Δ (docs/algorithms/gap-matchers.md#hull-shape-distance)."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.maths.shape_distance import (
    HullShapeMatcher,
    ShapeDistanceSettings,
    chi_square_costs,
    hull_polygon,
    resample_closed,
    shape_context_descriptors,
    shape_distance,
)

METHODS = ["shape_context", "hu", "procrustes"]


def _rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def test_hull_drops_interior_points_and_handles_degenerate_sets() -> None:
    points = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0], [2.0, 1.0], [1.0, 2.0]])
    hull = hull_polygon(points)
    assert sorted(map(tuple, hull)) == sorted(map(tuple, points[:4]))
    line = hull_polygon(np.array([[2.0, 2.0], [0.0, 0.0], [1.0, 1.0]]))
    assert line.tolist() == [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]
    assert hull_polygon(np.array([[5.0, 5.0]])).tolist() == [[5.0, 5.0]]


def test_resampling_is_even_along_the_boundary() -> None:
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    samples = resample_closed(square, 32)
    steps = np.sqrt(np.sum(np.diff(np.vstack([samples, samples[:1]]), axis=0) ** 2, axis=1))
    np.testing.assert_allclose(steps, 0.25)


def test_descriptors_are_normalised_histograms() -> None:
    samples = np.random.default_rng(0).uniform(0, 1, (3, 32, 2))
    descriptors = shape_context_descriptors(samples, ShapeDistanceSettings())
    assert descriptors.shape == (3, 32, 60)
    np.testing.assert_allclose(descriptors.sum(axis=2), 1.0)


def test_chi_square_costs_match_the_direct_formula() -> None:
    samples = np.random.default_rng(1).uniform(0, 1, (4, 32, 2))
    descriptors = shape_context_descriptors(samples, ShapeDistanceSettings())
    reference, others = descriptors[0], descriptors[1:]
    numerator = (others[:, :, None, :] - reference[None, None]) ** 2
    denominator = others[:, :, None, :] + reference[None, None]
    direct = 0.5 * np.where(
        denominator > 0, numerator / np.where(denominator > 0, denominator, 1), 0
    )
    np.testing.assert_allclose(chi_square_costs(reference, others), direct.sum(axis=3), atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_same_shape_scaled_and_shifted_has_zero_distance(method: str) -> None:
    shape = np.random.default_rng(2).uniform(0, 300, (8, 2))
    settings = ShapeDistanceSettings(method=method)
    assert shape_distance(shape, 2.5 * shape + [40.0, -70.0], settings) < 1e-6


@pytest.mark.parametrize("method", METHODS)
def test_distance_is_symmetric_and_in_unit_interval(method: str) -> None:
    rng = np.random.default_rng(3)
    settings = ShapeDistanceSettings(method=method)
    for _ in range(5):
        a, b = rng.uniform(0, 100, (7, 2)), rng.uniform(0, 100, (9, 2))
        forward, backward = shape_distance(a, b, settings), shape_distance(b, a, settings)
        assert 0.0 <= forward <= 1.0
        assert forward == pytest.approx(backward, abs=1e-6 if method != "hu" else 0.2)


def test_similar_shapes_are_closer_than_different_ones() -> None:
    rng = np.random.default_rng(4)
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    noisy_square = square @ _rotation(0.1).T * 1.3 + rng.normal(0, 3, (4, 2))
    sliver = np.array([[0.0, 0.0], [300.0, 0.0], [300.0, 20.0], [0.0, 20.0]])
    assert shape_distance(square, noisy_square) < 0.2
    assert shape_distance(square, sliver) > shape_distance(square, noisy_square) + 0.1


@pytest.mark.parametrize("method", METHODS)
def test_degenerate_sets_give_finite_distances(method: str) -> None:
    settings = ShapeDistanceSettings(method=method)
    triangle = np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]])
    for degenerate in (np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]), np.ones((2, 2))):
        value = shape_distance(triangle, degenerate, settings)
        assert np.isfinite(value) and 0.0 <= value <= 1.0


def test_matcher_equals_pairwise_distances() -> None:
    rng = np.random.default_rng(5)
    template = rng.uniform(0, 200, (8, 2))
    sets = [rng.uniform(0, 200, (int(rng.integers(4, 10)), 2)) for _ in range(6)]
    matcher = HullShapeMatcher(template)
    expected = [shape_distance(template, points) for points in sets]
    np.testing.assert_allclose(matcher.distances(sets), expected, atol=1e-12)


def test_rotation_invariant_option_ignores_rotation() -> None:
    shape = np.random.default_rng(6).uniform(0, 100, (8, 2))
    rotated = shape @ _rotation(1.2).T
    plain = shape_distance(shape, rotated)
    invariant = shape_distance(shape, rotated, ShapeDistanceSettings(rotation_invariant=True))
    assert invariant < plain

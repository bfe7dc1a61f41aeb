"""Tests of the per-coordinate AR forecast (docs/algorithms/predictors.md#ar-predictor)."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.maths.autoregressive import (
    ArSettings,
    companion_spectral_radius,
    fit_ar,
    forecast_ar,
    stabilise,
)


def _track(displacements: np.ndarray, start: tuple[float, float] = (100.0, 50.0)) -> np.ndarray:
    return np.vstack([np.asarray(start), np.asarray(start) + np.cumsum(displacements, axis=0)])


@pytest.mark.parametrize("order", [1, 2, 3])
def test_constant_velocity_track_is_extrapolated_exactly(order: int) -> None:
    velocity = np.array([2.5, -1.25])
    history = _track(np.tile(velocity, (29, 1)))
    horizon = 120
    forecast = forecast_ar(history, order, horizon)
    assert forecast.fallback is None
    assert forecast.order_used == order
    np.testing.assert_allclose(forecast.position, history[-1] + horizon * velocity, atol=1e-6)


def test_decelerating_track_follows_the_geometric_decay() -> None:
    ratio = 0.9
    steps = np.arange(1, 40)
    displacements = np.stack([10.0 * ratio**steps, -4.0 * ratio**steps], axis=1)
    history = _track(displacements)
    horizon = 50
    future = ratio ** np.arange(40, 40 + horizon)
    expected = history[-1] + np.array([10.0 * future.sum(), -4.0 * future.sum()])
    forecast = forecast_ar(history, 1, horizon)
    np.testing.assert_allclose(forecast.position, expected, rtol=1e-4)
    # The deceleration must be used: a constant-velocity guess overshoots by far.
    constant_velocity = history[-1] + horizon * displacements[-1]
    assert np.linalg.norm(forecast.position - expected) < 0.01 * np.linalg.norm(
        constant_velocity - expected
    )


def test_explosive_roots_are_tamed() -> None:
    growth = 1.1
    series = 0.01 * growth ** np.arange(30)
    model = fit_ar(series, 1)
    assert model is not None
    assert model.shrunk
    assert model.spectral_radius == pytest.approx(growth, rel=1e-3)
    assert companion_spectral_radius(model.coefficients) == pytest.approx(0.95, rel=1e-9)


def test_stabilise_scales_every_root() -> None:
    # Roots 1.2 and 0.6: z^2 - 1.8 z + 0.72.
    phi, rho, shrunk = stabilise([1.8, -0.72])
    assert shrunk
    assert rho == pytest.approx(1.2)
    roots = np.sort(np.abs(np.roots([1.0, -phi[0], -phi[1]])))
    np.testing.assert_allclose(roots, np.array([0.6, 1.2]) * 0.95 / 1.2)


def test_stable_coefficients_are_left_alone() -> None:
    phi, rho, shrunk = stabilise([0.5, 0.2])
    assert not shrunk
    np.testing.assert_array_equal(phi, [0.5, 0.2])
    assert rho < 0.99


def test_explosive_position_forecast_stays_bounded() -> None:
    # Accelerating track: AR on displacements sees growth 1.08 and must be shrunk.
    displacements = np.stack([1.08 ** np.arange(1, 40), np.zeros(39)], axis=1)
    history = _track(displacements)
    forecast = forecast_ar(history, 1, 200)
    unguarded = history[-1, 0] + sum(displacements[-1, 0] * 1.08**j for j in range(1, 201))
    assert forecast.position[0] < unguarded / 100
    assert forecast.position[0] > history[-1, 0]


def test_single_position_falls_back_to_constant_position() -> None:
    forecast = forecast_ar(np.array([[3.0, 4.0]]), 3, 30)
    assert forecast.fallback == "constant_position"
    assert forecast.order_used == 0
    np.testing.assert_array_equal(forecast.position, [3.0, 4.0])


def test_two_positions_fall_back_to_their_velocity() -> None:
    forecast = forecast_ar(np.array([[0.0, 0.0], [2.0, -1.0]]), 1, 10)
    assert forecast.fallback == "constant_velocity"
    np.testing.assert_allclose(forecast.position, [22.0, -11.0])


def test_five_positions_average_the_last_displacements() -> None:
    history = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 1.0], [6.0, 1.0], [10.0, 3.0]])
    forecast = forecast_ar(history, 1, 4)
    assert forecast.fallback == "constant_velocity"
    velocity = np.diff(history, axis=0).mean(axis=0)
    np.testing.assert_allclose(forecast.position, history[-1] + 4 * velocity)


def test_constant_velocity_fallback_uses_at_most_five_displacements() -> None:
    settings = ArSettings(min_eq_factor=100.0)  # make every AR order infeasible
    displacements = np.array([[9.0, 9.0]] * 3 + [[1.0, 2.0]] * 5)
    history = _track(displacements)
    forecast = forecast_ar(history, 2, 10, settings)
    assert forecast.fallback == "constant_velocity"
    np.testing.assert_allclose(forecast.position, history[-1] + 10 * np.array([1.0, 2.0]))


@pytest.mark.parametrize(("count", "order", "used"), [(6, 1, 1), (8, 2, 1), (9, 2, 2), (11, 3, 2)])
def test_minimum_data_rule_picks_the_largest_feasible_order(
    count: int, order: int, used: int
) -> None:
    rng = np.random.default_rng(count)
    history = _track(rng.normal(size=(count - 1, 2)))
    forecast = forecast_ar(history, order, 5)
    assert forecast.order_used == used
    assert forecast.fallback == (None if used == order else f"ar{used}")


def test_max_history_is_honoured() -> None:
    rng = np.random.default_rng(4)
    history = _track(rng.normal(size=(99, 2)) + np.array([1.0, 0.5]))
    capped = forecast_ar(history, 2, 30, ArSettings(max_history=20))
    truncated = forecast_ar(history[-20:], 2, 30, ArSettings(max_history=100))
    np.testing.assert_array_equal(capped.position, truncated.position)
    full = forecast_ar(history, 2, 30, ArSettings(max_history=100))
    assert np.linalg.norm(full.position - capped.position) > 1e-3
    # 7 positions leave 6 displacements: too few for order 3 (needs 8 + 3), enough for order 1.
    assert forecast_ar(history, 3, 10, ArSettings(max_history=7)).order_used == 1
    assert forecast_ar(history, 3, 10, ArSettings(max_history=5)).order_used == 0


def test_position_series_extrapolates_a_line_without_exploding() -> None:
    history = _track(np.tile([1.0, 0.5], (40, 1)))
    forecast = forecast_ar(history, 2, 100, ArSettings(series="position"))
    assert forecast.fallback is None
    # The unit root is shrunk to 0.95, so the forecast moves forward but stays bounded.
    assert history[-1, 0] < forecast.position[0] < history[-1, 0] + 100.0


def test_zero_horizon_returns_the_last_position() -> None:
    history = _track(np.tile([1.0, 1.0], (20, 1)))
    for series in ("displacement", "position"):
        forecast = forecast_ar(history, 2, 0, ArSettings(series=series))
        np.testing.assert_allclose(forecast.position, history[-1])


def test_bad_inputs_are_rejected() -> None:
    with pytest.raises(ValueError, match="at least one"):
        forecast_ar(np.zeros((0, 2)), 1, 5)
    with pytest.raises(ValueError, match="non-finite"):
        forecast_ar(np.array([[0.0, np.nan]]), 1, 5)
    with pytest.raises(ValueError, match="order"):
        fit_ar(np.arange(20.0), 0)
    with pytest.raises(ValueError, match="shrink_to"):
        ArSettings(shrink_to=1.0)

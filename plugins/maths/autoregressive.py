"""Per-coordinate autoregressive (AR) prediction across an info-less interval.

See docs/algorithms/predictors.md#ar-predictor.

Each image coordinate is modelled on its own. By default the model runs on frame-to-frame
displacements (an ARIMA(k,1,0) with drift), because an AR fitted on trending positions sits next to
a unit root and explodes over horizons of hundreds of frames; the displacement model instead tends
to a constant velocity, which is what the paper assumes happens during the interval.

The fit is conditional least squares with a tiny ridge on the AR coefficients (never on the
intercept), a minimum-data rule, a chain of fallbacks for short histories and a stability guard that
pulls every companion root inside the unit circle.

>>> import numpy as np
>>> history = np.array([[float(t), 2.0 * t] for t in range(10)])
>>> forecast = forecast_ar(history, order=2, horizon=5)
>>> forecast.position.round(6).tolist(), forecast.order_used, forecast.fallback
([14.0, 28.0], 2, None)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from trackfw.arrays import FloatArray

SeriesKind = Literal["displacement", "position"]

#: How many of the most recent displacements the constant-velocity fallback averages.
CONSTANT_VELOCITY_WINDOW = 5


@dataclass(frozen=True)
class ArSettings:
    """Fit and forecast settings; the defaults of docs/algorithms/predictors.md#parameters.

    Attributes:
        series: ``"displacement"`` (model δ_t = z_t − z_{t−1}) or ``"position"`` (model z_t,
            centred on the last observed value).
        max_history: only the most recent ``max_history`` positions are used.
        min_eq_factor: an order k is fitted only with at least ``min_eq_factor·(k+1)`` equations.
        stability_rho: companion spectral radius at or above which the coefficients are shrunk.
        shrink_to: spectral radius after shrinking.
        ridge: relative ridge weight; λ = ridge·trace(XᵀX)/(k+1), applied to φ only.
    """

    series: SeriesKind = "displacement"
    max_history: int = 100
    min_eq_factor: float = 2.0
    stability_rho: float = 0.99
    shrink_to: float = 0.95
    ridge: float = 1e-6

    def __post_init__(self) -> None:
        if self.series not in ("displacement", "position"):
            raise ValueError(f"series must be 'displacement' or 'position', not {self.series!r}")
        if self.max_history < 1:
            raise ValueError("max_history must be at least 1")
        if not 0.0 < self.shrink_to < self.stability_rho:
            raise ValueError("need 0 < shrink_to < stability_rho")


@dataclass(frozen=True)
class ArModel:
    """A fitted AR(k) with intercept: x_t = c + Σ_i φ_i x_{t−i}.

    Attributes:
        intercept: c.
        coefficients: ``(k,)`` φ_1..φ_k, after the stability guard.
        spectral_radius: companion-matrix spectral radius of the raw least-squares φ.
        shrunk: True when the stability guard rescaled the coefficients.
    """

    intercept: float
    coefficients: FloatArray
    spectral_radius: float
    shrunk: bool

    @property
    def order(self) -> int:
        """The AR order k."""
        return len(self.coefficients)


@dataclass(frozen=True)
class ArForecast:
    """Forecast of one target's position on frame b.

    Attributes:
        position: ``(2,)`` forecast (x, y) after ``horizon`` steps.
        order_used: the AR order actually fitted (0 when no AR model could be fitted).
        fallback: None when the requested order was fitted, ``"ar{k'}"`` for a lower order,
            ``"constant_velocity"`` or ``"constant_position"``.
    """

    position: FloatArray
    order_used: int
    fallback: str | None


def required_equations(order: int, min_eq_factor: float = 2.0) -> float:
    """Minimum number of equations m for fitting ``order`` (m ≥ factor·(k+1)).

    >>> required_equations(3)
    8.0
    """
    return float(min_eq_factor) * (order + 1)


def companion_spectral_radius(coefficients: ArrayLike) -> float:
    """Largest root modulus of the AR polynomial, from the k×k companion matrix.

    >>> companion_spectral_radius([0.5])
    0.5
    >>> round(companion_spectral_radius([1.5, -0.56]), 6)  # roots 0.8 and 0.7
    0.8
    """
    phi = np.asarray(coefficients, dtype=np.float64).reshape(-1)
    if len(phi) == 0:
        return 0.0
    companion = np.zeros((len(phi), len(phi)))
    companion[0] = phi
    companion[1:, :-1] = np.eye(len(phi) - 1)
    return float(np.max(np.abs(np.linalg.eigvals(companion))))


def stabilise(
    coefficients: ArrayLike, stability_rho: float = 0.99, shrink_to: float = 0.95
) -> tuple[FloatArray, float, bool]:
    """Stability guard: scale every root by α = shrink_to/ρ when ρ ≥ stability_rho.

    See docs/algorithms/predictors.md#stability-guard.

    φ_i ← α^i φ_i maps each root r of z^k − Σ φ_i z^{k−i} to α·r.

    Returns:
        ``(φ (k,), raw spectral radius ρ, whether φ was rescaled)``.

    >>> phi, rho, shrunk = stabilise([1.1])
    >>> phi.round(6).tolist(), round(rho, 6), shrunk
    ([0.95], 1.1, True)
    """
    phi = np.asarray(coefficients, dtype=np.float64).reshape(-1).copy()
    rho = companion_spectral_radius(phi)
    if rho < stability_rho:
        return phi, rho, False
    alpha = shrink_to / rho
    phi *= alpha ** np.arange(1, len(phi) + 1)
    return phi, rho, True


def fit_ar(
    series: ArrayLike,
    order: int,
    *,
    ridge: float = 1e-6,
    min_eq_factor: float = 2.0,
    stability_rho: float = 0.99,
    shrink_to: float = 0.95,
) -> ArModel | None:
    """Conditional least-squares AR(k) with intercept on a univariate series.

    One equation per t = k+1..L (1-based): x_t = c + Σ φ_i x_{t−i}, so m = L − k equations.
    The ridge λ = ridge·trace(XᵀX)/(k+1) is added on φ only, as extra rows √λ·e_i of the
    ``lstsq`` system, so the intercept stays unbiased.

    Args:
        series: ``(L,)`` values, oldest first.
        order: k ≥ 1.
        ridge, min_eq_factor, stability_rho, shrink_to: see :class:`ArSettings`.

    Returns:
        The model, or None when m < min_eq_factor·(k+1).

    >>> model = fit_ar([1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125], order=1, min_eq_factor=1)
    >>> abs(model.intercept) < 1e-4, model.coefficients.round(4).tolist()
    (True, [0.5])
    >>> fit_ar([1.0, 2.0, 3.0], order=1) is None
    True
    """
    if order < 1:
        raise ValueError(f"AR order must be at least 1, got {order}")
    values = np.asarray(series, dtype=np.float64).reshape(-1)
    equations = len(values) - order
    if equations < required_equations(order, min_eq_factor) or equations <= 0:
        return None
    # Column i (1-based) holds x_{t−i} for the targets x_t, t = k..L−1 (0-based).
    lagged = np.stack(
        [values[order - lag : len(values) - lag] for lag in range(1, order + 1)], axis=1
    )
    design = np.hstack([np.ones((equations, 1)), lagged])
    target = values[order:]
    ridge_weight = ridge * float(np.trace(design.T @ design)) / (order + 1)
    penalty_rows = np.hstack([np.zeros((order, 1)), np.sqrt(ridge_weight) * np.eye(order)])
    solution = np.linalg.lstsq(
        np.vstack([design, penalty_rows]), np.concatenate([target, np.zeros(order)]), rcond=None
    )[0]
    phi, rho, shrunk = stabilise(solution[1:], stability_rho, shrink_to)
    return ArModel(
        intercept=float(solution[0]), coefficients=phi, spectral_radius=rho, shrunk=shrunk
    )


def forecast_series(model: ArModel, series: ArrayLike, steps: int) -> FloatArray:
    """Recursive multi-step forecast: feed forecasts back where observations run out.

    Args:
        model: the fitted model.
        series: ``(L,)`` observed values, oldest first, with L ≥ k.
        steps: how many future values to produce (≥ 0).

    Returns:
        ``(steps,)`` forecasts x̂_{L+1}..x̂_{L+steps}.

    >>> model = ArModel(intercept=1.0, coefficients=np.array([0.5]), spectral_radius=0.5,
    ...                 shrunk=False)
    >>> forecast_series(model, [2.0], 3).tolist()
    [2.0, 2.0, 2.0]
    """
    values = np.asarray(series, dtype=np.float64).reshape(-1)
    order = model.order
    # Most recent value first, so that recent[i] multiplies φ_{i+1}.
    recent = list(values[::-1][:order]) if order else []
    output = np.empty(steps)
    for step in range(steps):
        value = model.intercept + float(np.dot(model.coefficients, recent))
        output[step] = value
        if order:
            recent = [value, *recent[:-1]]
    return output


def _fit_both(
    series_per_axis: list[FloatArray], order: int, settings: ArSettings
) -> list[ArModel] | None:
    models = []
    for series in series_per_axis:
        model = fit_ar(
            series,
            order,
            ridge=settings.ridge,
            min_eq_factor=settings.min_eq_factor,
            stability_rho=settings.stability_rho,
            shrink_to=settings.shrink_to,
        )
        if model is None:
            return None
        models.append(model)
    return models


def forecast_ar(
    history: ArrayLike,
    order: int,
    horizon: int,
    settings: ArSettings | None = None,
) -> ArForecast:
    """Forecast one target's position ``horizon`` frames after its last observation.

    Fallbacks: the largest feasible order k' < k, then constant velocity (mean of the last
    min(n−1, 5) displacements), then constant position when n = 1.

    Args:
        history: ``(n, 2)`` positions, oldest first, ending at frame a (n ≥ 1).
        order: the requested AR order k ≥ 1.
        horizon: h = b − a ≥ 0.
        settings: fit settings; the defaults when None.

    Returns:
        The forecast, with the order used and the fallback taken.

    >>> forecast_ar([[5.0, 7.0]], order=1, horizon=10).fallback
    'constant_position'
    >>> result = forecast_ar([[0.0, 0.0], [1.0, 2.0], [3.0, 4.0]], order=1, horizon=2)
    >>> result.position.tolist(), result.fallback
    ([6.0, 8.0], 'constant_velocity')
    """
    settings = settings or ArSettings()
    positions = np.asarray(history, dtype=np.float64).reshape(-1, 2)
    if len(positions) == 0:
        raise ValueError("an AR forecast needs at least one position")
    if not np.all(np.isfinite(positions)):
        raise ValueError("AR history contains non-finite positions")
    if horizon < 0:
        raise ValueError(f"horizon must be non-negative, got {horizon}")
    if order < 1:
        raise ValueError(f"AR order must be at least 1, got {order}")
    positions = positions[-settings.max_history :]
    last = positions[-1]
    if len(positions) == 1:
        return ArForecast(position=last.copy(), order_used=0, fallback="constant_position")

    if settings.series == "displacement":
        series_per_axis = [np.diff(positions[:, axis]) for axis in range(2)]
    else:
        # Centring on z_n keeps the intercept column well conditioned against the lags.
        series_per_axis = [positions[:, axis] - last[axis] for axis in range(2)]

    for candidate in range(order, 0, -1):
        models = _fit_both(series_per_axis, candidate, settings)
        if models is None:
            continue
        forecast = np.empty(2)
        for axis, (model, series) in enumerate(zip(models, series_per_axis, strict=True)):
            future = forecast_series(model, series, horizon)
            if settings.series == "displacement":
                forecast[axis] = last[axis] + float(np.sum(future))
            else:
                forecast[axis] = last[axis] + (float(future[-1]) if horizon else 0.0)
        fallback = None if candidate == order else f"ar{candidate}"
        return ArForecast(position=forecast, order_used=candidate, fallback=fallback)

    displacements = np.diff(positions, axis=0)[-CONSTANT_VELOCITY_WINDOW:]
    velocity = displacements.mean(axis=0)
    return ArForecast(
        position=last + horizon * velocity, order_used=0, fallback="constant_velocity"
    )

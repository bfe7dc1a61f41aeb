"""AR motion predictor: one candidate U_k per AR order k (paper §3.4.1).

See docs/algorithms/predictors.md#ar-predictor.

The gap matcher receives U_1, U_2, U_3 (by default) and picks the order whose association cost is
lowest, so this predictor only forecasts and never chooses.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from trackfw.records import GapProblem, Prediction
from trackfw.stages import Predictor, StageParams
from trackfw_plugins.maths.autoregressive import ArSettings, forecast_ar

MAX_ORDER = 10


class ArParams(StageParams):
    """Parameters of the AR predictor (docs/algorithms/predictors.md#parameters)."""

    orders: list[int] = Field(
        default=[1, 2, 3],
        description="AR orders k to forecast with (each 1..10); one candidate U_k per order.",
    )
    series: Literal["displacement", "position"] = Field(
        default="displacement",
        description="Model frame-to-frame displacements (ARIMA(k,1,0) with drift) or "
        "positions centred on the last one.",
    )
    max_history: int = Field(
        default=100, ge=1, description="Use only the most recent positions of the segment."
    )
    min_eq_factor: float = Field(
        default=2.0,
        gt=0.0,
        description="Fit order k only with at least min_eq_factor*(k+1) equations.",
    )
    stability_rho: float = Field(
        default=0.99,
        gt=0.0,
        description="Companion spectral radius at or above which the AR roots are shrunk.",
    )
    shrink_to: float = Field(
        default=0.95,
        gt=0.0,
        description="Spectral radius after shrinking (must be below stability_rho).",
    )
    ridge: float = Field(
        default=1e-6,
        ge=0.0,
        description="Relative ridge on the AR coefficients: trace(X'X)/(k+1) times this.",
    )

    relative_motion: float = Field(
        default=1.0,
        ge=0.0,
        le=1.0,
        description="Weight of each target's own forecast motion relative to the group's mean motion: "
        "1 = independent per-target AR (paper); 0 = the group moves rigidly by its mean AR displacement "
        "(ours: long horizons amplify per-target velocity noise into pattern distortion).",
    )

    @field_validator("orders")
    @classmethod
    def _check_orders(cls, orders: list[int]) -> list[int]:
        if not orders:
            raise ValueError("orders must name at least one AR order")
        for order in orders:
            if not 1 <= order <= MAX_ORDER:
                raise ValueError(f"each AR order must lie in 1..{MAX_ORDER}, got {order}")
        if len(set(orders)) != len(orders):
            raise ValueError(f"AR orders must be distinct, got {orders}")
        return orders

    @model_validator(mode="after")
    def _check_shrink(self) -> ArParams:
        if not self.shrink_to < self.stability_rho:
            raise ValueError(
                f"shrink_to ({self.shrink_to}) must be below stability_rho ({self.stability_rho})"
            )
        return self

    def settings(self) -> ArSettings:
        """The settings for :func:`forecast_ar`."""
        return ArSettings(
            series=self.series,
            max_history=self.max_history,
            min_eq_factor=self.min_eq_factor,
            stability_rho=self.stability_rho,
            shrink_to=self.shrink_to,
            ridge=self.ridge,
        )


class ArPredictor(Predictor[ArParams]):
    """Per-coordinate AR(k) forecast of every target on frame b, one candidate per order."""

    name = "ar"
    uses_pixels = False

    def __init__(self, params: ArParams | None = None) -> None:
        super().__init__(params)
        self._settings = self.params.settings()

    def predict(self, problem: GapProblem) -> Sequence[Prediction]:
        """Forecast every target ``problem.horizon`` frames ahead, once per configured order.

        Returns:
            One :class:`Prediction` per order, labelled ``"ar{k}"``, with ``(K, 2)`` positions
            and ``diagnostics["fallbacks"]`` mapping each target id to the fallback taken (a
            string) or the order used (an int).
        """
        target_ids = [int(target_id) for target_id in np.asarray(problem.target_ids).reshape(-1)]
        if len(problem.histories) != len(target_ids):
            raise ValueError(
                f"gap problem has {len(problem.histories)} histories for {len(target_ids)} targets"
            )
        predictions = []
        for order in self.params.orders:
            positions = np.zeros((len(target_ids), 2))
            fallbacks: dict[int, str | int] = {}
            for row, (target_id, history) in enumerate(
                zip(target_ids, problem.histories, strict=True)
            ):
                forecast = forecast_ar(history, order, problem.horizon, self._settings)
                positions[row] = forecast.position
                fallbacks[target_id] = (
                    forecast.fallback if forecast.fallback is not None else forecast.order_used
                )
            if self.params.relative_motion < 1.0 and len(target_ids):
                start = problem.positions_at_a
                displacement = positions - start
                mean = displacement.mean(axis=0)
                positions = start + mean + self.params.relative_motion * (displacement - mean)
            predictions.append(
                Prediction(
                    label=f"ar{order}", positions=positions, diagnostics={"fallbacks": fallbacks}
                )
            )
        return predictions

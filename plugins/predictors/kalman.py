"""Kalman "TR" predictor: constant-velocity extrapolation of the filter state at a.

See docs/algorithms/predictors.md#kalman-tr-predictor.

From the state s_a the filter is predicted h = b − a times without correction, s_b = F^h s_a, and
the prediction is u = H s_b, which equals position + h·velocity.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from trackfw.records import GapProblem, Prediction
from trackfw.stages import Predictor, StageParams
from trackfw_plugins.maths.kalman import extrapolate


class KalmanPredictorParams(StageParams):
    """The Kalman predictor has no parameters: F and H are the paper's (§1.1)."""


class KalmanPredictor(Predictor[KalmanPredictorParams]):
    """Kalman prediction without correction across the interval ("TR" in the paper)."""

    name = "kalman"
    uses_pixels = False

    def predict(self, problem: GapProblem) -> Sequence[Prediction]:
        """Extrapolate every target's state at a over ``problem.horizon`` frames.

        A state without velocity (a tracker without motion model) is extrapolated with zero
        velocity, i.e. it stays in place.

        Returns:
            One :class:`Prediction` labelled ``"kalman"`` with ``(K, 2)`` positions.
        """
        states = np.zeros((len(problem.states), 4))
        for row, state in enumerate(problem.states):
            states[row, :2] = np.asarray(state.position, dtype=np.float64).reshape(2)
            if state.velocity is not None:
                states[row, 2:] = np.asarray(state.velocity, dtype=np.float64).reshape(2)
        positions = extrapolate(states, problem.horizon)
        return [Prediction(label="kalman", positions=positions, diagnostics={})]

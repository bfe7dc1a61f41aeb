"""The ``assignment`` gap matcher: Hungarian or nearest neighbour on predicted positions.

The Kalman1/Kalman2 baselines of the paper (section 4.2): predict every target to frame b (TR or
AR), then associate predictions and detections with the same routine as inside segments. With
several candidate predictions (AR orders), the one with the smallest mean assigned distance wins
(docs/algorithms/gap-matchers.md#assignment).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.records import NO_MATCH, GapProblem, GapSolution, Prediction
from trackfw.stages import GapMatcher, StageParams
from trackfw_plugins.maths.assignment import distance_matrix, greedy_nearest, hungarian


class AssignmentParams(StageParams):
    """Parameters of the assignment gap matcher."""

    method: Literal["hungarian", "nearest"] = Field(
        "hungarian", description="'hungarian' (Kalman1) or greedy 'nearest' neighbour (Kalman2)"
    )
    gate_at_b_px: float | None = Field(
        None,
        gt=0.0,
        description="gate on frame b in pixels; null (default) = no gate, distance cannot gate after a pose change",
    )


class AssignmentGapMatcher(GapMatcher[AssignmentParams]):
    """Assigns detections on frame b to the predicted target positions."""

    name = "assignment"

    def _solve(self, prediction: Prediction, problem: GapProblem) -> tuple[GapSolution, float]:
        params = self.params
        detections = problem.detections
        positions = np.array(prediction.positions, dtype=np.float64).reshape(-1, 2)
        matched = np.full(len(positions), NO_MATCH, dtype=np.int64)
        cost = distance_matrix(positions, detections.points)
        solve = greedy_nearest if params.method == "nearest" else hungarian
        rows = solve(cost, params.gate_at_b_px) if len(detections) else matched.copy()
        assigned = np.flatnonzero(rows >= 0)
        mean_distance = (
            float(cost[assigned, rows[assigned]].mean()) if len(assigned) else float("inf")
        )
        positions[assigned] = detections.points[rows[assigned]]
        matched[assigned] = detections.index[rows[assigned]]
        solution = GapSolution(
            positions=positions,
            matched_detection=matched,
            cost=mean_distance if np.isfinite(mean_distance) else None,
            chosen=prediction.label,
            diagnostics={"predictor": prediction.diagnostics},
        )
        return solution, mean_distance

    def match(self, problem: GapProblem) -> GapSolution:
        candidates = list(self.predictor.predict(problem))
        scored = [self._solve(candidate, problem) for candidate in candidates]
        # Smallest mean assigned distance; the first candidate (lowest AR order) wins ties.
        best_index = min(range(len(scored)), key=lambda i: (scored[i][1], i))
        best = scored[best_index][0]
        best.diagnostics["candidates"] = {
            candidate.label: (None if not np.isfinite(score) else round(score, 4))
            for candidate, (_, score) in zip(candidates, scored, strict=True)
        }
        return best

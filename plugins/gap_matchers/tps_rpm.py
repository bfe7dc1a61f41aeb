"""The ``tps-rpm`` gap matcher: plain TPS-RPM between all predictions and all detections.

The ablation of the proposed method without windows (and the Kalman3 baseline at frame b,
docs/algorithms/gap-matchers.md#plain-tps-rpm): one TPS-RPM run registers the predicted pattern U
onto every detection on frame b. With several candidate predictions (AR orders) the one with the
smallest psi = bending + lambda1 * unmatched wins. Unmatched targets are placed by the TPS map.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from trackfw.records import NO_MATCH, GapProblem, GapSolution
from trackfw.stages import GapMatcher, StageParams
from trackfw_plugins.maths.tps_rpm import match_points
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings, one_image_settings


class TpsRpmGapParams(StageParams):
    """Parameters of the plain TPS-RPM gap matcher."""

    rpm: TpsRpmSettings = Field(
        default_factory=one_image_settings,
        description="TPS-RPM settings (docs/algorithms/tps-rpm.md#parameters)",
    )
    lambda1: float = Field(
        1.0, ge=0, description="weight of the unmatched count when choosing among predictions"
    )


class TpsRpmGapMatcher(GapMatcher[TpsRpmGapParams]):
    """TPS-RPM registration of the predicted pattern onto all detections at frame b (no windows)."""

    name = "tps-rpm"

    def match(self, problem: GapProblem) -> GapSolution:
        params = self.params
        detections = problem.detections
        best: GapSolution | None = None
        costs: dict[str, float] = {}
        for candidate in self.predictor.predict(problem):
            rows, positions, result = match_points(
                candidate.positions, detections.points, params.rpm
            )
            unmatched = int((rows < 0).sum())
            bending = 0.0 if result is None else float(result.bending_energy)
            cost = bending + params.lambda1 * unmatched
            costs[candidate.label] = round(cost, 6)
            if best is None or best.cost is None or cost < best.cost:
                matched = np.where(
                    rows >= 0,
                    detections.index[np.maximum(rows, 0)] if len(detections) else NO_MATCH,
                    NO_MATCH,
                )
                best = GapSolution(
                    positions=positions,
                    matched_detection=matched.astype(np.int64),
                    cost=cost,
                    chosen=candidate.label,
                    diagnostics={"bending": bending, "unmatched": unmatched},
                )
        assert best is not None, "the predictor returned no candidate"
        best.diagnostics["candidates"] = costs
        return best

"""The ``reid`` gap matcher: LOMO or GOG person re-identification at frame b (paper section 4.2).

The paper's re-ID baselines track inside segments like the proposed method and, on frame b,
match targets to detections by descriptor distance. Each target's descriptor comes from its
crop at its tracked position on frame a, each detection's from its crop on frame b; the
training-free distance (pooled mean subtraction, L2, Euclidean; ALGORITHMS.md 8.1-8.2) feeds a
Hungarian assignment. Targets left without a detection are placed at the predictor's position.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray
from trackfw.records import NO_MATCH, GapProblem, GapSolution
from trackfw.stages import GapMatcher, StageParams
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.gog import gog_block_sizes, gog_descriptors
from trackfw_plugins.maths.lomo import lomo_descriptors
from trackfw_plugins.maths.reid_crop import reid_crops, reid_distance_matrix


class ReidParams(StageParams):
    """Parameters of the re-ID gap matcher."""

    descriptor: Literal["lomo", "gog"] = Field(
        "lomo", description="re-ID descriptor: 'lomo' (Liao 2015) or 'gog' (Matsukawa 2016)"
    )
    crop: Literal["body", "head80"] = Field(
        "body",
        description="'body' = 1.5s x 4s box below the head resized to 128x48; 'head80' = the head patch",
    )


class ReidGapMatcher(GapMatcher[ReidParams]):
    """Hungarian assignment on LOMO or GOG descriptor distances between frames a and b."""

    name = "reid"
    uses_pixels = True

    def _descriptors(self, image: np.ndarray, points: FloatArray) -> FloatArray:
        params = self.params
        crops = reid_crops(image, points, params.crop)
        if params.descriptor == "gog":
            return gog_descriptors(crops)
        return lomo_descriptors(crops)

    def match(self, problem: GapProblem) -> GapSolution:
        params = self.params
        if problem.frame_a is None or problem.frame_b is None:
            raise ValueError("the reid gap matcher needs the pixels of frames a and b")
        prediction = self.predictor.predict(problem)[0]
        positions = np.array(prediction.positions, dtype=np.float64).reshape(-1, 2)
        matched = np.full(len(positions), NO_MATCH, dtype=np.int64)
        detections = problem.detections
        cost = None
        if len(detections) and len(positions):
            query = self._descriptors(problem.frame_a, problem.positions_at_a)
            gallery = self._descriptors(problem.frame_b, detections.points)
            blocks = gog_block_sizes() if params.descriptor == "gog" else None
            distances = reid_distance_matrix(query, gallery, blocks)
            rows = hungarian(distances)
            assigned = np.flatnonzero(rows >= 0)
            positions[assigned] = detections.points[rows[assigned]]
            matched[assigned] = detections.index[rows[assigned]]
            cost = float(distances[assigned, rows[assigned]].mean()) if len(assigned) else None
        return GapSolution(
            positions=positions,
            matched_detection=matched,
            cost=cost,
            chosen=prediction.label,
            diagnostics={"descriptor": params.descriptor, "crop": params.crop},
        )

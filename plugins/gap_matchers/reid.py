"""The ``reid`` gap matcher: LOMO, GOG or deep person re-identification at frame b (section 4.2).

The paper's re-ID baselines track inside segments like the proposed method and, on frame b,
match targets to detections by descriptor distance. Each target's descriptor comes from its
crop at its tracked position on frame a, each detection's from its crop on frame b; the
training-free distance (pooled mean subtraction, L2, Euclidean;
docs/algorithms/gap-matchers.md#re-identification) feeds a
Hungarian assignment. Targets left without a detection are placed at the predictor's position.

``descriptor: person-reid`` [OURS] uses a pretrained deep embedder instead
(:mod:`trackfw_plugins.maths.person_reid`): body crops from the head points and the detections'
head sizes, cosine distance between the L2-normalised embeddings.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray
from trackfw.records import NO_MATCH, Detections, GapProblem, GapSolution
from trackfw.stages import GapMatcher, Stage, StageParams
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.gog import gog_block_sizes, gog_descriptors
from trackfw_plugins.maths.lomo import lomo_descriptors
from trackfw_plugins.maths.person_reid import (
    PersonReidEmbedder,
    body_boxes,
    cosine_distance_matrix,
    detection_rows,
)
from trackfw_plugins.maths.reid_crop import head_size, reid_crops, reid_distance_matrix


class ReidParams(StageParams):
    """Parameters of the re-ID gap matcher."""

    descriptor: Literal["lomo", "gog", "person-reid"] = Field(
        "lomo",
        description="re-ID descriptor: 'lomo' (Liao 2015), 'gog' (Matsukawa 2016) or"
        " 'person-reid' (a pretrained deep embedder, cosine distance)",
    )
    reid_model: str = Field(
        "0287",
        description="person-reid: embedder '0287' (shipped), '0248' (shipped, smaller) or an"
        " ONNX path",
    )
    threads: int = Field(
        0, ge=0, description="person-reid: onnxruntime threads; 0 = the automatic choice"
    )
    crop: Literal["body", "head80"] = Field(
        "body",
        description="'body' = 1.5s x 4s box below the head resized to 128x48; 'head80' = the head patch",
    )


class ReidGapMatcher(GapMatcher[ReidParams]):
    """Hungarian assignment on LOMO or GOG descriptor distances between frames a and b."""

    name = "reid"
    uses_pixels = True

    def __init__(self, params: ReidParams | None = None, **nested: Stage) -> None:
        super().__init__(params, **nested)
        self.embedder = (
            PersonReidEmbedder(self.params.reid_model, self.params.threads)
            if self.params.descriptor == "person-reid"
            else None
        )

    def _embeddings(
        self, image: np.ndarray, points: FloatArray, detections: Detections | None, rows: np.ndarray
    ) -> FloatArray:
        assert self.embedder is not None
        boxes = body_boxes(points, detections, rows, head_size(image.shape[0]))
        return self.embedder.describe(image, boxes)

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
            if self.embedder is not None:
                matched_at_a = [state.matched_detection for state in problem.states]
                query = self._embeddings(
                    problem.frame_a,
                    problem.positions_at_a,
                    problem.detections_a,
                    detection_rows(problem.detections_a, matched_at_a),
                )
                gallery = self._embeddings(
                    problem.frame_b, detections.points, detections, np.arange(len(detections))
                )
                distances = cosine_distance_matrix(query, gallery)
            else:
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

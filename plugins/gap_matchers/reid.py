"""The ``reid`` gap matcher: LOMO, GOG or deep person re-identification at frame b (section 4.2).

The paper's re-ID baselines track inside segments like the proposed method and, on frame b,
match targets to detections by descriptor distance. Each target's descriptor comes from its
crop at its tracked position on frame a, each detection's from its crop on frame b; the
training-free distance (pooled mean subtraction, L2, Euclidean;
docs/algorithms/gap-matchers.md#re-identification) feeds a
Hungarian assignment. Targets left without a detection are placed at the predictor's position;
with several candidates (AR orders) each is scored by the mean re-ID distance of every target
to what lies at its position on b, and the cheapest wins.

``descriptor: person-reid`` [OURS] uses a pretrained deep embedder instead
(:mod:`trackfw_plugins.maths.person_reid`): body crops from the head points and the detections'
head sizes, cosine distance between the L2-normalised embeddings.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray, IntArray
from trackfw.records import NO_MATCH, Detections, GapProblem, GapSolution, Prediction
from trackfw.stages import GapMatcher, Stage, StageParams
from trackfw_plugins.maths.assignment import hungarian, match_ratios
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
        0,
        ge=0,
        description="person-reid: crops embedded at once (one onnxruntime thread each); 0 = the"
        " automatic choice",
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

    def _query(self, problem: GapProblem) -> FloatArray:
        """``(K, D)`` descriptors of the targets at their tracked positions on frame a."""
        assert problem.frame_a is not None
        if self.embedder is not None:
            matched_at_a = [state.matched_detection for state in problem.states]
            return self._embeddings(
                problem.frame_a,
                problem.positions_at_a,
                problem.detections_a,
                detection_rows(problem.detections_a, matched_at_a),
            )
        return self._descriptors(problem.frame_a, problem.positions_at_a)

    def _features(
        self, image: np.ndarray, points: FloatArray, detections: Detections | None
    ) -> FloatArray:
        """``(P, D)`` features of what lies at ``points`` on ``image``.

        ``detections`` are the detections at ``points`` (their boxes give the person sizes), or
        None for positions that no detection supports.
        """
        if self.embedder is not None:
            rows = np.arange(len(points)) if detections is not None else np.full(len(points), -1)
            return self._embeddings(image, points, detections, rows)
        return self._descriptors(image, points)

    def _distance(self, query: FloatArray, gallery: FloatArray) -> FloatArray:
        """``(K, P)`` re-ID distances (the pooled normalisation spans query and gallery)."""
        if self.embedder is not None:
            return cosine_distance_matrix(query, gallery)
        blocks = gog_block_sizes() if self.params.descriptor == "gog" else None
        return reid_distance_matrix(query, gallery, blocks)

    def _solve(
        self,
        candidate: Prediction,
        problem: GapProblem,
        rows: IntArray,
        query: FloatArray,
        gallery: FloatArray,
    ) -> tuple[GapSolution, float]:
        """The solution with ``candidate`` placing the unmatched targets, and its cost.

        The cost is the mean re-ID distance of every target to what lies at its position on b:
        its detection, or, for a target without one, the crop at the candidate's position. Only
        that second part depends on the candidate.
        """
        assert problem.frame_b is not None
        detections = problem.detections
        positions = np.array(candidate.positions, dtype=np.float64).reshape(-1, 2)
        matched = np.full(len(positions), NO_MATCH, dtype=np.int64)
        assigned = np.flatnonzero(rows >= 0)
        positions[assigned] = detections.points[rows[assigned]]
        matched[assigned] = detections.index[rows[assigned]]
        unmatched = np.flatnonzero(rows < 0)
        pool = [gallery] if len(gallery) else []
        if len(unmatched):
            pool.append(self._features(problem.frame_b, positions[unmatched], None))
        # One normalisation pool for detections and placements, so that their distances compare
        # (with every target matched it is the assignment's own matrix).
        distances = self._distance(query, np.concatenate(pool))
        placed_columns = len(gallery) + np.arange(len(unmatched))
        per_target = np.zeros(len(positions))
        per_target[assigned] = distances[assigned, rows[assigned]]
        per_target[unmatched] = distances[unmatched, placed_columns]
        cost = float(per_target.mean()) if len(positions) else float("inf")
        solution = GapSolution(
            positions=positions,
            matched_detection=matched,
            cost=cost if np.isfinite(cost) else None,
            chosen=candidate.label,
            diagnostics={"descriptor": self.params.descriptor, "crop": self.params.crop},
        )
        return solution, cost

    def match(self, problem: GapProblem) -> GapSolution:
        """Hungarian on re-ID distances; the predictor's candidates place the unmatched targets.

        Every candidate is scored (see :meth:`_solve`); the cheapest wins, the first on ties.
        Each match's distance over the target's distance to its nearest other detection is
        given as the solution's ``match_ratios`` (a tracker may test a match that barely beat
        another harder).
        """
        if problem.frame_a is None or problem.frame_b is None:
            raise ValueError("the reid gap matcher needs the pixels of frames a and b")
        candidates = list(self.predictor.predict(problem))
        detections = problem.detections
        rows = np.full(len(problem.target_ids), NO_MATCH, dtype=np.int64)
        if not len(problem.target_ids):
            return GapSolution(np.zeros((0, 2)), rows, chosen=candidates[0].label)
        query = self._query(problem)
        gallery = self._features(problem.frame_b, detections.points, detections)
        ratios = np.full(len(rows), np.nan)
        if len(detections):
            # The assignment does not depend on the candidate: appearance alone decides it.
            distances = self._distance(query, gallery)
            rows = hungarian(distances)
            ratios = match_ratios(distances, rows)
        scored = [self._solve(c, problem, rows, query, gallery) for c in candidates]
        best = min(range(len(scored)), key=lambda i: (scored[i][1], i))
        solution = scored[best][0]
        solution.match_ratios = ratios
        solution.diagnostics["candidates"] = {
            candidate.label: None if not np.isfinite(cost) else round(cost, 6)
            for candidate, (_, cost) in zip(candidates, scored, strict=True)
        }
        return solution

"""The ``window-tps-rpm`` gap matcher: the proposed method of Yu et al. 2018 (section 3.4).

For every candidate prediction U_k (AR orders 1..3 by default), every 4-point window W of the
detections on frame b is matched to U_k with TPS-RPM; the cost
psi = bending energy + lambda1 (|U| - d_W) + lambda2 E_a picks the window, and the order with the
smallest cost wins. Unmatched targets are placed by the window's TPS map. With ``look_margin``
(ours), the one-to-one assignment on appearance alone overrules a chosen window whose pairs look
much less alike than that assignment's (docs/algorithms/gap-matchers.md#look-check). The maths
lives in :mod:`trackfw_plugins.maths.window_association`; this module wires the predictor, the
appearance term and the records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from typing import Any, Literal

import numpy as np
from pydantic import Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.records import NO_MATCH, Detections, GapProblem, GapSolution, Prediction
from trackfw.stages import GapMatcher, Stage, StageParams
from trackfw_plugins.maths.appearance import (
    appearance_descriptors,
    appearance_distance_matrix,
    patch_descriptor,
)
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.candidate_windows import WindowSet
from trackfw_plugins.maths.gated_association import associate_gated
from trackfw_plugins.maths.person_reid import (
    PersonReidEmbedder,
    body_boxes,
    detection_rows,
    nearest_rows,
)
from trackfw_plugins.maths.reid_crop import crop_box
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings
from trackfw_plugins.maths.window_association import (
    FALLBACK_BOUND,
    TIE_TOLERANCE,
    WindowAssociationParams,
    WindowAssociationResult,
    associate_candidates,
    select_candidate,
    skipped_result,
)


def _fast_rpm() -> TpsRpmSettings:
    # float32 annealing agrees with float64 to ~1e-8 in psi with the same matches, at half the time.
    return TpsRpmSettings(precision="float32")


class WindowTpsRpmParams(StageParams, WindowAssociationParams):
    """Parameters of the window-based TPS-RPM gap matcher.

    See docs/algorithms/gap-matchers.md#parameters.
    """

    rpm: TpsRpmSettings = Field(
        default_factory=_fast_rpm,
        description="TPS-RPM settings (docs/algorithms/tps-rpm.md#parameters)",
    )
    patch_at_1080: float = Field(
        80.0,
        gt=0,
        description="side of the appearance patches at 1080p (paper: 80), scaled by height/1080",
    )
    appearance_region: Literal["patch", "body", "person-reid"] = Field(
        "patch",
        description="'patch' = square centred on the head (paper); 'body' = the 1.5s x 4s box below a head of "
        "detected size s, resized to 80x80 (ours: clothing tells people apart when heads are small); "
        "'person-reid' = a pretrained deep re-ID embedding of the body crop (ours, for real footage)",
    )
    lambda3: float = Field(
        0.0,
        ge=0,
        description="weight of the position evidence E_p (1 for a free candidate, the mean "
        "distance/gate of a positioned one's pairs); 0 = the paper's cost",
    )
    reid_model: str = Field(
        "0287",
        description="appearance_region person-reid: embedder '0287' (shipped), '0248' (shipped,"
        " smaller) or an ONNX path",
    )
    look_margin: float | None = Field(
        None,
        ge=0,
        description="when the chosen match's mean appearance distance exceeds that of the best "
        "one-to-one appearance assignment by more than this, the pattern was found on other "
        "people and the appearance assignment is the answer; None = the paper's rule (ours)",
    )
    look_region: float | None = Field(
        None,
        ge=0,
        description="with look_margin: the appearance assignment takes only detections within "
        "the chosen match's bounding box grown on every side by this many times its larger "
        "side; None = anywhere in frame b (ours)",
    )


def _head_sizes(
    detections: Detections | None, rows: IntArray | None, count: int, fallback: float
) -> FloatArray:
    """Head size per point from detection boxes (the median box where a point has none)."""
    if detections is None or detections.boxes is None or len(detections) == 0:
        return np.full(count, fallback)
    sides = detections.boxes[:, 2:4].mean(axis=1)
    median = float(np.median(sides))
    if rows is None:
        return sides.copy()
    return np.array(
        [sides[row] if 0 <= row < len(sides) else median for row in rows], dtype=np.float64
    )


def _body_descriptors(image: np.ndarray, points: FloatArray, sizes: FloatArray) -> FloatArray:
    patches = [
        crop_box(image, x - 0.75 * s, y - 0.5 * s, 1.5 * s, 4.0 * s, (80, 80))
        for (x, y), s in zip(points, sizes, strict=True)
    ]
    return np.array([patch_descriptor(patch) for patch in patches]).reshape(len(patches), -1)


def target_embeddings(
    problem: GapProblem, embedder: PersonReidEmbedder, fallback_size: float
) -> FloatArray:
    """``(K, D)`` person re-ID embeddings of the targets before the interval.

    A target that a detection supported on frame a is described there. One that none did was
    only predicted on a, which is often already turning away (the classifier saw the interval
    a few frames late): it is described on the look-back frame instead, where the problem
    carries its tracked position and the frame's detections, when there is one.
    """
    assert problem.frame_a is not None
    matched_at_a = [state.matched_detection for state in problem.states]
    rows_a = detection_rows(problem.detections_a, matched_at_a)
    boxes_a = body_boxes(problem.positions_at_a, problem.detections_a, rows_a, fallback_size)
    lookback = problem.lookback
    earlier = np.array([index == NO_MATCH for index in matched_at_a], dtype=bool)
    if lookback is None or lookback.image is None or not earlier.any():
        return embedder.describe(problem.frame_a, boxes_a)
    # Each target is embedded once: on frame a or on the look-back frame.
    points = lookback.positions[earlier]
    rows = nearest_rows(points, lookback.detections)
    on_lookback = embedder.describe(
        lookback.image, body_boxes(points, lookback.detections, rows, fallback_size)
    )
    embeddings = np.zeros((len(matched_at_a), on_lookback.shape[1]), dtype=on_lookback.dtype)
    embeddings[earlier] = on_lookback
    if not earlier.all():
        embeddings[~earlier] = embedder.describe(problem.frame_a, boxes_a[~earlier])
    return embeddings


def appearance_matrix(
    problem: GapProblem, params: WindowTpsRpmParams, embedder: PersonReidEmbedder | None = None
) -> FloatArray | None:
    """``(K, N)`` appearance distances between targets at frame a and detections at frame b.

    With ``embedder`` (``appearance_region: person-reid``) the distance is the Euclidean one
    between unit embeddings, in [0, 2] like the paper descriptor's [0, sqrt 2].
    """
    if problem.frame_a is None or problem.frame_b is None:
        return None
    scale = problem.video.height / 1080.0
    if embedder is not None:
        fallback = params.patch_at_1080 * scale / 2
        boxes_b = body_boxes(
            problem.detections.points,
            problem.detections,
            np.arange(len(problem.detections)),
            fallback,
        )
        return appearance_distance_matrix(
            target_embeddings(problem, embedder, fallback),
            embedder.describe(problem.frame_b, boxes_b),
        )
    if params.appearance_region == "body":
        fallback = params.patch_at_1080 * scale / 2
        detections_a = problem.detections_a
        rows_a = None
        if detections_a is not None:
            position = {int(index): row for row, index in enumerate(detections_a.index)}
            rows_a = np.array(
                [position.get(state.matched_detection, -1) for state in problem.states]
            )
        sizes_a = _head_sizes(detections_a, rows_a, len(problem.states), fallback)
        sizes_b = _head_sizes(problem.detections, None, len(problem.detections), fallback)
        targets = _body_descriptors(problem.frame_a, problem.positions_at_a, sizes_a)
        detections = _body_descriptors(problem.frame_b, problem.detections.points, sizes_b)
    else:
        factor = scale * params.patch_at_1080 / 80.0
        targets = appearance_descriptors(problem.frame_a, problem.positions_at_a, scale=factor)
        detections = appearance_descriptors(
            problem.frame_b, problem.detections.points, scale=factor
        )
    return appearance_distance_matrix(targets, detections)


def score_candidates(
    candidates: Sequence[Prediction],
    detections: FloatArray,
    appearance: FloatArray | None,
    params: WindowAssociationParams,
    windows: WindowSet | None,
    lambda3: float = 0.0,
) -> tuple[list[WindowAssociationResult], list[float]]:
    """Cost and association of every candidate, in candidate order, and each one's E_p.

    Candidates in frame a's geometry (``gate`` None) search every window with TPS-RPM and have
    no position evidence (E_p = 1); positioned ones (``gate`` set) are associated inside their
    gate (docs/algorithms/gap-matchers.md#positioned-candidates). Every cost is
    ψ + ``lambda3`` · E_p. Positioned candidates are scored first: when no free candidate can
    beat the best of them (:func:`free_cost_bound`), the window search is skipped and the free
    candidates are recorded with an infinite cost and the fallback ``bound``.
    """
    count = len(candidates[0].positions) if candidates else 0
    results: list[WindowAssociationResult | None] = [None] * len(candidates)
    evidence = [1.0] * len(candidates)
    for index, candidate in enumerate(candidates):
        if candidate.gate is not None and len(detections) and count:
            results[index], evidence[index] = associate_gated(
                candidate.positions, detections, candidate.gate, appearance, params, lambda3
            )
    best = min((result.cost for result in results if result is not None), default=np.inf)
    free = [index for index, result in enumerate(results) if result is None]
    bound = free_cost_bound(count, len(detections), appearance, params, lambda3)
    if free and bound > best + TIE_TOLERANCE:
        for index in free:
            results[index] = skipped_result(candidates[index].positions, FALLBACK_BOUND)
    elif free:
        free_results = associate_candidates(
            [candidates[index].positions for index in free], detections, appearance, params, windows
        )
        for index, result in zip(free, free_results, strict=True):
            result.cost += lambda3
            results[index] = result
    return [result for result in results if result is not None], evidence


def free_cost_bound(
    count: int,
    detections: int,
    appearance: FloatArray | None,
    params: WindowAssociationParams,
    lambda3: float,
) -> float:
    """A lower bound on the cost ψ + λ3 of any free candidate, whatever window wins.

    φ ≥ 0; a window, or all of V in the fallbacks, leaves at least K − N targets unmatched; E_a
    is a mean of appearance distances, so at least their minimum, unless nothing is matched,
    which costs λ1 K.
    """
    smallest = float(np.min(appearance)) if appearance is not None and appearance.size else 0.0
    matched = params.lambda1 * max(0, count - detections) + params.lambda2 * smallest
    return lambda3 + min(params.lambda1 * count, matched)


def region_columns(points: FloatArray, rows: IntArray, grow: float) -> BoolArray:
    """``(N,)`` detections within the bounding box of ``points[rows]`` grown by ``grow`` sides.

    The box is grown on every side by ``grow`` times its larger side (at least one pixel, so
    that a single matched head still has a region).

    >>> points = np.array([[0.0, 0.0], [10.0, 0.0], [14.0, 0.0], [30.0, 0.0]])
    >>> region_columns(points, np.array([0, 1, -1]), 0.5).tolist()
    [True, True, True, False]
    """
    held = rows[rows >= 0]
    if not held.size:
        return np.ones(len(points), dtype=bool)
    low, high = points[held].min(axis=0), points[held].max(axis=0)
    margin = max(grow * float((high - low).max()), 1.0)
    inside = (points >= low - margin) & (points <= high + margin)
    return np.asarray(inside.all(axis=1), dtype=bool)


def look_check(
    window_rows: IntArray,
    appearance: FloatArray,
    margin: float,
    allowed: BoolArray | None = None,
) -> tuple[IntArray | None, dict[str, Any]]:
    """Whether the look overrules the pattern's match, and the record of the check.

    ``window_rows`` ``(K,)`` are the detections (columns of the ``(K, N)`` ``appearance``
    distances) the chosen window matched, -1 for none. When the mean distance of those pairs
    exceeds the mean of the best one-to-one assignment on appearance alone by more than
    ``margin``, the pattern was found on other people: the assignment's ``(K,)`` rows are
    returned (-1 where it leaves a target out), else None. ``allowed`` ``(N,)`` limits the
    assignment to those detections.

    >>> distances = np.array([[0.2, 0.9, 0.8], [0.9, 0.3, 0.8]])
    >>> look_check(np.array([0, 1]), distances, 0.1)[0] is None
    True
    >>> look_check(np.array([2, 0]), distances, 0.1)[0].tolist()
    [0, 1]
    """
    matched = np.flatnonzero(window_rows >= 0)
    if allowed is None:
        rows = hungarian(appearance)
    else:
        columns = np.flatnonzero(allowed)
        rows = hungarian(appearance[:, columns])
        rows = np.where(rows >= 0, columns[np.maximum(rows, 0)], NO_MATCH)
    assigned = np.flatnonzero(rows >= 0)
    if not matched.size or not assigned.size:
        return None, {"overruled": False}
    window = float(appearance[matched, window_rows[matched]].mean())
    best = float(appearance[assigned, rows[assigned]].mean())
    overruled = window - best > margin
    record = {"window": round(window, 6), "assignment": round(best, 6), "overruled": overruled}
    return (rows if overruled else None), record


def candidate_records(
    candidates: Sequence[Prediction],
    results: Sequence[WindowAssociationResult],
    evidence: Sequence[float],
    detections: Detections,
) -> dict[str, Any]:
    """gaps.json's record of every candidate: its cost terms, window and diagnostics."""
    records: dict[str, Any] = {}
    for index, (candidate, result) in enumerate(zip(candidates, results, strict=True)):
        record: dict[str, Any] = {
            "cost": round(float(result.cost), 6),
            "bending": round(float(result.bending), 6),
            "unmatched": int(result.unmatched),
            "appearance": round(float(result.appearance), 6),
            "window": [int(detections.index[i]) for i in result.window],
            "counts": asdict(result.diagnostics),
            "predictor": candidate.diagnostics,
        }
        if candidate.gate is not None:
            record["gate_px"] = round(float(candidate.gate), 3)
            record["position_evidence"] = round(evidence[index], 6)
        records[candidate.label] = record
    return records


class WindowTpsRpmGapMatcher(GapMatcher[WindowTpsRpmParams]):
    """AR prediction + window-based TPS-RPM matching of the group's spatial pattern (the paper's method)."""

    name = "window-tps-rpm"
    default_predictor = "ar"

    def __init__(self, params: WindowTpsRpmParams | None = None, **nested: Stage) -> None:
        super().__init__(params, **nested)
        self.embedder = (
            PersonReidEmbedder(self.params.reid_model)
            if self.params.appearance_region == "person-reid" and self.params.lambda2 > 0
            else None
        )

    @property
    def needs_pixels(self) -> bool:
        # Pixels serve only the appearance term.
        return self.params.lambda2 > 0 or super().needs_pixels

    def match(self, problem: GapProblem) -> GapSolution:
        params = self.params
        candidates = list(self.predictor.predict(problem))
        detections = problem.detections
        appearance = (
            appearance_matrix(problem, params, self.embedder)
            if params.lambda2 > 0 and len(detections)
            else None
        )
        association = WindowAssociationParams(
            **{name: getattr(params, name) for name in WindowAssociationParams.model_fields}
        )
        results, evidence = score_candidates(
            candidates, detections.points, appearance, association, None, params.lambda3
        )
        best = select_candidate(results)
        result = results[best]
        rows = result.matched_detection
        positions = np.asarray(result.positions, dtype=np.float64)
        chosen = candidates[best].label
        look: dict[str, Any] | None = None
        if params.look_margin is not None and appearance is not None:
            allowed = (
                None
                if params.look_region is None
                else region_columns(detections.points, rows, params.look_region)
            )
            overruling, look = look_check(rows, appearance, params.look_margin, allowed)
            if overruling is not None:
                # Targets the look leaves out (fewer detections than targets) stay where the
                # chosen candidate placed them.
                look["overruled_candidate"] = chosen
                rows = overruling
                positions = np.where(
                    (rows >= 0)[:, None], detections.points[np.maximum(rows, 0)], positions
                )
                chosen = "look"
        matched = np.where(
            rows >= 0,
            detections.index[np.maximum(rows, 0)] if len(detections) else NO_MATCH,
            NO_MATCH,
        )
        diagnostics: dict[str, Any] = {
            "fallback": result.diagnostics.fallback,
            "candidates": candidate_records(candidates, results, evidence, detections),
            "appearance_used": appearance is not None,
        }
        if look is not None:
            diagnostics["look_check"] = look
        return GapSolution(
            positions=positions,
            matched_detection=matched.astype(np.int64),
            cost=float(result.cost),
            chosen=chosen,
            diagnostics=diagnostics,
        )

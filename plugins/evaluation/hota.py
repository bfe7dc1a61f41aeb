"""HOTA (Luiten et al., IJCV 2021), TrackEval's convention.

Similarity: IoU for boxes; for points ``sim = max(0, 1 - d / zero_distance)`` (TrackEval's
Euclidean similarity). The default zero distance is twice the CLEAR MOT threshold [OURS], so that
alpha = 0.5 accepts exactly the pairs CLEAR MOT accepts (40 px of 80 px).

Per sequence: a global alignment score between every ground-truth and hypothesis identity weights
the per-frame similarity; one Hungarian matching per frame on that weighted score; then, for each
alpha in 0.05, 0.10, ..., 0.95, pairs with similarity >= alpha are true positives. DetA, AssA and
LocA follow; HOTA(alpha) = sqrt(DetA * AssA) and each metric is the mean over alphas. Sequences
are pooled by summing TP, FN, FP and the TP-weighted association and localisation sums, which is
TrackEval's combination.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.evaluation.clear_mot import (
    FrameObservations,
    Geometry,
    default_threshold,
    identity_indices,
    pairwise_distances,
)
from trackfw_plugins.maths.assignment import linear_sum_assignment
from trackfw_plugins.maths.box_overlap import box_iou

#: TrackEval's alpha thresholds 0.05 .. 0.95.
ALPHAS: FloatArray = np.arange(0.05, 0.99, 0.05)
_EPSILON = float(np.finfo(float).eps)


def similarity_matrix(
    gt_positions: FloatArray,
    hyp_positions: FloatArray,
    geometry: Geometry = "point",
    zero_distance: float | None = None,
) -> FloatArray:
    """``(N, M)`` similarities in [0, 1]: IoU for boxes, ``max(0, 1 - d / zero_distance)`` for points.

    >>> similarity_matrix(np.array([[0.0, 0.0]]), np.array([[20.0, 0.0]]), zero_distance=80.0).tolist()
    [[0.75]]
    """
    if geometry == "box":
        return box_iou(gt_positions, hyp_positions)
    distances = pairwise_distances(gt_positions, hyp_positions, "point")
    return _similarity_from_distances(distances, "point", zero_distance)


def _similarity_from_distances(
    distances: FloatArray, geometry: Geometry, zero_distance: float | None
) -> FloatArray:
    if geometry == "box":
        # The box distance is 1 - IoU.
        return 1.0 - distances
    limit = 2.0 * default_threshold("point") if zero_distance is None else float(zero_distance)
    return np.maximum(0.0, 1.0 - distances / limit)


@dataclass
class HotaCounts:
    """Per-alpha sums of one sequence, or several pooled with ``+``.

    Attributes:
        alphas: ``(A,)`` thresholds.
        tp, fn, fp: ``(A,)`` detection true positives, false negatives, false positives.
        association_sum: ``(A,)`` sum over TPs of the pair's association IoU (AssA * TP).
        association_recall_sum, association_precision_sum: the same for AssRe and AssPr.
        localisation_sum: ``(A,)`` sum of the TPs' similarities (LocA * TP).
    """

    alphas: FloatArray = field(default_factory=lambda: ALPHAS.copy())
    tp: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    fn: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    fp: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    association_sum: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    association_recall_sum: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    association_precision_sum: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))
    localisation_sum: FloatArray = field(default_factory=lambda: np.zeros(len(ALPHAS)))

    def __add__(self, other: HotaCounts) -> HotaCounts:
        """Pool two sequences (TrackEval's TP-weighted combination)."""
        return HotaCounts(
            alphas=self.alphas,
            tp=self.tp + other.tp,
            fn=self.fn + other.fn,
            fp=self.fp + other.fp,
            association_sum=self.association_sum + other.association_sum,
            association_recall_sum=self.association_recall_sum + other.association_recall_sum,
            association_precision_sum=self.association_precision_sum
            + other.association_precision_sum,
            localisation_sum=self.localisation_sum + other.localisation_sum,
        )

    def per_alpha(self) -> dict[str, FloatArray]:
        """``(A,)`` arrays HOTA, DetA, AssA, DetRe, DetPr, AssRe, AssPr, LocA."""
        true_positives = np.maximum(1.0, self.tp)
        det_a = self.tp / np.maximum(1.0, self.tp + self.fn + self.fp)
        ass_a = self.association_sum / true_positives
        return {
            "HOTA": np.sqrt(det_a * ass_a),
            "DetA": det_a,
            "AssA": ass_a,
            "DetRe": self.tp / np.maximum(1.0, self.tp + self.fn),
            "DetPr": self.tp / np.maximum(1.0, self.tp + self.fp),
            "AssRe": self.association_recall_sum / true_positives,
            "AssPr": self.association_precision_sum / true_positives,
            "LocA": np.maximum(1e-10, self.localisation_sum) / np.maximum(1e-10, self.tp),
        }

    def summary(self) -> dict[str, float]:
        """Each metric's mean over alphas (fractions in [0, 1])."""
        return {name: float(values.mean()) for name, values in self.per_alpha().items()}

    @property
    def hota(self) -> float:
        """HOTA averaged over alphas."""
        return self.summary()["HOTA"]


def _similarities(
    sequence: Sequence[FrameObservations],
    gt_index: dict[int, int],
    hyp_index: dict[int, int],
    geometry: Geometry,
    zero_distance: float | None,
) -> tuple[FloatArray, FloatArray, FloatArray, list[tuple[IntArray, IntArray, FloatArray]]]:
    """First pass: per-frame similarities and the global alignment score of every identity pair.

    Returns:
        Frames per ground-truth identity (G,), per hypothesis identity (H,), the summed
        normalised similarity of every pair (G, H), and each frame's (rows, columns, similarity).
    """
    n_gt, n_hyp = len(gt_index), len(hyp_index)
    gt_counts = np.zeros(n_gt)
    hyp_counts = np.zeros(n_hyp)
    potential = np.zeros((n_gt, n_hyp))
    prepared: list[tuple[IntArray, IntArray, FloatArray]] = []
    for observation in sequence:
        rows = np.fromiter((gt_index[i] for i in observation.gt_ids.tolist()), dtype=np.int64)
        columns = np.fromiter((hyp_index[i] for i in observation.hyp_ids.tolist()), dtype=np.int64)
        gt_counts[rows] += 1
        hyp_counts[columns] += 1
        similarity = _similarity_from_distances(
            observation.distances(geometry), geometry, zero_distance
        )
        prepared.append((rows, columns, similarity))
        if similarity.size == 0:
            continue
        denominator = similarity.sum(0)[None, :] + similarity.sum(1)[:, None] - similarity
        normalised = np.zeros_like(similarity)
        mask = denominator > _EPSILON
        normalised[mask] = similarity[mask] / denominator[mask]
        potential[rows[:, None], columns[None, :]] += normalised
    return gt_counts, hyp_counts, potential, prepared


def _matched_pairs(
    prepared: list[tuple[IntArray, IntArray, FloatArray]], alignment: FloatArray
) -> tuple[IntArray, IntArray, FloatArray]:
    """Second pass: one matching per frame; every matched pair's identities and similarity."""
    pair_gt: list[IntArray] = []
    pair_hyp: list[IntArray] = []
    pair_similarity: list[FloatArray] = []
    for rows, columns, similarity in prepared:
        if len(rows) == 0 or len(columns) == 0:
            continue
        score = alignment[rows[:, None], columns[None, :]] * similarity
        match_rows, match_columns = linear_sum_assignment(-score)
        pair_gt.append(rows[match_rows])
        pair_hyp.append(columns[match_columns])
        pair_similarity.append(similarity[match_rows, match_columns])
    gt_of_pair = np.concatenate(pair_gt) if pair_gt else np.zeros(0, dtype=np.int64)
    hyp_of_pair = np.concatenate(pair_hyp) if pair_hyp else np.zeros(0, dtype=np.int64)
    similarity_of_pair = np.concatenate(pair_similarity) if pair_similarity else np.zeros(0)
    return gt_of_pair, hyp_of_pair, similarity_of_pair


def hota_counts(
    sequence: Sequence[FrameObservations],
    geometry: Geometry = "point",
    zero_distance: float | None = None,
    alphas: FloatArray | None = None,
) -> HotaCounts:
    """HOTA sums of one sequence.

    Args:
        sequence: the frames.
        geometry: ``"point"`` or ``"box"``.
        zero_distance: point mode: the distance at which similarity reaches 0 (default 80 px).
        alphas: the thresholds; default :data:`ALPHAS`.

    >>> from trackfw_plugins.evaluation.clear_mot import build_sequence
    >>> gt = {t: {1: (0.0, 0.0), 2: (100.0, 0.0)} for t in range(3)}
    >>> round(hota_counts(build_sequence(gt, gt)).hota, 6)
    1.0
    """
    thresholds = ALPHAS.copy() if alphas is None else np.asarray(alphas, dtype=np.float64)
    gt_index, hyp_index = identity_indices(sequence)
    n_gt, n_hyp, n_alpha = len(gt_index), len(hyp_index), len(thresholds)
    gt_counts, hyp_counts, potential, prepared = _similarities(
        sequence, gt_index, hyp_index, geometry, zero_distance
    )
    alignment = potential / np.maximum(1.0, gt_counts[:, None] + hyp_counts[None, :] - potential)
    result = HotaCounts(
        alphas=thresholds,
        tp=np.zeros(n_alpha),
        fn=np.zeros(n_alpha),
        fp=np.zeros(n_alpha),
        association_sum=np.zeros(n_alpha),
        association_recall_sum=np.zeros(n_alpha),
        association_precision_sum=np.zeros(n_alpha),
        localisation_sum=np.zeros(n_alpha),
    )
    # The alpha thresholds are applied to all matched pairs at once.
    gt_of_pair, hyp_of_pair, similarity_of_pair = _matched_pairs(prepared, alignment)
    pair_code = gt_of_pair * max(n_hyp, 1) + hyp_of_pair
    total_gt, total_hyp = gt_counts.sum(), hyp_counts.sum()
    for a, alpha in enumerate(thresholds):
        accepted = similarity_of_pair >= alpha - _EPSILON
        n_matched = float(accepted.sum())
        result.tp[a] = n_matched
        result.fn[a] = total_gt - n_matched
        result.fp[a] = total_hyp - n_matched
        result.localisation_sum[a] = similarity_of_pair[accepted].sum()
        pair_counts = np.bincount(pair_code[accepted], minlength=n_gt * n_hyp).reshape(n_gt, n_hyp)
        association = pair_counts / np.maximum(
            1.0, gt_counts[:, None] + hyp_counts[None, :] - pair_counts
        )
        result.association_sum[a] = (pair_counts * association).sum()
        result.association_recall_sum[a] = (
            pair_counts * pair_counts / np.maximum(1.0, gt_counts[:, None])
        ).sum()
        result.association_precision_sum[a] = (
            pair_counts * pair_counts / np.maximum(1.0, hyp_counts[None, :])
        ).sum()
    return result

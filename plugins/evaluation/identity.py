"""Identity measures IDF1, IDP and IDR (Ristani et al. 2016), py-motmetrics' convention.

Each ground-truth trajectory is paired with at most one hypothesis trajectory by a global
minimum-cost bipartite matching. The cost of a pair is its false positives plus false negatives,
which is the same as maximising the number of frames on which the pair co-occurs within the
match threshold. IDTP counts those frames for the chosen pairs; IDFN and IDFP are the rest of the
ground-truth and hypothesis appearances.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trackfw_plugins.evaluation.clear_mot import (
    FrameObservations,
    Geometry,
    default_threshold,
    identity_indices,
)
from trackfw_plugins.maths.assignment import linear_sum_assignment
from trackfw_plugins.maths.confusion import ConfusionCounts, PooledCounts


@dataclass
class IdentityCounts(PooledCounts):
    """ID counts of a sequence (or pooled over sequences with ``+``).

    Attributes:
        idtp: appearances matched to the trajectory's assigned identity.
        idfp: hypothesis appearances not matched that way.
        idfn: ground-truth appearances not matched that way.
    """

    idtp: int = 0
    idfp: int = 0
    idfn: int = 0

    def confusion(self) -> ConfusionCounts:
        """IDTP, IDFP and IDFN as the TP, FP and FN of identities."""
        return ConfusionCounts(self.idtp, self.idfp, self.idfn)

    @property
    def idf1(self) -> float:
        """2 IDTP / (2 IDTP + IDFP + IDFN), the F1 of identities; NaN when both sides are empty."""
        return self.confusion().f1

    @property
    def idp(self) -> float:
        """IDTP / (IDTP + IDFP)."""
        return self.confusion().precision

    @property
    def idr(self) -> float:
        """IDTP / (IDTP + IDFN)."""
        return self.confusion().recall


def identity_counts(
    sequence: Sequence[FrameObservations],
    geometry: Geometry = "point",
    threshold: float | None = None,
) -> IdentityCounts:
    """IDTP, IDFP and IDFN of one sequence.

    Args:
        sequence: the frames, in any order.
        geometry: ``"point"`` or ``"box"`` (see :mod:`.clear_mot`).
        threshold: largest distance at which a pair co-occurs; default 40 px or 0.5.

    >>> from trackfw_plugins.evaluation.clear_mot import build_sequence
    >>> gt = {0: {1: (0.0, 0.0)}, 1: {1: (0.0, 0.0)}, 2: {1: (0.0, 0.0)}}
    >>> hyp = {0: {7: (1.0, 0.0)}, 1: {7: (1.0, 0.0)}, 2: {8: (1.0, 0.0)}}
    >>> counts = identity_counts(build_sequence(gt, hyp))
    >>> counts.idtp, counts.idfp, counts.idfn, round(counts.idf1, 4)
    (2, 1, 1, 0.6667)
    """
    limit = default_threshold(geometry) if threshold is None else float(threshold)
    gt_index, hyp_index = identity_indices(sequence)
    gt_appearances = np.zeros(len(gt_index), dtype=np.int64)
    hyp_appearances = np.zeros(len(hyp_index), dtype=np.int64)
    co_occurrences = np.zeros((len(gt_index), len(hyp_index)), dtype=np.int64)
    for observation in sequence:
        rows = np.fromiter((gt_index[i] for i in observation.gt_ids.tolist()), dtype=np.int64)
        columns = np.fromiter((hyp_index[i] for i in observation.hyp_ids.tolist()), dtype=np.int64)
        gt_appearances[rows] += 1
        hyp_appearances[columns] += 1
        if len(rows) and len(columns):
            close = observation.distances(geometry) <= limit
            pair_rows, pair_columns = np.nonzero(close)
            np.add.at(co_occurrences, (rows[pair_rows], columns[pair_columns]), 1)
    idtp = 0
    if co_occurrences.size and co_occurrences.any():
        matched_rows, matched_columns = linear_sum_assignment(-co_occurrences)
        idtp = int(co_occurrences[matched_rows, matched_columns].sum())
    return IdentityCounts(
        idtp=idtp,
        idfp=int(hyp_appearances.sum()) - idtp,
        idfn=int(gt_appearances.sum()) - idtp,
    )

"""CLEAR MOT for point or box targets (Bernardin & Stiefelhagen 2008).

See docs/algorithms/evaluation.md#clear-mot-for-points.

The metrics core works on plain arrays, independent of any file format. A sequence is a list of
:class:`FrameObservations`, one per evaluated frame (the union of frames with ground truth and
frames with hypotheses). Two geometries are supported:

* ``"point"``: ``(N, 2)`` positions, Euclidean distance in pixels, threshold ``mot_dist_px``;
* ``"box"``: ``(N, 4)`` boxes ``(left, top, width, height)``, distance ``1 - IoU`` with threshold
  0.5, as py-motmetrics, so that this implementation can be checked against its asserted values.

Matching follows py-motmetrics: (1) an object keeps its last known hypothesis when both are present
and within the threshold; (2) the rest are matched by a minimum-cost assignment that first
maximises the number of pairs; (3) a match whose hypothesis differs from the object's last known
hypothesis is a mismatch ("switch").
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from itertools import pairwise
from typing import Literal

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.assignment import distance_matrix, hungarian
from trackfw_plugins.maths.box_overlap import box_iou
from trackfw_plugins.maths.confusion import PooledCounts, ratio

Geometry = Literal["point", "box"]

#: Default match threshold in point mode [OURS: ``mot_dist_px``].
DEFAULT_POINT_THRESHOLD_PX = 40.0
#: Default threshold on ``1 - IoU`` in box mode (py-motmetrics' ``distth``).
DEFAULT_BOX_THRESHOLD = 0.5
#: Track-ratio limits of mostly tracked / mostly lost objects (py-motmetrics, MOTChallenge).
MOSTLY_TRACKED_RATIO = 0.8
MOSTLY_LOST_RATIO = 0.2


@dataclass(frozen=True)
class FrameObservations:
    """Ground truth and hypotheses on one frame.

    Attributes:
        frame: the frame index (any monotonic integer; 0-based inside trackfw).
        gt_ids: ``(N,)`` object ids.
        gt_positions: ``(N, 2)`` points or ``(N, 4)`` boxes ``(left, top, width, height)``.
        hyp_ids: ``(M,)`` hypothesis ids.
        hyp_positions: ``(M, 2)`` points or ``(M, 4)`` boxes, like ``gt_positions``.
    """

    frame: int
    gt_ids: IntArray
    gt_positions: FloatArray
    hyp_ids: IntArray
    hyp_positions: FloatArray
    _distance_cache: dict[str, FloatArray] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def distances(self, geometry: Geometry = "point") -> FloatArray:
        """``(N, M)`` distances of :func:`pairwise_distances`, computed once per geometry.

        CLEAR MOT, the identity measures and HOTA all need them, some at several thresholds.
        """
        cached = self._distance_cache.get(geometry)
        if cached is None:
            cached = pairwise_distances(self.gt_positions, self.hyp_positions, geometry)
            self._distance_cache[geometry] = cached
        return cached


def identity_indices(
    sequence: Sequence[FrameObservations],
) -> tuple[dict[int, int], dict[int, int]]:
    """Row index of every ground-truth id and every hypothesis id, in order of appearance.

    >>> gt = {0: {5: (0.0, 0.0)}, 1: {3: (0.0, 0.0), 5: (1.0, 0.0)}}
    >>> identity_indices(build_sequence(gt, gt))
    ({5: 0, 3: 1}, {5: 0, 3: 1})
    """
    gt_index: dict[int, int] = {}
    hyp_index: dict[int, int] = {}
    for observation in sequence:
        for object_id in observation.gt_ids.tolist():
            gt_index.setdefault(object_id, len(gt_index))
        for hypothesis_id in observation.hyp_ids.tolist():
            hyp_index.setdefault(hypothesis_id, len(hyp_index))
    return gt_index, hyp_index


def build_sequence(
    ground_truth: Mapping[int, Mapping[int, Sequence[float]]],
    hypotheses: Mapping[int, Mapping[int, Sequence[float]]],
    frames: Sequence[int] | None = None,
) -> list[FrameObservations]:
    """Frames ``{frame: {id: position}}`` of both sides as a sorted list of observations.

    Args:
        ground_truth: frame -> ``{object id: (x, y)}`` or ``{object id: (left, top, w, h)}``.
        hypotheses: the same for the tracker's output.
        frames: the frames to evaluate; default the union of both sides' frames.

    Returns:
        One :class:`FrameObservations` per frame, in increasing frame order.

    >>> sequence = build_sequence({0: {1: (0.0, 0.0)}}, {1: {7: (1.0, 1.0)}})
    >>> [(f.frame, f.gt_ids.tolist(), f.hyp_ids.tolist()) for f in sequence]
    [(0, [1], []), (1, [], [7])]
    """
    if frames is None:
        frames = sorted(set(ground_truth) | set(hypotheses))
    dimension = _dimension(ground_truth, hypotheses)
    sequence = []
    for frame in frames:
        gt_ids, gt_positions = _frame_arrays(ground_truth.get(frame, {}), dimension)
        hyp_ids, hyp_positions = _frame_arrays(hypotheses.get(frame, {}), dimension)
        sequence.append(FrameObservations(frame, gt_ids, gt_positions, hyp_ids, hyp_positions))
    return sequence


def _dimension(*sides: Mapping[int, Mapping[int, Sequence[float]]]) -> int:
    for side in sides:
        for frame_items in side.values():
            for position in frame_items.values():
                return len(position)
    return 2


def _frame_arrays(
    items: Mapping[int, Sequence[float]], dimension: int
) -> tuple[IntArray, FloatArray]:
    ids = np.fromiter(items.keys(), dtype=np.int64, count=len(items))
    positions = np.asarray(list(items.values()), dtype=np.float64).reshape(len(items), dimension)
    return ids, positions


def pairwise_distances(
    gt_positions: FloatArray, hyp_positions: FloatArray, geometry: Geometry = "point"
) -> FloatArray:
    """``(N, M)`` distances: Euclidean pixels for points, ``1 - IoU`` for boxes.

    >>> pairwise_distances(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0]])).tolist()
    [[5.0]]
    """
    if geometry == "point":
        return distance_matrix(gt_positions, hyp_positions)
    if geometry == "box":
        return 1.0 - box_iou(gt_positions, hyp_positions)
    raise ValueError(f"geometry is {geometry!r}; expected 'point' or 'box'.")


def assign_allowed(distances: FloatArray) -> tuple[IntArray, IntArray]:
    """Minimum-cost assignment among the finite entries of ``(N, M)`` ``distances``.

    Forbidden pairs (NaN or inf) get a cost so large that the solver first maximises the number of
    allowed pairs, as py-motmetrics does; forbidden pairs are then dropped.

    Returns:
        ``(K,)`` row indices and ``(K,)`` column indices of the kept pairs.

    >>> rows, columns = assign_allowed(np.array([[1.0, np.nan], [0.5, 2.0]]))
    >>> rows.tolist(), columns.tolist()
    ([0, 1], [0, 1])
    """
    allowed = np.isfinite(distances)
    if not allowed.any():
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    largest = float(np.abs(distances[allowed]).max())
    # Scaling to [-1, 1] keeps the shared solver's forbidden constant far above any real total.
    scale = largest if largest > 0 else 1.0
    cost = np.where(allowed, distances / scale, np.inf)
    assignment = hungarian(cost, gate=1.0)
    rows = np.flatnonzero(assignment >= 0)
    return rows.astype(np.int64), assignment[rows].astype(np.int64)


@dataclass
class ClearMotCounts(PooledCounts):
    """Summed CLEAR MOT counts of a sequence (or of several, pooled by :meth:`__add__`).

    Attributes:
        n_frames: evaluated frames.
        n_objects: ground-truth appearances, the sum over frames of g_t.
        n_predictions: hypothesis appearances.
        n_correspondences: matched pairs, the sum of c_t (switches included).
        n_switches: mismatches (the "last known" rule).
        n_false_positives: the sum of fp_t.
        n_misses: the sum of miss_t.
        distance_sum: the sum of match distances d_{i,t}.
        n_transfers, n_ascends, n_migrates: py-motmetrics' sub-events of identity changes.
        n_unique_objects: distinct object ids.
        mostly_tracked, partially_tracked, mostly_lost: objects tracked for >= 80 %, 20-80 %,
            < 20 % of their appearances.
        n_fragmentations: changes from tracked to missed within an object's tracked span.
    """

    n_frames: int = 0
    n_objects: int = 0
    n_predictions: int = 0
    n_correspondences: int = 0
    n_switches: int = 0
    n_false_positives: int = 0
    n_misses: int = 0
    distance_sum: float = 0.0
    n_transfers: int = 0
    n_ascends: int = 0
    n_migrates: int = 0
    n_unique_objects: int = 0
    mostly_tracked: int = 0
    partially_tracked: int = 0
    mostly_lost: int = 0
    n_fragmentations: int = 0

    @property
    def mota(self) -> float:
        """1 - (misses + false positives + switches) / objects, as a fraction; NaN without GT."""
        if self.n_objects == 0:
            return float("nan")
        errors = self.n_misses + self.n_false_positives + self.n_switches
        return 1.0 - errors / self.n_objects

    @property
    def motp(self) -> float:
        """Mean match distance (pixels in point mode, ``1 - IoU`` in box mode); NaN without match."""
        return ratio(self.distance_sum, self.n_correspondences)

    @property
    def recall(self) -> float:
        """Correspondences over objects."""
        return ratio(self.n_correspondences, self.n_objects)

    @property
    def precision(self) -> float:
        """Correspondences over correspondences plus false positives."""
        return ratio(self.n_correspondences, self.n_correspondences + self.n_false_positives)


@dataclass
class ClearMotAccumulator:
    """Frame-by-frame CLEAR MOT matching with py-motmetrics' history rules.

    Call :meth:`update` once per frame in time order, then :meth:`counts`.
    """

    last_hypothesis: dict[int, int] = field(default_factory=dict)
    hypothesis_owner: dict[int, int] = field(default_factory=dict)
    matched_hypotheses: set[int] = field(default_factory=set)
    tracked_flags: dict[int, list[bool]] = field(default_factory=dict)
    totals: ClearMotCounts = field(default_factory=ClearMotCounts)

    def update(
        self, gt_ids: IntArray, hyp_ids: IntArray, distances: FloatArray
    ) -> list[tuple[int, int, float]]:
        """Match one frame.

        Args:
            gt_ids: ``(N,)`` object ids present on the frame.
            hyp_ids: ``(M,)`` hypothesis ids present on the frame.
            distances: ``(N, M)`` distances; NaN or inf marks pairs that may not match.

        Returns:
            The frame's matches as ``(object id, hypothesis id, distance)``.
        """
        gt_ids = np.asarray(gt_ids, dtype=np.int64).reshape(-1)
        hyp_ids = np.asarray(hyp_ids, dtype=np.int64).reshape(-1)
        n_gt, n_hyp = len(gt_ids), len(hyp_ids)
        distances = np.asarray(distances, dtype=np.float64).reshape(n_gt, n_hyp).copy()
        gt_matched = np.zeros(n_gt, dtype=bool)
        hyp_matched = np.zeros(n_hyp, dtype=bool)
        matches: list[tuple[int, int, float]] = []
        totals = self.totals
        if n_gt and n_hyp:
            column_of = {int(h): j for j, h in enumerate(hyp_ids)}
            # Step 1: an established correspondence survives while it stays within the threshold,
            # even when a closer hypothesis appears.
            for i, object_id in enumerate(gt_ids.tolist()):
                previous = self.last_hypothesis.get(object_id)
                j = column_of.get(previous) if previous is not None else None
                if j is None or hyp_matched[j] or not np.isfinite(distances[i, j]):
                    continue
                gt_matched[i] = hyp_matched[j] = True
                self.matched_hypotheses.add(int(hyp_ids[j]))
                matches.append((object_id, int(hyp_ids[j]), float(distances[i, j])))
            # Step 2: the rest by assignment; a changed hypothesis is a mismatch.
            distances[gt_matched, :] = np.nan
            distances[:, hyp_matched] = np.nan
            for i, j in zip(*assign_allowed(distances), strict=True):
                object_id, hypothesis_id = int(gt_ids[i]), int(hyp_ids[j])
                previous = self.last_hypothesis.get(object_id)
                if previous is not None and previous != hypothesis_id:
                    totals.n_switches += 1
                    if hypothesis_id not in self.matched_hypotheses:
                        totals.n_ascends += 1
                owner = self.hypothesis_owner.get(hypothesis_id)
                if owner is not None and owner != object_id:
                    totals.n_transfers += 1
                    if object_id not in self.last_hypothesis:
                        totals.n_migrates += 1
                self.last_hypothesis[object_id] = hypothesis_id
                self.hypothesis_owner[hypothesis_id] = object_id
                self.matched_hypotheses.add(hypothesis_id)
                gt_matched[i] = hyp_matched[j] = True
                matches.append((object_id, hypothesis_id, float(distances[i, j])))
        n_matches = len(matches)
        totals.n_frames += 1
        totals.n_objects += n_gt
        totals.n_predictions += n_hyp
        totals.n_correspondences += n_matches
        totals.n_misses += n_gt - n_matches
        totals.n_false_positives += n_hyp - n_matches
        totals.distance_sum += sum(match[2] for match in matches)
        for object_id, tracked in zip(gt_ids.tolist(), gt_matched.tolist(), strict=True):
            self.tracked_flags.setdefault(object_id, []).append(tracked)
        return matches

    def counts(self) -> ClearMotCounts:
        """The totals so far, with the per-object statistics (MT, PT, ML, fragmentations)."""
        result = ClearMotCounts(
            **{f.name: getattr(self.totals, f.name) for f in fields(self.totals)}
        )
        result.n_unique_objects = len(self.tracked_flags)
        for flags in self.tracked_flags.values():
            ratio = sum(flags) / len(flags)
            if ratio >= MOSTLY_TRACKED_RATIO:
                result.mostly_tracked += 1
            elif ratio >= MOSTLY_LOST_RATIO:
                result.partially_tracked += 1
            else:
                result.mostly_lost += 1
            result.n_fragmentations += _fragmentations(flags)
        return result


def _fragmentations(tracked: list[bool]) -> int:
    """Tracked-to-missed changes between the first and last tracked appearance.

    >>> _fragmentations([False, True, False, False, True, False, True, False])
    2
    """
    indices = [index for index, flag in enumerate(tracked) if flag]
    if not indices:
        return 0
    span = tracked[indices[0] : indices[-1] + 1]
    return sum(1 for before, after in pairwise(span) if before and not after)


def default_threshold(geometry: Geometry) -> float:
    """The default match threshold of a geometry (40 px for points, 0.5 for ``1 - IoU``)."""
    return DEFAULT_POINT_THRESHOLD_PX if geometry == "point" else DEFAULT_BOX_THRESHOLD


def clear_mot(
    sequence: Sequence[FrameObservations],
    geometry: Geometry = "point",
    threshold: float | None = None,
) -> ClearMotCounts:
    """CLEAR MOT counts of one sequence, starting with no correspondence history.

    Args:
        sequence: the frames to evaluate, in time order.
        geometry: ``"point"`` (Euclidean pixels) or ``"box"`` (``1 - IoU``).
        threshold: largest distance that may match; default 40 px or 0.5.

    Returns:
        The summed counts; ``.mota`` and ``.motp`` give the metrics.

    >>> frames = build_sequence({0: {1: (0.0, 0.0)}, 1: {1: (0.0, 0.0)}}, {0: {5: (3.0, 4.0)}})
    >>> counts = clear_mot(frames)
    >>> counts.n_correspondences, counts.n_misses, counts.mota, counts.motp
    (1, 1, 0.5, 5.0)
    """
    limit = default_threshold(geometry) if threshold is None else float(threshold)
    accumulator = ClearMotAccumulator()
    for observation in sequence:
        distances = observation.distances(geometry)
        distances = np.where(distances > limit, np.nan, distances)
        accumulator.update(observation.gt_ids, observation.hyp_ids, distances)
    return accumulator.counts()


def clear_mot_windows(
    sequence: Sequence[FrameObservations],
    windows: Sequence[Sequence[int]],
    geometry: Geometry = "point",
    threshold: float | None = None,
) -> ClearMotCounts | None:
    """Pooled CLEAR MOT over short frame windows, each starting with no history (-In variants).

    Args:
        sequence: the full sequence of frames.
        windows: per window, the frames to evaluate (for an interval: ``(a, b, b + 1)``); frames
            absent from ``sequence`` are evaluated as empty frames.
        geometry, threshold: as :func:`clear_mot`.

    Returns:
        The counts summed over windows, or None when there is no window.
    """
    if not windows:
        return None
    by_frame = {observation.frame: observation for observation in sequence}
    pooled = ClearMotCounts()
    for window in windows:
        frames = [by_frame.get(frame, _empty_frame(frame, sequence)) for frame in window]
        pooled = pooled + clear_mot(frames, geometry, threshold)
    return pooled


def _empty_frame(frame: int, sequence: Sequence[FrameObservations]) -> FrameObservations:
    dimension = sequence[0].gt_positions.shape[1] if sequence else 2
    empty_ids = np.zeros(0, dtype=np.int64)
    empty_positions = np.zeros((0, dimension), dtype=np.float64)
    return FrameObservations(frame, empty_ids, empty_positions, empty_ids, empty_positions)


def interval_windows(intervals: Sequence[tuple[int, int]], n_frames: int) -> list[list[int]]:
    """The frames ``(a, b, b + 1)`` of each interval ``(a, b)``, clipped to the video.

    An interval that reaches the end of the video (``b >= n_frames``) has no frame b and gives no
    window.

    >>> interval_windows([(3, 9), (20, 29)], n_frames=30)
    [[3, 9, 10], [20, 29]]
    """
    windows = []
    for a, b in intervals:
        if b >= n_frames:
            continue
        windows.append([frame for frame in (a, b, b + 1) if 0 <= frame < n_frames])
    return windows

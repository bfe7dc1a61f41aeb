"""GTCSA-like: a documented approximation of groupwise tracking with thin-plate association.

Yu, Zhou, Simmons, Przybyla, Lin, Fan, Mi & Wang, "Groupwise Tracking of Crowded
Similar-Appearance Targets from Low-Continuity Image Sequences", CVPR 2016 (the GTCSA row of
Table 1 of Yu et al. 2018). Only the paper's abstract was available: targets are tracked by
Kalman filters, the predictions are split into groups, each group is associated with the
observations through a non-rigid 2-D thin-plate spline, and groups are refined by shrinking,
growing and merging. Everything below that sentence is **our rule, not the paper's**; the
numbers of this plugin are those of a "GTCSA-like" tracker, not a reproduction of the row.

The rules chosen, per frame ``t`` with ``m`` live targets and ``n`` observations:

1. *Prediction*: one constant-velocity Kalman filter per target
   (:mod:`trackfw_plugins.maths.kalman`, the paper's P0, Q and R by default).
2. *Grouping*: k-means with ``k = min(groups, m)`` on the predicted positions; seeds by
   farthest-point from the oldest target, at most 10 Lloyd iterations (deterministic).
3. *Observations of a group*: an observation joins the group of its nearest prediction when that
   prediction is within ``join`` (an observation farther from every prediction only starts a
   target: it would distort the group's normalised point set).
4. *Within-group association*: TPS-RPM (:mod:`trackfw_plugins.maths.tps_rpm`, outlier row and
   column, so ``m != n`` is allowed) from the group's predictions to its observations, the
   correspondence thresholded at 0.5. Groups with fewer than 3 predictions or observations skip
   the spline (it is not defined by fewer points) and go to step 8. For speed the frame's
   groups anneal together, block-diagonally, on two-dimensional arrays
   (:func:`trackfw_plugins.maths.single_rpm.tps_rpm_groups`); each group's fit is the one
   ``tps_rpm`` gives it, up to float rounding.
5. *Merge*: two fitted groups merge when each one's spline maps the other's matched predictions
   within ``gate`` of their observations (one spline explains both); the union is refitted by
   TPS-RPM. Repeated until no pair merges.
6. *Shrink*: a match whose displacement (observation minus prediction) differs from the median
   displacement of the group's matches by more than ``gate`` is dropped (the spline itself can
   bend a member onto any point, so its own residual does not reveal a wrong match).
7. *Grow*: unmatched members of a fitted group are mapped by its spline and matched to free
   observations by Hungarian on distance, gated at ``gate``.
8. *Fallback*: targets still unmatched are matched to observations still free by Hungarian on
   their Kalman predictions, gated at ``gate``.
9. *Update, births and deaths*: matched targets are corrected; unmatched targets coast on their
   prediction and die after ``max_miss`` consecutive misses; every free observation starts a
   target.

Each step runs once per frame (the paper iterates its refinements "until stable"). A coasted
frame between two matches is reported with ``observed = False``; coasting after the last match
is not reported. The video is processed as continuous: an info-less interval is one more
``m -> n`` step, which is the case the paper says the method does not handle well.

See ``docs/algorithms/batch-trackers.md#gtcsa-like``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydantic import Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.stages import StageParams
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections
from trackfw_plugins.maths.assignment import distance_matrix, hungarian
from trackfw_plugins.maths.kalman import PAPER_P0, PAPER_Q, PAPER_R, KalmanBank
from trackfw_plugins.maths.single_rpm import tps_rpm_groups
from trackfw_plugins.maths.tps_rpm import TpsRpmResult
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings

_LLOYD_ITERATIONS = 10
_SPLINE_MIN_POINTS = 3


def _fast_rpm() -> TpsRpmSettings:
    # A coarser annealing than the paper's gap matcher: 13 levels of 2 updates instead of
    # 86 of 5, so that a fit per group per frame stays within the speed target.
    return TpsRpmSettings(anneal_rate=0.7, T_finalfac=100.0, perT_maxit=2, sinkhorn_maxit=5)


class GtcsaParams(StageParams):
    """GTCSA-like settings (our rules; see the module docstring)."""

    groups: int = Field(2, ge=1, description="K: number of target groups (the paper used 2)")
    gate_px_at_1080: float = Field(
        50.0, gt=0.0, description="largest match residual in px at 1080p, scaled by frame height"
    )
    join_px_at_1080: float = Field(
        150.0, gt=0.0, description="an observation joins a group within this distance, px at 1080p"
    )
    max_miss: int = Field(5, ge=0, description="a target dies after this many unmatched frames")
    P0: float = Field(PAPER_P0, gt=0.0, description="Kalman initial variance")
    Q: float = Field(PAPER_Q, gt=0.0, description="Kalman transition variance")
    R: float = Field(PAPER_R, gt=0.0, description="Kalman observation variance")
    rpm: TpsRpmSettings = Field(
        default_factory=_fast_rpm, description="TPS-RPM settings of the within-group fits"
    )


def kmeans(points: FloatArray, k: int) -> IntArray:
    """Deterministic k-means labels ``(P,)`` of ``(P, 2)`` points.

    Seeds: the first point, then repeatedly the point farthest from every seed.

    >>> kmeans(np.array([[0.0, 0], [1, 0], [100, 0], [101, 0]]), 2).tolist()
    [0, 0, 1, 1]
    """
    count = len(points)
    k = max(1, min(k, count))
    seeds = [0]
    nearest = np.sum((points - points[0]) ** 2, axis=1)
    for _ in range(1, k):
        seeds.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, np.sum((points - points[seeds[-1]]) ** 2, axis=1))
    centres = points[seeds].copy()
    labels = np.zeros(count, dtype=np.int64)
    for _ in range(_LLOYD_ITERATIONS):
        new_labels = np.argmin(distance_matrix(points, centres), axis=1).astype(np.int64)
        if _ and (new_labels == labels).all():
            break
        labels = new_labels
        for group in range(k):
            members = labels == group
            if members.any():
                centres[group] = points[members].mean(axis=0)
    return labels


class _Group:
    """One group's members (target rows), observations and spline fit."""

    def __init__(self, members: IntArray, observations: IntArray) -> None:
        self.members = members
        self.observations = observations
        self.fit: TpsRpmResult | None = None
        self.matched = np.full(len(members), -1, dtype=np.int64)  # observation row per member

    def use(self, fit: TpsRpmResult | None) -> None:
        """Take a spline fit (None: the group is too small for one) and its matches."""
        self.fit = fit
        self.matched = np.full(len(self.members), -1, dtype=np.int64)
        if fit is not None:
            pairs = fit.matches
            self.matched[pairs[:, 0]] = self.observations[pairs[:, 1]]

    def explains(
        self, other: _Group, predicted: FloatArray, points: FloatArray, gate: float
    ) -> bool:
        """Whether this group's spline maps ``other``'s matched predictions within ``gate``."""
        if self.fit is None:
            return False
        taken = other.matched >= 0
        if not taken.any():
            return False
        mapped = self.fit.transform(predicted[other.members[taken]])
        residual = np.linalg.norm(mapped - points[other.matched[taken]], axis=1)
        return bool(residual.max() <= gate)


def associate_frame(
    predicted: FloatArray, points: FloatArray, params: GtcsaParams, gate: float, join: float
) -> IntArray:
    """Groupwise association of ``(m, 2)`` predictions with ``(n, 2)`` observations.

    ``gate`` and ``join`` are the match and group-joining distances in px.

    Returns:
        ``(m,)`` observation row per target, -1 when unmatched; one-to-one.
    """
    count = len(predicted)
    result = np.full(count, -1, dtype=np.int64)
    if count == 0 or len(points) == 0:
        return result
    labels = kmeans(predicted, params.groups)
    distances = distance_matrix(points, predicted)
    nearest = np.argmin(distances, axis=1)
    owner = np.where(distances[np.arange(len(points)), nearest] <= join, labels[nearest], -1)
    groups = [
        _Group(np.flatnonzero(labels == group), np.flatnonzero(owner == group))
        for group in range(int(labels.max()) + 1)
    ]
    _register(groups, predicted, points, params.rpm)
    groups = _merge(groups, predicted, points, params.rpm, gate)
    free = np.ones(len(points), dtype=bool)
    for group in groups:
        if group.fit is None:
            continue
        taken = np.flatnonzero(group.matched >= 0)
        if len(taken) == 0:
            continue
        # Shrink: a match that does not move with the rest of the group is dropped.
        shift = points[group.matched[taken]] - predicted[group.members[taken]]
        deviation = np.linalg.norm(shift - np.median(shift, axis=0), axis=1)
        keep = taken[deviation <= gate]
        result[group.members[keep]] = group.matched[keep]
        free[group.matched[keep]] = False
    for group in groups:
        if group.fit is None:
            continue
        # Grow: unmatched members, mapped by the group's spline, take free observations.
        loose = group.members[result[group.members] < 0]
        _gated_match(group.fit.transform(predicted[loose]), loose, points, free, gate, result)
    loose = np.flatnonzero(result < 0)
    _gated_match(predicted[loose], loose, points, free, gate, result)
    return result


def _register(
    groups: list[_Group], predicted: FloatArray, points: FloatArray, settings: TpsRpmSettings
) -> None:
    """Fit each group's spline (TPS-RPM from its predictions to its observations), all the
    groups' fits in one annealing; groups with too few points for a spline get none."""
    fitted = [
        group
        for group in groups
        if min(len(group.members), len(group.observations)) >= _SPLINE_MIN_POINTS
    ]
    fits = tps_rpm_groups(
        [(predicted[group.members], points[group.observations]) for group in fitted], settings
    )
    for group in groups:
        group.use(None)
    for group, fit in zip(fitted, fits, strict=True):
        group.use(fit)


def _merge(
    groups: list[_Group],
    predicted: FloatArray,
    points: FloatArray,
    settings: TpsRpmSettings,
    gate: float,
) -> list[_Group]:
    merged = True
    while merged and len(groups) > 1:
        merged = False
        for first in range(len(groups)):
            for second in range(first + 1, len(groups)):
                a, b = groups[first], groups[second]
                if a.explains(b, predicted, points, gate) and b.explains(
                    a, predicted, points, gate
                ):
                    union = _Group(
                        np.concatenate([a.members, b.members]),
                        np.concatenate([a.observations, b.observations]),
                    )
                    _register([union], predicted, points, settings)
                    groups = [g for index, g in enumerate(groups) if index not in (first, second)]
                    groups.append(union)
                    merged = True
                    break
            if merged:
                break
    return groups


def _gated_match(
    positions: FloatArray,
    targets: IntArray,
    points: FloatArray,
    free: BoolArray,
    gate: float,
    result: IntArray,
) -> None:
    rows = np.flatnonzero(free)
    if len(targets) == 0 or len(rows) == 0:
        return
    assignment = hungarian(distance_matrix(positions, points[rows]), gate=gate)
    taken = assignment >= 0
    result[targets[taken]] = rows[assignment[taken]]
    free[rows[assignment[taken]]] = False


@dataclass
class _Reported:
    """The rows reported so far, in pieces: ids, frames, points ``(n, 2)``, observed flags."""

    ids: list[IntArray] = field(default_factory=list)
    frames: list[IntArray] = field(default_factory=list)
    points: list[FloatArray] = field(default_factory=list)
    observed: list[BoolArray] = field(default_factory=list)

    def add(self, ids: IntArray, frames: IntArray, points: FloatArray, observed: bool) -> None:
        """Report ``points`` of tracks ``ids`` at ``frames``, all observed or all filled in."""
        self.ids.append(ids)
        self.frames.append(frames)
        self.points.append(points)
        self.observed.append(np.full(len(ids), observed, dtype=bool))

    def tracks(self) -> Tracks:
        """Everything reported, as tracks."""
        if not self.ids:
            return Tracks.empty()
        return Tracks(
            np.concatenate(self.ids),
            np.concatenate(self.frames),
            np.concatenate(self.points),
            np.concatenate(self.observed),
        )


def track_gtcsa(
    detections: VideoDetections, height: float, params: GtcsaParams | None = None
) -> Tracks:
    """Run the GTCSA-like tracker over a video (the points are used, boxes and scores are not).

    Args:
        detections: all detections of the video.
        height: frame height in px (scales the gate).
        params: settings; defaults when None.

    Returns:
        Tracks numbered by birth; coasted frames between two matches have ``observed = False``.
    """
    params = params or GtcsaParams()
    gate = params.gate_px_at_1080 * height / 1080.0
    join = params.join_px_at_1080 * height / 1080.0
    bank = KalmanBank.start(np.zeros((0, 2)), params.P0, params.Q, params.R)
    ids = np.zeros(0, dtype=np.int64)
    misses = np.zeros(0, dtype=np.int64)
    bounds = detections.frame_bounds()
    reported = _Reported()
    coasted: dict[int, list[tuple[int, FloatArray]]] = {}
    next_id = 1
    for frame in range(detections.n_frames):
        points = detections.points[bounds[frame] : bounds[frame + 1]]
        bank.predict()
        matched = associate_frame(bank.positions, points, params, gate, join)
        hit = np.flatnonzero(matched >= 0)
        bank.correct(hit, points[matched[hit]])
        misses = np.where(matched >= 0, 0, misses + 1)
        for index in hit.tolist():
            # Coasted frames between two matches are reported as filled in.
            for coast_frame, coast_point in coasted.pop(int(ids[index]), []):
                reported.add(
                    ids[index : index + 1], np.array([coast_frame]), coast_point[None], False
                )
        reported.add(ids[hit], np.full(len(hit), frame), points[matched[hit]], True)
        positions = bank.positions
        for index in np.flatnonzero(matched < 0).tolist():
            coasted.setdefault(int(ids[index]), []).append((frame, positions[index]))
        alive = misses <= params.max_miss
        for index in np.flatnonzero(~alive).tolist():
            coasted.pop(int(ids[index]), None)
        bank.keep(alive)
        ids, misses = ids[alive], misses[alive]
        free = np.ones(len(points), dtype=bool)
        free[matched[hit]] = False
        births = points[free]
        if len(births):
            bank.add(births)
            new_ids = np.arange(next_id, next_id + len(births), dtype=np.int64)
            next_id += len(births)
            ids = np.concatenate([ids, new_ids])
            misses = np.concatenate([misses, np.zeros(len(births), dtype=np.int64)])
            reported.add(new_ids, np.full(len(births), frame), births, True)
    return reported.tracks()

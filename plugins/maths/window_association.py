"""Window-based TPS-RPM association of predicted points with detections.

See docs/algorithms/gap-matchers.md#window-tps-rpm.

Pure maths, independent of frames: ``U`` (K, 2) are the points predicted for one candidate (one
AR order), ``V`` (N, 2) the detections on frame b, and an optional appearance distance matrix
(K, N). Steps: the candidate windows of V (:func:`~.candidate_windows.build_windows`, shared by
all candidates); then hull shape prescreen, TPS-RPM per
window (batched by window size and across candidates; identical candidates share their runs),
post-RPM prune, cost ψ = φ + λ1 (K − d_W) + λ2 E_a, best window, and the fallback chain.

Shape checks (both hull cuts) can be evaluated lazily (default): all windows are registered,
then the windows are visited in increasing ψ and the first that passes both cuts wins. That is
the same window the eager order (prescreen, RPM on the survivors, prune, argmin) selects, with
ties broken by window order in both, but it computes Δ for a handful of windows instead of
all of them. ``lazy_shape_checks=False`` runs the eager order and gives exact counts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw_plugins.maths.assignment import linear_sum_assignment
from trackfw_plugins.maths.candidate_windows import WindowSet, WindowSettings, build_windows
from trackfw_plugins.maths.shape_distance import (
    HullShapeMatcher,
    ShapeDistanceSettings,
    hull_polygon,
)
from trackfw_plugins.maths.tps_rpm import tps_rpm_multi_batch
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings, TpsRpmTemplate

#: Costs closer than this are a tie: the smaller AR order wins
#: (docs/algorithms/gap-matchers.md#window-cost).
TIE_TOLERANCE = 1e-6

FALLBACK_NONE = "none"
FALLBACK_NO_SHAPE_CUTS = "no_shape_cuts"
FALLBACK_ALL_DETECTIONS = "all_detections"
FALLBACK_APPEARANCE = "appearance_hungarian"
FALLBACK_NO_DETECTIONS = "no_detections"
#: Not searched: a positioned candidate is cheaper than any window could be
#: (docs/algorithms/gap-matchers.md#positioned-candidates).
FALLBACK_BOUND = "bound"


class WindowAssociationParams(WindowSettings):
    """Parameters of the window association (docs/algorithms/gap-matchers.md#parameters)."""

    hull_pre: float = Field(0.6, ge=0, description="Discard W when Δ(C_U, C_W) >= hull_pre.")
    hull_post: float = Field(
        0.5, ge=0, description="Discard W when Δ of the matched pairs' hulls >= hull_post."
    )
    lambda1: float = Field(1.0, ge=0, description="Weight of the unmatched count |U| - d_W.")
    lambda2: float = Field(0.35, ge=0, description="Weight of the appearance term E_a.")
    min_matches: int = Field(3, ge=1, description="Discard W when d_W < min_matches.")
    lazy_shape_checks: bool = Field(
        True,
        description="Evaluate the hull cuts in increasing ψ order after RPM (same result, far "
        "fewer Δ computations); False runs prescreen -> RPM -> prune eagerly.",
    )
    rpm: TpsRpmSettings = Field(default_factory=TpsRpmSettings, description="TPS-RPM settings.")
    shape: ShapeDistanceSettings = Field(
        default_factory=ShapeDistanceSettings, description="Shape distance Δ settings."
    )


@dataclass
class WindowDiagnostics:
    """Counts of one association; None where lazy evaluation did not compute a count."""

    windows_total: int = 0
    after_dedup: int = 0
    after_size: int = 0
    after_hull_prescreen: int | None = None
    after_rpm_prune: int | None = None
    rpm_runs: int = 0
    with_min_matches: int = 0
    shape_checks: int = 0
    window_rule: str = "boxes"
    fallback: str = FALLBACK_NONE


@dataclass
class WindowAssociationResult:
    """Association of one candidate U with V.

    Attributes:
        positions: (K, 2) target positions on frame b.
        matched_detection: (K,) row of V matched to each target, -1 when none.
        cost: ψ = bending + lambda1·unmatched + lambda2·appearance.
        bending: φ(f_W); unmatched: |U| − d_W; appearance: E_a (0 without a matrix).
        window: indices into V of the chosen window W (empty for the Hungarian fallback).
        diagnostics: counts and the fallback used.
    """

    positions: FloatArray
    matched_detection: IntArray
    cost: float
    bending: float
    unmatched: int
    appearance: float
    window: IntArray
    diagnostics: WindowDiagnostics = field(default_factory=WindowDiagnostics)


@dataclass
class _Registered:
    """RPM outputs of the windows of one candidate (window order; ``ran`` marks those run)."""

    ran: BoolArray  # (W,)
    matched: IntArray  # (W, K) detection index (into V) or -1
    bending: FloatArray  # (W,)
    warped: FloatArray  # (W, K, 2) f_W(U) in image coordinates
    cost: FloatArray = field(default_factory=lambda: np.zeros(0))
    appearance: FloatArray = field(default_factory=lambda: np.zeros(0))
    count: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def copy(self) -> _Registered:
        """An independent copy (stores are mutated by the fallbacks)."""
        return _Registered(
            ran=self.ran.copy(),
            matched=self.matched.copy(),
            bending=self.bending.copy(),
            warped=self.warped.copy(),
            cost=self.cost.copy(),
            appearance=self.appearance.copy(),
            count=self.count.copy(),
        )

    @classmethod
    def empty(cls, windows: int, size: int) -> _Registered:
        return cls(
            ran=np.zeros(windows, dtype=bool),
            matched=np.full((windows, size), -1, dtype=np.int64),
            bending=np.zeros(windows),
            warped=np.zeros((windows, size, 2)),
        )

    def finish(self, appearance: FloatArray | None, params: WindowAssociationParams) -> None:
        """Recompute d_W, E_a and ψ (windows not run get ψ = inf and d_W = -1)."""
        size = self.matched.shape[1]
        self.count = np.where(self.ran, (self.matched >= 0).sum(axis=1), -1)
        self.appearance = _appearance_terms(self.matched, appearance)
        cost = (
            self.bending + params.lambda1 * (size - self.count) + params.lambda2 * self.appearance
        )
        self.cost = np.where(self.ran, cost, np.inf)


def _register(
    templates: Sequence[TpsRpmTemplate],
    detections: FloatArray,
    members: BoolArray,
    needed: Sequence[BoolArray],
    stores: Sequence[_Registered],
) -> None:
    """TPS-RPM of each template against its needed windows; one batched run per window size."""
    sizes = members.sum(axis=1)
    for size in np.unique(sizes):
        group = sizes == size
        owners, window_ids = [], []
        for template_index, (mask, store) in enumerate(zip(needed, stores, strict=True)):
            ids = np.nonzero(group & mask & ~store.ran)[0]
            owners.append(np.full(ids.size, template_index, dtype=np.int64))
            window_ids.append(ids)
        owner = np.concatenate(owners)
        if owner.size == 0:
            continue
        ids_all = np.concatenate(window_ids)
        indices = np.nonzero(members[ids_all])[1].reshape(ids_all.size, int(size))
        outputs = tps_rpm_multi_batch(templates, owner, detections[indices])
        matched = np.where(
            outputs.matched >= 0,
            np.take_along_axis(indices, np.maximum(outputs.matched, 0), axis=1),
            -1,
        )
        for template_index, store in enumerate(stores):
            part = owner == template_index
            ids = ids_all[part]
            store.ran[ids] = True
            store.matched[ids] = matched[part]
            store.bending[ids] = outputs.bending_energy[part]
            store.warped[ids] = outputs.warped_template[part]


def _appearance_terms(matched: IntArray, appearance: FloatArray | None) -> FloatArray:
    """E_a per window: mean appearance distance over the matched pairs (0 without pairs)."""
    if appearance is None:
        return np.zeros(matched.shape[0])
    rows = np.arange(matched.shape[1])[None, :]
    values = np.where(matched >= 0, appearance[rows, np.maximum(matched, 0)], 0.0)
    pairs = (matched >= 0).sum(axis=1)
    return np.divide(values.sum(axis=1), pairs, out=np.zeros(matched.shape[0]), where=pairs > 0)


class _ShapeCache:
    """Δ with memoised hulls: template subsets and detection subsets keyed by index tuples."""

    def __init__(
        self, predicted: FloatArray, detections: FloatArray, settings: ShapeDistanceSettings
    ):
        self.predicted = predicted
        self.detections = detections
        self.settings = settings
        self.matchers: dict[tuple[int, ...], HullShapeMatcher] = {}
        self.checks = 0

    def distance(self, template_rows: IntArray, detection_rows: IntArray) -> float:
        key = tuple(int(value) for value in template_rows)
        matcher = self.matchers.get(key)
        if matcher is None:
            matcher = HullShapeMatcher(self.predicted[template_rows], self.settings)
            self.matchers[key] = matcher
        self.checks += 1
        return float(
            matcher.distances_to_polygons([hull_polygon(self.detections[detection_rows])])[0]
        )

    def many(self, template_rows: IntArray, detection_sets: Sequence[IntArray]) -> FloatArray:
        key = tuple(int(value) for value in template_rows)
        matcher = self.matchers.get(key)
        if matcher is None:
            matcher = HullShapeMatcher(self.predicted[template_rows], self.settings)
            self.matchers[key] = matcher
        self.checks += len(detection_sets)
        return matcher.distances([self.detections[rows] for rows in detection_sets])


def _post_prune_passes(
    cache: _ShapeCache, matched_row: IntArray, params: WindowAssociationParams
) -> bool:
    template_rows = np.nonzero(matched_row >= 0)[0]
    return cache.distance(template_rows, matched_row[template_rows]) < params.hull_post


def _result_from_window(
    detections: FloatArray,
    registered: _Registered,
    window_index: int,
    window: IntArray,
    diagnostics: WindowDiagnostics,
) -> WindowAssociationResult:
    matched = registered.matched[window_index].copy()
    # Unmatched targets go to f_W(u_p) in image coordinates; matched ones to their detection.
    positions = registered.warped[window_index].copy()
    positions[matched >= 0] = detections[matched[matched >= 0]]
    return WindowAssociationResult(
        positions=positions,
        matched_detection=matched,
        cost=float(registered.cost[window_index]),
        bending=float(registered.bending[window_index]),
        unmatched=int(matched.shape[0] - registered.count[window_index]),
        appearance=float(registered.appearance[window_index]),
        window=window,
        diagnostics=diagnostics,
    )


def _hungarian_fallback(
    predicted: FloatArray,
    detections: FloatArray,
    appearance: FloatArray | None,
    params: WindowAssociationParams,
    diagnostics: WindowDiagnostics,
) -> WindowAssociationResult:
    """Fallback 3: Hungarian on E_a alone (on distances to the prediction without E_a).

    See docs/algorithms/gap-matchers.md#fallbacks.
    """
    count = predicted.shape[0]
    if appearance is not None:
        cost_matrix = np.asarray(appearance, dtype=np.float64)
    else:
        cost_matrix = np.sqrt(np.sum((predicted[:, None] - detections[None]) ** 2, axis=2))
    rows, columns = linear_sum_assignment(cost_matrix)
    matched = np.full(count, -1, dtype=np.int64)
    matched[rows] = columns
    positions = predicted.copy()
    positions[rows] = detections[columns]
    energy = (
        float(appearance[rows, columns].mean()) if appearance is not None and rows.size else 0.0
    )
    unmatched = count - int(rows.size)
    diagnostics.fallback = FALLBACK_APPEARANCE
    return WindowAssociationResult(
        positions=positions,
        matched_detection=matched,
        cost=params.lambda1 * unmatched + params.lambda2 * energy,
        bending=0.0,
        unmatched=unmatched,
        appearance=energy,
        window=np.zeros(0, dtype=np.int64),
        diagnostics=diagnostics,
    )


def _choose(
    template: TpsRpmTemplate,
    detections: FloatArray,
    appearance: FloatArray | None,
    windows: WindowSet,
    registered: _Registered,
    prescreen: BoolArray | None,
    params: WindowAssociationParams,
    cache: _ShapeCache,
) -> WindowAssociationResult:
    """Best window of one candidate, with the fallback chain.

    See docs/algorithms/gap-matchers.md#fallbacks.
    """
    count = template.template.shape[0]
    diagnostics = WindowDiagnostics(
        windows_total=windows.total,
        after_dedup=windows.after_dedup,
        after_size=windows.after_size,
        window_rule=windows.rule,
    )
    minimum = min(params.min_matches, count)
    member_rows = [np.nonzero(row)[0] for row in windows.members]
    diagnostics.rpm_runs = int(registered.ran.sum())
    diagnostics.with_min_matches = int((registered.count >= minimum).sum())
    order = np.argsort(registered.cost, kind="stable")
    order = order[registered.count[order] >= minimum]
    chosen: int | None = None
    if prescreen is None:
        # Lazy: visit windows by increasing ψ; the first passing both cuts is the argmin.
        for index in order:
            if cache.distance(np.arange(count), member_rows[index]) >= params.hull_pre:
                continue
            if _post_prune_passes(cache, registered.matched[index], params):
                chosen = int(index)
                break
    else:
        diagnostics.after_hull_prescreen = int(prescreen.sum())
        passes = [_post_prune_passes(cache, registered.matched[i], params) for i in order]
        diagnostics.after_rpm_prune = int(sum(passes))
        chosen = next((int(i) for i, ok in zip(order, passes, strict=True) if ok), None)
        if chosen is None:
            # Fallback 1 needs the windows the prescreen removed as well.
            _register([template], detections, windows.members, [~registered.ran], [registered])
            registered.finish(appearance, params)
            diagnostics.rpm_runs = int(registered.ran.sum())
            order = np.argsort(registered.cost, kind="stable")
            order = order[registered.count[order] >= minimum]
    if chosen is None and order.size:
        # Fallback 1: without both shape cuts the best window is the smallest ψ overall.
        diagnostics.fallback = FALLBACK_NO_SHAPE_CUTS
        chosen = int(order[0])
    diagnostics.shape_checks = cache.checks
    if chosen is not None:
        return _result_from_window(detections, registered, chosen, member_rows[chosen], diagnostics)
    # Fallback 2: TPS-RPM with W = V, accepted with any number of matches.
    everything = np.ones((1, detections.shape[0]), dtype=bool)
    whole = _Registered.empty(1, count)
    _register([template], detections, everything, [np.ones(1, dtype=bool)], [whole])
    whole.finish(appearance, params)
    diagnostics.rpm_runs += 1
    if whole.count[0] > 0:
        diagnostics.fallback = FALLBACK_ALL_DETECTIONS
        return _result_from_window(
            detections, whole, 0, np.arange(detections.shape[0]), diagnostics
        )
    predicted = template.template
    return _hungarian_fallback(predicted, detections, appearance, params, diagnostics)


def associate_candidates(
    candidates: Sequence[FloatArray],
    detections: FloatArray,
    appearance: FloatArray | None = None,
    params: WindowAssociationParams | None = None,
    windows: WindowSet | None = None,
) -> list[WindowAssociationResult]:
    """Window association of several candidate predictions (e.g. AR orders) with one V.

    All candidates must have the same number of points K; the windows are built once and the
    TPS-RPM runs of all candidates share one batched annealing loop per window size.

    Args:
        candidates: C arrays (K, 2) of predicted points U_k.
        detections: (N, 2) detections V.
        appearance: optional (K, N) appearance distances (rows: targets, columns: detections).
        params: parameters.
        windows: windows from :func:`build_windows` (built here when None).

    Returns:
        One result per candidate.
    """
    params = params if params is not None else WindowAssociationParams()
    detections = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
    predicted_sets = [np.asarray(u, dtype=np.float64).reshape(-1, 2) for u in candidates]
    if not predicted_sets:
        return []
    count = predicted_sets[0].shape[0]
    if any(u.shape[0] != count for u in predicted_sets):
        raise ValueError("all candidates must have the same number of points")
    if appearance is not None:
        appearance = np.asarray(appearance, dtype=np.float64)
        if appearance.shape != (count, detections.shape[0]):
            raise ValueError(
                f"appearance must have shape ({count}, {detections.shape[0]}), "
                f"got {appearance.shape}"
            )
    if count == 0 or detections.shape[0] == 0:
        return [_no_detection_result(u, params) for u in predicted_sets]
    if windows is None:
        windows = build_windows(detections, count, params)
    window_count = windows.members.shape[0]
    templates = [TpsRpmTemplate(u, params.rpm) for u in predicted_sets]
    caches = [_ShapeCache(u, detections, params.shape) for u in predicted_sets]
    prescreens: list[BoolArray | None] = [None] * len(templates)
    needed = [np.ones(window_count, dtype=bool) for _ in templates]
    if not params.lazy_shape_checks:
        member_rows = [np.nonzero(row)[0] for row in windows.members]
        for index, cache in enumerate(caches):
            passing = cache.many(np.arange(count), member_rows) < params.hull_pre
            prescreens[index] = passing
            needed[index] = passing
    stores = [_Registered.empty(window_count, count) for _ in templates]
    # Identical candidates (AR orders that agree) share one set of RPM runs. With noise_seed
    # the noise is drawn per batch, so there every candidate keeps its own runs.
    source = _first_copies(predicted_sets) if params.rpm.noise_seed is None else None
    if source is None:
        _register(templates, detections, windows.members, needed, stores)
    else:
        unique = [index for index, first in enumerate(source) if first == index]
        _register(
            [templates[i] for i in unique],
            detections,
            windows.members,
            [needed[i] for i in unique],
            [stores[i] for i in unique],
        )
        for index, first in enumerate(source):
            if first != index:
                stores[index] = stores[first].copy()
    for store in stores:
        store.finish(appearance, params)
    return [
        _choose(template, detections, appearance, windows, store, prescreen, params, cache)
        for template, store, prescreen, cache in zip(
            templates, stores, prescreens, caches, strict=True
        )
    ]


def _first_copies(point_sets: Sequence[FloatArray]) -> list[int]:
    """Index of the first point set equal to each one (its own index when it is the first).

    >>> _first_copies([np.zeros((2, 2)), np.ones((2, 2)), np.zeros((2, 2))])
    [0, 1, 0]
    """
    first: list[int] = []
    for index, points in enumerate(point_sets):
        match = next(
            (
                earlier
                for earlier in range(index)
                if first[earlier] == earlier and np.array_equal(points, point_sets[earlier])
            ),
            index,
        )
        first.append(match)
    return first


def associate_window(
    predicted: FloatArray,
    detections: FloatArray,
    appearance: FloatArray | None = None,
    params: WindowAssociationParams | None = None,
    windows: WindowSet | None = None,
) -> WindowAssociationResult:
    """Window association of one candidate U (K, 2) with detections V (N, 2)."""
    return associate_candidates([predicted], detections, appearance, params, windows)[0]


def _no_detection_result(
    predicted: FloatArray, params: WindowAssociationParams
) -> WindowAssociationResult:
    count = predicted.shape[0]
    return WindowAssociationResult(
        positions=predicted.copy(),
        matched_detection=np.full(count, -1, dtype=np.int64),
        cost=params.lambda1 * count,
        bending=0.0,
        unmatched=count,
        appearance=0.0,
        window=np.zeros(0, dtype=np.int64),
        diagnostics=WindowDiagnostics(fallback=FALLBACK_NO_DETECTIONS),
    )


def skipped_result(predicted: FloatArray, fallback: str) -> WindowAssociationResult:
    """A candidate left unsearched: infinite cost, nothing matched, targets at U ``(K, 2)``."""
    count = predicted.shape[0]
    return WindowAssociationResult(
        positions=np.asarray(predicted, dtype=np.float64).copy(),
        matched_detection=np.full(count, -1, dtype=np.int64),
        cost=float("inf"),
        bending=0.0,
        unmatched=count,
        appearance=0.0,
        window=np.zeros(0, dtype=np.int64),
        diagnostics=WindowDiagnostics(fallback=fallback),
    )


def select_candidate(results: Sequence[WindowAssociationResult]) -> int:
    """Index of the candidate with the smallest ψ; ties go to the first (smaller AR order).

    >>> a = WindowAssociationResult(np.zeros((1, 2)), np.zeros(1, dtype=np.int64), 2.0, 0, 0, 0,
    ...                             np.zeros(0, dtype=np.int64))
    >>> b = WindowAssociationResult(np.zeros((1, 2)), np.zeros(1, dtype=np.int64), 1.0, 0, 0, 0,
    ...                             np.zeros(0, dtype=np.int64))
    >>> select_candidate([a, b, b])
    1
    """
    if not results:
        raise ValueError("no candidates to choose from")
    costs = np.array([result.cost for result in results])
    # float32 annealing leaves ~1e-7 noise on psi: equal costs within that are ties.
    return int(np.flatnonzero(costs <= costs.min() + TIE_TOLERANCE)[0])

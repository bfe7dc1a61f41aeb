"""The segment tracker at frame b: the gap matcher's matches checked by look, and re-matched.

Used by :meth:`trackfw_plugins.trackers.kalman.KalmanTracker.reinitialise`. After an interval the
gap matcher hands each target a detection of frame b (or none). A match to a head of another
size, or one that looks like someone else, is refused, and the refused targets, with the targets
lost before the interval, take by look alone the detections no kept match holds
(docs/algorithms/segment-tracker.md#re-initialisation-at-b).
Also the two lookups the restart needs: each target's row among the detections, and its box side.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import FloatArray, IntArray, UInt8Array
from trackfw.records import NO_MATCH, Detections
from trackfw_plugins.maths.assignment import distance_matrix, hungarian
from trackfw_plugins.maths.kalman import extrapolate
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory, AppearanceSettings
from trackfw_plugins.trackers.lifecycle import Lifecycle
from trackfw_plugins.trackers.look_rules import nearer_by_ratio
from trackfw_plugins.trackers.neighbour_looks import NeighbourLooks


def box_sides(detections: Detections) -> FloatArray:
    """``(N,)`` square root of each detection's box area; NaN without boxes."""
    if detections.boxes is None:
        return np.full(len(detections), np.nan)
    return np.sqrt(np.abs(detections.boxes[:, 2] * detections.boxes[:, 3]))


def detection_rows_of(matched: IntArray, detections: Detections | None) -> IntArray:
    """``(K,)`` row of ``detections`` of each target's matched detection index (-1: none)."""
    rows = np.full(len(matched), NO_MATCH, dtype=np.int64)
    if detections is None or len(detections) == 0:
        return rows
    lookup = {int(index): row for row, index in enumerate(detections.index)}
    for k, index in enumerate(matched):
        rows[k] = lookup.get(int(index), NO_MATCH)
    return rows


def detection_indices(rows: IntArray, detections: Detections) -> IntArray:
    """``(K,)`` detection index of each row of ``detections`` in ``rows`` (-1 stays -1)."""
    indices = np.full(len(rows), NO_MATCH, dtype=np.int64)
    found = rows >= 0
    indices[found] = detections.index[rows[found]]
    return indices


def matched_sides(detection_rows: IntArray, detections: Detections | None) -> FloatArray:
    """``(K,)`` box side of each target's matched detection row at b (NaN when none)."""
    sides = np.full(len(detection_rows), np.nan)
    if detections is None or len(detections) == 0:
        return sides
    found = detection_rows >= 0
    sides[found] = box_sides(detections)[detection_rows[found]]
    return sides


def refuse_by_size(
    life: Lifecycle,
    active: IntArray,
    matched: IntArray,
    detection_rows: IntArray,
    sides: FloatArray,
) -> IntArray:
    """Drop the matches at b to heads of another size than the target's.

    The ``active`` targets' stored sizes are first rescaled by the camera's change of scale
    (``sides``: ``(K,)`` box side of each target's match, NaN when none); ``matched`` and
    ``detection_rows`` are updated in place.

    Returns:
        The rows refused this way when ``lifecycle.size_refused_at_b`` is ``lost`` (hand them
        to :func:`check_looks_at_b` as ``refused``); none when it is ``tentative``.
    """
    life.rescale_sizes(active, sides[active])
    mismatch = np.diagonal(life.size_mismatch(np.arange(len(matched)), sides))
    # A head of another size is someone else's: placed there, the target would take it on the
    # next frame.
    refused = (
        np.flatnonzero(mismatch & (matched != NO_MATCH))
        if life.settings.size_refused_at_b == "lost"
        else np.zeros(0, dtype=np.int64)
    )
    matched[mismatch] = NO_MATCH
    detection_rows[matched == NO_MATCH] = NO_MATCH
    return refused


def look_limits(settings: AppearanceSettings, ratios: FloatArray | None, count: int) -> FloatArray:
    """``(count,)`` look limit of each target's match at b: ``gap_max_distance``, or
    ``gap_weak_max_distance`` for a weak match (its ``ratios`` entry, the gap matcher's
    :attr:`.GapSolution.match_ratios`, above ``gap_weak_ratio``; NaN is never weak).

    >>> settings = AppearanceSettings(descriptor="person-reid", gap_max_distance=0.4,
    ...                               gap_weak_ratio=0.9, gap_weak_max_distance=0.3)
    >>> look_limits(settings, np.array([0.5, 0.95, np.nan]), 3).tolist()
    [0.4, 0.3, 0.4]
    >>> look_limits(settings, None, 2).tolist()
    [0.4, 0.4]
    """
    limit = np.inf if settings.gap_max_distance is None else settings.gap_max_distance
    limits = np.full(count, limit)
    weak_limit, weak_ratio = settings.gap_weak_max_distance, settings.gap_weak_ratio
    if ratios is None or weak_limit is None or weak_ratio is None or len(ratios) != count:
        return limits
    with np.errstate(invalid="ignore"):
        weak = np.asarray(ratios) > weak_ratio
    limits[weak] = np.minimum(limits[weak], weak_limit)
    return limits


def check_looks_at_b(
    memory: AppearanceMemory,
    life: Lifecycle,
    image: UInt8Array | None,
    settings: AppearanceSettings,
    active: IntArray,
    matched: IntArray,
    detection_rows: IntArray,
    positions: FloatArray,
    detections: Detections | None,
    inactive: IntArray,
    refused: IntArray | None = None,
    checked_looks: FloatArray | None = None,
    limits: FloatArray | None = None,
    continuity: IntArray | None = None,
) -> tuple[IntArray, IntArray]:
    """Refuse the matches at b that look like someone else; re-match those targets by look.

    A match farther than ``settings.gap_max_distance`` (or its target's entry of ``limits``)
    from the target's descriptor is refused. A refused target first falls back to its
    ``continuity`` proposal (:func:`take_continuity`). The other refused targets, and the
    ``inactive`` ones (lost and out-of-view targets with ``gap_rematch_inactive``), then take,
    by Hungarian on appearance distance (``gap_max_distance``, ratio test, sizes checked), the
    detections no kept match holds, never the one a target's match was just refused for: when
    the window match swapped two targets, each finds its own head again.

    Args:
        memory: the targets' descriptors.
        life: the targets' lifecycle (head sizes).
        image: frame b's pixels.
        settings: the appearance settings.
        active: rows of the targets the gap matcher matched or placed.
        matched: ``(K,)`` detection index of each target's match (-1: none); updated in place.
        detection_rows: ``(K,)`` row of ``detections`` of each match; updated in place.
        positions: ``(K, 2)`` each target's position at b; updated in place.
        detections: frame b's detections.
        inactive: rows of the lost and out-of-view targets looked for by look.
        refused: rows of the targets whose match was already refused (their head's size):
            re-matched by look like the ones the look refuses.
        checked_looks: ``(K,)``, when given, receives the look distance of each checked match
            (the value compared with ``gap_max_distance``), for the record of the check.
        limits: ``(K,)`` look limit of each target's match (a weak match's is stricter); None:
            ``gap_max_distance`` for every one.
        continuity: ``(K,)`` row of ``detections`` that continuity proposes for each target
            where it differs from the gap matcher's (-1: none; :func:`continuity_rows`); None:
            no fallback.

    Returns:
        The refused targets left without a match (to be lost), and the inactive targets that
        found a detection.
    """
    none = np.zeros(0, dtype=np.int64)
    limit = settings.gap_max_distance
    if limit is None or detections is None or len(detections) == 0:
        # Nothing to look at: the targets refused already stay without a match.
        return (none if refused is None else refused), none
    checked = active[detection_rows[active] >= 0]
    look = memory.looks(image, checked, detections, detection_rows[checked])
    if checked_looks is not None:
        checked_looks[checked] = np.diagonal(look)
    own_limits = np.full(len(checked), limit) if limits is None else limits[checked]
    unlike = checked[np.diagonal(look) > own_limits]  # NaN (nothing known) refuses nothing
    refused_columns = detection_rows[unlike].copy()
    if refused is not None:
        unlike = np.concatenate([unlike, refused])
    if len(unlike) + len(inactive) == 0:
        return none, none
    detection_rows[unlike] = NO_MATCH
    matched[unlike] = NO_MATCH
    free = np.setdiff1d(np.arange(len(detections)), detection_rows[detection_rows >= 0])
    if continuity is not None:
        took = take_continuity(
            memory,
            life,
            image,
            limit,
            unlike[np.isin(continuity[unlike], free)],
            continuity,
            (matched, detection_rows, positions),
            detections,
        )
        kept = ~np.isin(unlike, took)
        refused_columns, unlike = refused_columns[kept[: len(refused_columns)]], unlike[kept]
        free = np.setdiff1d(free, detection_rows[took])
        if len(unlike) + len(inactive) == 0:
            return none, none
    candidates = np.concatenate([unlike, inactive])
    # Every detection is described: the ratio test compares with the taken ones too.
    look = memory.looks(image, candidates, detections, np.arange(len(detections)))
    if settings.gap_rematch_ratio is not None:
        look = np.where(nearer_by_ratio(look, settings.gap_rematch_ratio), look, np.inf)
    # A match refused by look is not handed back by the re-match (a weak match's limit is
    # stricter than the re-match's).
    look[np.arange(len(refused_columns)), refused_columns] = np.inf
    cost = look[:, free]
    sides = box_sides(detections)[free]
    cost[np.isnan(cost) | life.size_mismatch(candidates, sides)] = np.inf
    strict = settings.anywhere_max_distance
    lost_rows = cost[len(unlike) :]  # a view: the inactive targets' rows
    if strict is not None:
        # A target lost before the interval has no match to be refused from: it is found by
        # look alone, as the search anywhere finds it, and under that search's limit.
        lost_rows[lost_rows > strict] = np.inf
    columns = hungarian(cost, limit)
    hit = columns >= 0
    found, rows = candidates[hit], free[columns[hit]]
    detection_rows[found] = rows
    matched[found] = detections.index[rows]
    positions[found] = detections.points[rows]
    return unlike[~hit[: len(unlike)]], inactive[hit[len(unlike) :]]


def continuity_rows(
    means: FloatArray, horizon: int, detections: Detections | None, proposed: IntArray
) -> IntArray:
    """``(K,)`` detection row that continuity proposes for each target at b, -1 where it is the
    gap matcher's own proposal or there is none.

    Continuity is what the ``assignment`` gap matcher with the ``kalman`` predictor would match
    (``pipelines/real-tr.yaml``, the floor of ``real.yaml``): each filter's state at a carried
    over the interval without correction, then Hungarian on pixel distance, no gate.

    Args:
        means: ``(K, 4)`` filter states at a of the targets in the gap match.
        horizon: frames from a to b.
        detections: frame b's detections.
        proposed: ``(K,)`` detection row of the gap matcher's match of each target (-1: none).

    >>> dets = Detections.from_points(np.array([[0.0, 0.0], [50.0, 0.0]]))
    >>> continuity_rows(np.array([[40.0, 0, 1, 0], [0, 0, 0, 0]]), 10, dets, np.array([1, 1]))
    array([-1,  0])
    """
    rows = np.full(len(means), NO_MATCH, dtype=np.int64)
    if detections is None or len(detections) == 0 or len(means) == 0:
        return rows
    rows = hungarian(distance_matrix(extrapolate(means, horizon), detections.points))
    rows[rows == proposed] = NO_MATCH
    return rows


def take_continuity(
    memory: AppearanceMemory,
    life: Lifecycle,
    image: UInt8Array | None,
    limit: float,
    refused: IntArray,
    continuity: IntArray,
    held: tuple[IntArray, IntArray, FloatArray],
    detections: Detections,
) -> IntArray:
    """The ``refused`` targets that take their ``continuity`` proposal instead: it passes the
    checks the gap matcher's match failed (the head's size; the look within ``limit``, an
    unknown look passing as it does there).

    ``held`` is ``(matched, detection_rows, positions)``, as in :func:`check_looks_at_b`, updated
    in place; ``refused`` holds only targets whose proposal no other target holds. Returns the
    rows that took theirs.
    """
    if len(refused) == 0:
        return refused
    matched, detection_rows, positions = held
    columns = continuity[refused]
    look = np.diagonal(memory.looks(image, refused, detections, columns))
    other_size = np.diagonal(life.size_mismatch(refused, box_sides(detections)[columns]))
    fits = ~(look > limit) & ~other_size
    took, columns = refused[fits], columns[fits]
    detection_rows[took] = columns
    matched[took] = detections.index[columns]
    positions[took] = detections.points[columns]
    return took


def refuse_beside(
    memory: AppearanceMemory,
    neighbours: NeighbourLooks,
    image: UInt8Array | None,
    margin: float,
    rows: IntArray,
    matched: IntArray,
    detection_rows: IntArray,
    detections: Detections | None,
) -> IntArray:
    """Drop the matches at b of ``rows`` whose detection looks at least as much like one of the
    people kept beside the target as like the target (within ``margin``;
    docs/algorithms/segment-tracker.md#people-seen-beside-a-lost-target).

    ``matched`` and ``detection_rows`` (``(K,)``, as in :func:`check_looks_at_b`) are updated in
    place. Returns the rows dropped.
    """
    none = np.zeros(0, dtype=np.int64)
    if detections is None or len(detections) == 0:
        return none
    checked = rows[detection_rows[rows] >= 0]
    look, described = memory.described_looks(image, checked, detections, detection_rows[checked])
    if described is None:
        return none
    beside = np.diagonal(neighbours.distances(checked, described, memory.distance_matrix))
    dropped = checked[np.diagonal(look) + margin > beside]
    matched[dropped] = NO_MATCH
    detection_rows[dropped] = NO_MATCH
    return dropped


def record_at_b(
    proposed: IntArray,
    final: IntArray,
    looks: FloatArray,
    refusals: dict[str, IntArray],
    rows: IntArray,
    statuses: list[str],
    ratios: FloatArray | None = None,
    continuity: IntArray | None = None,
) -> dict[int, dict[str, object]]:
    """The record of the check at b (gaps.json ``at_b``) for ``rows``, keyed by row.

    Args:
        proposed: ``(K,)`` detection index the gap matcher gave each target (-1: none).
        final: ``(K,)`` detection index each target holds after the check (-1: none).
        looks: ``(K,)`` look distance of each checked match (NaN: not looked at).
        refusals: reason -> rows whose proposed match was refused for it (the first reason
            listed wins); a refused match not listed was refused by look.
        rows: the targets to record (those in the gap match and those found by look).
        statuses: every target's lifecycle status after b.
        ratios: ``(K,)`` the gap matcher's :attr:`.GapSolution.match_ratios` (recorded as
            ``ratio``; None or NaN: not given).
        continuity: ``(K,)`` detection index continuity proposed where it differed from the
            gap matcher (-1: none); a target that holds it was matched ``by`` ``continuity``.

    >>> import numpy as np
    >>> record = record_at_b(np.array([3, 4, -1]), np.array([3, 5, -1]),
    ...                      np.array([0.1, 0.6, np.nan]), {}, np.arange(3),
    ...                      ["tracked", "tracked", "tentative"])
    >>> record[1]
    {'proposed': 4, 'look': 0.6, 'ratio': None, 'refused': 'look', 'detection': 5, 'by': 'look', 'status': 'tracked'}
    >>> record[2]["refused"], record[2]["by"]
    (None, None)
    """
    record: dict[int, dict[str, object]] = {}
    for row in rows.tolist():
        given, held = int(proposed[row]), int(final[row])
        reason = None
        if given != NO_MATCH and held != given:
            reason = next((name for name, refused in refusals.items() if row in refused), "look")
        record[row] = {
            "proposed": None if given == NO_MATCH else given,
            "look": _rounded(looks[row]),
            "ratio": _rounded(None if ratios is None else ratios[row]),
            "refused": reason,
            "detection": None if held == NO_MATCH else held,
            "by": _matched_by(given, held, NO_MATCH if continuity is None else continuity[row]),
            "status": statuses[row],
        }
    return record


def _matched_by(given: int, held: int, continuity: int) -> str | None:
    """Who gave a target the detection it holds after the check at b (None: it holds none)."""
    if held == NO_MATCH:
        return None
    if held == given:
        return "gap matcher"
    return "continuity" if held == continuity else "look"


def _rounded(value: float | None) -> float | None:
    """``value`` to 4 decimals for a JSON record; None when unknown (None or not finite)."""
    return None if value is None or not np.isfinite(value) else round(float(value), 4)

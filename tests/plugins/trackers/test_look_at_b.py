"""The look check of the gap matcher's matches at b, and the lookups of the restart."""

from __future__ import annotations

import numpy as np

from trackfw.records import Detections, VideoContext
from trackfw_plugins.trackers.appearance_memory import AppearanceSettings
from trackfw_plugins.trackers.lifecycle import Lifecycle, LifecycleSettings
from trackfw_plugins.trackers.look_at_b import (
    check_looks_at_b,
    continuity_rows,
    detection_rows_of,
    look_limits,
    matched_sides,
    record_at_b,
)

VIDEO = VideoContext(name="v", path="v", n_frames=10, width=640, height=480)


class _Looks:
    """A stand-in for the appearance memory: fixed ``(K, N)`` look distances."""

    def __init__(self, table: list[list[float]]) -> None:
        self.table = np.array(table)

    def looks(self, image: object, targets: np.ndarray, detections: object, columns: np.ndarray):
        return self.table[np.ix_(targets, columns)]


def _detections() -> Detections:
    return Detections.from_points(np.array([[100.0, 100.0], [200.0, 100.0], [300.0, 100.0]]))


def _three_targets() -> tuple[_Looks, Lifecycle, AppearanceSettings]:
    """Three targets' looks at :func:`_detections` (rows: targets), their lifecycle, the limits."""
    looks = _Looks([[0.6, 0.5, 0.1], [0.9, 0.2, 0.8], [0.7, 0.7, 0.7]])
    life = Lifecycle.start(LifecycleSettings(), VIDEO, 0, np.zeros((3, 2)))
    return looks, life, AppearanceSettings(gap_max_distance=0.4, anywhere_max_distance=0.4)


def _check_the_first_two(
    looks: _Looks,
    life: Lifecycle,
    settings: AppearanceSettings,
    matched: np.ndarray,
    **options: np.ndarray,
) -> None:
    """:func:`check_looks_at_b` of targets 0 and 1 of three, with their ``matched`` detections
    (updated in place) and the keyword ``options`` of the check."""
    check_looks_at_b(
        looks,  # type: ignore[arg-type]
        life,
        None,
        settings,
        np.array([0, 1]),
        matched,
        matched.copy(),
        np.zeros((3, 2)),
        _detections(),
        np.zeros(0, dtype=np.int64),
        **options,  # type: ignore[arg-type]
    )


def test_detection_rows_follow_the_detection_index() -> None:
    detections = _detections()
    assert detection_rows_of(np.array([2, -1, 0]), detections).tolist() == [2, -1, 0]
    assert detection_rows_of(np.array([1]), None).tolist() == [-1]
    assert np.isnan(matched_sides(np.array([0, -1]), detections)).all()  # no boxes


def test_a_match_that_looks_like_someone_else_is_refused_and_rematched_by_look() -> None:
    # Target 0 was matched to detection 0 but looks far from it (0.6) and near detection 2 (0.1);
    # target 1 keeps its match (0.2). A lost target 2 looks like nothing in the frame.
    looks, life, settings = _three_targets()
    matched = np.array([0, 1, -1])
    rows = matched.copy()
    positions = np.array([[100.0, 100.0], [200.0, 100.0], [0.0, 0.0]])
    unlike, returned = check_looks_at_b(
        looks,  # type: ignore[arg-type]
        life,
        None,
        settings,
        np.array([0, 1]),
        matched,
        rows,
        positions,
        _detections(),
        np.array([2]),
    )
    assert unlike.tolist() == [] and returned.tolist() == []
    assert matched.tolist() == [2, 1, -1] and rows.tolist() == [2, 1, -1]
    assert positions[0].tolist() == [300.0, 100.0]


def test_the_check_at_b_is_recorded_with_its_looks_and_reasons() -> None:
    # The case above, recorded: target 0's match refused by look (0.6) and re-matched by look,
    # target 1's kept (0.2), target 2's (refused by size before the look) left without one.
    looks, life, settings = _three_targets()
    proposed = np.array([0, 1, 2])
    matched = np.array([0, 1, -1])
    checked = np.full(3, np.nan)
    _check_the_first_two(looks, life, settings, matched, checked_looks=checked)
    assert checked[:2].tolist() == [0.6, 0.2] and np.isnan(checked[2])
    record = record_at_b(
        proposed,
        matched,
        checked,
        {"size": np.array([2])},
        np.arange(3),
        ["tracked", "tracked", "lost"],
    )
    assert record[0] == {
        "proposed": 0,
        "look": 0.6,
        "ratio": None,
        "refused": "look",
        "detection": 2,
        "by": "look",
        "status": "tracked",
    }
    assert record[1]["refused"] is None and record[1]["by"] == "gap matcher"
    assert record[2]["refused"] == "size" and record[2]["detection"] is None
    assert record[2]["look"] is None and record[2]["status"] == "lost"


def test_a_refused_target_without_a_clear_look_is_left_to_be_lost() -> None:
    # Target 0's look at every other detection is as far as at its match: nothing stands out.
    settings = AppearanceSettings(gap_max_distance=0.4, gap_rematch_ratio=0.8)
    assert _check_one([[0.6, 0.35, 0.36]], settings) == ([0], [-1])


WEAK = AppearanceSettings(
    gap_max_distance=0.4, gap_weak_ratio=0.92, gap_weak_max_distance=0.3, gap_rematch_ratio=0.8
)


def _check_one(
    table: list[list[float]],
    settings: AppearanceSettings,
    ratio: float | None = None,
    continuity: int | None = None,
) -> tuple[list[int], list[int]]:
    """One target matched to detection 0 (gap-matcher ``ratio``, if given; the ``continuity``
    detection, if given), checked with the look distances ``table`` to :func:`_detections`;
    returns (refused left without one, matched).
    """
    life = Lifecycle.start(LifecycleSettings(), VIDEO, 0, np.zeros((1, 2)))
    matched = np.array([0])
    unlike, _ = check_looks_at_b(
        _Looks(table),  # type: ignore[arg-type]
        life,
        None,
        settings,
        np.array([0]),
        matched,
        matched.copy(),
        np.zeros((1, 2)),
        _detections(),
        np.zeros(0, dtype=np.int64),
        limits=look_limits(settings, None if ratio is None else np.array([ratio]), 1),
        continuity=None if continuity is None else np.array([continuity]),
    )
    return unlike.tolist(), matched.tolist()


def test_a_weak_match_needs_the_stricter_look_and_is_not_handed_back() -> None:
    # Its look (0.35) passes gap_max_distance; it barely beat another detection in the gap
    # matcher (0.95), so it must be within 0.3. The re-match by look would take detection 0
    # again (0.35 against 0.6 and 0.7 passes the ratio test): a refused match is not handed back.
    table = [[0.35, 0.6, 0.7]]
    assert _check_one(table, WEAK, 0.95) == ([0], [-1])
    assert _check_one(table, WEAK, 0.85) == ([], [0])  # clear in the gap matcher: the usual limit
    assert _check_one(table, WEAK, float("nan")) == ([], [0])  # not said: the usual limit


def test_a_refused_weak_match_still_finds_its_own_head_by_look() -> None:
    # Refused on detection 0, the target takes detection 2, which it looks like clearly.
    assert _check_one([[0.35, 0.6, 0.2]], WEAK, 0.95) == ([], [2])


def test_a_refused_match_falls_back_to_continuity_only_where_that_passes_the_look() -> None:
    # Refused on detection 0 (0.6); nothing is clear by look (0.35 against 0.36).
    table = [[0.6, 0.35, 0.36]]
    assert _check_one(table, WEAK) == ([0], [-1])
    assert _check_one(table, WEAK, continuity=2) == ([], [2])  # within gap_max_distance
    assert _check_one([[0.6, 0.5, 0.2]], WEAK, continuity=1) == ([], [2])  # 0.5: re-matched
    assert _check_one([[0.6, 0.5, 0.45]], WEAK, continuity=1) == ([0], [-1])


def test_continuity_never_takes_a_detection_a_kept_match_holds() -> None:
    # Target 1 keeps detection 1 (0.2); continuity proposes it to target 0 as well, which
    # looks like it (0.3) but finds nothing clear by look.
    _, life, _ = _three_targets()
    looks = _Looks([[0.6, 0.3, 0.9], [0.9, 0.2, 0.8], [0.7, 0.7, 0.7]])
    matched = np.array([0, 1, -1])
    settings = AppearanceSettings(gap_max_distance=0.4, gap_rematch_ratio=0.1)
    _check_the_first_two(looks, life, settings, matched, continuity=np.array([1, -1, -1]))
    assert matched.tolist() == [-1, 1, -1]


def test_continuity_is_the_walk_carried_over_the_gap_and_names_what_differs() -> None:
    # Target 0 walked right 10 px a frame from 100; target 1 stood at 300. After 10 frames
    # continuity puts them on detections 1 (200) and 2 (300); the gap matcher gave target 1
    # detection 2 already, so only target 0's proposal is named.
    means = np.array([[100.0, 100.0, 10.0, 0.0], [300.0, 100.0, 0.0, 0.0]])
    proposed = np.array([0, 2])
    assert continuity_rows(means, 10, _detections(), proposed).tolist() == [1, -1]
    assert continuity_rows(means, 10, None, proposed).tolist() == [-1, -1]


def test_a_match_by_continuity_is_recorded_as_such() -> None:
    record = record_at_b(
        np.array([0, 1]),
        np.array([2, -1]),
        np.array([0.6, 0.7]),
        {},
        np.arange(2),
        ["tracked", "lost"],
        continuity=np.array([2, 0]),
    )
    assert record[0]["refused"] == "look" and record[0]["by"] == "continuity"
    assert record[1]["by"] is None and record[1]["detection"] is None

"""CLEAR MOT: py-motmetrics' asserted synthetic cases and the point-mode behaviour of section 9."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trackfw_plugins.evaluation.clear_mot import (
    ClearMotAccumulator,
    assign_allowed,
    box_iou,
    build_sequence,
    clear_mot,
    clear_mot_windows,
    interval_windows,
)

NAN = np.nan


def _empty(n_gt: int, n_hyp: int) -> np.ndarray:
    return np.zeros((n_gt, n_hyp))


def test_mota_motp_matches_motmetrics() -> None:
    accumulator = ClearMotAccumulator()
    accumulator.update([], [1, 2], _empty(0, 2))
    accumulator.update([1, 2], [], _empty(2, 0))
    accumulator.update([1, 2], [1, 2], [[1, 0.5], [0.3, 1]])
    accumulator.update([1, 2], [1, 2], [[0.2, NAN], [NAN, 0.1]])
    # A better new match exists but the history must be kept.
    matches = accumulator.update([1, 2], [1, 2], [[5, 1], [1, 5]])
    accumulator.update([], [], _empty(0, 0))
    counts = accumulator.counts()
    assert sorted(matches) == [(1, 1, 5.0), (2, 2, 5.0)]
    assert counts.n_correspondences - counts.n_switches == 4
    assert counts.n_false_positives == 2
    assert counts.n_misses == 2
    assert counts.n_switches == 2
    assert counts.n_correspondences == 6
    assert counts.n_objects == 8
    assert counts.n_predictions == 8
    assert counts.n_frames == 6
    assert counts.mota == pytest.approx(0.25)
    assert counts.motp == pytest.approx(11.1 / 6)


def test_switch_sub_events_match_motmetrics() -> None:
    accumulator = ClearMotAccumulator()
    accumulator.update([], [], _empty(0, 0))
    accumulator.update([1, 2], [1, 2], [[1, 0], [0, 1]])
    accumulator.update([1, 2], [1, 2], [[0.4, NAN], [NAN, 0.4]])
    accumulator.update([1, 2], [1, 2], [[0, 1], [1, 0]])
    accumulator.update([1, 2], [2, 3], [[1, 0], [0.4, 0.7]])
    accumulator.update([1, 3], [2, 3], [[1, 0], [0.4, 0.7]])
    accumulator.update([], [], _empty(0, 0))
    counts = accumulator.counts()
    assert counts.n_correspondences - counts.n_switches == 7
    assert (counts.n_switches, counts.n_transfers, counts.n_ascends, counts.n_migrates) == (
        3,
        3,
        1,
        1,
    )
    assert (counts.n_false_positives, counts.n_misses) == (0, 0)
    assert (counts.n_objects, counts.n_predictions, counts.n_frames) == (10, 10, 7)
    assert counts.mota == pytest.approx(0.7)
    assert counts.motp == pytest.approx(0.16)


def test_correct_average_of_bernardin_figure_3() -> None:
    accumulator = ClearMotAccumulator()
    for _ in range(4):
        accumulator.update([1, 2, 3, 4], [], _empty(4, 0))
    for _ in range(4):
        accumulator.update([4], [4], [[0.0]])
    assert accumulator.counts().mota == pytest.approx(0.2)


def test_empty_sides_and_no_events() -> None:
    only_hypotheses = ClearMotAccumulator()
    only_objects = ClearMotAccumulator()
    neither = ClearMotAccumulator()
    for _ in range(4):
        only_hypotheses.update([], [1, 2, 3, 4], _empty(0, 4))
        only_objects.update([1, 2, 3, 4], [], _empty(4, 0))
        neither.update([], [], _empty(0, 0))
    assert only_hypotheses.counts().n_false_positives == 16
    assert only_hypotheses.counts().n_frames == 4
    assert only_objects.counts().n_misses == 16
    counts = neither.counts()
    assert (counts.n_frames, counts.n_objects, counts.n_false_positives, counts.n_misses) == (
        4,
        0,
        0,
        0,
    )
    empty = ClearMotAccumulator().counts()
    assert math.isnan(empty.mota) and math.isnan(empty.motp) and empty.n_frames == 0


def test_frames_with_only_one_side_count_like_motmetrics() -> None:
    annotations = {1: [0, 2, 4, 6, None, None, None], 2: [None, None, 0, 2, 4, None, None]}
    predictions = {1: [None, None, 3, 5, 7, 7, 7]}

    def frames(tracks: dict[int, list[int | None]]) -> dict[int, dict[int, tuple[float, float]]]:
        result: dict[int, dict[int, tuple[float, float]]] = {}
        for track_id, positions in tracks.items():
            for frame, position in enumerate(positions, start=1):
                if position is not None:
                    result.setdefault(frame, {})[track_id] = (float(position), 0.0)
        return result

    counts = clear_mot(build_sequence(frames(annotations), frames(predictions)), "point", 2.0)
    assert (counts.n_objects, counts.n_predictions, counts.n_unique_objects) == (7, 5, 2)
    assert counts.n_frames == 7


def _walk(
    n_frames: int, ids: tuple[int, ...] = (1, 2, 3)
) -> dict[int, dict[int, tuple[float, float]]]:
    """Targets 200 px apart walking right by 2 px per frame."""
    return {t: {i: (100.0 + 200.0 * i + 2.0 * t, 500.0) for i in ids} for t in range(n_frames)}


def test_ground_truth_against_itself() -> None:
    ground_truth = _walk(30)
    counts = clear_mot(build_sequence(ground_truth, ground_truth))
    assert counts.mota == 1.0
    assert counts.motp == 0.0
    assert counts.n_correspondences == 90
    assert (counts.mostly_tracked, counts.mostly_lost, counts.n_fragmentations) == (3, 0, 0)


def test_one_missed_target_one_false_positive_one_swap() -> None:
    ground_truth = _walk(20)
    hypotheses = {t: dict(points) for t, points in ground_truth.items()}
    del hypotheses[5][2]  # one miss
    hypotheses[7][9] = (1500.0, 100.0)  # one false positive, far from everything
    for t in range(12, 20):  # identity swap of targets 1 and 2 from frame 12 on
        hypotheses[t][1], hypotheses[t][2] = ground_truth[t][2], ground_truth[t][1]
    counts = clear_mot(build_sequence(ground_truth, hypotheses))
    assert counts.n_misses == 1
    assert counts.n_false_positives == 1
    assert counts.n_switches == 2
    assert counts.n_objects == 60
    assert counts.mota == pytest.approx(1.0 - 4 / 60)
    assert counts.n_fragmentations == 1


def test_match_threshold_is_inclusive_and_forbids_farther_pairs() -> None:
    ground_truth = {0: {1: (0.0, 0.0)}, 1: {1: (0.0, 0.0)}}
    hypotheses = {0: {1: (40.0, 0.0)}, 1: {1: (40.5, 0.0)}}
    counts = clear_mot(build_sequence(ground_truth, hypotheses), "point", 40.0)
    assert (counts.n_correspondences, counts.n_misses, counts.n_false_positives) == (1, 1, 1)
    assert counts.motp == 40.0


def test_interval_swap_is_a_mismatch_at_b_in_the_in_variant() -> None:
    # Interval a=9, b=15: frames 10..14 are info-less, no GT and no output there.
    ground_truth = {t: points for t, points in _walk(30).items() if not 9 < t < 15}
    hypotheses = {t: dict(points) for t, points in ground_truth.items()}
    for t in range(15, 30):
        hypotheses[t][1], hypotheses[t][2] = ground_truth[t][2], ground_truth[t][1]
    sequence = build_sequence(ground_truth, hypotheses)
    windows = interval_windows([(9, 15)], n_frames=30)
    assert windows == [[9, 15, 16]]
    clear_in = clear_mot_windows(sequence, windows)
    assert clear_in is not None
    assert clear_in.n_objects == 9
    assert clear_in.n_switches == 2
    assert clear_in.mota == pytest.approx(1.0 - 2 / 9)
    assert clear_in.motp == 0.0
    perfect = clear_mot_windows(build_sequence(ground_truth, ground_truth), windows)
    assert perfect is not None and perfect.mota == 1.0
    assert clear_mot_windows(sequence, []) is None


def test_in_variant_starts_each_triple_without_history() -> None:
    # Target 1 is tracked by hypothesis 7 up to frame 4 and by 8 from frame 5 (= a) on: the full
    # sequence counts that change, the triple (a, b, b+1) starts afresh at a and does not.
    ground_truth = _walk(12, ids=(1,))
    hypotheses = {t: {7 if t < 5 else 8: points[1]} for t, points in ground_truth.items()}
    sequence = build_sequence(ground_truth, hypotheses)
    assert clear_mot(sequence).n_switches == 1
    triple = clear_mot_windows(sequence, [[5, 6, 7]])
    assert triple is not None
    assert (triple.n_switches, triple.n_correspondences, triple.mota) == (0, 3, 1.0)


def test_interval_reaching_the_end_has_no_window() -> None:
    assert interval_windows([(20, 30)], n_frames=30) == []
    assert interval_windows([(20, 29)], n_frames=30) == [[20, 29]]


def test_assignment_maximises_pairs_before_cost() -> None:
    # Cheapest single pair (0,0)=0.1 would leave row 1 unmatched; two pairs must win.
    rows, columns = assign_allowed(np.array([[0.1, 0.9], [0.2, NAN]]))
    assert sorted(zip(rows.tolist(), columns.tolist(), strict=True)) == [(0, 1), (1, 0)]
    rows, columns = assign_allowed(np.full((2, 2), NAN))
    assert len(rows) == 0 and len(columns) == 0


def test_box_iou() -> None:
    boxes = np.array([[0.0, 0.0, 10.0, 10.0], [5.0, 5.0, 10.0, 10.0], [50.0, 50.0, 1.0, 1.0]])
    iou = box_iou(boxes, boxes)
    assert np.allclose(np.diag(iou), 1.0)
    assert iou[0, 1] == pytest.approx(25.0 / 175.0)
    assert iou[0, 2] == 0.0

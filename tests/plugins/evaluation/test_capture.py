"""'Captured by a non-target': reported points on a bystander's head."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from trackfw_plugins.evaluation.capture import capture_counts, frame_captured
from trackfw_plugins.evaluation.clear_mot import build_sequence
from trackfw_plugins.evaluation.report import evaluate_dataset

HEADS = np.array([[100.0, 100.0, 60.0], [400.0, 100.0, 60.0], [700.0, 100.0, 60.0]])


def test_a_point_on_its_own_target_is_not_captured() -> None:
    targets = np.array([[100.0, 100.0]])
    assert frame_captured(np.array([[110.0, 95.0]]), targets, HEADS, distance_px=40.0) == 0


def test_a_point_on_a_bystander_head_is_captured_and_one_in_empty_space_is_not() -> None:
    targets = np.array([[100.0, 100.0]])
    reported = np.array([[405.0, 110.0], [550.0, 100.0], [690.0, 90.0]])
    assert frame_captured(reported, targets, HEADS, distance_px=40.0) == 2


def test_the_targets_own_head_is_never_a_bystander_even_when_the_point_misses_it() -> None:
    # 35 px from the target's point is outside a 20 px match but still on the target's head.
    targets = np.array([[100.0, 100.0]])
    assert frame_captured(np.array([[125.0, 100.0]]), targets, HEADS, distance_px=20.0) == 0


def test_without_targets_on_the_frame_every_head_is_a_bystander() -> None:
    reported = np.array([[100.0, 100.0]])
    assert frame_captured(reported, np.zeros((0, 2)), HEADS, distance_px=40.0) == 1


def test_counts_pool_over_frames_and_skip_frames_without_heads() -> None:
    hypotheses = {0: {1: (400.0, 100.0)}, 1: {1: (100.0, 100.0)}, 2: {1: (400.0, 100.0)}}
    targets = {0: {1: (100.0, 100.0)}, 1: {1: (100.0, 100.0)}, 2: {1: (100.0, 100.0)}}
    sequence = build_sequence(targets, hypotheses)
    counts = capture_counts(sequence, {0: HEADS, 1: HEADS}, distance_px=40.0)
    assert (counts.reported, counts.captured) == (3, 1)


def test_the_report_counts_a_target_that_took_over_a_bystander(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    dataset, runs = tmp_path / "dataset", tmp_path / "runs"
    truth = {t: {1: (100.0 + t, 300.0)} for t in range(20)}
    bystander = {t: (600.0 - t, 300.0) for t in range(20)}
    heads = [(t, 1, x, y, 60.0) for t, points in truth.items() for (x, y) in points.values()]
    heads += [(t, 9, x, y, 60.0) for t, (x, y) in bystander.items()]
    make_video(dataset, "v1", truth, n_frames=20, heads=heads)
    # The target is followed for 12 frames, then reported on the bystander for 8.
    tracks = {t: {1: truth[t][1] if t < 12 else bystander[t]} for t in range(20)}
    make_run(runs, "v1", tracks, n_frames=20)
    row = evaluate_dataset(dataset, runs).pooled_row()
    assert row["Captured"] == 8
    assert abs(row["Captured-%"] - 40.0) < 1e-9

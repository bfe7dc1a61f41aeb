"""Under the name it was given: ground-truth points reported under their own id."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from trackfw_plugins.evaluation.clear_mot import build_sequence
from trackfw_plugins.evaluation.given_identity import given_identity_counts
from trackfw_plugins.evaluation.report import evaluate_dataset

# Two people 200 px apart for 20 frames.
TRUTH = {t: {1: (100.0 + t, 300.0), 2: (300.0 + t, 300.0)} for t in range(20)}


def test_a_point_counts_only_under_its_own_id_and_within_the_distance() -> None:
    hypotheses = {
        0: {1: (101.0, 300.0), 2: (301.0, 300.0)},  # both named
        1: {1: (301.0, 300.0), 2: (101.0, 300.0)},  # swapped: neither
        2: {1: (160.0, 300.0)},  # 1 reported 59 px off, 2 not reported
    }
    sequence = build_sequence({t: TRUTH[t] for t in range(3)}, hypotheses)
    counts = given_identity_counts(sequence, distance_px=40.0)
    assert (counts.points, counts.named) == (6, 2)


def _swap_from_frame(start: int) -> dict[int, dict[int, tuple[float, float]]]:
    return {t: TRUTH[t] if t < start else {1: TRUTH[t][2], 2: TRUTH[t][1]} for t in range(20)}


def _row(
    root: Path, make: tuple[Callable[..., Path], Callable[..., Path]], start: int, source: str
) -> dict[str, float]:
    """The pooled row of a run whose two names swap from frame ``start`` on."""
    make_video, make_run = make
    dataset, runs = root / "dataset", root / "runs"
    make_video(dataset, "v1", TRUTH, n_frames=20)
    make_run(runs, "v1", _swap_from_frame(start), n_frames=20, initialised_from=source)
    return evaluate_dataset(dataset, runs).pooled_row()


def test_a_swap_on_the_start_frame_costs_idf1_nothing_and_every_name(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    row = _row(tmp_path, (make_video, make_run), 0, "gt")
    assert row["IDF1"] == 100.0 and row["MOTA"] == 100.0
    assert row["Named"] == 0 and row["Named-%"] == 0.0


def test_a_swap_halfway_loses_half_of_the_names(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    row = _row(tmp_path, (make_video, make_run), 10, "gt")
    assert row["Named"] == 20 and abs(row["Named-%"] - 50.0) < 1e-9


def test_a_run_not_started_from_the_ground_truth_ids_has_no_names_to_read(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    row = _row(tmp_path, (make_video, make_run), 20, "batch")
    assert math.isnan(row["Named"]) and math.isnan(row["Named-%"])
    assert not np.isnan(row["IDF1"])

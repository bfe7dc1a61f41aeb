"""End-to-end evaluation of fake runs written in the real formats."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.evaluation.report import (
    EvalSettings,
    csv_text,
    evaluate_dataset,
    render_table,
    write_reports,
)

INTERVAL = (9, 15)  # frames 10..14 are info-less


def _walk(
    n_frames: int, skip: tuple[int, int] | None = None
) -> dict[int, dict[int, tuple[float, float]]]:
    return {
        t: {i: (100.0 + 300.0 * i + 2.0 * t, 500.0) for i in (1, 2, 3)}
        for t in range(n_frames)
        if skip is None or not skip[0] < t < skip[1]
    }


@pytest.fixture
def folders(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> tuple[Path, Path]:
    dataset, runs = tmp_path / "dataset", tmp_path / "runs"
    truth_v1 = _walk(40, skip=INTERVAL)
    make_video(dataset, "v1", truth_v1, n_frames=40, intervals=[INTERVAL])
    tracks_v1 = {t: dict(points) for t, points in truth_v1.items()}
    for t in range(15, 40):  # identity swap across the interval
        tracks_v1[t][1], tracks_v1[t][2] = truth_v1[t][2], truth_v1[t][1]
    make_run(runs, "v1", tracks_v1, n_frames=40, infoless_frames=[10, 11, 12, 13, 20])
    truth_v2 = _walk(30)
    heads = [(t, i, x, y, 80.0) for t, points in truth_v2.items() for i, (x, y) in points.items()]
    make_video(dataset, "v2", truth_v2, n_frames=30, heads=heads)
    detections = {
        t: np.asarray(list(points.values())) + np.array([3.0, 4.0])
        for t, points in truth_v2.items()
    }
    detections[0] = np.vstack([detections[0], [[1800.0, 50.0]]])
    make_run(runs, "v2", truth_v2, n_frames=30, detections=detections)
    return dataset, runs


@pytest.fixture
def walkers(tmp_path: Path, make_video: Callable[..., Path]) -> tuple[Path, dict]:
    """Dataset folder with one 30-frame video ``v`` of three walkers, INTERVAL info-less; and
    its ground truth."""
    truth = _walk(30, skip=INTERVAL)
    make_video(tmp_path / "dataset", "v", truth, n_frames=30, intervals=[INTERVAL])
    return tmp_path / "dataset", truth


def test_per_video_mean_and_pooled_rows(folders: tuple[Path, Path]) -> None:
    dataset, runs = folders
    evaluation = evaluate_dataset(
        dataset, runs, EvalSettings(detections=True, sensitivity_px=(20.0,))
    )
    v1, v2, mean, pooled = evaluation.rows()
    assert (v1["video"], v2["video"], mean["video"], pooled["video"]) == (
        "v1",
        "v2",
        "mean",
        "pooled",
    )
    # v2 is the ground truth itself.
    assert (v2["MOTA"], v2["MOTP"], v2["IDF1"], v2["FP"], v2["FN"]) == (100.0, 0.0, 100.0, 0.0, 0.0)
    assert v2["HOTA"] == pytest.approx(100.0)
    assert math.isnan(v2["MOTA-In"]) and math.isnan(v2["IL-Recall"])
    # v1: one swap of two targets after the interval: 2 mismatches over 35 frames x 3 targets.
    assert v1["IDSW"] == 2.0
    assert v1["MOTA"] == pytest.approx(100.0 * (1 - 2 / 105))
    assert v1["MOTA-In"] == pytest.approx(100.0 * (1 - 2 / 9))
    assert v1["MOTP-In"] == 0.0
    assert v1["IL-Precision"] == pytest.approx(80.0)
    assert v1["IL-Recall"] == pytest.approx(80.0)
    assert v1["IL-Misclassified"] == 2.0
    # The mean of MOTA-In runs over videos that have an interval only.
    assert mean["MOTA-In"] == pytest.approx(v1["MOTA-In"])
    assert mean["MOTA"] == pytest.approx((v1["MOTA"] + v2["MOTA"]) / 2)
    assert pooled["MOTA"] == pytest.approx(100.0 * (1 - 2 / 195))
    assert pooled["MOTA-In"] == pytest.approx(v1["MOTA-In"])
    # Detections of v2: all heads found within 5 px, one far false positive.
    assert v2["Det-Recall"] == 100.0
    assert v2["Det-Precision"] == pytest.approx(100.0 * 90 / 91)
    assert math.isnan(v1["Det-Precision"])  # v1 has no heads.csv
    assert v2["MOTA@20"] == 100.0 and v1["MOTA-In@20"] == pytest.approx(v1["MOTA-In"])


def test_output_on_infoless_frames_is_false_positive(
    walkers: tuple[Path, dict],
    tmp_path: Path,
    make_video: Callable[..., Path],
    make_run: Callable[..., Path],
) -> None:
    (dataset, truth), runs = walkers, tmp_path / "runs"
    tracks = {**truth, 11: {1: (400.0, 500.0)}, 12: {1: (400.0, 500.0)}}
    make_run(runs, "v", tracks, n_frames=30, infoless_frames=range(10, 15))
    evaluation = evaluate_dataset(dataset, runs)
    row = evaluation.video_rows()[0]
    assert row["FP"] == 2.0 and row["FN"] == 0.0
    assert row["MOTA"] == pytest.approx(100.0 * (1 - 2 / 75))
    assert (row["IL-Precision"], row["IL-Recall"], row["IL-F1"]) == (100.0, 100.0, 100.0)
    assert evaluation.videos[0].gt_points_in_intervals == 0
    # A dataset that annotates an info-less frame fails `trackfw dataset check`, so eval refuses
    # it with check's own line instead of scoring it.
    make_video(tmp_path / "annotated", "v", {**truth, 12: {1: (0.0, 0.0)}}, n_frames=30,
               intervals=[INTERVAL])  # fmt: skip
    with pytest.raises(UserError, match=r"frame 13 is inside the info-less interval 11\.\.15"):
        evaluate_dataset(tmp_path / "annotated", runs)


def test_missed_target_changes_counts_exactly(
    walkers: tuple[Path, dict], tmp_path: Path, make_run: Callable[..., Path]
) -> None:
    (dataset, truth), runs = walkers, tmp_path / "runs"
    tracks = {
        t: {i: p for i, p in points.items() if not (i == 3 and t == 15)}
        for t, points in truth.items()
    }
    make_run(runs, "v", tracks, n_frames=30)
    row = evaluate_dataset(dataset, runs).video_rows()[0]
    assert (row["FN"], row["FP"], row["IDSW"]) == (1.0, 0.0, 0.0)
    assert row["MOTA"] == pytest.approx(100.0 * (1 - 1 / 75))
    assert row["MOTA-In"] == pytest.approx(100.0 * (1 - 1 / 9))
    # Frame 15 is b of the interval: the miss is MOTA-In's one error, split out as FN-In.
    assert (row["FN-In"], row["FP-In"], row["IDSW-In"]) == (1.0, 0.0, 0.0)


def test_reports_are_written(folders: tuple[Path, Path], tmp_path: Path) -> None:
    dataset, runs = folders
    evaluation = evaluate_dataset(dataset, runs)
    csv_path, json_path = write_reports(evaluation, tmp_path / "out")
    rows = list(csv.DictReader(io.StringIO(csv_path.read_text(encoding="utf-8"))))
    assert [row["video"] for row in rows] == ["v1", "v2", "mean", "pooled"]
    assert rows[1]["MOTA-In"] == "" and float(rows[1]["MOTA"]) == 100.0
    assert csv_path.read_text(encoding="utf-8") == csv_text(evaluation)
    document = json.loads(json_path.read_text(encoding="utf-8"))
    assert document["videos"][1]["MOTA-In"] is None
    assert document["pooled"]["IDSW"] == 2.0
    assert document["counts"][0]["clear_in"]["n_switches"] == 2
    assert document["settings"]["distance_px"] == 40.0
    assert render_table(evaluation).row_count == 4


def test_missing_run_is_one_clear_error(folders: tuple[Path, Path]) -> None:
    dataset, runs = folders
    (runs / "v2" / "tracks.txt").unlink()
    (runs / "v2" / "frames.csv").unlink()
    (runs / "v2" / "summary.json").unlink()
    (runs / "v2" / "gaps.json").unlink()
    (runs / "v2").rmdir()
    with pytest.raises(UserError, match=r"no run for video\(s\) v2"):
        evaluate_dataset(dataset, runs)


def test_frames_beyond_the_video_are_rejected(folders: tuple[Path, Path]) -> None:
    dataset, runs = folders
    with (runs / "v2" / "tracks.txt").open("a", encoding="utf-8") as stream:
        stream.write("31,1,0,0,80,80,1,-1,-1,-1\n")
    with pytest.raises(
        UserError, match=r"tracks.txt: line \d+: frame 31 is outside the video; expected 1..30"
    ):
        evaluate_dataset(dataset, runs)


def test_non_positive_distance_is_rejected(folders: tuple[Path, Path]) -> None:
    dataset, runs = folders
    with pytest.raises(UserError, match=r"--dist is 0\.0; expected a positive number of pixels"):
        evaluate_dataset(dataset, runs, EvalSettings(distance_px=0.0))


def test_a_run_without_a_classifier_has_no_infoless_scores(
    walkers: tuple[Path, dict], tmp_path: Path, make_run: Callable[..., Path]
) -> None:
    (dataset, truth), runs = walkers, tmp_path / "runs"
    make_run(runs, "v", truth, n_frames=30, classifier=False)
    evaluation = evaluate_dataset(dataset, runs)
    for row in (evaluation.video_rows()[0], evaluation.mean_row(), evaluation.pooled_row()):
        # Not applicable, not 0: nothing was classified.
        for key in ("IL-Precision", "IL-Recall", "IL-F1", "IL-Misclassified"):
            assert math.isnan(row[key]), (key, row[key])
        assert row["MOTA"] == 100.0
    # The same run with a classifier that calls no frame info-less scores 0.
    make_run(tmp_path / "classified", "v", truth, n_frames=30, classifier=True)
    row = evaluate_dataset(dataset, tmp_path / "classified").video_rows()[0]
    assert row["IL-F1"] == 0.0 and row["IL-Recall"] == 0.0

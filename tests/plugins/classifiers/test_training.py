"""Tests of classifier training and online evaluation on synthetic measurements."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.classifiers.measurements import (
    FeatureSettings,
    VideoMeasurements,
    load_measurements,
    read_video_list,
    save_measurements,
)
from trackfw_plugins.classifiers.svm_model import load_model
from trackfw_plugins.classifiers.training import (
    FrameScores,
    classify_online,
    fit_flow_thresholds,
    fit_model,
    flow_threshold_online,
)


def test_fit_model_separates_fast_motion_and_records_settings(
    make_measurements: Callable[..., VideoMeasurements],
) -> None:
    videos = [make_measurements(f"v{i}", i) for i in range(4)]
    settings = FeatureSettings(flow="farneback", flow_width=640)
    model, report = fit_model(videos, settings, seed=3)
    assert report.folds == 4
    assert report.cross_validated.f1 > 0.9
    assert model.features["flow"] == "farneback" and model.features["flow_width"] == 640
    assert model.platt_a < 0  # larger decision values mean info-less
    test = make_measurements("test", 99)
    probabilities, decisions = classify_online(model, test)
    assert not decisions[0]
    scores = FrameScores.of(decisions, test.labels)
    assert scores.f1 > 0.9
    assert np.all((probabilities >= 0) & (probabilities <= 1))


def test_grid_search_reports_every_setting(
    make_measurements: Callable[..., VideoMeasurements],
) -> None:
    videos = [make_measurements(f"v{i}", i, length=60) for i in range(3)]
    _, report = fit_model(videos, FeatureSettings(), grid=True, seed=0)
    assert len(report.grid) == 16
    best = max(report.grid, key=lambda row: row["f1"])
    assert (report.C, report.gamma) == (best["C"], best["gamma"])


def test_one_class_is_a_user_error(make_measurements: Callable[..., VideoMeasurements]) -> None:
    video = make_measurements("v", 0)
    video.labels[:] = False
    with pytest.raises(UserError, match="only one class"):
        fit_model([video], FeatureSettings())


def test_flow_threshold_replay_and_fit(make_measurements: Callable[..., VideoMeasurements]) -> None:
    videos = [make_measurements(f"v{i}", i) for i in range(3)]
    high, low, scores = fit_flow_thresholds(videos, flow_width=320)
    assert low <= high
    assert scores.f1 > 0.9
    # Motion 10 px at 320 px is 3.1 % of the width; 0.6 px is 0.19 %.
    assert 0.19 < high < 3.1
    decisions = flow_threshold_online(videos[0], high, low, 320)
    assert FrameScores.of(decisions, videos[0].labels).f1 > 0.85
    assert not decisions[0]


def test_hysteresis_in_the_replay(make_measurements: Callable[..., VideoMeasurements]) -> None:
    video = make_measurements("v", 0, length=6)
    video.motion[:] = np.array([0.0, 20.0, 8.0, 8.0, 2.0, 8.0])  # percent = 100 * m / 400
    decisions = flow_threshold_online(video, high=4.0, low=1.0, flow_width=400)
    # 5 % enters, 2 % stays inside, 0.5 % leaves, 2 % does not re-enter.
    assert decisions.tolist() == [False, True, True, True, False, False]


def test_frame_scores() -> None:
    scores = FrameScores.of(np.array([1, 1, 0, 0], bool), np.array([1, 0, 1, 0], bool))
    assert (scores.tp, scores.fp, scores.fn, scores.tn) == (1, 1, 1, 1)
    assert scores.precision == scores.recall == scores.f1 == 0.5
    assert scores.misclassified == 2
    assert FrameScores().as_dict()["precision"] is None


def test_measurement_cache_round_trip(
    tmp_path: Path, make_measurements: Callable[..., VideoMeasurements]
) -> None:
    video = make_measurements("v", 5)
    key = {"video": "v", "flow": "dis"}
    save_measurements(tmp_path / "v.npz", video, key)
    loaded = load_measurements(tmp_path / "v.npz", "v", key)
    assert loaded is not None
    for name in ("frames", "motion", "counts", "spreads", "labels"):
        assert np.array_equal(getattr(loaded, name), getattr(video, name))
    assert load_measurements(tmp_path / "v.npz", "v", {"video": "v", "flow": "farneback"}) is None
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    assert load_measurements(tmp_path / "bad.npz", "v", key) is None


def test_model_file_of_training_loads(tmp_path: Path, toy_model_path: Path) -> None:
    model = load_model(toy_model_path)
    assert model.n_features == 11
    assert model.features["flow"] == "dis"


def test_read_video_list(tmp_path: Path) -> None:
    split = tmp_path / "train.txt"
    split.write_text("# training videos\nvideo01\n\nvideo02  # second\n")
    assert read_video_list(split) == ["video01", "video02"]
    split.write_text("# nothing\n")
    with pytest.raises(UserError, match="no video name"):
        read_video_list(split)

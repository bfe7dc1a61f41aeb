"""Tests of the ``svm`` classifier stage."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from trackfw.errors import UserError
from trackfw.records import Detections, FrameData, VideoContext
from trackfw_plugins.classifiers.measurements import VideoMeasurements
from trackfw_plugins.classifiers.svm import SvmClassifier, SvmParams
from trackfw_plugins.classifiers.training import classify_online

VIDEO = VideoContext(name="toy", path="toy", n_frames=40, width=640, height=360)


def group(count: int, radius: float) -> Detections:
    angles = np.linspace(0, 2 * np.pi, count, endpoint=False)
    points = np.column_stack([320 + radius * np.cos(angles), 180 + radius * np.sin(angles)])
    return Detections.from_points(points)


def run(
    classifier: SvmClassifier, frames: list[np.ndarray], fast: set[int]
) -> tuple[list[bool], list[float], list[tuple[float, float, float]]]:
    classifier.start(VIDEO)
    decisions, probabilities, measurements = [], [], []
    for t, image in enumerate(frames):
        detections = group(1, 0.0) if t in fast else group(6, 120.0)
        decision = classifier.classify(FrameData(t, image, VIDEO, first=t == 0), detections)
        infoless = decision.infoless
        assert decision.features is not None and decision.features.shape == (11,)
        decisions.append(infoless)
        probabilities.append(decision.probability)
        measurements.append(classifier.extractor.last_measurements)
    return decisions, probabilities, measurements


def shifts_with_a_turn() -> tuple[list[int], set[int]]:
    shifts, fast, x = [], set(), 0
    for t in range(30):
        step = 24 if 12 <= t < 18 else 1
        if step > 1:
            fast.add(t)
        x += step
        shifts.append(x)
    return shifts, fast


def test_fast_turn_is_infoless_and_replay_agrees(
    toy_model_path: Path, make_frames: Callable[..., list[np.ndarray]]
) -> None:
    shifts, fast = shifts_with_a_turn()
    classifier = SvmClassifier(SvmParams(model=str(toy_model_path)))
    decisions, probabilities, measurements = run(classifier, make_frames(shifts), fast)
    assert all(decisions[t] for t in sorted(fast)[1:])
    assert not any(decisions[t] for t in range(0, 12))
    assert not any(decisions[t] for t in range(25, 30))
    # The evaluation replay (training.classify_online) must reproduce the stage exactly.
    table = np.asarray(measurements)
    replay = VideoMeasurements(
        "toy",
        np.arange(len(table)),
        table[:, 0],
        table[:, 1],
        table[:, 2],
        np.zeros(len(table), bool),
    )
    replay_probabilities, replay_decisions = classify_online(classifier.model, replay)
    assert replay_decisions.tolist() == decisions
    assert np.array_equal(replay_probabilities, np.asarray(probabilities))


def test_threshold_one_never_fires(
    toy_model_path: Path, make_frames: Callable[..., list[np.ndarray]]
) -> None:
    shifts, fast = shifts_with_a_turn()
    classifier = SvmClassifier(SvmParams(model=str(toy_model_path), threshold=1.0))
    decisions, _, _ = run(classifier, make_frames(shifts[:16]), fast)
    assert not any(decisions)


def test_feature_settings_come_from_the_model(
    toy_model_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    classifier = SvmClassifier(SvmParams(model=str(toy_model_path)))
    assert classifier.extractor.meter.method == "dis" and classifier.extractor.meter.width == 320
    with caplog.at_level(logging.WARNING):
        other = SvmClassifier(SvmParams(model=str(toy_model_path), flow_width=640))
    assert other.extractor.meter.width == 640
    assert "flow_width" in caplog.text


def test_history_other_than_five_is_rejected() -> None:
    with pytest.raises(ValidationError, match="11-d"):
        SvmParams(history=4)


def test_missing_or_wrong_model_is_a_user_error(tmp_path: Path, toy_model_path: Path) -> None:
    with pytest.raises(UserError, match="no such model file") as caught:
        SvmClassifier(SvmParams(model=str(tmp_path / "absent.json")))
    assert str(tmp_path / "absent.json") in str(caught.value)
    data = json.loads(toy_model_path.read_text())
    data["feature_layout"] = [f"f{i}" for i in range(11)]
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps(data))
    with pytest.raises(UserError, match="feature_layout"):
        SvmClassifier(SvmParams(model=str(wrong)))


def test_needs_pixels(toy_model_path: Path) -> None:
    classifier = SvmClassifier(SvmParams(model=str(toy_model_path)))
    assert classifier.needs_pixels
    classifier.start(VIDEO)
    with pytest.raises(ValueError, match="pixels"):
        classifier.classify(FrameData(0, None, VIDEO), Detections.empty())


def test_shipped_model_is_the_default(make_frames: Callable[..., list[np.ndarray]]) -> None:
    classifier = SvmClassifier()
    model = classifier.model
    assert model.n_features == 11 and len(model.support_vectors) > 0
    assert model.features["flow"] == "dis" and model.training["frames"] > 0
    assert classifier.extractor.meter.width == model.features["flow_width"]
    shifts, fast = shifts_with_a_turn()
    decisions, probabilities, _ = run(classifier, make_frames(shifts), fast)
    assert len(decisions) == len(shifts)
    assert all(0.0 <= p <= 1.0 for p in probabilities)


def test_yolox_model_is_selected_by_name(make_frames: Callable[..., list[np.ndarray]]) -> None:
    from trackfw_plugins.classifiers.svm import NAMED_MODELS, shipped_model_path

    classifier = SvmClassifier(SvmParams(model="yolox"))
    # The named model is another file, trained on the yolox detector's counts, never the default.
    assert classifier.model.training["detector"]["type"] == "yolox"
    assert SvmClassifier().model.training["detector"]["type"] != "yolox"
    assert SvmClassifier.resource_files(SvmParams(model="yolox")) == [
        shipped_model_path(NAMED_MODELS["yolox"])
    ]
    shifts, fast = shifts_with_a_turn()
    decisions, probabilities, _ = run(classifier, make_frames(shifts), fast)
    assert len(decisions) == len(shifts) and all(0.0 <= p <= 1.0 for p in probabilities)

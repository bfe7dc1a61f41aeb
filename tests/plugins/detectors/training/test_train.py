"""Training, ONNX export and onnxruntime parity (skipped without PyTorch)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw_plugins.detectors.head_scorer import HeadScorer

pytest.importorskip("torch")
pytest.importorskip("onnx")

from trackfw_plugins.detectors.training.sampling import SamplingSettings
from trackfw_plugins.detectors.training.train import (
    PARITY_TOLERANCE,
    export_onnx,
    parity_difference,
    train_classifier,
)


def _toy_crops(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Light centred discs (heads) versus plain noisy crops."""
    import cv2

    rng = np.random.default_rng(seed)
    crops = rng.integers(0, 90, (count, 32, 32, 3), dtype=np.uint8)
    labels = (np.arange(count) % 2).astype(np.uint8)
    for index in np.flatnonzero(labels):
        cv2.circle(crops[index], (16, 16), 10, (200, 180, 160), -1)
    return crops, labels


def test_trains_exports_and_matches_onnxruntime(tmp_path: Path) -> None:
    crops, labels = _toy_crops(256, seed=0)
    model, report = train_classifier(crops, labels, epochs=3, seed=0, log=lambda _line: None)
    assert report.positives == 128 and len(report.losses) == 3
    assert report.losses[-1] < report.losses[0]
    assert report.validation_accuracy >= 0.9
    path = tmp_path / "head.onnx"
    export_onnx(model, path, 32)
    assert parity_difference(model, path, crops[:64]) <= PARITY_TOLERANCE
    scorer = HeadScorer(path)
    assert scorer.input_size == (32, 32)
    test_crops, test_labels = _toy_crops(64, seed=1)
    scores = scorer.score_crops(test_crops)
    assert np.mean((scores >= 0.5) == (test_labels == 1)) >= 0.9
    assert scorer.crop_settings == {}  # exported without crop settings: nothing recorded


def test_export_records_the_crop_settings(tmp_path: Path) -> None:
    crops, labels = _toy_crops(64, seed=0)
    model, _report = train_classifier(crops, labels, epochs=1, seed=0, log=lambda _line: None)
    path = tmp_path / "head.onnx"
    export_onnx(model, path, 32, SamplingSettings(context=12.0, min_crop=20.0))
    assert HeadScorer(path).crop_settings == {"context": 12.0, "min_crop": 20.0}
    assert parity_difference(model, path, crops[:16]) <= PARITY_TOLERANCE


def test_dense_export_scores_windows_like_the_crop_model(tmp_path: Path) -> None:
    import onnxruntime
    import torch

    from trackfw_plugins.detectors.head_scorer import crops_to_tensor
    from trackfw_plugins.detectors.training.model import HeadNet
    from trackfw_plugins.detectors.training.train import export_dense_onnx

    torch.manual_seed(0)
    model = HeadNet().eval()
    frame = np.random.default_rng(2).integers(0, 255, (1, 64, 96, 3), dtype=np.uint8)
    path = tmp_path / "dense.onnx"
    export_dense_onnx(model, path)
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    (logit_map,) = session.run(None, {"image": crops_to_tensor(frame)})
    assert logit_map.shape == (1, 1, 64 // 8 - 3, 96 // 8 - 3)
    # On a 32x32 input both networks see the same pixels and the same zero padding.
    window = frame[:, 16:48, 24:56]
    (single,) = session.run(None, {"image": crops_to_tensor(window)})
    with torch.no_grad():
        crop_logit = float(model(torch.from_numpy(crops_to_tensor(window)))[0, 0])
    assert single.shape == (1, 1, 1, 1)
    assert float(single[0, 0, 0, 0]) == pytest.approx(crop_logit, abs=1e-4)

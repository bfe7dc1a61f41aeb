"""Shared fixtures of the classifier tests: synthetic measurements and a small trained model."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw_plugins.classifiers.measurements import FeatureSettings, VideoMeasurements
from trackfw_plugins.classifiers.training import fit_model


def synthetic_measurements(name: str, seed: int, length: int = 120) -> VideoMeasurements:
    """A video whose info-less intervals have fast motion and scattered detections."""
    rng = np.random.default_rng(seed)
    labels = np.zeros(length, dtype=bool)
    start = 10
    while start < length - 10:
        duration = int(rng.integers(5, 15))
        labels[start : start + duration] = True
        start += duration + int(rng.integers(15, 30))
    motion = np.where(labels, rng.normal(10.0, 2.0, length), rng.normal(0.6, 0.3, length))
    counts = np.where(labels, rng.integers(0, 3, length), rng.integers(5, 9, length))
    spreads = np.where(labels, rng.normal(40.0, 20.0, length), rng.normal(120.0, 5.0, length))
    return VideoMeasurements(
        name=name,
        frames=np.arange(length, dtype=np.int64),
        motion=np.abs(motion),
        counts=counts.astype(np.float64),
        spreads=np.abs(spreads),
        labels=labels,
    )


def textured_scene(width: int = 1400, height: int = 400, seed: int = 0) -> np.ndarray:
    """A smooth random grey texture to cut shifted frames from."""
    noise = np.random.default_rng(seed).random((height, width)).astype(np.float32)
    blurred = cv2.GaussianBlur(noise, (0, 0), 3.0)
    blurred = (blurred - blurred.min()) / (blurred.max() - blurred.min())
    return (255 * blurred).astype(np.uint8)


def camera_frames(shifts: list[int], seed: int = 0) -> list[np.ndarray]:
    """``(360, 640, 3)`` BGR frames cut at the given horizontal offsets of one scene."""
    scene = textured_scene(seed=seed)
    return [
        np.ascontiguousarray(np.repeat(scene[20:380, x : x + 640, None], 3, axis=2)) for x in shifts
    ]


@pytest.fixture(scope="session")
def make_measurements() -> Callable[..., VideoMeasurements]:
    """The :func:`synthetic_measurements` factory."""
    return synthetic_measurements


@pytest.fixture(scope="session")
def make_frames() -> Callable[..., list[np.ndarray]]:
    """The :func:`camera_frames` factory."""
    return camera_frames


@pytest.fixture(scope="session")
def toy_model_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A model trained on synthetic measurements (fast motion means info-less)."""
    videos = [synthetic_measurements(f"video{i}", i) for i in range(4)]
    model, _ = fit_model(videos, FeatureSettings(), seed=0)
    path = tmp_path_factory.mktemp("model") / "toy.json"
    model.save(path)
    return path

"""Helpers the batch-tracker tests share: straight paths and the detections along them."""

from __future__ import annotations

import numpy as np

from trackfw_plugins.batch_trackers.tracks import VideoDetections


def line_path(start: tuple[float, float], step: tuple[float, float], n_frames: int) -> np.ndarray:
    """``(n_frames, 2)`` points from ``start``, moving by ``step`` each frame."""
    return np.array(start, dtype=float) + np.arange(n_frames)[:, None] * np.array(step, dtype=float)


def path_detections(paths: list[np.ndarray], n_frames: int, scores: float = 1.0) -> VideoDetections:
    """Detections of score ``scores`` from ``(n_frames, 2)`` paths; NaN rows are missed ones."""
    frames, points = [], []
    for path in paths:
        for frame, point in enumerate(path):
            if np.isfinite(point).all():
                frames.append(frame)
                points.append(point)
    return VideoDetections.from_points(
        np.array(frames), np.array(points), n_frames, np.full(len(frames), scores)
    )

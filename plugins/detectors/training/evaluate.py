"""Precision and recall of a head detector against annotated heads (NumPy only).

A detection point matches a head when it lies within ``0.5 × head_size`` of the head centre,
paired one-to-one: the project's one detection rule,
:func:`trackfw_plugins.maths.head_matching.match_heads`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackfw.records import Detections
from trackfw_plugins.detectors.training.sampling import AnnotatedFrame
from trackfw_plugins.maths.assignment import distance_matrix
from trackfw_plugins.maths.head_matching import MATCH_RATIO, match_heads


@dataclass
class DetectionScore:
    """Counts over many frames, with precision, recall and time per frame."""

    true_positives: int = 0
    detections: int = 0
    heads: int = 0
    frames: int = 0
    seconds: float = 0.0

    def add(self, detections: Detections, heads: NDArray[np.float64]) -> None:
        """Count one frame."""
        self.true_positives += match_heads(detections.points, heads).n_matched
        self.detections += len(detections)
        self.heads += len(heads)
        self.frames += 1

    @property
    def precision(self) -> float:
        """True positives over detections (1 when there is none)."""
        return self.true_positives / self.detections if self.detections else 1.0

    @property
    def recall(self) -> float:
        """True positives over annotated heads (1 when there is none)."""
        return self.true_positives / self.heads if self.heads else 1.0

    def summary(self) -> str:
        """One line: precision, recall, counts and milliseconds per frame."""
        milliseconds = 1000.0 * self.seconds / max(self.frames, 1)
        return (
            f"precision {self.precision:.3f} recall {self.recall:.3f}"
            f" (tp {self.true_positives}, detections {self.detections}, heads {self.heads},"
            f" frames {self.frames}, {milliseconds:.0f} ms/frame)"
        )


def evaluate(
    detect: Callable[[NDArray[np.uint8]], Detections],
    frames: Iterable[AnnotatedFrame],
    min_head_size: float = 0.0,
) -> DetectionScore:
    """Run ``detect`` on every frame and score it.

    Args:
        detect: maps a ``(H, W, 3)`` uint8 BGR image to detections.
        frames: annotated frames.
        min_head_size: heads smaller than this (pixels) are left out of the ground truth, and
            detections matching nothing within ``0.5 ×`` such a head are not counted either.
    """
    score = DetectionScore()
    for frame in frames:
        started = time.perf_counter()
        detections = detect(frame.image)
        score.seconds += time.perf_counter() - started
        heads = frame.heads.reshape(-1, 3)
        small = heads[heads[:, 2] < min_head_size]
        heads = heads[heads[:, 2] >= min_head_size]
        if len(small) and len(detections):
            # Detections on heads too small to count are neither right nor wrong.
            relative = distance_matrix(detections.points, small[:, :2]) / small[None, :, 2]
            keep = np.flatnonzero(relative.min(axis=1) >= MATCH_RATIO)
            detections = Detections(points=detections.points[keep], scores=detections.scores[keep])
        score.add(detections, heads)
    return score

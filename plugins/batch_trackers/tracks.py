"""The arrays every batch tracker reads and writes: all detections of a video, and tracks.

A batch tracker (DPNMS, SMOT, GTCSA-like, ByteTrack) sees every detection of a video at once
and returns tracks with its own identities. The detections are one flat table sorted by frame;
the tracks (:class:`trackfw.records.Tracks`, the batch-tracker stage's return type) another,
sorted by (id, frame). Both are plain numpy so the algorithm modules stay independent of the
engine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw.records import Tracks

__all__ = ["PAPER_BOX_SIZE", "Tracks", "VideoDetections"]

#: Side of the square box the paper puts around every head point for the batch trackers.
PAPER_BOX_SIZE = 80.0


@dataclass(frozen=True)
class VideoDetections:
    """Every detection of one video, sorted by frame (stable within a frame).

    Attributes:
        frames: ``(N,)`` frame index of each detection (0-based).
        points: ``(N, 2)`` box centres (the head point) in pixels.
        sizes: ``(N, 2)`` box width and height in pixels.
        scores: ``(N,)`` detection scores.
        n_frames: number of frames of the video (frames without detections included).
    """

    frames: IntArray
    points: FloatArray
    sizes: FloatArray
    scores: FloatArray
    n_frames: int

    def __post_init__(self) -> None:
        frames = np.asarray(self.frames, dtype=np.int64).reshape(-1)
        count = len(frames)
        points = np.asarray(self.points, dtype=np.float64).reshape(count, 2)
        sizes = np.asarray(self.sizes, dtype=np.float64).reshape(count, 2)
        scores = np.asarray(self.scores, dtype=np.float64).reshape(count)
        if count and (frames.min() < 0 or frames.max() >= self.n_frames):
            raise ValueError(f"detection frames must lie in [0, {self.n_frames - 1}]")
        order = np.argsort(frames, kind="stable")
        object.__setattr__(self, "frames", frames[order])
        object.__setattr__(self, "points", points[order])
        object.__setattr__(self, "sizes", sizes[order])
        object.__setattr__(self, "scores", scores[order])

    @classmethod
    def from_array(cls, table: FloatArray, n_frames: int | None = None) -> VideoDetections:
        """Build from an ``(N, 6)`` table of ``(frame, x, y, w, h, score)`` (x, y = box centre).

        >>> detections = VideoDetections.from_array(np.array([[1, 10, 20, 80, 80, 0.9]]))
        >>> detections.n_frames, detections.boxes().tolist()
        (2, [[-30.0, -20.0, 80.0, 80.0]])
        """
        table = np.asarray(table, dtype=np.float64).reshape(-1, 6)
        frames = table[:, 0].astype(np.int64)
        if n_frames is None:
            n_frames = int(frames.max()) + 1 if len(frames) else 0
        return cls(frames, table[:, 1:3], table[:, 3:5], table[:, 5], n_frames)

    @classmethod
    def from_points(
        cls,
        frames: IntArray,
        points: FloatArray,
        n_frames: int,
        scores: FloatArray | None = None,
        box_size: float = PAPER_BOX_SIZE,
    ) -> VideoDetections:
        """Head points with the paper's square boxes (``box_size`` px) and score 1 by default."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        count = len(points)
        if scores is None:
            scores = np.ones(count)
        return cls(frames, points, np.full((count, 2), float(box_size)), scores, n_frames)

    def __len__(self) -> int:
        return len(self.frames)

    def boxes(self) -> FloatArray:
        """``(N, 4)`` boxes as ``(left, top, width, height)``."""
        return np.hstack([self.points - 0.5 * self.sizes, self.sizes])

    def frame_bounds(self) -> IntArray:
        """``(n_frames + 1,)`` offsets: frame ``t`` owns rows ``bounds[t]:bounds[t + 1]``."""
        return np.searchsorted(self.frames, np.arange(self.n_frames + 1)).astype(np.int64)

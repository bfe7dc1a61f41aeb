"""The ``oracle`` detector: ground-truth head points with controlled noise.

For tracking-only experiments (isolating association from detection) and tests. Each frame's
detections are the dataset's head annotations, with seeded misses, position jitter and false
positives, so experiments are repeatable.
"""

from __future__ import annotations

import zlib
from typing import Literal

import numpy as np
from pydantic import Field

from trackfw.records import Detections, FrameData, VideoContext
from trackfw.stages import Detector, StageParams


class OracleDetectorParams(StageParams):
    """Parameters of the oracle detector."""

    source: Literal["auto", "heads", "targets"] = Field(
        "auto",
        description="'heads' = every visible head (heads.csv), 'targets' = people of interest (gt.csv), "
        "'auto' = heads when the dataset has them",
    )
    miss_rate: float = Field(
        0.0, ge=0.0, le=1.0, description="probability that a true head is not detected"
    )
    jitter_px: float = Field(
        0.0, ge=0.0, description="standard deviation of Gaussian position noise, pixels"
    )
    false_positives: float = Field(
        0.0,
        ge=0.0,
        description="mean number of false detections per frame (Poisson), uniform in the image",
    )
    head_size: float = Field(
        40.0, gt=0.0, description="box side used when the annotation has no head size, pixels"
    )
    seed: int = Field(
        0, description="random seed; combined with the video name so each video differs"
    )


class OracleDetector(Detector[OracleDetectorParams]):
    """Ground-truth head points, optionally with misses, jitter and false positives."""

    name = "oracle"
    uses_pixels = False
    needs_ground_truth = True

    def start(self, video: VideoContext) -> None:
        params = self.params
        self.video = video
        self.random = np.random.default_rng([params.seed, zlib.crc32(video.name.encode())])
        truth = video.ground_truth
        use_heads = params.source == "heads" or (
            params.source == "auto" and truth is not None and truth.heads
        )
        self.per_frame: dict[int, np.ndarray] = {}
        if truth is None:
            return
        if use_heads:
            self.per_frame = {t: rows.reshape(-1, 3) for t, rows in truth.heads.items()}
        else:
            for t, targets in truth.targets.items():
                rows = [(x, y, params.head_size) for _, (x, y) in sorted(targets.items())]
                self.per_frame[t] = np.asarray(rows, dtype=np.float64).reshape(-1, 3)

    def detect(self, frame: FrameData) -> Detections:
        params = self.params
        rows = self.per_frame.get(frame.t, np.zeros((0, 3)))
        if params.miss_rate > 0 and len(rows):
            rows = rows[self.random.random(len(rows)) >= params.miss_rate]
        points = rows[:, :2].copy()
        sizes = rows[:, 2].copy()
        if params.jitter_px > 0 and len(points):
            points += self.random.normal(0.0, params.jitter_px, points.shape)
        if params.false_positives > 0:
            count = int(self.random.poisson(params.false_positives))
            if count:
                extra = self.random.random((count, 2)) * [self.video.width, self.video.height]
                points = np.vstack([points, extra])
                sizes = np.concatenate([sizes, np.full(count, params.head_size)])
        boxes = (
            np.column_stack([points - sizes[:, None] / 2, sizes, sizes]) if len(points) else None
        )
        return Detections(points=points, scores=np.ones(len(points)), boxes=boxes)

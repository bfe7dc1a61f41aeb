"""The batch-tracker stages: the engine's per-frame detections in, the algorithm cores called.

Every stage turns the detections into the paper's input (``box_size`` px square boxes centred on
the head points, score 1 or the detector's score) and calls its algorithm module with BLAS held to
one thread: the cores solve thousands of tiny systems (SMOT's least squares, GTCSA's splines), for
which a multi-threaded BLAS mostly waits on its own threads (SMOT ran 5x slower on a busy 2-core
machine). See
``docs/algorithms/batch-trackers.md#dpnms`` and the sections after it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, TypeVar

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.records import Detections, Tracks, VideoContext
from trackfw.stages import BatchTracker, StageParams
from trackfw_plugins.batch_trackers.bytetrack import ByteTrackParams, track_bytetrack
from trackfw_plugins.batch_trackers.cem import CemParams, track_cem
from trackfw_plugins.batch_trackers.dpnms import DpnmsParams, track_dpnms
from trackfw_plugins.batch_trackers.gtcsa import GtcsaParams, track_gtcsa
from trackfw_plugins.batch_trackers.smot import SmotParams, track_smot
from trackfw_plugins.batch_trackers.tracks import PAPER_BOX_SIZE, VideoDetections
from trackfw_plugins.maths.gog import single_threaded_blas


class BatchInputParams(StageParams):
    """How the detections are given to a batch tracker (the paper's protocol by default)."""

    # Infinity or NaN in a cost, a window or a threshold is always a mistake.
    model_config = ConfigDict(allow_inf_nan=False)

    box_size: float = Field(
        PAPER_BOX_SIZE, gt=0.0, description="side in px of the square box around each head point"
    )
    score_policy: Literal["constant", "detector"] = Field(
        "constant", description="'constant': every score is 1; 'detector': the detector's score"
    )


def video_detections(
    frames: Sequence[Detections], video: VideoContext, params: BatchInputParams
) -> VideoDetections:
    """Every frame's detections as one table, with the configured boxes and scores."""
    counts = [len(detections) for detections in frames]
    total = sum(counts)
    frame_index = np.repeat(np.arange(len(frames)), counts)
    points = (
        np.concatenate([d.points for d in frames]) if total else np.zeros((0, 2), dtype=np.float64)
    )
    if params.score_policy == "detector" and total:
        scores = np.concatenate([d.scores for d in frames])
    else:
        scores = np.ones(total)
    return VideoDetections.from_points(
        frame_index, points, max(video.n_frames, len(frames)), scores, params.box_size
    )


P = TypeVar("P", bound=BatchInputParams)


class DpnmsStageParams(BatchInputParams, DpnmsParams):
    """DPNMS settings and its input."""


class ByteTrackStageParams(BatchInputParams, ByteTrackParams):
    """ByteTrack settings and its input; the detector's scores by default."""

    score_policy: Literal["constant", "detector"] = Field(
        "detector", description="'constant': every score is 1; 'detector': the detector's score"
    )


class SmotStageParams(BatchInputParams, SmotParams):
    """SMOT settings and its input (boxes and scores are not used)."""


class CemStageParams(BatchInputParams, CemParams):
    """CEM settings and its input (DPNMS, its start, uses the boxes; the energy the scores)."""


class GtcsaStageParams(BatchInputParams, GtcsaParams):
    """GTCSA-like settings and its input (boxes and scores are not used)."""


class _TableTracker(BatchTracker[P]):
    """A batch tracker whose core takes the detections as one table, BLAS on one thread."""

    def track(self, detections: Sequence[Detections], video: VideoContext) -> Tracks:
        table = video_detections(detections, video, self.params)
        with single_threaded_blas():
            return self.solve(table, video)

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """Run the algorithm core on the video's detection table."""
        raise NotImplementedError


class DpnmsTracker(_TableTracker[DpnmsStageParams]):
    """DPNMS: greedy dynamic-programming min-cost flow with NMS in the loop (Pirsiavash 2011)."""

    name = "dpnms"

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """DPNMS on the table."""
        return track_dpnms(table, self.params)


class ByteTrackTracker(_TableTracker[ByteTrackStageParams]):
    """ByteTrack: two-stage association by detection score (Zhang 2022) on our Kalman filter."""

    name = "bytetrack"

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """ByteTrack on the table, its lost buffer in seconds at the video's fps."""
        return track_bytetrack(table, video.fps, self.params)


class SmotTracker(_TableTracker[SmotStageParams]):
    """SMOT: tracklets stitched by Hankel-rank dynamics similarity (Dicle 2013)."""

    name = "smot"

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """SMOT on the table."""
        return track_smot(table, self.params)


class CemTracker(_TableTracker[CemStageParams]):
    """CEM: continuous energy minimisation with jump moves, started from DPNMS (Milan 2014)."""

    name = "cem"

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """CEM on the table, its exclusion terms in the video's frame size."""
        return track_cem(table, video.width, video.height, self.params)


class GtcsaTracker(_TableTracker[GtcsaStageParams]):
    """GTCSA-like groupwise tracking: k-means groups, TPS-RPM within groups (our approximation)."""

    name = "gtcsa"

    def solve(self, table: VideoDetections, video: VideoContext) -> Tracks:
        """GTCSA-like tracking on the table, its gate scaled by the frame height."""
        return track_gtcsa(table, video.height, self.params)


BATCH_TRACKERS: tuple[type[BatchTracker[StageParams]], ...] = (  # type: ignore[assignment]
    DpnmsTracker,
    ByteTrackTracker,
    SmotTracker,
    CemTracker,
    GtcsaTracker,
)

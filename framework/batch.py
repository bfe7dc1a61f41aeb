"""The batch path of the engine: detect on every frame, then one call of the batch tracker.

A batch pipeline (detector + batch tracker) follows the paper's protocol for the comparison rows
of Table 1: the video is treated as continuous, so every frame's detections reach the tracker,
info-less frames included. With ``engine.infoless_frames: drop`` the pipeline's classifier runs
too and the detections of the frames it calls info-less are left out (the first frame is never
dropped). The tracks are written like a segment pipeline's, so ``trackfw eval`` scores them the
same way; their identities are the tracker's own and the evaluation's matching maps them.

frames.csv: ``ms_tracker`` holds the batch tracker's time spread evenly over the frames read,
so that its mean is the tracker's cost per frame as for the other pipelines.
"""

from __future__ import annotations

import time
from typing import Any

from trackfw.engine import ProgressCallback, VideoRun, _check_ground_truth, stages_need_pixels
from trackfw.errors import UserError
from trackfw.front import FrameFront, FrameRecord
from trackfw.pipeline import Pipeline
from trackfw.records import Detections, Tracks, VideoContext
from trackfw.registry import Registry
from trackfw.stage_cache import CACHED_KINDS, StageCache
from trackfw.stages import Stage


def run_batch_video(
    pipeline: Pipeline,
    registry: Registry,
    video: VideoContext,
    progress: ProgressCallback | None = None,
    cache: StageCache | None = None,
) -> VideoRun:
    """Run a batch pipeline over one video (see :meth:`trackfw.engine.Engine.run_video`)."""
    stages = pipeline.build_batch()
    _check_ground_truth(stages, video)
    key = cache.key(pipeline, video, registry) if cache is not None else ""
    replay = cache.load(key, video.n_frames, video.name) if cache is not None else None
    live: dict[str, Stage[Any]] = {
        kind: stage
        for kind, stage in stages.by_kind().items()
        if replay is None or kind not in CACHED_KINDS
    }
    for stage in live.values():
        for candidate in stage.with_nested():
            candidate.start(video)
    front = FrameFront(
        video, stages.detector, stages.classifier, replay, stages_need_pixels(live), progress
    )
    drop = pipeline.engine.infoless_frames == "drop"
    frames: list[FrameRecord] = []
    per_frame: list[Detections] = []
    started = time.perf_counter()
    for observation in front:
        frames.append(observation.record)
        kept = observation.readable and not (drop and observation.infoless)
        per_frame.append(observation.detections if kept else Detections.empty())
    read = sum(record.status == "ok" for record in frames)
    if read == 0:
        raise UserError(f"{video.path}: no frame could be read; nothing to track.")
    tick = time.perf_counter()
    tracks = stages.batch_tracker.track(per_frame, video)
    tracker_ms = (time.perf_counter() - tick) * 1e3
    for record in frames:
        if record.status == "ok":
            record.milliseconds["tracker"] = tracker_ms / read
    seconds = time.perf_counter() - started
    if cache is not None and replay is None:
        cache.store(key, frames, video.name)
    return VideoRun(
        video=video,
        target_ids=[int(i) for i in tracks.track_ids()],
        tracks=track_rows(tracks, video),
        frames=frames,
        gaps=[],
        initialised_from="batch",
        seconds=seconds,
    )


def track_rows(tracks: Tracks, video: VideoContext) -> list[tuple[int, int, float, float]]:
    """``(t, id, x, y)`` rows of the points inside the image and the video (others are dropped)."""
    x, y = tracks.points[:, 0], tracks.points[:, 1]
    inside = (
        (x >= 0)
        & (x < video.width)
        & (y >= 0)
        & (y < video.height)
        & (tracks.frames >= 0)
        & (tracks.frames < video.n_frames)
    )
    return [
        (int(t), int(i), float(px), float(py))
        for t, i, px, py in zip(
            tracks.frames[inside], tracks.ids[inside], x[inside], y[inside], strict=True
        )
    ]

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

import numpy as np

from trackfw.engine import FrameRecord, ProgressCallback, VideoRun, _check_ground_truth
from trackfw.errors import UserError
from trackfw.pipeline import Pipeline
from trackfw.records import Detections, FrameData, Tracks, VideoContext
from trackfw.registry import Registry
from trackfw.stage_cache import CACHED_KINDS, StageCache, StageReplay
from trackfw.stages import BatchStages, Stage
from trackfw.video_io import iter_frames

_NO_DETECTIONS = Detections(np.zeros((0, 2)), np.zeros(0))


def run_batch_video(
    pipeline: Pipeline,
    registry: Registry,
    video: VideoContext,
    progress: ProgressCallback | None = None,
    cache: StageCache | None = None,
) -> VideoRun:
    """Run a batch pipeline over one video (see :meth:`trackfw.engine.Engine.run_video`)."""
    stages = pipeline.build()
    if not isinstance(stages, BatchStages):
        raise TypeError(f"pipeline {pipeline.name!r} is not a batch pipeline")
    _check_ground_truth(stages, video)
    replay: StageReplay | None = None
    cache_key = ""
    if cache is not None:
        cache_key = cache.key(pipeline, video, registry)
        replay = cache.load(cache_key, video.n_frames, video.name)
    live: dict[str, Stage[Any]] = {
        kind: stage
        for kind, stage in stages.by_kind().items()
        if replay is None or kind not in CACHED_KINDS
    }
    for stage in live.values():
        for candidate in stage.with_nested():
            candidate.start(video)
    drop = pipeline.engine.infoless_frames == "drop"
    decode = any(stage.needs_pixels for stage in live.values())
    clock = time.perf_counter
    frames: list[FrameRecord] = []
    per_frame: list[Detections] = []
    read = 0
    started = clock()
    for t, image, status in iter_frames(video, decode=decode):
        if progress is not None:
            progress(t)
        if replay is not None and status == "ok":
            status = replay.status_of(t)
        if status != "ok":
            frames.append(FrameRecord(t, status))
            per_frame.append(_NO_DETECTIONS)
            continue
        # Without a classifier every frame counts as informative: the video is continuous.
        record = FrameRecord(t, "ok", infoless=False)
        first = read == 0
        read += 1
        if replay is None:
            frame = FrameData(t, image, video, first)
            tick = clock()
            detections = stages.detector.detect(frame)
            if not np.array_equal(detections.index, np.arange(len(detections))):
                detections = Detections(detections.points, detections.scores, detections.boxes)
            tock = clock()
            record.milliseconds["detector"] = (tock - tick) * 1e3
            if stages.classifier is not None:
                decision = stages.classifier.classify(frame, detections)
                record.milliseconds["classifier"] = (clock() - tock) * 1e3
                record.probability = float(decision.probability)
                record.infoless = bool(decision.infoless) and not first
        else:
            detections, probability, infoless, detector_ms, classifier_ms = replay.frame(t)
            record.milliseconds["detector"] = detector_ms
            if stages.classifier is not None:
                record.milliseconds["classifier"] = classifier_ms
                record.probability, record.infoless = probability, infoless
        record.detections = detections
        frames.append(record)
        per_frame.append(_NO_DETECTIONS if drop and record.infoless else detections)
    if read == 0:
        raise UserError(f"{video.path}: no frame could be read; nothing to track.")
    tick = clock()
    tracks = stages.batch_tracker.track(per_frame, video)
    tracker_ms = (clock() - tick) * 1e3
    for record in frames:
        if record.status == "ok":
            record.milliseconds["tracker"] = tracker_ms / read
    seconds = clock() - started
    if cache is not None and replay is None:
        cache.store(cache_key, frames, video.name)
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

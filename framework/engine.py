"""The online loop (docs/algorithms/index.md#the-online-loop), frame by frame.

For each frame: detect, classify, and then either skip it (info-less), step the segment tracker
(normal frame after a normal frame), or, on the first normal frame ``b`` after an interval, ask
the gap matcher where the targets are and re-initialise the tracker there. Targets are fixed by
the first frame's annotation and never created or deleted; a target outside the image is not
reported on that frame.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.dataset import frame_source_path
from trackfw.errors import UserError
from trackfw.pipeline import Pipeline
from trackfw.records import NO_MATCH, Detections, FrameData, GapProblem, Interval, VideoContext
from trackfw.registry import Registry
from trackfw.stage_cache import CACHED_KINDS, StageCache, StageReplay
from trackfw.stages import STAGE_KINDS, BatchStages, PipelineStages, Stage
from trackfw.video_io import iter_frames

ProgressCallback = Callable[[int], None]


@dataclass
class FrameRecord:
    """What happened on one frame (one row of frames.csv)."""

    t: int
    status: str
    probability: float | None = None
    infoless: bool | None = None
    detections: Detections | None = None
    milliseconds: dict[str, float] = field(default_factory=dict)


@dataclass
class GapRecord:
    """One interval crossing (one entry of gaps.json)."""

    interval: Interval
    resolved: bool
    target_ids: list[int]
    positions: list[list[float]] = field(default_factory=list)
    matched_detection: list[int | None] = field(default_factory=list)
    cost: float | None = None
    chosen: str | None = None
    milliseconds: float = 0.0
    diagnostics: dict[str, Any] = field(default_factory=dict)


@dataclass
class VideoRun:
    """The result of running a pipeline over one video."""

    video: VideoContext
    target_ids: list[int]
    tracks: list[tuple[int, int, float, float]]
    frames: list[FrameRecord]
    gaps: list[GapRecord]
    initialised_from: str
    seconds: float

    @property
    def frames_per_second(self) -> float:
        """Processed frames per wall-clock second."""
        return len(self.frames) / self.seconds if self.seconds > 0 else float("inf")


def stages_need_pixels(stages: dict[str, Stage[Any]]) -> bool:
    """True when any stage (or a nested stage) reads pixels."""
    return any(stage.needs_pixels for stage in stages.values())


def _check_ground_truth(stages: PipelineStages | BatchStages, video: VideoContext) -> None:
    for kind, stage in stages.by_kind().items():
        for candidate in stage.with_nested():
            if candidate.needs_ground_truth and video.ground_truth is None:
                raise UserError(
                    f"{video.path}: the {kind.replace('_', ' ')} {candidate.name!r} needs ground truth"
                    " (gt.csv, heads.csv, intervals.csv) and this video has none."
                )


def check_videos(stages: PipelineStages | BatchStages, videos: Sequence[VideoContext]) -> None:
    """Raise the UserError a run would meet later: missing ground truth or missing frames.

    Called before anything is written, so a bad input never leaves half a run behind.
    """
    decode = stages.needs_pixels
    for video in videos:
        _check_ground_truth(stages, video)
        if decode:
            # A point-only video (annotations without frames) cannot feed a stage that reads
            # pixels.
            frame_source_path(Path(video.path))


def _initial_targets(
    video: VideoContext, mode: str, t: int, detections: Detections
) -> tuple[np.ndarray, FloatArray, str]:
    truth = video.ground_truth
    annotated = truth.targets.get(t, {}) if truth is not None else {}
    if mode == "gt" or (mode == "auto" and annotated):
        if not annotated:
            raise UserError(
                f"{video.path}: gt.csv has no target on frame {t + 1}; expected the people of"
                " interest annotated on the first frame (or engine.init: detections)."
            )
        ids = np.array(sorted(annotated), dtype=np.int64)
        positions = np.array([annotated[int(i)] for i in ids], dtype=np.float64).reshape(-1, 2)
        return ids, positions, "gt"
    ids = np.arange(1, len(detections) + 1, dtype=np.int64)
    return ids, detections.points.copy(), "detections"


def _histories(segment: list[FloatArray], count: int) -> list[FloatArray]:
    """Per target ``(n, 2)`` positions from per frame ``(K, 2)`` positions."""
    if not segment:
        return [np.zeros((0, 2)) for _ in range(count)]
    stacked = np.stack(segment)  # (n, K, 2)
    return [stacked[:, k, :].copy() for k in range(count)]


def _inside_image(
    reported: list[tuple[int, FloatArray]], target_ids: np.ndarray, width: int, height: int
) -> list[tuple[int, int, float, float]]:
    """``(t, id, x, y)`` rows for targets inside the image (others are not reported)."""
    rows: list[tuple[int, int, float, float]] = []
    for t, positions in reported:
        inside = (
            (positions[:, 0] >= 0)
            & (positions[:, 0] < width)
            & (positions[:, 1] >= 0)
            & (positions[:, 1] < height)
        )
        rows.extend(
            (t, int(target_ids[k]), float(positions[k, 0]), float(positions[k, 1]))
            for k in np.flatnonzero(inside)
        )
    return rows


class Engine:
    """Runs a validated pipeline over videos."""

    def __init__(self, pipeline: Pipeline, registry: Registry) -> None:
        self.pipeline = pipeline
        self.registry = registry

    def run_video(
        self,
        video: VideoContext,
        progress: ProgressCallback | None = None,
        cache: StageCache | None = None,
    ) -> VideoRun:
        """Track the targets through one video.

        Args:
            video: the video to track through.
            progress: called with each frame index before the frame is processed.
            cache: a stage cache. On a hit the detector and the classifier are not called: their
                recorded detections, decisions and milliseconds are replayed. On a miss they are
                recorded once the video is done.

        Raises:
            UserError: the video lacks what a stage needs (ground truth for oracle stages, an
                annotation on the first frame).
        """
        if self.pipeline.is_batch:
            from trackfw.batch import run_batch_video  # it imports this module

            return run_batch_video(self.pipeline, self.registry, video, progress, cache)
        stages = self.pipeline.build()
        assert isinstance(stages, PipelineStages)
        _check_ground_truth(stages, video)
        replay: StageReplay | None = None
        cache_key = ""
        if cache is not None:
            cache_key = cache.key(self.pipeline, video, self.registry)
            replay = cache.load(cache_key, video.n_frames, video.name)
        live = {
            kind: stage
            for kind, stage in stages.by_kind().items()
            if replay is None or kind not in CACHED_KINDS
        }
        for stage in live.values():
            for candidate in stage.with_nested():
                candidate.start(video)
        detector, classifier = stages.detector, stages.classifier
        tracker, gap_matcher = stages.tracker, stages.gap_matcher
        decode = stages_need_pixels(live)
        width, height = video.width, video.height
        clock = time.perf_counter

        frames: list[FrameRecord] = []
        reported: list[tuple[int, FloatArray]] = []
        gaps: list[GapRecord] = []
        target_ids = np.zeros(0, dtype=np.int64)
        # Positions of every target on each normal frame of the current segment.
        segment: list[FloatArray] = []
        initialised_from = ""
        last_normal_t: int | None = None
        last_normal_image: np.ndarray | None = None
        last_normal_detections: Detections | None = None
        interval_open = False
        started = clock()

        for t, image, status in iter_frames(video, decode=decode):
            if progress is not None:
                progress(t)
            if replay is not None and status == "ok":
                status = replay.status_of(t)
            if status != "ok":
                frames.append(FrameRecord(t, status))
                continue
            first = last_normal_t is None
            frame = FrameData(t, image, video, first)
            record = FrameRecord(t, "ok")
            if replay is None:
                tick = clock()
                detections = detector.detect(frame)
                # The stable index is the position in the detector's own output.
                if not np.array_equal(detections.index, np.arange(len(detections))):
                    detections = Detections(detections.points, detections.scores, detections.boxes)
                tock = clock()
                record.milliseconds["detector"] = (tock - tick) * 1e3
                decision = classifier.classify(frame, detections)
                tick = clock()
                record.milliseconds["classifier"] = (tick - tock) * 1e3
                probability, said_infoless = float(decision.probability), bool(decision.infoless)
            else:
                detections, probability, said_infoless, detector_ms, classifier_ms = replay.frame(t)
                record.milliseconds["detector"] = detector_ms
                record.milliseconds["classifier"] = classifier_ms
                tick = clock()
            infoless = said_infoless and not first
            record.probability = probability
            record.infoless = infoless
            record.detections = detections
            frames.append(record)

            if first:
                target_ids, positions, initialised_from = _initial_targets(
                    video, self.pipeline.engine.init, t, detections
                )
                tracker.initialise(t, target_ids, positions)
                record.milliseconds["tracker"] = (clock() - tick) * 1e3
            elif infoless:
                interval_open = True
                continue
            elif interval_open:
                assert last_normal_t is not None
                interval = Interval(a=last_normal_t, b=t)
                problem = GapProblem(
                    interval=interval,
                    target_ids=target_ids,
                    histories=_histories(segment, len(target_ids)),
                    states=tracker.states(),
                    detections=detections,
                    frame_a=last_normal_image,
                    detections_a=last_normal_detections,
                    frame_b=image,
                    video=video,
                )
                solution = gap_matcher.match(problem)
                tock = clock()
                record.milliseconds["gap_matcher"] = (tock - tick) * 1e3
                tracker.reinitialise(t, solution.positions, solution.matched_detection)
                record.milliseconds["tracker"] = (clock() - tock) * 1e3
                gaps.append(
                    GapRecord(
                        interval=interval,
                        resolved=True,
                        target_ids=[int(i) for i in target_ids],
                        positions=np.round(solution.positions, 3).tolist(),
                        matched_detection=[
                            None if int(d) == NO_MATCH else int(d)
                            for d in solution.matched_detection
                        ],
                        cost=None if solution.cost is None else float(solution.cost),
                        chosen=solution.chosen,
                        milliseconds=record.milliseconds["gap_matcher"],
                        diagnostics=solution.diagnostics,
                    )
                )
                segment = []
                interval_open = False
            else:
                tracker.step(t, detections)
                record.milliseconds["tracker"] = (clock() - tick) * 1e3

            positions = tracker.positions()
            segment.append(positions)
            reported.append((t, positions))
            last_normal_t = t
            last_normal_detections = detections
            if decode:
                last_normal_image = image

        if interval_open and last_normal_t is not None:
            # The video ends inside an interval: there is no frame b to re-link on.
            gaps.append(
                GapRecord(
                    interval=Interval(a=last_normal_t, b=video.n_frames),
                    resolved=False,
                    target_ids=[int(i) for i in target_ids],
                )
            )
        if last_normal_t is None:
            raise UserError(f"{video.path}: no frame could be read; nothing to track.")
        seconds = clock() - started
        if cache is not None and replay is None:
            cache.store(cache_key, frames, video.name)
        return VideoRun(
            video=video,
            target_ids=[int(i) for i in target_ids],
            tracks=_inside_image(reported, target_ids, width, height),
            frames=frames,
            gaps=gaps,
            initialised_from=initialised_from,
            seconds=seconds,
        )


__all__ = ["STAGE_KINDS", "Engine", "FrameRecord", "GapRecord", "VideoRun"]

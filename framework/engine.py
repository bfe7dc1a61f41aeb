"""The online loop (docs/algorithms/index.md#the-online-loop), frame by frame.

For each frame: detect, classify, and then either skip it (info-less), step the segment tracker
(normal frame after a normal frame), or, on the first normal frame ``b`` after an interval, ask
the gap matcher where the targets are and re-initialise the tracker there. Targets are chosen on
the start frame as ``engine.init`` says (:mod:`trackfw.targets`: gt.csv, the detections, those
inside a region, or a targets file) and never created or deleted; nothing is reported before the
start frame, and a target outside the image is not reported on that frame, and neither is a
target the tracker holds as lost, out-of-view or tentative
(docs/algorithms/segment-tracker.md#target-lifecycle): those take no part in a gap match either.
With ``engine.fill_missing_s`` the reports are completed once the video is done: a short absence
between two reports of one segment is filled in, and with ``engine.fill_after_b_s`` the first
frames of a segment before a target's first report (:mod:`trackfw.filling`).

The pieces: :class:`trackfw.front.FrameFront` yields one observation per frame (live stages or
a stage-cache replay), :class:`trackfw.segment.Segment` holds the targets between intervals and
builds the gap problem, and ``_OnlineLoop`` here is the interval state machine; each gap becomes
a :class:`GapRecord` over the gap matcher's solution.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw.dataset import frame_source_path
from trackfw.errors import UserError
from trackfw.filling import fill_missing
from trackfw.front import FrameFront, FrameRecord, Observation
from trackfw.pipeline import Pipeline
from trackfw.records import (
    LOOKBACK_S,
    LOST,
    NO_MATCH,
    OUT_OF_VIEW,
    TARGET_STATES,
    TRACKED,
    GapSolution,
    Interval,
    VideoContext,
)
from trackfw.registry import Registry
from trackfw.segment import Segment
from trackfw.stage_cache import CACHED_KINDS, StageCache, cache_key
from trackfw.stages import STAGE_KINDS, BatchStages, PipelineStages, Stage
from trackfw.targets import TargetChooser

ProgressCallback = Callable[[int], None]


@dataclass
class GapRecord:
    """One interval crossing (one entry of gaps.json), a view of the gap matcher's solution.

    Attributes:
        interval: the interval, ``a`` to ``b`` (``b = n_frames`` when the video ends inside it).
        target_ids: the targets, in the order of the solution's arrays.
        solution: the gap matcher's solution, or None when the video ended inside the interval.
        milliseconds: the gap matcher's time.
        at_b: by target id, what the tracker made of the matches at b
            (:meth:`trackfw.stages.Tracker.checked_at_b`); empty when it records nothing.
    """

    interval: Interval
    target_ids: list[int]
    solution: GapSolution | None = None
    milliseconds: float = 0.0
    at_b: dict[int, dict[str, Any]] = field(default_factory=dict)

    @property
    def resolved(self) -> bool:
        """Whether the targets were re-linked on a frame b."""
        return self.solution is not None

    @property
    def positions(self) -> list[list[float]]:
        """Per target, ``[x, y]`` on frame b (rounded to 1/1000 pixel)."""
        return [] if self.solution is None else np.round(self.solution.positions, 3).tolist()

    @property
    def matched_detection(self) -> list[int | None]:
        """Per target, the stable index of its detection on frame b, or None."""
        if self.solution is None:
            return []
        return [None if int(d) == NO_MATCH else int(d) for d in self.solution.matched_detection]

    @property
    def cost(self) -> float | None:
        """The solution's cost (its meaning depends on the gap matcher)."""
        cost = None if self.solution is None else self.solution.cost
        return None if cost is None else float(cost)

    @property
    def chosen(self) -> str | None:
        """The label of the chosen prediction candidate."""
        return None if self.solution is None else self.solution.chosen

    @property
    def diagnostics(self) -> dict[str, Any]:
        """The gap matcher's details."""
        return {} if self.solution is None else self.solution.diagnostics


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


def _inside_image(
    reported: list[tuple[int, FloatArray, np.ndarray]],
    target_ids: np.ndarray,
    width: int,
    height: int,
) -> list[tuple[int, int, float, float]]:
    """``(t, id, x, y)`` rows for tracked targets inside the image (others are not reported)."""
    rows: list[tuple[int, int, float, float]] = []
    for t, positions, tracked in reported:
        inside = (
            tracked
            & (positions[:, 0] >= 0)
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
        self.targets = TargetChooser(pipeline.engine)

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
        stages = self.pipeline.build_segment()
        _check_ground_truth(stages, video)
        key = cache.key(self.pipeline, video, self.registry) if cache is not None else ""
        replay = cache.load(key, video.n_frames, video.name) if cache is not None else None
        live = _start_live_stages(stages, video, replay is not None)
        front = FrameFront(
            video, stages.detector, stages.classifier, replay, stages_need_pixels(live), progress
        )
        engine = self.pipeline.engine
        loop = _OnlineLoop(
            stages,
            video,
            self.targets,
            engine.fill_missing_s,
            engine.fill_after_b_s,
            engine.fill_after_b_min_reports,
        )
        started = time.perf_counter()
        for observation in front:
            loop.observe(observation)
        run = loop.finish(time.perf_counter() - started)
        if cache is not None:
            if replay is None:
                cache.store(key, run.frames, video.name)
            if cache.share_detector:  # a segment pipeline always has a classifier
                detector_key = cache_key(self.pipeline, video, self.registry, ("detector",))
                cache.store_detector(detector_key, run.frames, video.name)
        return run


def _start_live_stages(
    stages: PipelineStages, video: VideoContext, replaying: bool
) -> dict[str, Stage[Any]]:
    """Call ``start`` on every stage that will run (not the replayed ones); return them."""
    live = {
        kind: stage
        for kind, stage in stages.by_kind().items()
        if not (replaying and kind in CACHED_KINDS)
    }
    for stage in live.values():
        for candidate in stage.with_nested():
            candidate.start(video)
    return live


class _OnlineLoop:
    """The interval state machine (docs/algorithms/index.md#the-online-loop).

    Before the first readable frame there is no segment. The first one initialises the targets.
    After it, an informative frame steps the tracker, an info-less one opens an interval (the
    segment's last frame is ``a``), and the first informative frame after an interval (``b``)
    asks the gap matcher to re-link the targets and starts a new segment.
    """

    def __init__(
        self,
        stages: PipelineStages,
        video: VideoContext,
        targets: TargetChooser,
        fill_missing_s: float | None = None,
        fill_after_b_s: float | None = None,
        fill_after_b_min_reports: int = 1,
    ) -> None:
        self.stages = stages
        self.fill_missing_frames = (
            0 if fill_missing_s is None else round(fill_missing_s * video.fps)
        )
        self.fill_after_b_frames = (
            0 if fill_after_b_s is None else round(fill_after_b_s * video.fps)
        )
        self.fill_after_b_min_reports = fill_after_b_min_reports
        self.video = video
        self.targets = targets
        self.start = targets.start_frame(video)
        self.frames: list[FrameRecord] = []
        self.gaps: list[GapRecord] = []
        self.reported: list[tuple[int, FloatArray, np.ndarray]] = []
        self.segment_numbers: list[int] = []  # of each reported frame: +1 at each frame b
        self.segment: Segment | None = None
        self.withdrawn: set[tuple[int, int]] = set()  # (frame, target row) taken back
        self.initialised_from = ""
        self.interval_open = False

    def observe(self, observation: Observation) -> None:
        """Advance the state machine by one frame."""
        self.frames.append(observation.record)
        if not observation.readable or (self.segment is None and observation.t < self.start):
            return  # nothing is tracked before the start frame (engine.init)
        if not observation.infoless or self.segment is None:
            self.stages.tracker.see(observation.image)
        if self.segment is None:
            self.segment = self._initialise(observation)
        elif observation.infoless:
            self.interval_open = True
            return
        elif self.interval_open:
            self.segment = self._relink(self.segment, observation)
            self.interval_open = False
        else:
            self.stages.tracker.step(observation.t, observation.detections)
            _time(observation, "tracker", observation.done_at)
        positions = self.stages.tracker.positions()
        statuses = np.asarray(self.stages.tracker.statuses(), dtype=object)
        self.segment.add(observation, positions)
        self.reported.append((observation.t, positions, statuses == TRACKED))
        self._withdraw(self.stages.tracker.withdrawn())
        self.segment_numbers.append(len(self.gaps))
        observation.record.target_states = {
            state: int(np.count_nonzero(statuses == state)) for state in TARGET_STATES
        }

    def _withdraw(self, withdrawals: list[tuple[int, int]]) -> None:
        """Unreport each ``(target row, first frame)`` withdrawal up to the last frame."""
        for row, since in withdrawals:
            for t, _, reported in reversed(self.reported):
                if t < since:
                    break
                reported[row] = False
                self.withdrawn.add((t, row))

    def _initialise(self, observation: Observation) -> Segment:
        chosen = self.targets.choose(self.video, observation.t, observation.detections)
        self.initialised_from = chosen.source
        self.stages.tracker.initialise(observation.t, chosen.ids, chosen.positions)
        _time(observation, "tracker", observation.done_at)
        return Segment(chosen.ids, round(LOOKBACK_S * self.video.fps))

    def _relink(self, segment: Segment, b: Observation) -> Segment:
        """Solve the gap from the segment's frame ``a`` to ``b``; the new segment starts at b.

        Lost and out-of-view targets are left out of the gap problem: they come back only
        through the tracker's re-acquisition. They keep their current position and no match.
        """
        tracker = self.stages.tracker
        states = tracker.states()
        rows = np.array(
            [k for k, state in enumerate(states) if state.status not in (LOST, OUT_OF_VIEW)],
            dtype=np.int64,
        )
        problem = segment.gap_problem(b, states, self.video, rows)
        solution = (
            self.stages.gap_matcher.match(problem)
            if len(rows)
            else GapSolution(np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
        )
        matched_at = _time(b, "gap_matcher", b.done_at)
        positions = tracker.positions()
        matched = np.full(len(states), NO_MATCH, dtype=np.int64)
        positions[rows] = solution.positions
        matched[rows] = solution.matched_detection
        if solution.match_ratios is not None:
            ratios = np.full(len(states), np.nan)
            ratios[rows] = solution.match_ratios
            tracker.see_match_ratios(ratios)
        tracker.reinitialise(b.t, positions, matched, b.detections)
        _time(b, "tracker", matched_at)
        self.gaps.append(
            GapRecord(
                problem.interval,
                _ids(problem.target_ids),
                solution,
                b.record.milliseconds["gap_matcher"],
                {states[row].target_id: outcome for row, outcome in tracker.checked_at_b().items()},
            )
        )
        return segment.next()

    def finish(self, seconds: float) -> VideoRun:
        """The run once every frame was observed."""
        segment = self.segment
        if segment is None:
            raise UserError(f"{self.video.path}: no frame could be read; nothing to track.")
        if self.interval_open:
            # The video ends inside an interval: there is no frame b to re-link on.
            interval = segment.interval_to(self.video.n_frames)
            self.gaps.append(GapRecord(interval, _ids(segment.target_ids)))
        return VideoRun(
            video=self.video,
            target_ids=_ids(segment.target_ids),
            tracks=_inside_image(
                self._filled(), segment.target_ids, self.video.width, self.video.height
            ),
            frames=self.frames,
            gaps=self.gaps,
            initialised_from=self.initialised_from,
            seconds=seconds,
        )

    def _filled(self) -> list[tuple[int, FloatArray, np.ndarray]]:
        """The reports with short absences filled in (``engine.fill_missing_s``,
        ``engine.fill_after_b_s``)."""
        if self.fill_missing_frames <= 0 and self.fill_after_b_frames <= 0:
            return self.reported
        frames = [t for t, _, _ in self.reported]
        positions, reported = fill_missing(
            frames,
            self.segment_numbers,
            [p for _, p, _ in self.reported],
            [r for _, _, r in self.reported],
            self.fill_missing_frames,
            self.fill_after_b_frames,
            self.fill_after_b_min_reports,
        )
        index = {t: i for i, t in enumerate(frames)}
        for t, row in self.withdrawn:
            # Withdrawn reports are not absences to fill: they were someone else.
            reported[index[t]][row] = False
        return list(zip(frames, positions, reported, strict=True))


def _time(observation: Observation, kind: str, since: float) -> float:
    """Record the milliseconds of ``kind`` on the frame since ``since``; return the time now."""
    now = time.perf_counter()
    observation.record.milliseconds[kind] = (now - since) * 1e3
    return now


def _ids(target_ids: IntArray) -> list[int]:
    return [int(i) for i in target_ids]


__all__ = ["STAGE_KINDS", "Engine", "FrameRecord", "GapRecord", "VideoRun"]

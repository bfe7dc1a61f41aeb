"""Batch pipelines: validation of the either/or rule, the engine's batch path and its outputs."""

from __future__ import annotations

import csv
import textwrap
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import ClassVar

import numpy as np
import pytest

from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.errors import UserError
from trackfw.formats.run import TRACKS_FILE, write_run
from trackfw.hookspecs import hookimpl
from trackfw.pipeline import load_pipeline
from trackfw.records import Detections, FrameData, Tracks, VideoContext
from trackfw.registry import Registry, load_registry
from trackfw.stage_cache import StageCache
from trackfw.stages import BatchTracker, Detector, StageParams

BATCH = textwrap.dedent(
    """\
    name: batch-test
    stages:
      detector:      {type: oracle}
      batch_tracker: {type: recorder}
    """
)


class RecorderParams(StageParams):
    """No parameters."""


class TwoHeads(Detector[RecorderParams]):
    """Two heads on every frame, info-less or not (no pixels needed)."""

    name = "two-heads"
    uses_pixels = False

    def detect(self, frame: FrameData) -> Detections:
        return Detections.from_points([[100.0 + frame.t, 50.0], [200.0, 80.0]])


class Recorder(BatchTracker[RecorderParams]):
    """Makes one track per detection index and remembers what it was given."""

    name = "recorder"
    seen: ClassVar[list[int]] = []

    def track(self, detections: Sequence[Detections], video: VideoContext) -> Tracks:
        Recorder.seen = [len(frame) for frame in detections]
        ids, frames, points = [], [], []
        for t, frame in enumerate(detections):
            for k, point in enumerate(frame.points):
                ids.append(k + 1)
                frames.append(t)
                points.append(point)
        return Tracks(
            np.array(ids, dtype=np.int64),
            np.array(frames, dtype=np.int64),
            np.array(points).reshape(-1, 2),
            np.ones(len(ids), dtype=bool),
        )


def _registry() -> Registry:
    module = ModuleType("recorder_plugin")

    @hookimpl
    def trackfw_register_stages(registry: Registry) -> None:
        registry.add_batch_tracker(Recorder)
        registry.add_detector(TwoHeads)

    module.trackfw_register_stages = trackfw_register_stages  # type: ignore[attr-defined]
    return load_registry(extra_modules=[("recorder", module)])


def test_the_built_in_batch_trackers_are_registered() -> None:
    assert load_registry().names("batch_tracker") == ["bytetrack", "cem", "dpnms", "gtcsa", "smot"]


@pytest.mark.parametrize(
    ("stages", "engine", "message"),
    [
        (
            "detector: {type: oracle}\n  tracker: {type: kalman}\n  batch_tracker: {type: dpnms}",
            "",
            "stages: tracker given with batch_tracker; expected either a segment tracker",
        ),
        ("detector: {type: oracle}", "", "stages: no tracker; expected either tracker"),
        (
            "detector: {type: oracle}\n  classifier: {type: oracle}\n  batch_tracker: {type: dpnms}",
            "",
            "stages.classifier: a batch pipeline uses a classifier only with",
        ),
        (
            "detector: {type: oracle}\n  batch_tracker: {type: dpnms}",
            "engine: {infoless_frames: drop}",
            "engine.infoless_frames: 'drop' needs stages.classifier",
        ),
        (
            "detector: {type: oracle}\n  classifier: {type: oracle}\n  tracker: {type: kalman}\n"
            "  gap_matcher: {type: assignment}",
            "engine: {infoless_frames: drop}",
            "engine.infoless_frames: 'drop' applies to batch pipelines only",
        ),
        (
            "detector: {type: oracle}\n  batch_tracker: {type: smot, params: {horizon: 0}}",
            "",
            "stages.batch_tracker.params.horizon: expected greater than or equal to 2, got 0",
        ),
    ],
)
def test_a_pipeline_has_a_segment_tracker_or_a_batch_tracker(
    stages: str, engine: str, message: str, pipeline_file
) -> None:
    path = pipeline_file(f"name: bad\nstages:\n  {stages}\n{engine}\n")
    with pytest.raises(UserError) as raised:
        load_pipeline(path, load_registry())
    assert any(message in line for line in raised.value.lines), raised.value.lines


def test_every_frame_reaches_the_batch_tracker_and_tracks_are_written(
    points_video, pipeline_file, tmp_path: Path
) -> None:
    video_dir = points_video(n_frames=60, intervals=[(20, 30)])
    registry = _registry()
    text = BATCH.replace("{type: oracle}", "{type: two-heads}")
    pipeline = load_pipeline(pipeline_file(text), registry)
    assert pipeline.is_batch
    video = load_video(video_dir)
    run = Engine(pipeline, registry).run_video(video)
    # Info-less frames included: the tracker got both heads on every frame.
    expected = [2] * 60
    assert Recorder.seen == expected
    assert run.initialised_from == "batch" and run.gaps == []
    assert len(run.tracks) == sum(expected)
    assert all(record.infoless is False for record in run.frames)
    out = write_run(run, pipeline, tmp_path / "run")
    assert len((out / TRACKS_FILE).read_text().splitlines()) == sum(expected)
    with (out / "frames.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert all(row["infoless"] == "0" and float(row["ms_tracker"]) >= 0 for row in rows)


def test_drop_leaves_out_the_frames_the_classifier_calls_infoless(
    points_video, pipeline_file
) -> None:
    video_dir = points_video(n_frames=60, intervals=[(20, 30)])
    registry = _registry()
    text = (
        BATCH.replace("{type: oracle}", "{type: two-heads}").replace(
            "  batch_tracker:", "  classifier:    {type: oracle}\n  batch_tracker:"
        )
        + "engine: {infoless_frames: drop}\n"
    )
    pipeline = load_pipeline(pipeline_file(text), registry)
    run = Engine(pipeline, registry).run_video(load_video(video_dir))
    infoless = [bool(record.infoless) for record in run.frames]
    assert sum(infoless) == 11
    assert Recorder.seen == [0 if flag else 2 for flag in infoless]


def test_a_batch_run_replays_its_detections_from_the_stage_cache(
    points_video, pipeline_file, tmp_path: Path
) -> None:
    video = load_video(points_video(n_frames=40, intervals=[(10, 15)]))
    registry = _registry()
    pipeline = load_pipeline(pipeline_file(BATCH), registry)
    cache = StageCache(tmp_path / "cache")
    first = Engine(pipeline, registry).run_video(video, cache=cache)
    second = Engine(pipeline, registry).run_video(video, cache=cache)
    assert cache.stores == 1
    assert second.tracks == first.tracks


@pytest.mark.parametrize("name", ["dpnms", "bytetrack", "cem", "gtcsa", "smot"])
def test_each_batch_tracker_runs_in_a_pipeline(name: str, points_video, pipeline_file) -> None:
    video_dir = points_video(n_frames=50, intervals=[(20, 25)])
    text = BATCH.replace("{type: recorder}", f"{{type: {name}}}")
    registry = load_registry()
    pipeline = load_pipeline(pipeline_file(text), registry)
    run = Engine(pipeline, registry).run_video(load_video(video_dir))
    truth = load_video(video_dir).ground_truth
    assert truth is not None
    # At least one track per annotated target, on frames of the video only.
    assert len(run.target_ids) >= len(truth.targets[0])
    assert all(0 <= t < 50 for t, *_ in run.tracks)

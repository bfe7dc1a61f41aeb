"""The online loop: intervals, missing detections, targets leaving the image, corrupt frames."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from types import ModuleType
from typing import ClassVar

import cv2
import numpy as np
import pytest

from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.formats.run import write_run
from trackfw.hookspecs import hookimpl
from trackfw.pipeline import load_pipeline
from trackfw.records import Detections, FrameData
from trackfw.registry import Registry, load_registry
from trackfw_plugins.gap_matchers.assignment import AssignmentGapMatcher
from trackfw_plugins.trackers.kalman import KalmanTracker

from .conftest import PixelCentreDetector, registry_with


def _run(
    video_dir: Path,
    pipeline_path: Path,
    overrides: list[str] | None = None,
    registry: Registry | None = None,
):
    registry = registry or load_registry()
    pipeline = load_pipeline(pipeline_path, registry, overrides or [])
    return Engine(pipeline, registry).run_video(load_video(video_dir)), pipeline


def _tracked(run) -> dict[int, dict[int, tuple[float, float]]]:
    frames: dict[int, dict[int, tuple[float, float]]] = {}
    for t, target_id, x, y in run.tracks:
        frames.setdefault(t, {})[target_id] = (x, y)
    return frames


def test_clean_video_is_tracked_exactly_and_gap_relinks(points_video, pipeline_file) -> None:
    # No pose change: TR prediction + Hungarian at b must recover every identity.
    video = points_video(
        n_frames=150, intervals=[(60, 80)], rotation_degrees=0.0, scale=1.0, shift=(0.0, 0.0)
    )
    run, _ = _run(video, pipeline_file())
    truth = load_video(video).ground_truth
    tracked = _tracked(run)
    assert len(run.gaps) == 1 and run.gaps[0].resolved
    assert run.gaps[0].interval.a == 58 and run.gaps[0].interval.b == 80
    for t, targets in truth.targets.items():
        for target_id, (x, y) in targets.items():
            tx, ty = tracked[t][target_id]
            assert abs(tx - x) < 5 and abs(ty - y) < 5, (t, target_id)
    # Nothing is reported on info-less frames.
    assert not any(59 <= t <= 79 for t in tracked)


def test_several_intervals_interval_at_start_and_at_end(points_video, pipeline_file) -> None:
    video = points_video(n_frames=120, intervals=[(2, 10), (40, 50), (100, 120)])
    run, _ = _run(video, pipeline_file())
    assert [gap.resolved for gap in run.gaps] == [True, True, False]
    assert run.gaps[0].interval.a == 0 and run.gaps[0].interval.b == 10
    assert run.gaps[2].interval.b == 120
    assert max(t for t, *_ in run.tracks) == 98
    assert sum(1 for r in run.frames if r.infoless) == 9 + 11 + 21


def test_fewer_and_zero_detections(points_video, pipeline_file) -> None:
    video = points_video(n_frames=80, intervals=[(30, 40)])
    run, _ = _run(video, pipeline_file(), ["stages.detector.params.miss_rate=0.5"])
    assert any(len(r.detections) < 8 for r in run.frames if r.detections is not None)
    coast = "stages.tracker.params.lifecycle.lost_after_s=2.0"
    run, _ = _run(video, pipeline_file(), ["stages.detector.params.miss_rate=1.0", coast])
    assert all(len(r.detections) == 0 for r in run.frames if r.detections is not None)
    # Without detections the targets coast (lifecycle.lost_after_s set to 2 s, longer than the 29
    # frames before the interval), are placed at b without a detection, so only tentatively
    # (not reported), and are lost once nothing confirms them.
    assert load_video(video).fps >= 29
    assert {t for t, *_ in run.tracks} == set(range(29))
    assert run.gaps[0].resolved and all(d is None for d in run.gaps[0].matched_detection)
    states = [r.target_states for r in run.frames if not r.infoless]
    assert states[0] == {"tracked": 8, "lost": 0, "out-of-view": 0, "tentative": 0}
    assert states[29] == {"tracked": 0, "lost": 0, "out-of-view": 0, "tentative": 8}
    assert states[-1] == {"tracked": 0, "lost": 8, "out-of-view": 0, "tentative": 0}


def test_targets_outside_the_image_are_not_reported(tmp_path: Path, pipeline_file) -> None:
    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(
        tmp_path / "v", n_frames=300, intervals=[], width=200, height=200, n_targets=3, n_others=0
    )
    run, _ = _run(video, pipeline_file())
    assert all(0 <= x < 200 and 0 <= y < 200 for _, _, x, y in run.tracks)
    per_frame = [len([row for row in run.tracks if row[0] == t]) for t in (0, 299)]
    assert per_frame[0] == 3 and per_frame[1] < 3


class PixelMeanDetector(PixelCentreDetector):
    """Test detector that needs pixels: one detection at the image centre if the frame is not black."""

    name = "pixel-mean"

    def detect(self, frame: FrameData) -> Detections:
        centre = super().detect(frame)
        assert frame.image is not None
        return centre if frame.image.mean() > 1 else Detections.from_points([])


def _pixel_mean_pipeline(pipeline_file) -> tuple[Path, Registry]:
    """The test pipeline with the ``pixel-mean`` detector, and a registry that has it."""
    registry = registry_with("pixel", PixelMeanDetector)
    text = pipeline_file().read_text()
    text = text.replace("detector:    {type: oracle}", "detector:    {type: pixel-mean}")
    return pipeline_file(text, "pixel.yaml"), registry


def test_corrupt_video_tail_is_tracked_up_to_the_corruption(tmp_path: Path, pipeline_file) -> None:
    video_dir = tmp_path / "clip"
    video_dir.mkdir()
    # MJPG in AVI keeps its index optional, so a cut file still decodes up to the cut.
    writer = cv2.VideoWriter(
        str(video_dir / "clip.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25, (64, 48)
    )
    for t in range(60):
        frame = np.full((48, 64, 3), 40 + t, dtype=np.uint8)
        writer.write(frame)
    writer.release()
    data = (video_dir / "clip.avi").read_bytes()
    (video_dir / "clip.avi").write_bytes(data[: len(data) // 2])  # cut the file in the middle
    (video_dir / "meta.json").write_text(
        json.dumps({"n_frames": 60, "width": 64, "height": 48, "fps": 25})
    )
    (video_dir / "gt.csv").write_text("frame,id,x,y\n1,1,32,24\n")
    path, registry = _pixel_mean_pipeline(pipeline_file)
    run, pipeline = _run(video_dir, path, registry=registry)
    statuses = [r.status for r in run.frames]
    assert statuses[0] == "ok" and statuses[-1] == "unread"
    read = statuses.count("ok")
    assert 0 < read < 60 and statuses == ["ok"] * read + ["unread"] * (60 - read)
    assert max(t for t, *_ in run.tracks) == read - 1
    out = write_run(run, pipeline, tmp_path / "out" / "clip")
    rows = list(csv.DictReader((out / "frames.csv").open()))
    assert [row["status"] for row in rows].count("unread") == 60 - read


def test_unreadable_image_in_folder_is_recorded_and_skipped(tmp_path: Path, pipeline_file) -> None:
    video_dir = tmp_path / "seq"
    (video_dir / "img1").mkdir(parents=True)
    for t in range(1, 11):
        cv2.imwrite(str(video_dir / "img1" / f"{t:06d}.jpg"), np.full((48, 64, 3), 120, np.uint8))
    (video_dir / "img1" / "000005.jpg").write_bytes(b"not a jpeg")
    (video_dir / "gt.csv").write_text("frame,id,x,y\n1,1,32,24\n")
    path, registry = _pixel_mean_pipeline(pipeline_file)
    run, _ = _run(video_dir, path, registry=registry)
    assert [r.status for r in run.frames].count("unreadable") == 1
    assert run.frames[4].status == "unreadable"
    assert 4 not in {t for t, *_ in run.tracks} and 5 in {t for t, *_ in run.tracks}


def test_outputs_are_written_and_consistent(points_video, pipeline_file, tmp_path: Path) -> None:
    video = points_video(n_frames=100, intervals=[(40, 60)])
    run, pipeline = _run(video, pipeline_file())
    out = write_run(run, pipeline, tmp_path / "out" / "video")
    assert {p.name for p in out.iterdir()} == {
        "tracks.txt",
        "frames.csv",
        "gaps.json",
        "summary.json",
    }
    rows = [line.split(",") for line in (out / "tracks.txt").read_text().splitlines()]
    assert len(rows) == len(run.tracks) and all(len(row) == 10 for row in rows)
    first = rows[0]
    assert first[0] == "1" and float(first[4]) == 80.0
    gaps = json.loads((out / "gaps.json").read_text())
    assert gaps[0]["a"] == 39 and gaps[0]["b"] == 61 and gaps[0]["resolved"]
    # The tracker's check of the matches at b: on this clean video every match is kept.
    at_b = gaps[0]["at_b"]
    assert set(at_b) == set(gaps[0]["matches"])
    for target_id, outcome in at_b.items():
        assert outcome["proposed"] == gaps[0]["matches"][target_id] == outcome["detection"]
        assert outcome["refused"] is None and outcome["by"] == "gap matcher"
        assert outcome["status"] == "tracked"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames_infoless"] == 21 and summary["pipeline_hash"] == pipeline.content_hash
    frames = list(csv.DictReader((out / "frames.csv").open()))
    assert len(frames) == 100 and frames[45]["infoless"] == "1" and frames[0]["infoless"] == "0"
    assert frames[60]["ms_gap_matcher"] != "" and frames[61]["ms_gap_matcher"] == ""


def test_oracle_stage_without_ground_truth_is_a_clear_error(
    tmp_path: Path, pipeline_file, capsys
) -> None:
    from trackfw.cli import main

    video_dir = tmp_path / "bare"
    video_dir.mkdir()
    (video_dir / "meta.json").write_text(json.dumps({"n_frames": 5, "width": 64, "height": 48}))
    assert (
        main(
            [
                "run",
                str(pipeline_file()),
                "--input",
                str(video_dir),
                "--output",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    assert "needs ground truth" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("association", ["hungarian", "nearest"])
def test_both_associations_run(points_video, pipeline_file, association: str) -> None:
    video = points_video(n_frames=60, intervals=[(20, 30)])
    run, _ = _run(video, pipeline_file(), [f"stages.tracker.params.association={association}"])
    assert len(run.tracks) > 0


def test_engine_accepts_callable_progress(points_video, pipeline_file) -> None:
    seen: list[int] = []
    registry = load_registry()
    pipeline = load_pipeline(pipeline_file(), registry)
    Engine(pipeline, registry).run_video(
        load_video(points_video(n_frames=30, intervals=[])), progress=seen.append
    )
    assert seen == list(range(30))


@pytest.mark.parametrize(
    ("gt", "message"),
    [
        ("frame,id,x,y\n1,1,10,10\n1,1,12,12\n", "gt.csv: line 3: id 1 appears twice in frame 1"),
        ("frame,id,x,y\n1,1,nan,10\n", "line 2: x is 'nan'; expected a finite number"),
    ],
)
def test_dataset_with_broken_ground_truth_names_file_and_line(
    gt: str, message: str, tmp_path: Path, pipeline_file, capsys
) -> None:
    from trackfw.cli import main

    video_dir = tmp_path / "v"
    video_dir.mkdir()
    (video_dir / "meta.json").write_text(json.dumps({"n_frames": 5, "width": 64, "height": 48}))
    (video_dir / "gt.csv").write_text(gt)
    output = tmp_path / "o"
    assert (
        main(["run", str(pipeline_file()), "--input", str(video_dir), "--output", str(output)]) == 2
    )
    assert message in capsys.readouterr().err


def test_init_from_detections_without_gt(tmp_path: Path, pipeline_file, points_video) -> None:
    video = points_video(n_frames=30, intervals=[])
    text = pipeline_file().read_text() + "engine: {init: detections}\n"
    run, _ = _run(video, pipeline_file(text, "det.yaml"))
    assert run.initialised_from == "detections" and len(run.target_ids) == 14


def test_ground_truth_files_without_rows(tmp_path: Path) -> None:
    from trackfw.formats.annotations import read_heads, read_targets

    (tmp_path / "heads.csv").write_text("frame,id,x,y,head_size\n")
    (tmp_path / "gt.csv").write_text("frame,id,x,y\n")
    assert read_heads(tmp_path / "heads.csv") == {} and read_targets(tmp_path / "gt.csv") == {}


class _WithdrawingTracker(KalmanTracker):
    """The Kalman tracker that, 5 frames after each b, withdraws target row 0's reports."""

    name = "withdrawing"

    def reinitialise(self, t, positions, matched_detection, detections=None) -> None:  # type: ignore[no-untyped-def]
        super().reinitialise(t, positions, matched_detection, detections)
        self.b = t

    def step(self, t: int, detections: Detections) -> None:
        super().step(t, detections)
        self.due = getattr(self, "b", None) is not None and t == self.b + 5

    def withdrawn(self) -> list[tuple[int, int]]:
        return [(0, self.b)] if getattr(self, "due", False) else []


def _registry_with_tracker(
    tracker: type[KalmanTracker], gap_matcher: type[AssignmentGapMatcher] | None = None
) -> Registry:
    """The built-in registry plus ``tracker`` (and ``gap_matcher``), registered as a one-file
    plugin would be."""
    module = ModuleType(f"{tracker.name}_plugin")

    @hookimpl
    def trackfw_register_stages(registry: Registry) -> None:
        registry.add_tracker(tracker)
        if gap_matcher is not None:
            registry.add_gap_matcher(gap_matcher)

    module.trackfw_register_stages = trackfw_register_stages  # type: ignore[attr-defined]
    return load_registry(extra_modules=[(tracker.name, module)])


def test_withdrawn_reports_are_taken_back_and_not_filled_in(points_video, pipeline_file) -> None:
    registry = _registry_with_tracker(_WithdrawingTracker)
    video = points_video(n_frames=100, intervals=[(40, 50)])
    text = pipeline_file().read_text().replace("{type: kalman,", "{type: withdrawing,")
    text += "engine: {fill_missing_s: 1.0, fill_after_b_s: 1.0}\n"
    run, _ = _run(video, pipeline_file(text, "withdrawing.yaml"), registry=registry)
    tracked = _tracked(run)
    first = int(run.gaps[0].interval.b)
    withdrawn_id = int(run.target_ids[0])
    # Reported before the interval; not from b to the frame of the withdrawal, even though the
    # target is reported again right after it (a short absence the filling would otherwise close).
    assert withdrawn_id in tracked[first - 15]
    assert all(withdrawn_id not in tracked.get(t, {}) for t in range(first, first + 6))
    assert withdrawn_id in tracked[first + 6]
    # The other targets are untouched.
    assert all(len(tracked[t]) == len(run.target_ids) - 1 for t in range(first, first + 6))


class _RecordingTracker(KalmanTracker):
    """The Kalman tracker that says it refused target row 1's match at b."""

    name = "recording"

    def checked_at_b(self) -> dict[int, dict[str, object]]:
        return {1: {"refused": "because"}}


def test_the_trackers_check_at_b_is_recorded_by_target_id(
    points_video, pipeline_file, tmp_path: Path
) -> None:
    registry = _registry_with_tracker(_RecordingTracker)
    video = points_video(n_frames=100, intervals=[(40, 60)])
    text = pipeline_file().read_text().replace("{type: kalman,", "{type: recording,")
    run, pipeline = _run(video, pipeline_file(text, "recording.yaml"), registry=registry)
    gaps = json.loads((write_run(run, pipeline, tmp_path / "out") / "gaps.json").read_text())
    assert gaps[0]["at_b"] == {str(run.target_ids[1]): {"refused": "because"}}


class _SayingGapMatcher(AssignmentGapMatcher):
    """The assignment gap matcher that gives each match a ratio: 0.5, 0.6, ... by problem row."""

    name = "saying"

    def match(self, problem):  # type: ignore[no-untyped-def]
        solution = super().match(problem)
        solution.match_ratios = 0.5 + 0.1 * np.arange(len(problem.target_ids))
        return solution


class _RatioTracker(KalmanTracker):
    """The Kalman tracker that records the ratios it is shown before each restart."""

    name = "ratio-seeing"
    seen: ClassVar[list[np.ndarray | None]] = []  # one entry per reinitialise, any instance

    def see_match_ratios(self, ratios) -> None:  # type: ignore[no-untyped-def]
        self.pending = np.asarray(ratios).copy()

    def reinitialise(self, t, positions, matched_detection, detections=None) -> None:  # type: ignore[no-untyped-def]
        _RatioTracker.seen.append(getattr(self, "pending", None))
        self.pending = None
        super().reinitialise(t, positions, matched_detection, detections)


def test_the_gap_matchers_ratios_reach_the_tracker_by_target_row(
    points_video, pipeline_file
) -> None:
    registry = _registry_with_tracker(_RatioTracker, _SayingGapMatcher)
    video = points_video(n_frames=100, intervals=[(40, 60)])
    text = pipeline_file().read_text().replace("{type: kalman,", "{type: ratio-seeing,")
    text = text.replace("{type: assignment,", "{type: saying,")
    _RatioTracker.seen = []
    run, _ = _run(video, pipeline_file(text, "ratios.yaml"), registry=registry)
    # One gap, every target in its match: the ratios come in the targets' order, before b.
    assert len(_RatioTracker.seen) == 1 and _RatioTracker.seen[0] is not None
    np.testing.assert_allclose(_RatioTracker.seen[0], 0.5 + 0.1 * np.arange(len(run.target_ids)))

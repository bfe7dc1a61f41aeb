"""benchmarks/error_breakdown.py: each target on each frame falls into the kind it is."""

from __future__ import annotations

import doctest
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType

from trackfw.dataset import load_video, write_meta
from trackfw.formats.annotations import write_annotations
from trackfw.formats.run import FRAMES_FILE, TRACKS_FILE, frames_header
from trackfw.records import Interval

from .conftest import BENCHMARKS, load_script


def _script() -> ModuleType:
    return load_script("error_breakdown")


def _video(root: Path, cover: bool = False) -> tuple[Path, Path]:
    """Two targets (1 at x=100, 2 at x=300) and a bystander at x=500, frames 0-5; an interval
    a=2, b=4 (frame 3 info-less). Target 2 leaves after frame 4. With ``cover`` a second
    bystander stands at x=316 on frame 1, nearer than target 2 to the detection at x=310."""
    video, run = root / "dataset" / "v", root / "runs" / "v"
    video.mkdir(parents=True)
    run.mkdir(parents=True)
    truth = {t: {1: (100.0, 50.0), 2: (300.0, 50.0)} for t in (0, 1, 2, 4)}
    truth[5] = {1: (100.0, 50.0)}
    heads = [(t, k, x, y, 20.0) for t, points in truth.items() for k, (x, y) in points.items()]
    heads += [(t, 9, 500.0, 50.0, 20.0) for t in (0, 1, 2, 4, 5)]
    if cover:
        heads.append((1, 8, 316.0, 50.0, 20.0))
    write_annotations(video, truth, heads, [Interval(a=2, b=4)])
    write_meta(video / "meta.json", {"n_frames": 6, "width": 640, "height": 480, "fps": 25})
    reported = {
        0: {1: (101.0, 50.0), 2: (301.0, 50.0)},  # both right
        1: {1: (101.0, 50.0)},  # 2 missed, detected
        2: {1: (300.0, 50.0)},  # 1 far on target 2's head; 2 missed, not detected
        4: {1: (500.0, 50.0), 2: (300.0, 50.0)},  # 1 far on the bystander; 2 right (after b)
        5: {1: (100.0, 50.0), 2: (100.0, 52.0)},  # 2 not in view, on target 1's head
    }
    lines = [
        f"{t + 1},{k},{x - 10:.2f},{y - 10:.2f},20.00,20.00,1,-1,-1,-1"
        for t, points in reported.items()
        for k, (x, y) in points.items()
    ]
    (run / TRACKS_FILE).write_text("\n".join(lines) + "\n", encoding="utf-8")
    detections = {0: "100 50;300 50", 1: "100 50;310 50", 2: "", 3: "", 4: "500 50", 5: ""}
    rows = [",".join(frames_header())]
    for t, points in detections.items():
        count = len(points.split(";")) if points else 0
        rows.append(f"{t + 1},ok,0.1,{int(t == 3)},{count},{points},,2,0,0,0,1,1,1,")
    (run / FRAMES_FILE).write_text("\n".join(rows) + "\n", encoding="utf-8")
    return video, run


def test_each_target_frame_is_counted_as_its_kind(tmp_path: Path) -> None:
    script = _script()
    video, run = _video(tmp_path)
    counts = script.video_breakdown(load_video(video), run, dist=40.0, near=22.0, after=2)
    assert dict(counts) == {
        ("right", "segment"): 3,  # frame 0 both targets, frame 1 target 1
        ("missed, detected", "segment"): 1,  # frame 1: a detection 10 px from target 2
        ("far, on a target", "segment"): 1,  # frame 2: target 1 reported on 2's head
        ("missed, not detected", "segment"): 1,  # frame 2: target 2, nothing detected
        ("far, on a bystander", "after b"): 1,  # frame 4: target 1 on the bystander
        ("right", "after b"): 2,  # frame 4 target 2, frame 5 target 1
        ("not in view, on a target", "after b"): 1,  # frame 5: target 2 left, on 1's head
    }


def test_a_miss_whose_detection_is_someone_elses_head_is_covered(tmp_path: Path) -> None:
    script = _script()
    video, run = _video(tmp_path, cover=True)
    counts = script.video_breakdown(load_video(video), run, dist=40.0, near=22.0, after=2)
    assert counts["missed, covered", "segment"] == 1
    assert counts["missed, detected", "segment"] == 0


def test_two_runs_are_compared_stretch_by_stretch(tmp_path: Path) -> None:
    script = _script()
    video, run = _video(tmp_path)
    other = tmp_path / "other" / "v"
    other.mkdir(parents=True)
    # The second run loses target 1 from frame 4 on (after b) and keeps everything else.
    kept = [
        line
        for line in (run / TRACKS_FILE).read_text(encoding="utf-8").splitlines()
        if not (line.split(",")[1] == "1" and int(line.split(",")[0]) >= 5)
    ]
    (other / TRACKS_FILE).write_text("\n".join(kept) + "\n", encoding="utf-8")
    (other / FRAMES_FILE).write_bytes((run / FRAMES_FILE).read_bytes())
    context = load_video(video)
    first = script.video_kinds(context, run, 40.0, 22.0, 2)
    second = script.video_kinds(context, other, 40.0, 22.0, 2)
    assert script.differences("v", first, second, "after b") == [
        ("v", 1, 4, 4, "far, on a bystander", "missed, not detected"),
        ("v", 1, 5, 5, "right", "missed, not detected"),
    ]
    assert script.differences("v", first, second, "segment") == []
    assert script.differences("v", first, first, None) == []


def test_reports_after_leaving_are_split_by_where_the_target_left(tmp_path: Path) -> None:
    script = _script()
    video, run = _video(tmp_path)
    context = load_video(video)
    kinds = script.video_kinds(context, run, 40.0, 22.0, 2)
    # Target 2 was last annotated at (300, 50), 50 px below the image's top edge.
    assert script.video_exits(context, kinds, 30.0) == {
        ("not in view, on a target", "elsewhere"): 1
    }
    assert script.video_exits(context, kinds, 60.0) == {
        ("not in view, on a target", "image edge"): 1
    }
    # A virtual wearer zoomed out so that the source frame's top edge shows at y = 240 - 240 s = 50.
    scale = 190.0 / 240.0
    rows = ["frame,pan,tilt,roll,scale,tx,ty,view"]
    rows += [f"{t},0,0,0,{scale:.6f},0,0,real" for t in range(1, 7)]
    (video / "poses.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    meta = {"n_frames": 6, "width": 640, "height": 480, "fps": 25, "horizontal_fov": 80.0}
    write_meta(video / "meta.json", {**meta, "generator": "trackfw dataset wear"})
    worn = load_video(video)
    assert script.video_exits(worn, kinds, 30.0) == {("not in view, on a target", "source edge"): 1}
    # Only the wear generator's poses say where its source frame shows.
    write_meta(video / "meta.json", {**meta, "generator": "trackfw dataset synth"})
    assert script.source_outlines(load_video(video)) == {}


def test_the_small_maths_examples_hold() -> None:
    result = doctest.testmod(_script())
    assert result.attempted > 0 and result.failed == 0


def _command_line(*arguments: str | Path, check: bool = True) -> subprocess.CompletedProcess[str]:
    """The script run as a command, its output captured."""
    command = [sys.executable, str(BENCHMARKS / "error_breakdown.py"), *map(str, arguments)]
    return subprocess.run(command, capture_output=True, text=True, check=check)


def test_a_runs_folder_without_the_video_is_one_sentence(tmp_path: Path) -> None:
    video, _ = _video(tmp_path)
    missing = tmp_path / "no-such-runs"
    result = _command_line("--dataset", video.parent, "--runs", missing, check=False)
    assert result.returncode == 1
    assert "Traceback" not in result.stderr
    assert result.stderr.strip().startswith(str(missing / "v"))
    assert "expected a folder with tracks.txt and frames.csv" in result.stderr


def test_the_stretches_of_a_kind_are_listed_from_the_command_line(tmp_path: Path) -> None:
    video, run = _video(tmp_path)
    paths = ("--dataset", video.parent, "--runs", run.parent)
    listed = _command_line(*paths, "--stretches", "far", "--min-frames", "1").stdout
    listed = listed.split("stretches of far")[1]
    # Target 1 on target 2's head on frame 2 (1-based 3), on the bystander on frame 4 (5).
    assert "v target 1 frames 3-3 (1): far, on a target" in listed
    assert "v target 1 frames 5-5 (1): far, on a bystander" in listed
    assert "missed" not in listed
    longer = _command_line(*paths, "--stretches", "far", "--min-frames", "2").stdout
    assert "target" not in longer.split("stretches of far")[1]


def _bench_folder(root: Path, dataset: Path, runs: Path) -> Path:
    """A trackfw bench output folder whose manifest names ``dataset`` and pipeline "p"'s runs."""
    root.mkdir(parents=True)
    manifest = {
        "dataset": str(dataset),
        "pipelines": [{"name": "p", "hash": "0", "file": "p.yaml", "runs_dir": str(runs)}],
    }
    (root / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    return root


def test_bench_folders_are_pooled_by_pipeline(tmp_path: Path) -> None:
    video, run = _video(tmp_path)
    alone = _command_line("--dataset", video.parent, "--runs", run.parent).stdout
    first = _bench_folder(tmp_path / "b1", video.parent, run.parent)
    second = _bench_folder(tmp_path / "b2", video.parent, run.parent)
    pooled = _command_line("--bench", first, second, "--pipeline", "p").stdout
    assert "2 videos of 2 bench folders, pipeline p; 18 ground-truth points" in pooled
    assert "1 videos of" in alone and "; 9 ground-truth points" in alone
    # Every count doubles; the shares stay.
    right_alone = alone.split("\nright")[1].split()
    right_pooled = pooled.split("\nright")[1].split()
    assert right_alone[:4] == ["3", "2", "0", "5"]
    assert right_pooled[:4] == ["6", "4", "0", "10"]
    assert right_pooled[4] == right_alone[4]


def test_a_bench_folder_without_the_pipeline_is_one_sentence(tmp_path: Path) -> None:
    video, run = _video(tmp_path)
    bench = _bench_folder(tmp_path / "b", video.parent, run.parent)
    result = _command_line("--bench", bench, "--pipeline", "q", check=False)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert result.stderr.strip() == (
        f"{bench / 'manifest.json'}: no pipeline named 'q' in 'pipelines'; expected one of p."
    )
    both = _command_line("--bench", bench, "--runs", run.parent, "--pipeline", "p", check=False)
    assert both.returncode == 1 and "neither --dataset nor --runs" in both.stderr
    # A pipeline name without bench folders would be ignored: refused instead.
    named = _command_line(
        "--dataset", video.parent, "--runs", run.parent, "--pipeline", "p", check=False
    )
    assert named.returncode == 1 and "or --bench with --pipeline" in named.stderr

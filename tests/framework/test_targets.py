"""Choosing the people of interest (engine.init): gt, detections, region, a targets file, and the
start frame; every bad input is one line, exit 2, nothing written."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.errors import UserError
from trackfw.formats.head_point import body_head_points
from trackfw.pipeline import EngineOptions, load_pipeline
from trackfw.registry import load_registry
from trackfw.targets import parse_region, read_target_file


def _run(video: Path, pipeline: Path, overrides: list[str]):
    registry = load_registry()
    loaded = load_pipeline(pipeline, registry, overrides)
    return Engine(loaded, registry).run_video(load_video(video))


def _first_frame(run) -> tuple[int, dict[int, tuple[float, float]]]:
    first = min(t for t, *_ in run.tracks)
    return first, {i: (x, y) for t, i, x, y in run.tracks if t == first}


def _heads(video: Path, t: int) -> np.ndarray:
    truth = load_video(video).ground_truth
    assert truth is not None
    return truth.heads[t][:, :2]


def test_gt_takes_the_annotated_targets_and_detections_take_everyone(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path]
) -> None:
    video = points_video(n_frames=40, intervals=[], n_targets=5, n_others=4)
    run = _run(video, pipeline_file(), ["engine.init=gt"])
    assert run.initialised_from == "gt" and run.target_ids == [1, 2, 3, 4, 5]
    run = _run(video, pipeline_file(), ["engine.init=detections"])
    assert run.initialised_from == "detections" and len(run.target_ids) == 9
    first, positions = _first_frame(run)
    assert first == 0
    assert np.allclose(sorted(positions.values()), sorted(map(tuple, _heads(video, 0))))


def test_region_takes_the_detections_inside_the_box(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path]
) -> None:
    video = points_video(n_frames=40, intervals=[], n_targets=6, n_others=6, seed=3)
    heads = _heads(video, 0)
    # A box around the left half of the people on frame 1: those and no others are the targets.
    middle = float(np.median(heads[:, 0]))
    box = (0.0, 0.0, middle, 720.0)
    inside = heads[heads[:, 0] < middle]
    assert 0 < len(inside) < len(heads)
    run = _run(video, pipeline_file(), ["engine.init=region", f"engine.region={list(box)}"])
    assert run.initialised_from == "region" and len(run.target_ids) == len(inside)
    _, positions = _first_frame(run)
    assert np.allclose(sorted(positions.values()), sorted(map(tuple, inside)))


def test_region_without_a_detection_inside_is_one_clear_error(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path]
) -> None:
    video = points_video(n_frames=20, intervals=[])
    with pytest.raises(UserError, match=r"no detection inside engine.region 0,0,5,5 on frame 1"):
        _run(video, pipeline_file(), ["engine.init=region", "engine.region=[0, 0, 5, 5]"])


def test_a_targets_file_starts_the_run_on_its_frame(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path], tmp_path: Path
) -> None:
    video = points_video(n_frames=60, intervals=[(30, 35)])
    heads = _heads(video, 11)
    # Two of the people on frame 12 (1-based), under ids of the user's choosing; a later frame's
    # rows (a whole gt file) do not add targets.
    chosen = {7: heads[0], 3: heads[4]}
    rows = [f"12,{i},{x},{y}" for i, (x, y) in chosen.items()] + ["20,5,1.0,1.0"]
    path = tmp_path / "targets.csv"
    path.write_text("frame,id,x,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    run = _run(video, pipeline_file(), ["engine.init=targets", f"engine.targets={path}"])
    assert run.initialised_from == "targets" and run.target_ids == [3, 7]
    first, positions = _first_frame(run)
    assert first == 11  # nothing is reported before the targets' frame
    for target_id, point in chosen.items():
        assert np.allclose(positions[target_id], point)
    # The targets are tracked on: each follows its person (the oracle detections) to the end.
    last = max(t for t, *_ in run.tracks)
    assert last == 59 and {i for t, i, *_ in run.tracks if t == last} == {3, 7}


def test_a_mot_file_gives_head_points_by_the_one_rule(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path], tmp_path: Path
) -> None:
    video = points_video(n_frames=30, intervals=[])
    boxes = np.array([[600.0, 300.0, 40.0, 120.0], [700.0, 320.0, 44.0, 130.0]])
    path = tmp_path / "gt.txt"
    lines = [f"5,{i + 1},{','.join(f'{v:g}' for v in box)},1,1,1" for i, box in enumerate(boxes)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    points = read_target_file(path, 30)
    assert list(points) == [4]
    expected = body_head_points(boxes)
    assert np.allclose([points[4][1], points[4][2]], expected)
    run = _run(video, pipeline_file(), ["engine.init=targets", f"engine.targets={path}"])
    first, positions = _first_frame(run)
    assert first == 4 and np.allclose([positions[1], positions[2]], expected)


def test_start_frame_applies_to_every_mode(
    points_video: Callable[..., Path], pipeline_file: Callable[..., Path]
) -> None:
    video = points_video(n_frames=50, intervals=[])
    for mode in ("gt", "detections"):
        run = _run(video, pipeline_file(), [f"engine.init={mode}", "engine.start_frame=15"])
        first, positions = _first_frame(run)
        assert first == 14, mode
        truth = load_video(video).ground_truth
        assert truth is not None
        if mode == "gt":
            assert positions.keys() == truth.targets[14].keys()
            assert np.allclose(
                [positions[i] for i in positions], [truth.targets[14][i] for i in positions]
            )


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("1,2,3", "four finite numbers"),
        ("a,b,c,d", "four finite numbers"),
        ("1,2,nan,4", "four finite numbers"),
        ("1,2,inf,4", "four finite numbers"),
        ("1,2,0,4", "width and height must be > 0"),
        ("1,2,3,-4", "width and height must be > 0"),
    ],
)
def test_parse_region_refuses_bad_boxes(text: str, fragment: str) -> None:
    with pytest.raises(UserError, match=fragment):
        parse_region(text)


def test_engine_options_need_the_input_of_their_mode() -> None:
    for options in (
        {"init": "region"},
        {"init": "targets"},
        {"region": [1, 2, 3, 4]},
        {"init": "gt", "targets": "x.csv"},
        {"init": "region", "region": [1, 2, 3, 0]},
        {"start_frame": 0},
    ):
        with pytest.raises(ValueError):
            EngineOptions(**options)  # type: ignore[arg-type]


BAD_FILES = [
    ("frame,id,x,y\n3,1,10,20\n3,2,abc,20\n", "targets.csv: line 3: x is 'abc'; expected a number"),
    ("frame,id,x,y\n3,0,10,20\n", "targets.csv: line 2: id 0 is not a positive integer"),
    ("frame,id,x,y\n3,1,10,20\n3,1,11,21\n", "targets.csv: line 3: id 1 appears twice in frame 3"),
    ("frame,id,x,y\n99,1,10,20\n", "targets.csv: line 2: frame 99 is outside the video"),
    ("frame,id,x,y\n3,1,10\n", "targets.csv: line 2: 3 values; expected 4"),
    ("frame,id,x\n3,1,10\n", "targets.csv: line 1: header is 'frame,id,x'"),
    ("frame,id,x,y\n", "targets.csv: no target rows"),
    ("\n", "targets.csv: empty file"),
    ("3,1,10,20,40,100,1,1,1\n3,2,10,20,nan,100,1,1,1\n", "targets.csv: line 2: width is 'nan'"),
    ("3,1,10,20,40,100,1,1,1\n3,-2,10,20,40,100,1,1,1\n", "targets.csv: line 2: id -2 is not a"),
    ("3,1,10,20,40,0,1,1,1\n", "targets.csv: line 1: box 40x0; expected a positive size"),
    ("3,1,10,20\n", "targets.csv: line 1: 4 values and no header; expected the header"),
    ("3,1,10,20,5\n", "targets.csv: line 1: 5 values; expected at least 6"),
]


@pytest.mark.parametrize(("text", "fragment"), BAD_FILES)
def test_bad_targets_files_are_one_line_exit_2_nothing_written(
    in_bad_input_workspace: Path, bad_input: Callable[..., str], text: str, fragment: str
) -> None:
    path = in_bad_input_workspace / "targets.csv"
    path.write_text(text, encoding="utf-8")
    try:
        bad_input(
            ["run", "pipeline.yaml", "-i", "data/v1", "-o", "out", "-q", "--targets", path],
            fragment,
        )
    finally:
        path.unlink()


@pytest.mark.parametrize(
    ("arguments", "fragment"),
    [
        (["-i", "data/v1", "--region", "1,2,3"], "--region '1,2,3': expected x,y,w,h"),
        (["-i", "data/v1", "--region", "1,2,0,3"], "width and height must be > 0"),
        (["-i", "data/v1", "--region", "5000,0,10,10"], "lies outside the 1280x720 image"),
        (["-i", "data/v1", "--region", "1,2,3,4", "--targets", "file.txt"], "both given"),
        (["-i", "data", "--targets", "file.txt"], "the input has 2 videos"),
        (["-i", "data/v1", "--targets", "missing.csv"], "missing.csv: file not found"),
        (["-i", "data/v1", "--set", "engine.start_frame=61"], "start frame 61 is beyond"),
        (["-i", "data/v1", "--set", "engine.start_frame=0"], "engine.start_frame"),
        (["-i", "data/v1", "--set", "engine.init=region"], "region is not set"),
    ],
)
def test_bad_target_options_are_one_line_exit_2_nothing_written(
    in_bad_input_workspace: Path,
    bad_input: Callable[..., str],
    arguments: list[str],
    fragment: str,
) -> None:
    bad_input(["run", "pipeline.yaml", "-o", "out", "-q", *arguments], fragment)


def test_region_and_targets_from_the_command_line_run(
    in_bad_input_workspace: Path, tmp_path: Path
) -> None:
    from trackfw.cli import main

    heads = _heads(in_bad_input_workspace / "data" / "v1", 0)
    x, y = heads[0]

    def run(out: str, *options: str) -> int:
        return main(
            ["run", "pipeline.yaml", "-i", "data/v1", "-o", str(tmp_path / out), "-q", *options]
        )

    assert run("a", "--region", f"{x - 5},{y - 5},10,10") == 0
    assert '"initialised_from": "region"' in (tmp_path / "a" / "v1" / "summary.json").read_text()
    path = tmp_path / "t.csv"
    path.write_text(f"frame,id,x,y\n4,9,{x},{y}\n", encoding="utf-8")
    assert run("b", "--targets", str(path)) == 0
    tracks = (tmp_path / "b" / "v1" / "tracks.txt").read_text().splitlines()
    assert tracks[0].startswith("4,9,") and {line.split(",")[1] for line in tracks} == {"9"}

"""Rendering, writing and reading back tiny videos; the demo clip; the command line."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from trackfw.dataset import load_video
from trackfw.errors import UserError
from trackfw.formats.annotations import read_heads
from trackfw_plugins.datasets.synth import generate as generate_module
from trackfw_plugins.datasets.synth.cli import parse_size, register, run_synth
from trackfw_plugins.datasets.synth.generate import generate_demo, generate_video
from trackfw_plugins.datasets.synth.presets import IntervalPlan, custom_plan

from ....conftest import decode_video

TEXT_FILES = ("gt.csv", "heads.csv", "intervals.csv", "meta.json", "poses.csv")


def _tiny_plan(kind: str = "group"):
    plan = custom_plan(4, videos=1, frames=60, intervals=1, width=192, height=108)[0]
    return replace(plan, intervals=(IntervalPlan(start=20, length=18, kind=kind),))


def test_tiny_video_round_trips_through_load_video(tmp_path: Path) -> None:
    plan = _tiny_plan()
    folder = generate_video(plan, tmp_path, "mp4", preview_dir=tmp_path / "preview").path
    video = load_video(folder)
    assert (video.n_frames, video.width, video.height, video.fps) == (60, 192, 108, 30.0)
    assert video.ground_truth is not None
    assert [(i.a, i.b, i.kind) for i in video.ground_truth.intervals] == [(19, 38, "group")]
    targets = video.ground_truth.targets
    assert len(targets[0]) == plan.n_targets
    assert not any(frame in targets for frame in range(20, 38))
    assert video.meta["source"] == "synth" and video.meta["seed"] == plan.seed
    frames = decode_video(folder / "video.mp4")
    assert len(frames) == 60 and frames[0].shape == (108, 192, 3)
    heads = read_heads(folder / "heads.csv", 60)
    assert set(heads) >= set(targets)
    assert (tmp_path / "preview" / f"{plan.name}_group.png").is_file()
    assert not [child for child in tmp_path.iterdir() if child.name.startswith(".")]


def test_generation_is_deterministic(tmp_path: Path) -> None:
    plan = _tiny_plan("path")
    first = generate_video(plan, tmp_path / "one", "jpg").path
    second = generate_video(plan, tmp_path / "two", "jpg").path
    for name in TEXT_FILES:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    images = sorted((first / "img1").iterdir())
    assert len(images) == 60
    for image in images:
        assert image.read_bytes() == (second / "img1" / image.name).read_bytes()
    # The frames show something: not flat, and different from one frame to the next.
    pixels = [np.asarray(cv2.imread(str(image))) for image in images[:2]]
    assert pixels[0].std() > 5 and np.abs(pixels[0].astype(int) - pixels[1]).mean() > 0.5


class _BrokenRenderer:
    """Renders two black frames, then fails like a full disk would."""

    def __init__(self, simulation: object) -> None:
        self.count = 0

    def render(self, frame: int) -> np.ndarray:
        self.count += 1
        if self.count > 2:
            raise RuntimeError("disk full")
        return np.zeros((108, 192, 3), dtype=np.uint8)


def test_failed_video_leaves_no_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(generate_module, "FrameRenderer", _BrokenRenderer)
    with pytest.raises(RuntimeError):
        generate_video(_tiny_plan(), tmp_path, "mp4")
    assert list(tmp_path.iterdir()) == []


def test_demo_clip(tmp_path: Path) -> None:
    folder = generate_demo(tmp_path)
    video = load_video(folder)
    assert (video.n_frames, video.width, video.height) == (150, 640, 360)
    assert video.ground_truth is not None
    assert len(video.ground_truth.targets[0]) == 6
    assert [(i.a + 2, i.b, i.kind) for i in video.ground_truth.intervals] == [(61, 90, "sky")]
    assert len(decode_video(folder / "video.mp4")) == 150


def test_cli_writes_a_dataset_and_refuses_to_overwrite(tmp_path: Path) -> None:
    app = typer.Typer()
    dataset_app = typer.Typer()
    register(dataset_app)
    app.add_typer(dataset_app, name="dataset")
    out = tmp_path / "data"
    arguments = [
        "dataset",
        "synth",
        "--out",
        str(out),
        "--size",
        "160x90",
        "--frames",
        "60",
        "--videos",
        "2",
        "--jobs",
        "1",
        "--format",
        "jpg",
        "--seed",
        "9",
    ]
    result = CliRunner().invoke(app, arguments)
    assert result.exit_code == 0, result.output
    assert "Done: 2 video(s)" in result.output and " s" in result.output
    names = sorted(child.name for child in out.iterdir() if child.is_dir())
    assert names == ["synth001-plaza", "synth002-campus"]
    assert (out / "synth.json").is_file()
    assert not (out / "preview").exists()  # previews default to on for presets only
    result = CliRunner().invoke(app, arguments)
    assert result.exit_code != 0 and isinstance(result.exception, UserError)
    assert "not empty" in str(result.exception)


def test_cli_rejects_bad_options(tmp_path: Path) -> None:
    for size in ("1280", "0x0", "1281x720"):
        with pytest.raises(UserError, match="--size"):
            parse_size(size)
    with pytest.raises(UserError, match="--trajectories"):
        run_synth(tmp_path / "x", trajectories=tmp_path / "missing.txt", echo=False)
    with pytest.raises(UserError, match="--preset"):
        run_synth(tmp_path / "x", preset="nope", echo=False)
    with pytest.raises(UserError, match="--scale-range"):
        run_synth(tmp_path / "x", scale_range="1.4,0.7", echo=False)
    with pytest.raises(UserError, match="--max-pan"):
        run_synth(tmp_path / "x", max_pan=90.0, echo=False)
    assert not (tmp_path / "x").exists()

"""Bad input to ``trackfw dataset synth|wear|check``: one error line, exit 2, nothing written."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

SYNTH = ["dataset", "synth", "--size", "160x90", "--jobs", "1"]

BAD_INPUT_CASES = [
    ([*SYNTH, "--out", "s", "--size", "huge"], ["--size 'huge'", "WIDTHxHEIGHT"]),
    ([*SYNTH, "--out", "s", "--preset", "nope"], ["--preset 'nope'", "paper"]),
    ([*SYNTH, "--out", "s", "--frames", "-5"], ["--frames -5", "expected at least"]),
    ([*SYNTH, "--out", "s", "--fps", "0", "--frames", "60"], ["--fps", "between 1 and 240"]),
    ([*SYNTH, "--out", "s", "--frames", "60", "--trajectories", "missing.txt"], ["missing.txt"]),
    ([*SYNTH, "--out", "s", "--frames", "60", "--scale-range", "2,1"], ["--scale-range '2,1'"]),
    ([*SYNTH, "--out", "s", "--frames", "60", "--format", "gif"], ["--format 'gif'", "mp4"]),
    ([*SYNTH, "--out", "s", "--videos", "0"], ["--videos 0", "at least 1"]),
    ([*SYNTH, "--out", "file.txt", "--frames", "60"], ["file.txt", "folder"]),
    ([*SYNTH, "--out", "file.txt/s", "--frames", "60"], ["file.txt", "not a folder"]),
    (["dataset", "wear", "--mot", "missing", "--out", "w"], ["missing: no such folder"]),
    (["dataset", "wear", "--mot", "emptydir", "--out", "w"], ["emptydir/img1"]),
    (["dataset", "wear", "--mot", "data/v1", "--out", "file.txt"], ["--out", "file.txt"]),
    (["dataset", "wear", "--mot", "data/v1", "--out", "w", "--size", "big"], ["--size", "'big'"]),
    (
        [
            "dataset",
            "wear",
            "--mot",
            "data/v1",
            "--out",
            "w",
            "--min-length",
            "50",
            "--max-length",
            "9",
        ],
        ["--min-length 50", "min <= max"],
    ),
    (["dataset", "check", "missing"], ["missing: no such folder", "dataset folder"]),
    (["dataset", "check", "file.txt"], ["file.txt: is a file", "dataset folder"]),
    (["dataset", "check", "fake.mp4"], ["fake.mp4: is a file"]),
    (["dataset", "check", "emptydir"], ["emptydir: no video found"]),
]


def test_dataset_commands_refuse_bad_input_in_one_line(bad_input_case: Callable[[], str]) -> None:
    bad_input_case()


def test_dataset_check_reports_a_fake_video_once_without_ffmpeg_lines(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from trackfw.cli import main
    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(tmp_path / "data" / "v1", n_frames=40, intervals=((10, 15),))
    (video / "video.mp4").write_text("text, not a video\n", encoding="utf-8")
    assert main(["dataset", "check", str(tmp_path / "data")]) == 2
    stderr = capfd.readouterr().err
    assert stderr.count("video.mp4") == 1, stderr
    assert "not a video FFmpeg can open" in stderr
    assert "moov atom" not in stderr


def test_dataset_check_reports_frames_of_mixed_sizes(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    import cv2
    import numpy as np

    from trackfw.cli import main

    frames = tmp_path / "data" / "v1" / "img1"
    frames.mkdir(parents=True)
    for index, (width, height) in enumerate([(32, 24), (32, 24), (24, 32)], start=1):
        cv2.imwrite(str(frames / f"{index:06d}.png"), np.zeros((height, width, 3), np.uint8))
    assert main(["dataset", "check", str(tmp_path / "data")]) == 2
    stderr = capfd.readouterr().err
    assert "000003.png: frame is 24x32; expected 32x24 like 000001.png" in stderr

"""A folder of several video files (a recording split by the camera) is one video per file."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.cli import main
from trackfw.dataset import frame_source_path, list_videos
from trackfw.errors import UserError


def _write_mp4(path: Path, n_frames: int) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), 25, (64, 48))
    for t in range(n_frames):
        writer.write(np.full((48, 64, 3), 60 + t, dtype=np.uint8))
    writer.release()


def _clip_folder(folder: Path, frames: dict[str, int]) -> Path:
    """``folder`` with one small MP4 per name (``frames``: name -> frame count)."""
    folder.mkdir()
    for name, n_frames in frames.items():
        _write_mp4(folder / name, n_frames)
    return folder


def test_each_video_file_of_a_folder_is_run_into_its_own_output(
    tmp_path: Path, pixel_pipeline: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _clip_folder(tmp_path / "gopro", {"GX010001.MP4": 30, "GX010002.MP4": 20})
    out = tmp_path / "out"
    code = main(["run", str(pixel_pipeline), "--input", str(folder), "--output", str(out), "-q"])
    assert code == 0, capsys.readouterr().err
    frames = {
        child.name: json.loads((child / "summary.json").read_text())["n_frames"]
        for child in out.iterdir()
    }
    assert frames == {"GX010001": 30, "GX010002": 20}


def test_videos_that_would_share_an_output_folder_are_refused(
    tmp_path: Path, pixel_pipeline: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _clip_folder(tmp_path / "clips", {"clip.mp4": 5, "clip.MOV": 5, "other.mp4": 5})
    out = tmp_path / "out"
    assert (
        main(["run", str(pixel_pipeline), "--input", str(folder), "--output", str(out), "-q"]) == 2
    )
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "clip.mp4" in lines[0] and "clip.MOV" in lines[0], lines
    assert not out.exists()


def test_one_video_file_with_annotations_stays_one_video(tmp_path: Path) -> None:
    folder = tmp_path / "seq"
    folder.mkdir()
    _write_mp4(folder / "GX010001.MP4", 5)
    (folder / "gt.csv").write_text("frame,id,x,y\n1,1,10,10\n")
    assert list_videos(folder) == [folder]
    _write_mp4(folder / "GX010002.MP4", 5)  # two recordings beside one gt.csv: which is it?
    with pytest.raises(UserError, match="several video files"):
        frame_source_path(folder)

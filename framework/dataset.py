"""The dataset layout on disk: read, validate and write it.

See docs/algorithms/datasets.md#dataset-layout.

A dataset is a folder of videos; each video is a folder::

    <video>/video.mp4 | img1/000001.jpg ...   frames
    <video>/gt.csv          frame,id,x,y              people of interest (1-based frames)
    <video>/heads.csv       frame,id,x,y,head_size    every visible head (optional)
    <video>/intervals.csv   start,end,kind            ground-truth info-less frames (inclusive)
    <video>/meta.json       fps, width, height, n_frames, source, seed, ...
    <video>/poses.csv       frame,pan,tilt,roll,scale,tx,ty  (optional, synthetic camera pose)

The annotation files (gt.csv, heads.csv, intervals.csv) are read and written by
:mod:`trackfw.formats.annotations`. Every reader error names the file and the line and says what
was expected.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from trackfw.atomic import write_json
from trackfw.errors import UserError
from trackfw.formats.annotations import (
    GT_FILE,
    HEADS_FILE,
    INTERVALS_FILE,
    read_heads,
    read_intervals,
    read_targets,
)
from trackfw.records import GroundTruth, VideoContext

META_FILE = "meta.json"
POSES_FILE = "poses.csv"
VIDEO_FILE = "video.mp4"
IMAGE_FOLDER = "img1"
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v")

#: meta.json numbers the readers rely on: the smallest valid value and what the error says.
META_NUMBERS: dict[str, tuple[float, str]] = {
    "n_frames": (0, "a whole number of frames >= 0"),
    "width": (1, "a whole number of pixels >= 1"),
    "height": (1, "a whole number of pixels >= 1"),
    "fps": (1e-6, "a positive number of frames per second"),
}


def _video_files(folder: Path) -> list[Path]:
    """Video files directly in ``folder`` (not hidden), sorted."""
    return sorted(
        child
        for child in folder.iterdir()
        if child.is_file()
        and child.suffix.lower() in VIDEO_SUFFIXES
        and not child.name.startswith(".")
    )


def is_video_dir(path: Path) -> bool:
    """True when ``path`` is one video, not a dataset.

    A video folder has frames (img1/, video.mp4 or a single video file) or at least a meta.json:
    a point-only video (annotations without pixels) runs with pipelines whose stages need no
    pixels. A folder of several video files and no annotation (a camera's recording split into
    GX010001.MP4, GX010002.MP4) is a dataset of one video per file.
    """
    if not path.is_dir():
        return False
    if (
        (path / IMAGE_FOLDER).is_dir()
        or (path / VIDEO_FILE).is_file()
        or (path / META_FILE).is_file()
    ):
        return True
    files = _video_files(path)
    annotated = any((path / name).is_file() for name in (GT_FILE, HEADS_FILE, INTERVALS_FILE))
    return len(files) == 1 or (len(files) > 1 and annotated)


def _video_name(path: Path) -> str:
    return path.stem if path.is_file() else path.name


def list_videos(dataset: Path) -> list[Path]:
    """The videos of a dataset (or the single video when ``dataset`` is one), sorted.

    A dataset's videos are its video folders and the video files directly in it; hidden
    entries (names starting with ``.``, such as a generator's staging folder left by a killed
    run) are skipped. Two videos may not share a name: outputs go to one folder per name.
    """
    if dataset.is_file() or is_video_dir(dataset):
        return [dataset]
    if not dataset.is_dir():
        raise UserError(f"{dataset}: no such file or folder; expected a video or a dataset folder.")
    videos = sorted(
        [
            child
            for child in dataset.iterdir()
            if not child.name.startswith(".") and is_video_dir(child)
        ]
        + _video_files(dataset)
    )
    if not videos:
        raise UserError(
            f"{dataset}: no video found; expected sub-folders with img1/ or {VIDEO_FILE}, or"
            f" video files ({', '.join(VIDEO_SUFFIXES)})."
        )
    by_name: dict[str, list[str]] = {}
    for video in videos:
        by_name.setdefault(_video_name(video), []).append(video.name)
    clashes = [
        f"{', '.join(entries)} (all named {name!r})"
        for name, entries in by_name.items()
        if len(entries) > 1
    ]
    if clashes:
        raise UserError(
            f"{dataset}: several videos would write to the same output folder: {'; '.join(clashes)};"
            " expected one video per name: rename or move all but one."
        )
    return videos


def frame_source_path(video_dir: Path) -> Path:
    """The file or folder holding the frames of a video."""
    if video_dir.is_file():
        return video_dir
    if (video_dir / IMAGE_FOLDER).is_dir():
        return video_dir / IMAGE_FOLDER
    if (video_dir / VIDEO_FILE).is_file():
        return video_dir / VIDEO_FILE
    files = _video_files(video_dir)
    if len(files) > 1:
        raise UserError(
            f"{video_dir}: several video files ({', '.join(f.name for f in files)}) beside the"
            f" annotations; expected one video per folder ({IMAGE_FOLDER}/, {VIDEO_FILE} or a"
            " single video file)."
        )
    if files:
        return files[0]
    raise UserError(f"{video_dir}: no frames; expected {IMAGE_FOLDER}/ or {VIDEO_FILE}.")


# --------------------------------------------------------------------------------------- reading


def read_meta(video_dir: Path) -> dict[str, Any]:
    """meta.json as a dict (empty when the file is absent)."""
    path = video_dir / META_FILE
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise UserError(f"{path}: line {error.lineno}: invalid JSON ({error.msg}).") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a JSON object at the top level.")
    for key, (low, expected) in META_NUMBERS.items():
        value = data.get(key)
        if value is None:
            continue
        whole = key != "fps"
        valid = (
            isinstance(value, int | float)
            and not isinstance(value, bool)
            and math.isfinite(value)
            and value >= low
            and (not whole or float(value).is_integer())
        )
        if not valid:
            raise UserError(f"{path}: {key} is {json.dumps(value)}; expected {expected}.")
    return data


def count_frames(video_dir: Path) -> int:
    """Number of frames, without decoding them (meta.json, the image list or the container)."""
    meta = read_meta(video_dir) if video_dir.is_dir() else {}
    if "n_frames" in meta:
        return int(meta["n_frames"])
    source = frame_source_path(video_dir)
    if source.is_dir():
        return sum(1 for child in source.iterdir() if child.suffix.lower() in IMAGE_SUFFIXES)
    from trackfw.video_io import probe_container

    return probe_container(source).n_frames


def _frame_size(video_dir: Path) -> tuple[int, int, float]:
    import cv2

    from trackfw.video_io import check_frame_sizes, probe_container

    source = frame_source_path(video_dir)
    if source.is_dir():
        files = sorted(c for c in source.iterdir() if c.suffix.lower() in IMAGE_SUFFIXES)
        image = cv2.imread(str(files[0])) if files else None
        if image is None:
            raise UserError(
                f"{source}: no readable image to take the frame size from; expected frames named"
                f" like 000001.jpg ({', '.join(IMAGE_SUFFIXES)})."
            )
        check_frame_sizes(files)
        return image.shape[1], image.shape[0], 30.0
    info = probe_container(source)
    return info.width, info.height, info.fps


def _check_frames(video_dir: Path) -> None:
    """Probe the frames of a video whose size meta.json gives; point-only videos pass."""
    from trackfw.video_io import check_frame_sizes, probe_container

    try:
        source = frame_source_path(video_dir)
    except UserError:
        return  # no frames at all: a point-only video
    if source.is_dir():
        check_frame_sizes(sorted(c for c in source.iterdir() if c.suffix.lower() in IMAGE_SUFFIXES))
    else:
        probe_container(source)


def load_video(video_dir: Path) -> VideoContext:
    """Read one video's metadata and ground truth (whatever of it exists)."""
    video_dir = Path(video_dir)
    meta = read_meta(video_dir) if video_dir.is_dir() else {}
    if {"width", "height"} <= meta.keys():
        width, height, fps = int(meta["width"]), int(meta["height"]), float(meta.get("fps", 30.0))
        # Probed even so: a file that is no video, or frames of mixed sizes, is a one-line error
        # here rather than a run of unread frames.
        _check_frames(video_dir)
    else:
        width, height, fps = _frame_size(video_dir)
        fps = float(meta.get("fps", fps))
    n_frames = count_frames(video_dir)
    ground_truth: GroundTruth | None = None
    if video_dir.is_dir() and any(
        (video_dir / name).is_file() for name in (GT_FILE, HEADS_FILE, INTERVALS_FILE)
    ):
        ground_truth = GroundTruth()
        if (video_dir / GT_FILE).is_file():
            ground_truth.targets = read_targets(video_dir / GT_FILE, n_frames)
        if (video_dir / HEADS_FILE).is_file():
            ground_truth.heads = read_heads(video_dir / HEADS_FILE, n_frames)
        if (video_dir / INTERVALS_FILE).is_file():
            ground_truth.intervals = read_intervals(video_dir / INTERVALS_FILE, n_frames)
    name = video_dir.stem if video_dir.is_file() else video_dir.name
    return VideoContext(
        name=name,
        path=str(video_dir),
        n_frames=n_frames,
        width=width,
        height=height,
        fps=fps,
        ground_truth=ground_truth,
        meta=meta,
    )


# --------------------------------------------------------------------------------------- writing


def write_meta(path: Path, meta: dict[str, Any]) -> None:
    """Write meta.json."""
    write_json(path, meta)

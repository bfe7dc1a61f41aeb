"""The dataset layout on disk (DESIGN.md section 6): read, validate and write it.

A dataset is a folder of videos; each video is a folder::

    <video>/video.mp4 | img1/000001.jpg ...   frames
    <video>/gt.csv          frame,id,x,y              people of interest (1-based frames)
    <video>/heads.csv       frame,id,x,y,head_size    every visible head (optional)
    <video>/intervals.csv   start,end,kind            ground-truth info-less frames (inclusive)
    <video>/meta.json       fps, width, height, n_frames, source, seed, ...
    <video>/poses.csv       frame,pan,tilt,roll,scale,tx,ty  (optional, synthetic camera pose)

Every reader error names the file and the line and says what was expected.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.atomic import write_json, write_text
from trackfw.errors import UserError
from trackfw.records import GroundTruth, Interval, VideoContext

GT_FILE = "gt.csv"
HEADS_FILE = "heads.csv"
INTERVALS_FILE = "intervals.csv"
META_FILE = "meta.json"
POSES_FILE = "poses.csv"
VIDEO_FILE = "video.mp4"
IMAGE_FOLDER = "img1"
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v")

#: Interval kinds of the paper: (i) sky or building, (ii) another group, (iii) the walking path.
INTERVAL_KINDS = ("sky", "group", "path", "unknown")


def is_video_dir(path: Path) -> bool:
    """True when ``path`` is one video, not a dataset.

    A video folder has frames (img1/ or a video file) or at least a meta.json: a point-only
    video (annotations without pixels) runs with pipelines whose stages need no pixels.
    """
    if not path.is_dir():
        return False
    if (
        (path / IMAGE_FOLDER).is_dir()
        or (path / VIDEO_FILE).is_file()
        or (path / META_FILE).is_file()
    ):
        return True
    return any(
        child.suffix.lower() in VIDEO_SUFFIXES for child in path.iterdir() if child.is_file()
    )


def list_videos(dataset: Path) -> list[Path]:
    """The video folders of a dataset (or the single video when ``dataset`` is one), sorted."""
    if dataset.is_file() or is_video_dir(dataset):
        return [dataset]
    if not dataset.is_dir():
        raise UserError(f"{dataset}: no such file or folder; expected a video or a dataset folder.")
    videos = sorted(child for child in dataset.iterdir() if is_video_dir(child))
    if not videos:
        raise UserError(
            f"{dataset}: no video found; expected sub-folders with img1/ or {VIDEO_FILE}."
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
    for child in sorted(video_dir.iterdir()):
        if child.suffix.lower() in VIDEO_SUFFIXES:
            return child
    raise UserError(f"{video_dir}: no frames; expected {IMAGE_FOLDER}/ or {VIDEO_FILE}.")


# --------------------------------------------------------------------------------------- reading


def _read_csv(path: Path, columns: Sequence[str]) -> list[tuple[int, dict[str, str]]]:
    """Rows of a CSV whose header must start with ``columns``; returns (line number, row)."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None:
        raise UserError(f"{path}: empty file; expected the header {','.join(columns)}.")
    header = [name.strip() for name in header]
    if header[: len(columns)] != list(columns):
        raise UserError(
            f"{path}: line 1: header is {','.join(header)!r}; expected {','.join(columns)!r}."
        )
    rows: list[tuple[int, dict[str, str]]] = []
    for line_number, values in enumerate(reader, start=2):
        if not values or all(not value.strip() for value in values):
            continue
        if len(values) != len(header):
            raise UserError(
                f"{path}: line {line_number}: {len(values)} values; expected {len(header)}"
                f" ({','.join(header)})."
            )
        rows.append((line_number, dict(zip(header, (v.strip() for v in values), strict=True))))
    return rows


def _number(path: Path, line: int, column: str, text: str, integer: bool = False) -> float:
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        expected = "an integer" if integer else "a number"
        raise UserError(
            f"{path}: line {line}: {column} is {text!r}; expected {expected}."
        ) from None
    if not integer and not math.isfinite(value):
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected a finite number.")
    return value


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
    return data


def _fast_table(path: Path, columns: Sequence[str], n_frames: int | None) -> np.ndarray | None:
    """The numeric table of a well-formed file, or None so the line-by-line reader explains.

    Ground-truth files run to tens of thousands of rows; parsing them with numpy and checking
    the rules vectorised is much faster than the validating reader, which then only runs when
    some rule fails (to name the line).
    """
    try:
        with path.open(encoding="utf-8") as stream:
            header = [name.strip() for name in stream.readline().split(",")]
            if header != list(columns):
                return None
            rows = stream.read()
        if not rows.strip():
            return np.zeros((0, len(columns)))
        table = np.loadtxt(io.StringIO(rows), delimiter=",", ndmin=2, dtype=np.float64)
    except (ValueError, UnicodeDecodeError):
        return None
    if table.size == 0:
        return np.zeros((0, len(columns)))
    if table.shape[1] != len(columns) or not np.isfinite(table).all():
        return None
    frames, ids = table[:, 0], table[:, 1]
    if (frames != np.round(frames)).any() or (ids != np.round(ids)).any() or (frames < 1).any():
        return None
    if n_frames is not None and (frames > n_frames).any():
        return None
    return table


def read_targets(
    path: Path, n_frames: int | None = None
) -> dict[int, dict[int, tuple[float, float]]]:
    """gt.csv as ``{0-based frame: {id: (x, y)}}``; duplicate ids or bad frames are errors."""
    table = _fast_table(path, ("frame", "id", "x", "y"), n_frames)
    if table is not None:
        keys = table[:, 0] * 1e9 + table[:, 1]
        if len(np.unique(keys)) == len(keys):
            fast: dict[int, dict[int, tuple[float, float]]] = {}
            for frame, target_id, x, y in table.tolist():
                fast.setdefault(int(frame) - 1, {})[int(target_id)] = (x, y)
            return fast
    targets: dict[int, dict[int, tuple[float, float]]] = {}
    for line, row in _read_csv(path, ("frame", "id", "x", "y")):
        frame = int(_number(path, line, "frame", row["frame"], integer=True))
        target_id = int(_number(path, line, "id", row["id"], integer=True))
        x = _number(path, line, "x", row["x"])
        y = _number(path, line, "y", row["y"])
        if frame < 1 or (n_frames is not None and frame > n_frames):
            limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
            raise UserError(
                f"{path}: line {line}: frame {frame} is outside the video; expected {limit}."
            )
        frame_targets = targets.setdefault(frame - 1, {})
        if target_id in frame_targets:
            raise UserError(f"{path}: line {line}: id {target_id} appears twice in frame {frame}.")
        frame_targets[target_id] = (x, y)
    return targets


def read_heads(path: Path, n_frames: int | None = None) -> dict[int, np.ndarray]:
    """heads.csv as ``{0-based frame: (M, 3) array of x, y, head_size}``."""
    table = _fast_table(path, ("frame", "id", "x", "y", "head_size"), n_frames)
    if table is not None:
        if len(table) == 0:
            return {}
        frames = table[:, 0].astype(np.int64) - 1
        order = np.argsort(frames, kind="stable")
        frames, rows = frames[order], table[order][:, 2:5]
        starts: list[int] = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]]).tolist()
        ends = [*starts[1:], len(frames)]
        return {int(frames[s]): rows[s:e].copy() for s, e in zip(starts, ends, strict=True)}
    grouped: dict[int, list[tuple[float, float, float]]] = {}
    for line, row in _read_csv(path, ("frame", "id", "x", "y", "head_size")):
        frame = int(_number(path, line, "frame", row["frame"], integer=True))
        if frame < 1 or (n_frames is not None and frame > n_frames):
            raise UserError(f"{path}: line {line}: frame {frame} is outside the video.")
        grouped.setdefault(frame - 1, []).append(
            (
                _number(path, line, "x", row["x"]),
                _number(path, line, "y", row["y"]),
                _number(path, line, "head_size", row["head_size"]),
            )
        )
    return {frame: np.asarray(rows, dtype=np.float64) for frame, rows in grouped.items()}


def read_intervals(path: Path, n_frames: int | None = None) -> list[Interval]:
    """intervals.csv (inclusive 1-based info-less frames) as :class:`Interval` records."""
    intervals: list[Interval] = []
    for line, row in _read_csv(path, ("start", "end", "kind")):
        start = int(_number(path, line, "start", row["start"], integer=True))
        end = int(_number(path, line, "end", row["end"], integer=True))
        if start < 2 or end < start or (n_frames is not None and end > n_frames):
            raise UserError(
                f"{path}: line {line}: interval {start}..{end} is invalid; expected"
                f" 2 <= start <= end{'' if n_frames is None else f' <= {n_frames}'}"
                " (frame 1 carries the annotation)."
            )
        kind = row["kind"] or "unknown"
        if kind not in INTERVAL_KINDS:
            raise UserError(
                f"{path}: line {line}: kind {kind!r}; expected one of {', '.join(INTERVAL_KINDS)}."
            )
        # 1-based inclusive start..end -> 0-based a = start-2, b = end.
        intervals.append(Interval(a=start - 2, b=end, kind=kind))
    intervals.sort(key=lambda interval: interval.a)
    for previous, current in itertools.pairwise(intervals):
        if current.a < previous.b:
            raise UserError(f"{path}: intervals overlap or touch near frame {current.a + 2}.")
    return intervals


def count_frames(video_dir: Path) -> int:
    """Number of frames, without decoding them (meta.json, the image list or the container)."""
    meta = read_meta(video_dir) if video_dir.is_dir() else {}
    if "n_frames" in meta:
        return int(meta["n_frames"])
    source = frame_source_path(video_dir)
    if source.is_dir():
        return sum(1 for child in source.iterdir() if child.suffix.lower() in IMAGE_SUFFIXES)
    import cv2

    capture = cv2.VideoCapture(str(source))
    try:
        return int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        capture.release()


def _frame_size(video_dir: Path) -> tuple[int, int, float]:
    import cv2

    source = frame_source_path(video_dir)
    if source.is_dir():
        first = next(
            (c for c in sorted(source.iterdir()) if c.suffix.lower() in IMAGE_SUFFIXES), None
        )
        image = None if first is None else cv2.imread(str(first))
        if image is None:
            raise UserError(f"{source}: no readable image to take the frame size from.")
        return image.shape[1], image.shape[0], 30.0
    capture = cv2.VideoCapture(str(source))
    try:
        width = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fps = float(capture.get(cv2.CAP_PROP_FPS)) or 30.0
    finally:
        capture.release()
    if width <= 0 or height <= 0:
        raise UserError(f"{source}: cannot read the video's frame size.")
    return width, height, fps


def load_video(video_dir: Path) -> VideoContext:
    """Read one video's metadata and ground truth (whatever of it exists)."""
    video_dir = Path(video_dir)
    meta = read_meta(video_dir) if video_dir.is_dir() else {}
    if {"width", "height"} <= meta.keys():
        width, height, fps = int(meta["width"]), int(meta["height"]), float(meta.get("fps", 30.0))
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


def _csv_text(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_format(value) for value in row])
    return buffer.getvalue()


def _format(value: Any) -> Any:
    if isinstance(value, float | np.floating):
        return f"{float(value):.3f}"
    return value


def write_targets(path: Path, targets: dict[int, dict[int, tuple[float, float]]]) -> None:
    """Write gt.csv from ``{0-based frame: {id: (x, y)}}``."""
    rows = (
        (frame + 1, target_id, x, y)
        for frame in sorted(targets)
        for target_id, (x, y) in sorted(targets[frame].items())
    )
    write_text(path, _csv_text(("frame", "id", "x", "y"), rows))


def write_heads(path: Path, heads: Iterable[tuple[int, int, float, float, float]]) -> None:
    """Write heads.csv from ``(0-based frame, id, x, y, head_size)`` tuples."""
    rows = ((frame + 1, head_id, x, y, size) for frame, head_id, x, y, size in heads)
    write_text(path, _csv_text(("frame", "id", "x", "y", "head_size"), rows))


def write_intervals(path: Path, intervals: Iterable[Interval]) -> None:
    """Write intervals.csv (1-based inclusive info-less frames)."""
    rows = ((i.a + 2, i.b, i.kind) for i in intervals)
    write_text(path, _csv_text(("start", "end", "kind"), rows))


def write_meta(path: Path, meta: dict[str, Any]) -> None:
    """Write meta.json."""
    write_json(path, meta)

"""Readers for a run folder (DESIGN.md section 6) and for MOTChallenge text files.

A runs folder has one sub-folder per video name, holding:

* ``tracks.txt``: MOTChallenge text ``frame,id,left,top,width,height,conf,-1,-1,-1`` with 1-based
  frames; the tracked point is the box centre ``(left + w/2, top + h/2)``;
* ``frames.csv``: one row per frame, header
  ``frame,status,infoless_probability,infoless,n_detections,detections,ms_...``;
* ``gaps.json`` and ``summary.json`` (optional here; read and checked to be JSON; ``trackfw eval``
  first checks every run is complete with :func:`trackfw.outputs.check_complete_run`).

Every error is a :class:`trackfw.errors.UserError` that names the file, the line and the field.
Nothing is dropped silently: a bad value stops the evaluation with one sentence.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.errors import UserError

TRACKS_FILE = "tracks.txt"
FRAMES_FILE = "frames.csv"
GAPS_FILE = "gaps.json"
SUMMARY_FILE = "summary.json"

FRAMES_COLUMNS = (
    "frame",
    "status",
    "infoless_probability",
    "infoless",
    "n_detections",
    "detections",
)
FRAME_STATUSES = ("ok", "unreadable", "unread")
#: A MOTChallenge line needs at least frame, id, left, top, width, height.
MOT_MIN_COLUMNS = 6


@dataclass(frozen=True)
class MotRows:
    """The rows of a MOTChallenge text file.

    Attributes:
        frames: ``(R,)`` 1-based frame numbers, as in the file.
        ids: ``(R,)`` track or object ids.
        boxes: ``(R, 4)`` boxes ``(left, top, width, height)``.
        confidences: ``(R,)`` the 7th column, or 1 when the line has only six.
        lines: ``(R,)`` the 1-based line number of each row, for error messages.
    """

    frames: IntArray
    ids: IntArray
    boxes: FloatArray
    confidences: FloatArray
    lines: IntArray


def _integer(path: Path, line: int, column: str, text: str) -> int:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value != int(value):
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected an integer.")
    return int(value)


def _finite(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected a number.") from None
    if not math.isfinite(value):
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected a finite number.")
    return value


def read_mot_text(path: Path, n_frames: int | None = None) -> MotRows:
    """Read a MOTChallenge text file (``frame,id,left,top,width,height[,conf,...]``).

    Args:
        path: the file.
        n_frames: when given, frames must lie in ``1..n_frames``.

    Returns:
        The rows; a frame holding the same id twice is an error.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(
            f"{path}: file not found; expected MOTChallenge text (frame,id,left,top,w,h,...)."
        )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None
    # The vectorised reader handles well-formed files; any doubt goes to the line-by-line reader,
    # which names the offending line.
    rows = _parse_mot_fast(text, n_frames)
    return rows if rows is not None else _parse_mot_lines(path, text, n_frames)


def _parse_mot_fast(text: str, n_frames: int | None) -> MotRows | None:
    """All rows at once, or None when anything is off (then the slow reader explains it)."""
    numbered = [
        (number, raw) for number, raw in enumerate(text.splitlines(), start=1) if raw.strip()
    ]
    split = [raw.split(",") for _, raw in numbered]
    if any(len(values) < MOT_MIN_COLUMNS for values in split):
        return None
    try:
        table = np.asarray(
            [
                [*values[:MOT_MIN_COLUMNS], values[6] if len(values) > 6 else "1"]
                for values in split
            ],
            dtype=np.float64,
        ).reshape(-1, MOT_MIN_COLUMNS + 1)
    except ValueError:
        return None
    frames, ids = table[:, 0], table[:, 1]
    if (
        not np.isfinite(table).all()
        or (frames != np.round(frames)).any()
        or (ids != np.round(ids)).any()
    ):
        return None
    frame_numbers, track_ids = frames.astype(np.int64), ids.astype(np.int64)
    if len(frames) and (
        frame_numbers.min() < 1 or (n_frames is not None and frame_numbers.max() > n_frames)
    ):
        return None
    pairs = np.stack([frame_numbers, track_ids], axis=1)
    if len(np.unique(pairs, axis=0)) != len(pairs):
        return None
    return MotRows(
        frames=frame_numbers,
        ids=track_ids,
        boxes=table[:, 2:6].copy(),
        confidences=table[:, 6].copy(),
        lines=np.asarray([number for number, _ in numbered], dtype=np.int64),
    )


def _parse_mot_lines(path: Path, text: str, n_frames: int | None) -> MotRows:
    """Line-by-line reader that raises a UserError naming the first bad line."""
    names = ("frame", "id", "left", "top", "width", "height")
    frames: list[int] = []
    ids: list[int] = []
    boxes: list[tuple[float, float, float, float]] = []
    confidences: list[float] = []
    lines: list[int] = []
    seen: set[tuple[int, int]] = set()
    for line_number, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        values = [value.strip() for value in raw.split(",")]
        if len(values) < MOT_MIN_COLUMNS:
            raise UserError(
                f"{path}: line {line_number}: {len(values)} values; expected at least"
                f" {MOT_MIN_COLUMNS} ({','.join(names)},...)."
            )
        frame = _integer(path, line_number, "frame", values[0])
        track_id = _integer(path, line_number, "id", values[1])
        box = tuple(
            _finite(path, line_number, name, value)
            for name, value in zip(names[2:], values[2:6], strict=True)
        )
        if frame < 1 or (n_frames is not None and frame > n_frames):
            limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
            raise UserError(
                f"{path}: line {line_number}: frame {frame} is outside the video; expected {limit}."
            )
        if (frame, track_id) in seen:
            raise UserError(
                f"{path}: line {line_number}: id {track_id} appears twice in frame {frame}."
            )
        seen.add((frame, track_id))
        confidence = (
            _finite(path, line_number, "conf", values[6]) if len(values) > MOT_MIN_COLUMNS else 1.0
        )
        frames.append(frame)
        ids.append(track_id)
        boxes.append(box)  # type: ignore[arg-type]
        confidences.append(confidence)
        lines.append(line_number)
    return MotRows(
        frames=np.asarray(frames, dtype=np.int64),
        ids=np.asarray(ids, dtype=np.int64),
        boxes=np.asarray(boxes, dtype=np.float64).reshape(-1, 4),
        confidences=np.asarray(confidences, dtype=np.float64),
        lines=np.asarray(lines, dtype=np.int64),
    )


def rows_by_frame(
    rows: MotRows, geometry: str = "point", frame_offset: int = -1
) -> dict[int, dict[int, tuple[float, ...]]]:
    """Group MOT rows as ``{frame + frame_offset: {id: position}}``.

    Args:
        rows: rows from :func:`read_mot_text`.
        geometry: ``"point"`` gives the box centre ``(x, y)``; ``"box"`` the box itself.
        frame_offset: added to the file's frame number (-1 gives trackfw's 0-based frames).
    """
    if geometry == "point":
        positions = rows.boxes[:, :2] + rows.boxes[:, 2:] / 2.0
    elif geometry == "box":
        positions = rows.boxes
    else:
        raise ValueError(f"geometry is {geometry!r}; expected 'point' or 'box'.")
    grouped: dict[int, dict[int, tuple[float, ...]]] = {}
    for frame, track_id, position in zip(
        rows.frames.tolist(), rows.ids.tolist(), positions.tolist(), strict=True
    ):
        grouped.setdefault(frame + frame_offset, {})[track_id] = tuple(position)
    return grouped


@dataclass(frozen=True)
class FrameRecords:
    """The per-frame records of frames.csv.

    Attributes:
        frames: ``(F,)`` 0-based frame indices, increasing.
        status: per frame, ``ok``, ``unreadable`` or ``unread``.
        infoless_probability: ``(F,)`` probability, NaN where the file leaves it empty.
        infoless: ``(F,)`` the classifier's label.
        detections: per frame, ``(K, 2)`` detected head points.
    """

    frames: IntArray
    status: list[str]
    infoless_probability: FloatArray
    infoless: BoolArray
    detections: list[FloatArray]

    @property
    def ok(self) -> BoolArray:
        """``(F,)`` True where the frame was read and processed."""
        return np.asarray([status == "ok" for status in self.status], dtype=bool)


def _parse_detections(path: Path, line: int, text: str) -> FloatArray:
    if not text:
        return np.zeros((0, 2), dtype=np.float64)
    points = []
    for item in text.split(";"):
        parts = item.split()
        if len(parts) != 2:
            raise UserError(f"{path}: line {line}: detections item {item!r}; expected 'x y'.")
        points.append([_finite(path, line, "detections", part) for part in parts])
    return np.asarray(points, dtype=np.float64).reshape(-1, 2)


def read_frames_csv(path: Path, n_frames: int | None = None) -> FrameRecords:
    """Read a run's frames.csv (1-based frames in the file, 0-based in the result)."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: file not found; expected the run's per-frame records.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None
    reader = csv.reader(io.StringIO(text))
    header = [name.strip() for name in next(reader, [])]
    if tuple(header[: len(FRAMES_COLUMNS)]) != FRAMES_COLUMNS:
        raise UserError(
            f"{path}: line 1: header is {','.join(header)!r}; expected it to start with"
            f" {','.join(FRAMES_COLUMNS)!r}."
        )
    frames: list[int] = []
    statuses: list[str] = []
    probabilities: list[float] = []
    labels: list[bool] = []
    detections: list[FloatArray] = []
    seen: set[int] = set()
    for line, values in enumerate(reader, start=2):
        if not values or all(not value.strip() for value in values):
            continue
        if len(values) != len(header):
            raise UserError(
                f"{path}: line {line}: {len(values)} values; expected {len(header)} ({','.join(header)})."
            )
        row = dict(zip(header, (value.strip() for value in values), strict=True))
        frame = _integer(path, line, "frame", row["frame"])
        if frame < 1 or (n_frames is not None and frame > n_frames):
            limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
            raise UserError(
                f"{path}: line {line}: frame {frame} is outside the video; expected {limit}."
            )
        if frame in seen:
            raise UserError(f"{path}: line {line}: frame {frame} appears twice.")
        seen.add(frame)
        status = row["status"]
        if status not in FRAME_STATUSES:
            raise UserError(
                f"{path}: line {line}: status is {status!r}; expected one of {', '.join(FRAME_STATUSES)}."
            )
        probability = (
            math.nan
            if not row["infoless_probability"]
            else _finite(path, line, "infoless_probability", row["infoless_probability"])
        )
        label_text = row["infoless"]
        if label_text not in ("0", "1") and not (status != "ok" and label_text == ""):
            raise UserError(f"{path}: line {line}: infoless is {label_text!r}; expected 0 or 1.")
        points = _parse_detections(path, line, row["detections"])
        if row["n_detections"] != "":
            count = _integer(path, line, "n_detections", row["n_detections"])
            if count != len(points):
                raise UserError(
                    f"{path}: line {line}: n_detections is {count} but detections lists {len(points)} points."
                )
        frames.append(frame - 1)
        statuses.append(status)
        probabilities.append(probability)
        labels.append(label_text == "1")
        detections.append(points)
    order = np.argsort(np.asarray(frames, dtype=np.int64), kind="stable")
    return FrameRecords(
        frames=np.asarray(frames, dtype=np.int64)[order],
        status=[statuses[i] for i in order],
        infoless_probability=np.asarray(probabilities, dtype=np.float64)[order],
        infoless=np.asarray(labels, dtype=bool)[order],
        detections=[detections[i] for i in order],
    )


def read_json_file(path: Path) -> Any:
    """A JSON file's content, or a UserError naming the line of the syntax error."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise UserError(f"{path}: line {error.lineno}: invalid JSON ({error.msg}).") from None
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None


@dataclass(frozen=True)
class RunRecord:
    """What a run wrote for one video.

    Attributes:
        name: the video name (the sub-folder's name).
        path: the run's sub-folder.
        tracks: 0-based frame -> ``{track id: (x, y)}`` (box centres).
        frames: the per-frame records.
        gaps: gaps.json content, or None when absent.
        summary: summary.json content, or None when absent.
    """

    name: str
    path: Path
    tracks: dict[int, dict[int, tuple[float, ...]]]
    frames: FrameRecords
    gaps: Any
    summary: Any


def read_run(run_dir: Path, n_frames: int | None = None) -> RunRecord:
    """Read one video's run folder; tracks.txt and frames.csv are required."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise UserError(
            f"{run_dir}: no run for this video; expected a folder with {TRACKS_FILE} and {FRAMES_FILE}."
        )
    rows = read_mot_text(run_dir / TRACKS_FILE, n_frames)
    frames = read_frames_csv(run_dir / FRAMES_FILE, n_frames)
    gaps = read_json_file(run_dir / GAPS_FILE) if (run_dir / GAPS_FILE).is_file() else None
    summary = read_json_file(run_dir / SUMMARY_FILE) if (run_dir / SUMMARY_FILE).is_file() else None
    return RunRecord(
        name=run_dir.name,
        path=run_dir,
        tracks=rows_by_frame(rows, "point"),
        frames=frames,
        gaps=gaps,
        summary=summary,
    )

"""Readers for a run folder (DESIGN.md section 6); tracks.txt through :mod:`trackfw.formats.mot`.

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
from trackfw.formats import read_mot_text, rows_by_frame
from trackfw.formats.text import parse_finite, parse_integer

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
        points.append([parse_finite(path, line, "detections", part) for part in parts])
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
        frame = parse_integer(path, line, "frame", row["frame"])
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
            else parse_finite(path, line, "infoless_probability", row["infoless_probability"])
        )
        label_text = row["infoless"]
        if label_text not in ("0", "1") and not (status != "ok" and label_text == ""):
            raise UserError(f"{path}: line {line}: infoless is {label_text!r}; expected 0 or 1.")
        points = _parse_detections(path, line, row["detections"])
        if row["n_detections"] != "":
            count = parse_integer(path, line, "n_detections", row["n_detections"])
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

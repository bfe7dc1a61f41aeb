"""A video's annotation files: gt.csv, heads.csv and intervals.csv (one reader and writer each).

::

    <video>/gt.csv          frame,id,x,y              people of interest (1-based frames)
    <video>/heads.csv       frame,id,x,y,head_size    every visible head (optional)
    <video>/intervals.csv   start,end,kind            ground-truth info-less frames (inclusive)

Readers return 0-based frames and raise a :class:`trackfw.errors.UserError` naming the file, the
line and the field; writers write atomically with three decimals.
"""

from __future__ import annotations

import io
import itertools
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.atomic import write_text
from trackfw.errors import UserError
from trackfw.formats.text import check_frame, csv_text, parse_finite, parse_integer, read_csv_rows
from trackfw.records import Interval

GT_FILE = "gt.csv"
HEADS_FILE = "heads.csv"
INTERVALS_FILE = "intervals.csv"
GT_COLUMNS = ("frame", "id", "x", "y")
HEADS_COLUMNS = ("frame", "id", "x", "y", "head_size")
INTERVALS_COLUMNS = ("start", "end", "kind")

#: Interval kinds of the paper: (i) sky or building, (ii) another group, (iii) the walking path.
INTERVAL_KINDS = ("sky", "group", "path", "unknown")
#: Decimals of the coordinates in the written files.
DECIMALS = 3


def _rows(path: Path, columns: Sequence[str]) -> list[tuple[int, dict[str, str]]]:
    return read_csv_rows(path, columns)[1]


def _fast_table(path: Path, columns: Sequence[str], n_frames: int | None) -> FloatArray | None:
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
    table = _fast_table(path, GT_COLUMNS, n_frames)
    if table is not None and (table[:, 1] < 1).any():
        table = None  # the line-by-line reader names the line with a bad id
    if table is not None:
        keys = table[:, 0] * 1e9 + table[:, 1]
        if len(np.unique(keys)) == len(keys):
            fast: dict[int, dict[int, tuple[float, float]]] = {}
            for frame, target_id, x, y in table.tolist():
                fast.setdefault(int(frame) - 1, {})[int(target_id)] = (x, y)
            return fast
    targets: dict[int, dict[int, tuple[float, float]]] = {}
    for line, row in _rows(path, GT_COLUMNS):
        frame = parse_integer(path, line, "frame", row["frame"])
        target_id = parse_integer(path, line, "id", row["id"])
        if target_id < 1:
            raise UserError(
                f"{path}: line {line}: id {target_id} is not a positive integer; expected ids"
                " 1, 2, ... (they become the track ids of tracks.txt)."
            )
        x = parse_finite(path, line, "x", row["x"])
        y = parse_finite(path, line, "y", row["y"])
        check_frame(path, line, frame, n_frames)
        frame_targets = targets.setdefault(frame - 1, {})
        if target_id in frame_targets:
            raise UserError(f"{path}: line {line}: id {target_id} appears twice in frame {frame}.")
        frame_targets[target_id] = (x, y)
    return targets


def read_heads(path: Path, n_frames: int | None = None) -> dict[int, FloatArray]:
    """heads.csv as ``{0-based frame: (M, 3) array of x, y, head_size}``."""
    table = _fast_table(path, HEADS_COLUMNS, n_frames)
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
    for line, row in _rows(path, HEADS_COLUMNS):
        frame = parse_integer(path, line, "frame", row["frame"])
        check_frame(path, line, frame, n_frames)
        grouped.setdefault(frame - 1, []).append(
            (
                parse_finite(path, line, "x", row["x"]),
                parse_finite(path, line, "y", row["y"]),
                parse_finite(path, line, "head_size", row["head_size"]),
            )
        )
    return {frame: np.asarray(rows, dtype=np.float64) for frame, rows in grouped.items()}


def read_intervals(path: Path, n_frames: int | None = None) -> list[Interval]:
    """intervals.csv (inclusive 1-based info-less frames) as :class:`Interval` records."""
    intervals: list[Interval] = []
    for line, row in _rows(path, INTERVALS_COLUMNS):
        start = parse_integer(path, line, "start", row["start"])
        end = parse_integer(path, line, "end", row["end"])
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


def write_targets(path: Path, targets: dict[int, dict[int, tuple[float, float]]]) -> None:
    """Write gt.csv from ``{0-based frame: {id: (x, y)}}``."""
    rows = (
        (frame + 1, target_id, x, y)
        for frame in sorted(targets)
        for target_id, (x, y) in sorted(targets[frame].items())
    )
    write_text(path, csv_text(GT_COLUMNS, rows, DECIMALS))


def write_heads(path: Path, heads: Iterable[tuple[int, int, float, float, float]]) -> None:
    """Write heads.csv from ``(0-based frame, id, x, y, head_size)`` tuples."""
    rows = ((frame + 1, head_id, x, y, size) for frame, head_id, x, y, size in heads)
    write_text(path, csv_text(HEADS_COLUMNS, rows, DECIMALS))


def write_intervals(path: Path, intervals: Iterable[Interval]) -> None:
    """Write intervals.csv (1-based inclusive info-less frames)."""
    rows = ((i.a + 2, i.b, i.kind) for i in intervals)
    write_text(path, csv_text(INTERVALS_COLUMNS, rows, DECIMALS))


def write_annotations(
    folder: Path,
    targets: dict[int, dict[int, tuple[float, float]]],
    heads: Iterable[tuple[int, int, float, float, float]],
    intervals: Iterable[Interval],
) -> None:
    """Write a video's gt.csv, heads.csv and intervals.csv into ``folder`` (0-based frames in)."""
    write_targets(folder / GT_FILE, targets)
    write_heads(folder / HEADS_FILE, heads)
    write_intervals(folder / INTERVALS_FILE, intervals)

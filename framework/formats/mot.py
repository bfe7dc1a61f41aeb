"""MOTChallenge text: ground truth (gt.txt), detections (det.txt) and tracks (tracks.txt).

One box per line, 1-based frames, comma-separated::

    frame,id,left,top,width,height[,conf,...]

The layouts met in practice:

    MOT15 gt    frame,id,left,top,width,height,flag,wx,wy,wz          10 values, every row kept
    MOT16/17 gt frame,id,left,top,width,height,flag,class,visibility 9 values
    det         frame,-1,left,top,width,height,score,-1,-1,-1       (score may be any number)
    tracks      frame,id,left,top,width,height,1,-1,-1,-1            (what trackfw writes)

:func:`read_mot_text` reads any of them into :class:`MotRows`; :func:`read_mot_ground_truth`
applies the ground-truth rules on top (one layout per file, positive sizes, and in the MOT16/17
layout only the rows with flag 1 and class 1, pedestrians that count; MOT15 has no class column
and its 7th value is a confidence, so no row is dropped there); :func:`read_mot_detections`
accepts many rows per frame with the same id (det.txt ids are -1). :func:`mot_track_text` writes
tracks.

Every error is a :class:`trackfw.errors.UserError` that names the file, the line and the field.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.errors import UserError
from trackfw.formats.text import check_frame, read_text

#: The leading columns every MOTChallenge line has.
MOT_COLUMNS = ("frame", "id", "left", "top", "width", "height")
#: A line needs at least these values (frame, id and the box).
MOT_MIN_COLUMNS = len(MOT_COLUMNS)
#: The widest layout (MOT15 ground truth and det files); values beyond it are not read.
MOT_MAX_COLUMNS = 10
_EXPECTED = "MOTChallenge text (frame,id,left,top,width,height,...)"


@dataclass(frozen=True)
class MotRows:
    """The rows of a MOTChallenge text file, in file order.

    Attributes:
        frames: ``(R,)`` 1-based frame numbers, as in the file.
        ids: ``(R,)`` track or object ids.
        boxes: ``(R, 4)`` boxes ``(left, top, width, height)``.
        confidences: ``(R,)`` the 7th value (confidence, score or flag), 1 where a line has six.
        extra: ``(R, 3)`` the 8th to 10th values, NaN where a line is shorter.
        n_values: ``(R,)`` how many values each line has.
        lines: ``(R,)`` the 1-based line number of each row, for error messages.
    """

    frames: IntArray
    ids: IntArray
    boxes: FloatArray
    confidences: FloatArray
    extra: FloatArray
    n_values: IntArray
    lines: IntArray

    def __len__(self) -> int:
        return len(self.frames)

    def select(self, keep: BoolArray | IntArray) -> MotRows:
        """The rows picked by a boolean mask or an index array."""
        return MotRows(
            frames=self.frames[keep],
            ids=self.ids[keep],
            boxes=self.boxes[keep],
            confidences=self.confidences[keep],
            extra=self.extra[keep],
            n_values=self.n_values[keep],
            lines=self.lines[keep],
        )


def read_mot_text(path: Path, n_frames: int | None = None, unique_ids: bool = True) -> MotRows:
    """Read a MOTChallenge text file, any layout.

    Args:
        path: the file.
        n_frames: when given, frames must lie in ``1..n_frames``.
        unique_ids: an id twice in one frame is an error (tracks and ground truth; not det.txt).

    Returns:
        Every row, in file order.
    """
    path = Path(path)
    numbered = [
        (number, raw)
        for number, raw in enumerate(read_text(path, _EXPECTED).splitlines(), start=1)
        if raw.strip()
    ]
    split = [raw.split(",") for _, raw in numbered]
    lines = np.asarray([number for number, _ in numbered], dtype=np.int64)
    n_values = np.asarray([len(values) for values in split], dtype=np.int64)
    short = np.flatnonzero(n_values < MOT_MIN_COLUMNS)
    if len(short):
        index = int(short[0])
        raise UserError(
            f"{path}: line {lines[index]}: {n_values[index]} values; expected at least"
            f" {MOT_MIN_COLUMNS} ({','.join(MOT_COLUMNS)},...)."
        )
    table = _numeric_table(path, split, lines)
    _check_values(path, table, split, lines, n_values, n_frames)
    rows = MotRows(
        frames=table[:, 0].astype(np.int64),
        ids=table[:, 1].astype(np.int64),
        boxes=table[:, 2:6].copy(),
        confidences=np.where(n_values > MOT_MIN_COLUMNS, table[:, 6], 1.0),
        extra=table[:, 7:MOT_MAX_COLUMNS].copy(),
        n_values=n_values,
        lines=lines,
    )
    if unique_ids:
        check_unique_ids(path, rows)
    return rows


def _numeric_table(path: Path, split: list[list[str]], lines: IntArray) -> FloatArray:
    """``(R, 10)`` values, NaN past each line's end; a value that is no number names its line."""
    width = MOT_MAX_COLUMNS
    padded = [values[:width] + ["nan"] * (width - len(values)) for values in split]
    try:
        return np.asarray(padded, dtype=np.float64).reshape(-1, width)
    except ValueError:
        pass
    # Only on a bad file: find the first value that is no number, to name it.
    names = (*MOT_COLUMNS, "conf", "column 8", "column 9", "column 10")
    for line, values in zip(lines.tolist(), split, strict=True):
        for name, text in zip(names, values[:width], strict=False):
            try:
                float(text)
            except ValueError:
                raise UserError(
                    f"{path}: line {line}: {name} is {text.strip()!r}; expected a number."
                ) from None
    raise AssertionError("unreachable: numpy refused a table whose values all parse")


def _check_values(
    path: Path,
    table: FloatArray,
    split: list[list[str]],
    lines: IntArray,
    n_values: IntArray,
    n_frames: int | None,
) -> None:
    """Integer frames and ids, finite boxes (and 7th values), frames inside the video."""
    checks = [
        (0, "an integer", ~np.isfinite(table[:, 0]) | (table[:, 0] != np.round(table[:, 0]))),
        (1, "an integer", ~np.isfinite(table[:, 1]) | (table[:, 1] != np.round(table[:, 1]))),
        *((column, "a finite number", ~np.isfinite(table[:, column])) for column in range(2, 6)),
        (6, "a finite number", (n_values > MOT_MIN_COLUMNS) & ~np.isfinite(table[:, 6])),
    ]
    names = (*MOT_COLUMNS, "conf")
    for column, expected, bad in checks:
        if bad.any():
            index = int(np.flatnonzero(bad)[0])
            text = split[index][column].strip()
            raise UserError(
                f"{path}: line {lines[index]}: {names[column]} is {text!r}; expected {expected}."
            )
    frames = table[:, 0]
    outside = frames < 1
    if n_frames is not None:
        outside |= frames > n_frames
    if outside.any():
        index = int(np.flatnonzero(outside)[0])
        check_frame(path, int(lines[index]), int(frames[index]), n_frames)


def check_unique_ids(path: Path, rows: MotRows) -> None:
    """An id may appear once per frame; the error names the line of its second appearance."""
    if len(rows) == 0:
        return
    pairs = np.stack([rows.frames, rows.ids], axis=1)
    _, first = np.unique(pairs, axis=0, return_index=True)
    if len(first) == len(pairs):
        return
    repeated = np.ones(len(pairs), dtype=bool)
    repeated[first] = False
    index = int(np.flatnonzero(repeated)[0])
    raise UserError(
        f"{path}: line {rows.lines[index]}: id {rows.ids[index]} appears twice in frame"
        f" {rows.frames[index]}."
    )


def read_mot_ground_truth(path: Path, n_frames: int | None = None) -> MotRows:
    """Read a MOTChallenge ``gt.txt`` and keep the boxes that count (see the module docstring).

    Args:
        path: the file.
        n_frames: number of frames of the sequence; rows beyond it are errors when given.

    Returns:
        The kept rows, in file order.

    Raises:
        UserError: a malformed line (naming the file and the line), a layout change within the
            file, a box without a positive size, or an id twice in a frame among the kept rows.
    """
    path = Path(path)
    rows = read_mot_text(path, n_frames, unique_ids=False)
    if len(rows) == 0:
        return rows
    layout = int(rows.n_values[0])
    if layout > MOT_MAX_COLUMNS:
        raise UserError(
            f"{path}: line {rows.lines[0]}: {layout} values; expected {MOT_MIN_COLUMNS} to"
            f" {MOT_MAX_COLUMNS} ({','.join(MOT_COLUMNS)},...)."
        )
    other = np.flatnonzero(rows.n_values != layout)
    if len(other):
        index = int(other[0])
        raise UserError(
            f"{path}: line {rows.lines[index]}: {rows.n_values[index]} values; expected"
            f" {layout} like the first line."
        )
    empty = np.flatnonzero((rows.boxes[:, 2] <= 0) | (rows.boxes[:, 3] <= 0))
    if len(empty):
        index = int(empty[0])
        width, height = rows.boxes[index, 2:]
        raise UserError(
            f"{path}: line {rows.lines[index]}: box {width:g}x{height:g}; expected a positive size."
        )
    keep = np.ones(len(rows), dtype=bool)
    if layout in (7, 8, 9):  # MOT16/17: flag (consider the box) ...
        keep &= rows.confidences == 1
    if layout in (8, 9):  # ... then the class (1 = pedestrian)
        keep &= rows.extra[:, 0] == 1
    kept = rows.select(keep)
    check_unique_ids(path, kept)
    return kept


def read_mot_detections(path: Path, n_frames: int | None = None) -> MotRows:
    """Read a MOTChallenge ``det.txt``: many rows per frame may share an id (-1)."""
    return read_mot_text(path, n_frames, unique_ids=False)


def rows_by_frame(
    rows: MotRows, geometry: str = "point", frame_offset: int = -1
) -> dict[int, dict[int, tuple[float, ...]]]:
    """Group rows as ``{frame + frame_offset: {id: position}}``.

    Args:
        rows: rows from a reader of this module.
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


def boxes_by_frame(rows: MotRows, sort_ids: bool = True) -> dict[int, FloatArray]:
    """``{0-based frame: (M, 5) rows id, left, top, width, height}``.

    Args:
        rows: rows from a reader of this module.
        sort_ids: sort each frame's rows by id; else keep the file's order.
    """
    grouped: dict[int, FloatArray] = {}
    for frame, indices in _frame_groups(rows).items():
        order = indices[np.argsort(rows.ids[indices], kind="stable")] if sort_ids else indices
        grouped[frame] = np.concatenate(
            [rows.ids[order, None].astype(np.float64), rows.boxes[order]], axis=1
        )
    return grouped


def detections_by_frame(rows: MotRows) -> dict[int, tuple[FloatArray, FloatArray]]:
    """``{0-based frame: ((N, 4) boxes, (N,) raw scores)}`` in file order within each frame."""
    return {
        frame: (rows.boxes[indices].copy(), rows.confidences[indices].copy())
        for frame, indices in _frame_groups(rows).items()
    }


def _frame_groups(rows: MotRows) -> dict[int, IntArray]:
    """0-based frame -> row indices, frames in increasing order, rows in file order."""
    order = np.argsort(rows.frames, kind="stable")
    frames = rows.frames[order]
    if len(frames) == 0:
        return {}
    starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
    ends = np.r_[starts[1:], len(frames)]
    return {
        int(frames[start]) - 1: order[start:end]
        for start, end in zip(starts.tolist(), ends.tolist(), strict=True)
    }


def mot_track_text(rows: Iterable[tuple[int, int, float, float]], box_size: float) -> str:
    """tracks.txt: one square box of side ``box_size`` around each tracked point.

    Args:
        rows: ``(0-based frame, id, x, y)``, in any order; written sorted by frame, then id.
        box_size: side of the box in pixels.

    Returns:
        Lines ``frame,id,left,top,width,height,1,-1,-1,-1`` (1-based frames, left and top with
        two decimals, the size in its shortest form).
    """
    half = box_size / 2.0
    lines = [
        f"{t + 1},{target_id},{x - half:.2f},{y - half:.2f},{box_size:g},{box_size:g},1,-1,-1,-1"
        for t, target_id, x, y in sorted(rows, key=lambda row: (row[0], row[1]))
    ]
    return "\n".join(lines) + ("\n" if lines else "")

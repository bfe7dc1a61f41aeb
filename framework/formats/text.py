"""What every reader of :mod:`trackfw.formats` shares: text, numbers, JSON and headed CSV.

Each error is a :class:`trackfw.errors.UserError` with one sentence that names the file, the line
and the field, and says what was expected.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.errors import UserError


def read_text(path: Path, expected: str) -> str:
    """The UTF-8 text of ``path``.

    Args:
        path: the file.
        expected: what the file should be, for the message when it is missing
            (e.g. ``"MOTChallenge text (frame,id,left,top,w,h,...)"``).
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: file not found; expected {expected}.")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None


def parse_integer(path: Path, line: int, column: str, text: str) -> int:
    """``text`` as an integer (``3`` or ``3.0``), else an error naming file, line and column."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value != int(value):
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected an integer.")
    return int(value)


def parse_finite(path: Path, line: int, column: str, text: str) -> float:
    """``text`` as a finite number, else an error naming file, line and column."""
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected a number.") from None
    if not math.isfinite(value):
        raise UserError(f"{path}: line {line}: {column} is {text!r}; expected a finite number.")
    return value


def check_frame(path: Path, line: int, frame: int, n_frames: int | None) -> None:
    """A 1-based frame number must lie in ``1..n_frames`` (``>= 1`` when the length is unknown)."""
    if frame < 1 or (n_frames is not None and frame > n_frames):
        limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
        raise UserError(
            f"{path}: line {line}: frame {frame} is outside the video; expected {limit}."
        )


def read_json(path: Path, expected: str = "a JSON file") -> Any:
    """A JSON file's content; a missing file or a syntax error names the file (and line)."""
    text = read_text(path, expected)
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise UserError(f"{path}: line {error.lineno}: invalid JSON ({error.msg}).") from None


def read_csv_rows(
    path: Path, columns: Sequence[str], expected: str | None = None
) -> tuple[list[str], list[tuple[int, dict[str, str]]]]:
    """Rows of a CSV whose header starts with ``columns``.

    Args:
        path: the file.
        columns: the leading header names, in order.
        expected: what the file should be, for the message when it is missing.

    Returns:
        The header and the non-blank rows as ``(1-based line number, {column: stripped value})``.
    """
    text = read_text(path, expected or f"a CSV file with the header {','.join(columns)}")
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None:
        raise UserError(f"{path}: empty file; expected the header {','.join(columns)}.")
    header = [name.strip() for name in header]
    if header[: len(columns)] != list(columns):
        raise UserError(
            f"{path}: line 1: header is {','.join(header)!r}; expected it to start with"
            f" {','.join(columns)!r}."
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
    return header, rows


def csv_text(header: Sequence[str], rows: Iterable[Sequence[Any]], decimals: int | None) -> str:
    """CSV text with a header line; floats get ``decimals`` places (None: as given)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow(row if decimals is None else [_fixed(value, decimals) for value in row])
    return buffer.getvalue()


def _fixed(value: Any, decimals: int) -> Any:
    if isinstance(value, float | np.floating):
        return f"{float(value):.{decimals}f}"
    return value

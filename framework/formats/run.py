"""Run files: what ``trackfw run`` writes per video, and the one reader of them.

A runs folder has one sub-folder per video name, holding (frames are 1-based in every file):

* ``tracks.txt``: MOTChallenge text ``frame,id,left,top,width,height,1,-1,-1,-1``, a square of
  side ``engine.box_size`` around each tracked point (:func:`trackfw.formats.mot.mot_track_text`);
  the point is read back as the box centre ``(left + w/2, top + h/2)``. The fixed square is the
  MOT-text output's convention only (the paper's 80 px head at 1080p): ``trackfw render`` draws
  each detection's own size;
* ``frames.csv``: one row per frame, columns :data:`FRAMES_COLUMNS`, ``detection_sizes`` (each
  detection's box ``width height``, in the order of ``detections``; empty when the detector gives
  no boxes), the targets per lifecycle state (:data:`TARGET_STATE_COLUMNS`: ``n_tracked``,
  ``n_lost``, ``n_out_of_view``, ``n_tentative``; empty where the frame was not tracked), then
  ``ms_<stage>`` per stage kind (:func:`frames_header`);
* ``gaps.json``: one entry per interval (frames a and b, the chosen candidate, matches, positions);
* ``summary.json``: the pipeline, counts and timings. It is written last, so its presence marks a
  complete run (:func:`check_complete_run`).

Every file is written atomically; every reader error is a :class:`trackfw.errors.UserError` that
names the file, the line and the field. Nothing is dropped silently.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from trackfw import __version__
from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.atomic import write_json, write_text
from trackfw.errors import UserError
from trackfw.formats.mot import mot_track_text, read_mot_text, rows_by_frame
from trackfw.formats.text import (
    check_frame,
    parse_finite,
    parse_integer,
    read_csv_rows,
    read_json,
)
from trackfw.records import TARGET_STATES
from trackfw.stages import STAGE_KINDS

if TYPE_CHECKING:
    from trackfw.engine import FrameRecord, VideoRun
    from trackfw.pipeline import Pipeline

TRACKS_FILE = "tracks.txt"
FRAMES_FILE = "frames.csv"
GAPS_FILE = "gaps.json"
SUMMARY_FILE = "summary.json"
#: The files of one video's run, in the order they are written (summary.json last).
RUN_FILES = (TRACKS_FILE, FRAMES_FILE, GAPS_FILE, SUMMARY_FILE)
#: The leading columns of frames.csv; one ``ms_<stage>`` column per stage kind follows.
FRAMES_COLUMNS = (
    "frame",
    "status",
    "infoless_probability",
    "infoless",
    "n_detections",
    "detections",
)
FRAME_STATUSES = ("ok", "unreadable", "unread")
#: Optional column (runs written before it lack it): ``width height`` per detection.
DETECTION_SIZES_COLUMN = "detection_sizes"
#: Optional columns (runs written before them lack them): targets per lifecycle state, in the
#: order of :data:`trackfw.records.TARGET_STATES`.
TARGET_STATE_COLUMNS = tuple(f"n_{state.replace('-', '_')}" for state in TARGET_STATES)


def frames_header() -> tuple[str, ...]:
    """Every column of frames.csv: :data:`FRAMES_COLUMNS`, the detection sizes, the target
    states, the stage times."""
    return (
        *FRAMES_COLUMNS,
        DETECTION_SIZES_COLUMN,
        *TARGET_STATE_COLUMNS,
        *(f"ms_{kind}" for kind in STAGE_KINDS),
    )


# --------------------------------------------------------------------------------------- writing


def tracks_text(run: VideoRun, box_size: float) -> str:
    """tracks.txt content: MOTChallenge rows, a ``box_size`` square around each tracked point."""
    return mot_track_text(run.tracks, box_size)


def _frame_row(record: FrameRecord) -> list[Any]:
    detections = record.detections
    points = (
        "" if detections is None else ";".join(f"{x:.1f} {y:.1f}" for x, y in detections.points)
    )
    sizes = (
        ""
        if detections is None or detections.boxes is None
        else ";".join(f"{w:.1f} {h:.1f}" for w, h in detections.boxes[:, 2:4])
    )
    return [
        record.t + 1,
        record.status,
        "" if record.probability is None else f"{record.probability:.4f}",
        "" if record.infoless is None else int(record.infoless),
        "" if detections is None else len(detections),
        points,
        sizes,
        *(record.target_states.get(state, "") for state in TARGET_STATES),
        *(
            f"{record.milliseconds[kind]:.3f}" if kind in record.milliseconds else ""
            for kind in STAGE_KINDS
        ),
    ]


def frames_text(run: VideoRun) -> str:
    """frames.csv content."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(frames_header())
    for record in run.frames:
        writer.writerow(_frame_row(record))
    return buffer.getvalue()


def gaps_data(run: VideoRun) -> list[dict[str, Any]]:
    """gaps.json content: frames are 1-based like every other file."""
    entries = []
    for gap in run.gaps:
        entry: dict[str, Any] = {
            "a": gap.interval.a + 1,
            "b": gap.interval.b + 1 if gap.resolved else None,
            "horizon": gap.interval.horizon,
            "resolved": gap.resolved,
            "chosen": gap.chosen,
            "cost": gap.cost,
            "matches": {
                str(target_id): detection
                for target_id, detection in zip(gap.target_ids, gap.matched_detection, strict=False)
            },
            "positions": {
                str(target_id): position
                for target_id, position in zip(gap.target_ids, gap.positions, strict=False)
            },
            "milliseconds": round(gap.milliseconds, 3),
            "diagnostics": gap.diagnostics,
        }
        if gap.at_b:
            entry["at_b"] = {
                str(target_id): outcome for target_id, outcome in sorted(gap.at_b.items())
            }
        entries.append(entry)
    return entries


def unread_warning(run: VideoRun) -> str | None:
    """One line saying how many frames of the video could not be read, or None when all were.

    A truncated or corrupt file still runs (the frames after the break are marked ``unread`` in
    frames.csv), but its results cover only part of the video, which the user must be told.
    """
    statuses = [record.status for record in run.frames]
    unread, unreadable = statuses.count("unread"), statuses.count("unreadable")
    if unread + unreadable == 0:
        return None
    causes = []
    if unread:
        last = len(statuses) - unread
        causes.append(f"the frames stop after frame {last}: a truncated or corrupt file")
    if unreadable:
        causes.append(f"{unreadable} failed to decode")
    return (
        f"{run.video.path}: {unread + unreadable} of {len(statuses)} frames could not be read"
        f" ({'; '.join(causes)}); they are marked in {FRAMES_FILE} and were not tracked."
    )


def finite_json(value: Any) -> Any:
    """``value`` with every non-finite float (``inf``, ``nan``) replaced by None, recursively.

    >>> finite_json({"cost": float("inf"), "costs": [1.0, float("nan")]})
    {'cost': None, 'costs': [1.0, None]}
    """
    if hasattr(value, "tolist") and not isinstance(value, float):
        value = value.tolist()  # numpy scalars and arrays from diagnostics
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_json(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [finite_json(item) for item in value]
    return value


def summary_data(run: VideoRun, pipeline: Pipeline) -> dict[str, Any]:
    """summary.json content."""
    statuses = [record.status for record in run.frames]
    warning = unread_warning(run)
    stage_means = {}
    for kind in STAGE_KINDS:
        values = [r.milliseconds[kind] for r in run.frames if kind in r.milliseconds]
        stage_means[kind] = round(sum(values) / len(values), 4) if values else None
    return {
        "trackfw_version": __version__,
        "pipeline": pipeline.name,
        "pipeline_hash": pipeline.content_hash,
        "pipeline_file": None if pipeline.source is None else str(pipeline.source),
        "config": pipeline.config,
        "video": run.video.name,
        "video_path": run.video.path,
        "n_frames": run.video.n_frames,
        "frames_ok": statuses.count("ok"),
        "frames_unreadable": statuses.count("unreadable"),
        "frames_unread": statuses.count("unread"),
        "frames_not_read": statuses.count("unreadable") + statuses.count("unread"),
        "frames_infoless": sum(1 for r in run.frames if r.infoless),
        "intervals": len(run.gaps),
        "targets": run.target_ids,
        "initialised_from": run.initialised_from,
        "seconds": round(run.seconds, 4),
        "frames_per_second": round(run.frames_per_second, 2),
        "ms_per_frame": stage_means,
        "warnings": [] if warning is None else [warning],
    }


def write_run(run: VideoRun, pipeline: Pipeline, directory: Path) -> Path:
    """Write the four files of one video run into ``directory``; returns it."""
    directory.mkdir(parents=True, exist_ok=True)
    # summary.json marks completion: drop a stale one first so a crash midway cannot leave an old
    # summary beside new partial files.
    (directory / SUMMARY_FILE).unlink(missing_ok=True)
    write_text(directory / TRACKS_FILE, tracks_text(run, pipeline.engine.box_size))
    write_text(directory / FRAMES_FILE, frames_text(run))
    # Readers of JSON refuse Infinity and NaN: undefined values are null.
    write_json(directory / GAPS_FILE, finite_json(gaps_data(run)), allow_nan=False)
    write_json(directory / SUMMARY_FILE, finite_json(summary_data(run, pipeline)), allow_nan=False)
    return directory


# --------------------------------------------------------------------------------------- reading


def check_complete_run(run_dir: Path, n_frames: int | None = None) -> dict[str, Any]:
    """summary.json of the complete run in ``run_dir``; a UserError naming the video otherwise.

    A run is complete when its summary.json (written last) is there and its frames.csv holds a
    row per frame: a killed run lacks the first, a file cut short after the run (a full disk, an
    interrupted copy) the second. Every command that reads a run folder checks it this way.

    Args:
        run_dir: one video's run folder.
        n_frames: frames the video has (the dataset's count); default summary.json's ``n_frames``.

    Returns:
        summary.json's content.
    """
    run_dir = Path(run_dir)
    video = run_dir.name
    path = run_dir / SUMMARY_FILE
    if not path.is_file():
        raise UserError(
            f"{path}: missing, so the run of video {video!r} is incomplete ({SUMMARY_FILE} is"
            " written last; the run was interrupted); expected a complete run: run it again."
        )
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as error:
        raise UserError(
            f"{path}: not valid JSON ({str(error)[:80]}); expected the {SUMMARY_FILE} of a"
            f" complete run of video {video!r}."
        ) from None
    if not isinstance(summary, dict):
        raise UserError(f"{path}: expected a JSON object (the run of video {video!r}).")
    expected = n_frames if n_frames is not None else summary.get("n_frames")
    frames = run_dir / FRAMES_FILE
    if not frames.is_file():
        raise UserError(
            f"{frames}: missing; expected a row per frame of video {video!r} (run it again)."
        )
    if isinstance(expected, int) and not isinstance(expected, bool):
        try:
            with frames.open(encoding="utf-8", newline="") as stream:
                rows = sum(1 for row in csv.reader(stream) if any(v.strip() for v in row)) - 1
        except (UnicodeDecodeError, csv.Error):
            rows = -1  # the reader that parses the file names the bad line
        if 0 <= rows < expected:
            raise UserError(
                f"{frames}: cut short, {rows} of {expected} frame rows of video {video!r};"
                " expected a complete run: run it again."
            )
    return summary


@dataclass(frozen=True)
class FrameRecords:
    """The per-frame records of frames.csv.

    Attributes:
        frames: ``(F,)`` 0-based frame indices, increasing.
        status: per frame, ``ok``, ``unreadable`` or ``unread``.
        infoless_probability: ``(F,)`` probability, NaN where the file leaves it empty.
        infoless: ``(F,)`` the classifier's label.
        detections: per frame, ``(K, 2)`` detected head points.
        detection_sizes: per frame, ``(K, 2)`` each detection's box ``(width, height)``; NaN
            where the detector gave no boxes (or the run predates the column).
    """

    frames: IntArray
    status: list[str]
    infoless_probability: FloatArray
    infoless: BoolArray
    detections: list[FloatArray]
    detection_sizes: list[FloatArray]

    @property
    def ok(self) -> BoolArray:
        """``(F,)`` True where the frame was read and processed."""
        return np.asarray([status == "ok" for status in self.status], dtype=bool)


def _parse_detections(
    path: Path, line: int, text: str, column: str = "detections", expected: str = "x y"
) -> FloatArray:
    """``(K, 2)`` pairs from ``"a b;a b;..."``."""
    if not text:
        return np.zeros((0, 2), dtype=np.float64)
    points = []
    for item in text.split(";"):
        parts = item.split()
        if len(parts) != 2:
            raise UserError(f"{path}: line {line}: {column} item {item!r}; expected '{expected}'.")
        points.append([parse_finite(path, line, column, part) for part in parts])
    return np.asarray(points, dtype=np.float64).reshape(-1, 2)


def _parse_sizes(path: Path, line: int, text: str, count: int) -> FloatArray:
    """``(count, 2)`` box sizes; NaN when the row has none."""
    if not text:
        return np.full((count, 2), np.nan)
    sizes = _parse_detections(path, line, text, DETECTION_SIZES_COLUMN, "width height")
    if len(sizes) != count:
        raise UserError(
            f"{path}: line {line}: {DETECTION_SIZES_COLUMN} lists {len(sizes)} sizes; expected"
            f" one per detection ({count})."
        )
    if (sizes <= 0).any():
        raise UserError(
            f"{path}: line {line}: {DETECTION_SIZES_COLUMN}: expected positive widths and heights."
        )
    return sizes


def read_frames_csv(path: Path, n_frames: int | None = None) -> FrameRecords:
    """Read a run's frames.csv (1-based frames in the file, 0-based in the result)."""
    path = Path(path)
    _, rows = read_csv_rows(path, FRAMES_COLUMNS, "the run's per-frame records")
    parsed: list[tuple[int, str, float, bool, FloatArray, FloatArray]] = []
    seen: set[int] = set()
    for line, row in rows:
        frame = parse_integer(path, line, "frame", row["frame"])
        check_frame(path, line, frame, n_frames)
        if frame in seen:
            raise UserError(f"{path}: line {line}: frame {frame} appears twice.")
        seen.add(frame)
        parsed.append((frame - 1, *_frame_values(path, line, row)))
    parsed.sort(key=lambda values: values[0])
    return FrameRecords(
        frames=np.asarray([values[0] for values in parsed], dtype=np.int64),
        status=[values[1] for values in parsed],
        infoless_probability=np.asarray([values[2] for values in parsed], dtype=np.float64),
        infoless=np.asarray([values[3] for values in parsed], dtype=bool),
        detections=[values[4] for values in parsed],
        detection_sizes=[values[5] for values in parsed],
    )


def _frame_values(
    path: Path, line: int, row: dict[str, str]
) -> tuple[str, float, bool, FloatArray, FloatArray]:
    """Status, info-less probability and label, ``(K, 2)`` points and ``(K,)`` sizes of a row."""
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
    sizes = _parse_sizes(path, line, row.get(DETECTION_SIZES_COLUMN, ""), len(points))
    return status, probability, label_text == "1", points, sizes


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
    gaps = read_json(run_dir / GAPS_FILE) if (run_dir / GAPS_FILE).is_file() else None
    summary = read_json(run_dir / SUMMARY_FILE) if (run_dir / SUMMARY_FILE).is_file() else None
    return RunRecord(
        name=run_dir.name,
        path=run_dir,
        tracks=rows_by_frame(rows, "point"),
        frames=frames,
        gaps=gaps,
        summary=summary,
    )

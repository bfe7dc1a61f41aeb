"""Run outputs on disk (DESIGN.md section 6), each file written atomically.

Per video: ``tracks.txt`` (MOTChallenge text), ``frames.csv`` (per-frame decisions, detections
and stage timings), ``gaps.json`` (one entry per interval) and ``summary.json``. summary.json is
written last, so its presence marks a complete run.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

from trackfw import __version__
from trackfw.atomic import write_json, write_text
from trackfw.engine import FrameRecord, VideoRun
from trackfw.errors import UserError
from trackfw.pipeline import Pipeline
from trackfw.stages import STAGE_KINDS

TRACKS_FILE = "tracks.txt"
FRAMES_FILE = "frames.csv"
GAPS_FILE = "gaps.json"
SUMMARY_FILE = "summary.json"
FRAMES_HEADER = (
    "frame",
    "status",
    "infoless_probability",
    "infoless",
    "n_detections",
    "detections",
    *(f"ms_{kind}" for kind in STAGE_KINDS),
)


def tracks_text(run: VideoRun, box_size: float) -> str:
    """MOTChallenge rows ``frame,id,left,top,width,height,conf,-1,-1,-1`` (1-based frames)."""
    half = box_size / 2.0
    lines = [
        f"{t + 1},{target_id},{x - half:.2f},{y - half:.2f},{box_size:g},{box_size:g},1,-1,-1,-1"
        for t, target_id, x, y in sorted(run.tracks, key=lambda row: (row[0], row[1]))
    ]
    return "\n".join(lines) + ("\n" if lines else "")


def _frame_row(record: FrameRecord) -> list[Any]:
    detections = record.detections
    points = (
        "" if detections is None else ";".join(f"{x:.1f} {y:.1f}" for x, y in detections.points)
    )
    return [
        record.t + 1,
        record.status,
        "" if record.probability is None else f"{record.probability:.4f}",
        "" if record.infoless is None else int(record.infoless),
        "" if detections is None else len(detections),
        points,
        *(
            f"{record.milliseconds[kind]:.3f}" if kind in record.milliseconds else ""
            for kind in STAGE_KINDS
        ),
    ]


def frames_text(run: VideoRun) -> str:
    """frames.csv content."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(FRAMES_HEADER)
    for record in run.frames:
        writer.writerow(_frame_row(record))
    return buffer.getvalue()


def gaps_data(run: VideoRun) -> list[dict[str, Any]]:
    """gaps.json content: frames are 1-based like every other file."""
    entries = []
    for gap in run.gaps:
        entries.append(
            {
                "a": gap.interval.a + 1,
                "b": gap.interval.b + 1 if gap.resolved else None,
                "horizon": gap.interval.horizon,
                "resolved": gap.resolved,
                "chosen": gap.chosen,
                "cost": gap.cost,
                "matches": {
                    str(target_id): detection
                    for target_id, detection in zip(
                        gap.target_ids, gap.matched_detection, strict=False
                    )
                },
                "positions": {
                    str(target_id): position
                    for target_id, position in zip(gap.target_ids, gap.positions, strict=False)
                },
                "milliseconds": round(gap.milliseconds, 3),
                "diagnostics": gap.diagnostics,
            }
        )
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
    write_json(directory / GAPS_FILE, gaps_data(run))
    write_json(directory / SUMMARY_FILE, summary_data(run, pipeline))
    return directory


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

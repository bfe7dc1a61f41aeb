"""``trackfw dataset check``: validate a dataset folder and print its statistics.

Every video folder is checked for: frames present and as many as meta.json's ``n_frames`` (and of
its size); meta.json, gt.csv, heads.csv, intervals.csv and poses.csv well formed (header, number
of values, integers, finite numbers); frames inside the video; no id twice in a frame; intervals
inside the video, of a known kind, neither overlapping nor touching; every gt id present on frame
1 (which defines the targets); gt points inside the image and never on an info-less frame.

All problems are collected, one line each naming the file (and the line) and what was expected.
The files are also read with the :mod:`trackfw.dataset` readers, so that whatever the pipeline
would refuse is reported here too.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import typer

from trackfw.dataset import (
    IMAGE_SUFFIXES,
    META_FILE,
    POSES_FILE,
    frame_source_path,
    list_videos,
    read_meta,
)
from trackfw.errors import UserError
from trackfw.formats.annotations import (
    GT_FILE,
    HEADS_FILE,
    INTERVAL_KINDS,
    INTERVALS_FILE,
    read_heads,
    read_intervals,
    read_targets,
)
from trackfw.records import VideoContext
from trackfw.video_io import check_frame_sizes, probe_container

POSE_COLUMNS = ("frame", "pan", "tilt", "roll", "scale", "tx", "ty")
#: Tolerance (pixels) for a gt point on the image border.
BORDER_TOLERANCE = 0.5


@dataclass
class DatasetReport:
    """Outcome of :func:`check_dataset`.

    Attributes:
        problems: one line per problem, naming the file (and line) and what was expected.
        stats: ``videos``, ``frames`` (total/min/max), ``intervals`` (count and length
            min/mean/max, overall and per kind), ``targets_per_video`` and ``heads_per_frame``
            (min/mean/max).
    """

    problems: list[str] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when no problem was found."""
        return not self.problems


Row = dict[str, float]


def _scan_csv(
    path: Path,
    columns: Sequence[str],
    integer_columns: Sequence[str],
    problems: list[str],
) -> list[tuple[int, Row, dict[str, str]]]:
    """Rows of a CSV whose values parse; every bad line becomes a problem.

    Returns:
        ``(line number, numeric values, raw values)`` per good row; the raw values keep the
        non-numeric columns (such as ``kind``).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        problems.append(f"{path}: not UTF-8 text ({error.reason}).")
        return []
    reader = csv.reader(io.StringIO(text))
    header = [name.strip() for name in next(reader, [])]
    if header[: len(columns)] != list(columns):
        problems.append(
            f"{path}: line 1: header is {','.join(header)!r}; expected {','.join(columns)!r}."
        )
        return []
    rows: list[tuple[int, Row, dict[str, str]]] = []
    for line, values in enumerate(reader, start=2):
        if not values or all(not value.strip() for value in values):
            continue
        if len(values) != len(header):
            problems.append(
                f"{path}: line {line}: {len(values)} values; expected {len(header)}"
                f" ({','.join(header)})."
            )
            continue
        raw = dict(zip(header, (value.strip() for value in values), strict=True))
        numbers: Row = {}
        for column in columns:
            if column == "kind":
                continue
            message = _number_problem(column, raw[column], column in integer_columns)
            if message:
                problems.append(f"{path}: line {line}: {message}")
            else:
                numbers[column] = float(raw[column])
        if len(numbers) == len([c for c in columns if c != "kind"]):
            rows.append((line, numbers, raw))
    return rows


def _number_problem(column: str, text: str, integer: bool) -> str | None:
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        expected = "an integer" if integer else "a number"
        return f"{column} is {text!r}; expected {expected}."
    if not math.isfinite(value):
        return f"{column} is {text!r}; expected a finite number."
    return None


def _with_reader(path: Path, problems: list[str], before: int, read: Callable[[], object]) -> None:
    """Also run the official reader; report its error when the scan found nothing in ``path``."""
    try:
        read()
    except UserError as error:
        if len(problems) == before:
            problems.extend(error.lines or [str(error)])


def _check_frames(video: Path, meta: dict[str, Any], problems: list[str]) -> int | None:
    """Count the frames and compare them with meta.json; returns the count (None if unknown)."""
    import cv2

    try:
        source = frame_source_path(video)
    except UserError as error:
        problems.extend(error.lines)
        return None
    if source.is_dir():
        images = sorted(c for c in source.iterdir() if c.suffix.lower() in IMAGE_SUFFIXES)
        count = len(images)
        if count == 0:
            problems.append(f"{source}: no image; expected the frames 000001.jpg ...")
            return None
        if all(image.stem.isdigit() for image in images):
            numbers = {int(image.stem) for image in images}
            missing = sorted(set(range(1, count + 1)) - numbers)
            if missing:
                shown = ", ".join(str(number) for number in missing[:5])
                problems.append(
                    f"{source}: frame numbers are not 1..{count}; missing {shown}"
                    f"{' ...' if len(missing) > 5 else ''}."
                )
        first = cv2.imread(str(images[0]))
        size = None if first is None else (first.shape[1], first.shape[0])
        if first is None:
            problems.append(f"{images[0]}: cannot read the image.")
        try:
            check_frame_sizes(images)
        except UserError as error:
            problems.extend(error.lines)
    else:
        try:  # the probe keeps FFmpeg's own messages off the terminal
            info = probe_container(source)
        except UserError as error:
            problems.extend(error.lines)
            return None
        count, size = info.n_frames, (info.width, info.height)
    meta_path = video / META_FILE
    expected = meta.get("n_frames")
    if isinstance(expected, int) and expected != count:
        problems.append(
            f"{meta_path}: n_frames is {expected} but {source.name} holds {count} frames;"
            " expected the same number."
        )
    width, height = meta.get("width"), meta.get("height")
    if (
        size is not None
        and isinstance(width, int)
        and isinstance(height, int)
        and size != (width, height)
    ):
        problems.append(
            f"{meta_path}: size is {width}x{height} but the frames are"
            f" {size[0]}x{size[1]}; expected the same."
        )
    return count


def _check_meta(video: Path, problems: list[str]) -> dict[str, Any]:
    path = video / META_FILE
    if not path.is_file():
        problems.append(f"{path}: missing; expected fps, width, height and n_frames.")
        return {}
    try:
        meta = read_meta(video)
    except UserError as error:
        problems.extend(error.lines)
        return {}
    for key in ("width", "height", "n_frames"):
        value = meta.get(key)
        if not isinstance(value, int) or isinstance(value, bool) or value <= 0:
            problems.append(f"{path}: {key} is {value!r}; expected a positive integer.")
    fps = meta.get("fps")
    if not isinstance(fps, int | float) or isinstance(fps, bool) or not fps > 0:
        problems.append(f"{path}: fps is {fps!r}; expected a positive number.")
    return meta


def _check_intervals(
    path: Path, n_frames: int | None, problems: list[str]
) -> list[tuple[int, int, str]]:
    """Intervals as 1-based inclusive ``(start, end, kind)``."""
    if not path.is_file():
        problems.append(f"{path}: missing; expected the header start,end,kind (even if empty).")
        return []
    before = len(problems)
    intervals: list[tuple[int, int, str, int]] = []
    for line, numbers, raw in _scan_csv(path, ("start", "end", "kind"), ("start", "end"), problems):
        start, end = int(numbers["start"]), int(numbers["end"])
        kind = raw["kind"] or "unknown"
        if start < 2 or end < start or (n_frames is not None and end > n_frames):
            limit = "" if n_frames is None else f" <= {n_frames}"
            problems.append(
                f"{path}: line {line}: interval {start}..{end} is invalid; expected"
                f" 2 <= start <= end{limit} (frame 1 carries the annotation)."
            )
            continue
        if kind not in INTERVAL_KINDS:
            problems.append(
                f"{path}: line {line}: kind {kind!r}; expected one of {', '.join(INTERVAL_KINDS)}."
            )
        intervals.append((start, end, kind, line))
    intervals.sort()
    for previous, current in itertools.pairwise(intervals):
        if current[0] <= previous[1] + 1:
            problems.append(
                f"{path}: line {current[3]}: interval {current[0]}..{current[1]} overlaps or"
                f" touches {previous[0]}..{previous[1]} (line {previous[3]}); expected at least"
                " one informative frame between intervals."
            )
    _with_reader(path, problems, before, lambda: read_intervals(path, n_frames))
    return [(start, end, kind) for start, end, kind, _ in intervals]


def _check_points(
    path: Path,
    columns: Sequence[str],
    n_frames: int | None,
    problems: list[str],
) -> list[tuple[int, Row]]:
    """Rows of gt.csv / heads.csv with good frames and no id twice in a frame."""
    rows = []
    seen: dict[tuple[int, int], int] = {}
    for line, numbers, _ in _scan_csv(path, columns, ("frame", "id"), problems):
        frame, identity = int(numbers["frame"]), int(numbers["id"])
        if identity < 1:
            problems.append(
                f"{path}: line {line}: id {identity} is not a positive integer; expected ids"
                " 1, 2, ... (they become the track ids of tracks.txt)."
            )
            continue
        if frame < 1 or (n_frames is not None and frame > n_frames):
            limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
            problems.append(
                f"{path}: line {line}: frame {frame} is outside the video; expected {limit}."
            )
            continue
        if (frame, identity) in seen:
            problems.append(
                f"{path}: line {line}: id {identity} appears twice in frame {frame}"
                f" (first on line {seen[frame, identity]})."
            )
            continue
        seen[frame, identity] = line
        rows.append((line, numbers))
    return rows


def _check_targets(
    video: Path,
    n_frames: int | None,
    meta: dict[str, Any],
    intervals: list[tuple[int, int, str]],
    problems: list[str],
) -> int:
    """Check gt.csv; returns the number of targets (ids on frame 1)."""
    path = video / GT_FILE
    if not path.is_file():
        problems.append(f"{path}: missing; expected frame,id,x,y of the people of interest.")
        return 0
    before = len(problems)
    rows = _check_points(path, ("frame", "id", "x", "y"), n_frames, problems)
    first_ids = {int(row["id"]) for _, row in rows if int(row["frame"]) == 1}
    if rows and not first_ids:
        problems.append(f"{path}: no row on frame 1; expected the targets annotated there.")
    reported: set[int] = set()
    width, height = meta.get("width"), meta.get("height")
    for line, row in rows:
        frame, identity, x, y = int(row["frame"]), int(row["id"]), row["x"], row["y"]
        if first_ids and identity not in first_ids and identity not in reported:
            reported.add(identity)
            problems.append(
                f"{path}: line {line}: id {identity} is not on frame 1; expected every target"
                " annotated on frame 1."
            )
        inside_interval = next((i for i in intervals if i[0] <= frame <= i[1]), None)
        if inside_interval is not None:
            problems.append(
                f"{path}: line {line}: frame {frame} is inside the info-less interval"
                f" {inside_interval[0]}..{inside_interval[1]}; expected no target there."
            )
        if (
            isinstance(width, int)
            and isinstance(height, int)
            and not (
                -BORDER_TOLERANCE <= x <= width + BORDER_TOLERANCE
                and -BORDER_TOLERANCE <= y <= height + BORDER_TOLERANCE
            )
        ):
            problems.append(
                f"{path}: line {line}: point ({x:g}, {y:g}) is outside the {width}x{height}"
                " image; expected targets only where inside it."
            )
    _with_reader(path, problems, before, lambda: read_targets(path, n_frames))
    return len(first_ids)


def _check_heads(video: Path, n_frames: int | None, problems: list[str]) -> dict[int, int] | None:
    """Check heads.csv (optional); returns heads per 1-based frame, None when absent."""
    path = video / HEADS_FILE
    if not path.is_file():
        return None
    before = len(problems)
    counts: dict[int, int] = {}
    for line, row in _check_points(
        path, ("frame", "id", "x", "y", "head_size"), n_frames, problems
    ):
        if row["head_size"] <= 0:
            problems.append(
                f"{path}: line {line}: head_size is {row['head_size']:g}; expected a positive size."
            )
        counts[int(row["frame"])] = counts.get(int(row["frame"]), 0) + 1
    _with_reader(path, problems, before, lambda: read_heads(path, n_frames))
    return counts


def _check_poses(video: Path, n_frames: int | None, problems: list[str]) -> None:
    path = video / POSES_FILE
    if not path.is_file():
        return
    seen: set[int] = set()
    for line, row, _ in _scan_csv(path, POSE_COLUMNS, ("frame",), problems):
        frame = int(row["frame"])
        if frame < 1 or (n_frames is not None and frame > n_frames):
            problems.append(f"{path}: line {line}: frame {frame} is outside the video.")
        elif frame in seen:
            problems.append(f"{path}: line {line}: frame {frame} appears twice.")
        seen.add(frame)


def _problem_order(problem: str) -> tuple[str, int]:
    """Sort key: the file, then the line number (problems without a line first)."""
    match = re.match(r"(.*?): line (\d+):", problem)
    if match is None:
        return problem.split(": ", 1)[0], 0
    return match[1], int(match[2])


def check_video(video: Path) -> tuple[list[str], dict[str, Any]]:
    """Check one video folder.

    Returns:
        ``(problems, facts)`` where ``facts`` has ``n_frames``, ``intervals`` (1-based inclusive
        ``(start, end, kind)``), ``targets`` and ``heads`` (per-frame counts, or None).
    """
    problems: list[str] = []
    meta = _check_meta(video, problems)
    count = _check_frames(video, meta, problems)
    declared = meta.get("n_frames")
    n_frames = declared if isinstance(declared, int) and declared > 0 else count
    truth_problems, facts = _check_truth(video, n_frames, meta)
    problems.extend(truth_problems)
    _check_poses(video, n_frames, problems)
    problems.sort(key=_problem_order)
    return problems, {"n_frames": n_frames, **facts}


def _check_truth(
    video: Path, n_frames: int | None, meta: dict[str, Any]
) -> tuple[list[str], dict[str, Any]]:
    """intervals.csv, gt.csv and heads.csv of one video: problems and facts."""
    problems: list[str] = []
    intervals = _check_intervals(video / INTERVALS_FILE, n_frames, problems)
    targets = _check_targets(video, n_frames, meta, intervals, problems)
    heads = _check_heads(video, n_frames, problems)
    return problems, {"intervals": intervals, "targets": targets, "heads": heads}


def check_ground_truth(video: VideoContext) -> list[str]:
    """Problems of a video's ground truth (gt.csv, intervals.csv, heads.csv), sorted.

    The same rules as ``trackfw dataset check``, for commands that score against the ground
    truth (``trackfw eval``): what check rejects is never scored.
    """
    meta = {"width": video.width, "height": video.height}
    problems, _ = _check_truth(Path(video.path), video.n_frames, meta)
    return sorted(problems, key=_problem_order)


def _summary(values: Sequence[float]) -> dict[str, float]:
    if not values:
        return {"min": 0, "mean": 0.0, "max": 0}
    return {"min": min(values), "mean": sum(values) / len(values), "max": max(values)}


def check_dataset(path: Path) -> DatasetReport:
    """Check every video of the dataset at ``path`` (or the single video ``path``).

    Returns:
        The report: all problems found and the dataset statistics.
    """
    report = DatasetReport()
    try:
        videos = list_videos(Path(path))
    except UserError as error:
        report.problems.extend(error.lines)
        videos = []
    frames: list[int] = []
    lengths: dict[str, list[int]] = {}
    targets: list[int] = []
    heads_per_frame: list[int] = []
    for video in videos:
        problems, facts = check_video(video)
        report.problems.extend(problems)
        if facts["n_frames"] is not None:
            frames.append(facts["n_frames"])
        for start, end, kind in facts["intervals"]:
            lengths.setdefault(kind, []).append(end - start + 1)
        targets.append(facts["targets"])
        if facts["heads"] is not None and facts["n_frames"]:
            heads_per_frame.extend(
                facts["heads"].get(f, 0) for f in range(1, facts["n_frames"] + 1)
            )
    all_lengths = [length for values in lengths.values() for length in values]
    report.stats = {
        "videos": len(videos),
        "frames": {
            "total": sum(frames),
            "min": min(frames, default=0),
            "max": max(frames, default=0),
        },
        "intervals": {
            "count": len(all_lengths),
            "length": _summary(all_lengths),
            "by_kind": {
                kind: {"count": len(values), "length": _summary(values)}
                for kind, values in sorted(lengths.items())
            },
        },
        "targets_per_video": _summary(targets),
        "heads_per_frame": _summary(heads_per_frame),
    }
    return report


def print_report(report: DatasetReport, path: Path) -> None:
    """Print the statistics (stdout) and the problems (stderr) with rich."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    stats = report.stats
    table = Table(title=f"dataset {path}", show_header=True)
    for column in ("", "count", "min", "mean", "max"):
        table.add_column(column, justify="left" if not column else "right")
    frames = stats["frames"]
    table.add_row("videos", str(stats["videos"]), "", "", "")
    mean_frames = frames["total"] / stats["videos"] if stats["videos"] else 0.0
    table.add_row(
        "frames", str(frames["total"]), str(frames["min"]), f"{mean_frames:.1f}", str(frames["max"])
    )

    def add(label: str, count: object, summary: dict[str, float]) -> None:
        table.add_row(
            label,
            str(count),
            f"{summary['min']:g}",
            f"{summary['mean']:.1f}",
            f"{summary['max']:g}",
        )

    intervals = stats["intervals"]
    add("interval length", intervals["count"], intervals["length"])
    for kind, values in intervals["by_kind"].items():
        add(f"  {kind}", values["count"], values["length"])
    add("targets per video", "", stats["targets_per_video"])
    add("heads per frame", "", stats["heads_per_frame"])
    console.print(table)
    errors = Console(stderr=True)
    for problem in report.problems:
        errors.print(problem, style="red", markup=False, highlight=False, soft_wrap=True)
    if report.problems:
        errors.print(f"{len(report.problems)} problem(s) found.", style="bold red")
    else:
        console.print("no problem found.", style="green")


def check_command(
    directory: Annotated[Path, typer.Argument(help="Dataset folder (or one video folder).")],
) -> None:
    """Validate a dataset and print its statistics; exit code 2 when a problem is found."""
    if not directory.is_dir():
        what = "is a file" if directory.exists() else "no such folder"
        raise UserError(f"{directory}: {what}; expected a dataset folder or one video folder.")
    list_videos(directory)  # a folder without any video is one error line, not a report
    report = check_dataset(directory)
    print_report(report, directory)
    if report.problems:
        raise typer.Exit(code=2)


def register(dataset_app: typer.Typer) -> None:
    """Add ``check`` to the ``trackfw dataset`` command group."""
    dataset_app.command("check")(check_command)

"""Evaluate a dataset against a runs folder: per-video rows, the mean over videos, pooled totals.

Conventions (docs/algorithms/evaluation.md#objects-and-hypotheses):

* Objects are the ground-truth people of interest on non-info-less frames; hypotheses are the
  box centres of tracks.txt. Frames are the union of both sides' frames, so hypotheses on
  ground-truth info-less frames are false positives and ground truth on skipped frames misses.
  :func:`evaluate_dataset` first checks the ground truth with the rules of ``trackfw dataset
  check`` (which refuses, among others, points inside the dataset's own info-less intervals);
  :func:`evaluate_video`, given such points anyway, leaves them out of the objects and counts them
  in ``gt_points_in_intervals``.
* MOTA-In / MOTP-In: the frames ``(a, b, b+1)`` of each ground-truth interval, each triple starting
  with no history, a video's triples pooled; the mean runs over videos that have an interval.
* The info-less classifier is scored on the frames frames.csv marks ``ok``; the others are counted
  in ``frames_not_evaluated``.
* Ratios are reported in percent (MOTA, IDF1, HOTA, precision, recall, F1), MOTP in pixels.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.atomic import write_json, write_text
from trackfw.dataset import list_videos, load_video
from trackfw.errors import UserError
from trackfw.formats.run import RunRecord, check_complete_run, read_run
from trackfw.records import VideoContext
from trackfw_plugins.datasets.check import check_ground_truth
from trackfw_plugins.evaluation.capture import CaptureCounts, capture_counts
from trackfw_plugins.evaluation.clear_mot import (
    ClearMotCounts,
    FrameObservations,
    build_sequence,
    clear_mot,
    clear_mot_windows,
    interval_windows,
)
from trackfw_plugins.evaluation.detection import DetectionCounts, frame_detection_counts
from trackfw_plugins.evaluation.given_identity import GivenIdentityCounts, given_identity_counts
from trackfw_plugins.evaluation.hota import HotaCounts, hota_counts
from trackfw_plugins.evaluation.identity import IdentityCounts, identity_counts
from trackfw_plugins.evaluation.infoless import InfolessCounts, infoless_counts, infoless_truth
from trackfw_plugins.maths.head_matching import MATCH_RATIO

EVAL_CSV = "eval.csv"
EVAL_JSON = "eval.json"

#: Columns shown in the terminal table (all columns go to CSV and JSON).
TABLE_COLUMNS = (
    "MOTA", "MOTP", "MOTA-In", "MOTP-In", "IDF1", "HOTA",
    "IL-Precision", "IL-Recall", "IL-F1", "IL-Misclassified",
)  # fmt: skip
UNITS = {
    "MOTA": "%", "MOTP": "px", "MOTA-In": "%", "MOTP-In": "px", "IDF1": "%", "IDP": "%", "IDR": "%",
    "HOTA": "%", "DetA": "%", "AssA": "%", "LocA": "%", "IL-Precision": "%", "IL-Recall": "%",
    "IL-F1": "%", "IL-Misclassified": "frames", "Det-Precision": "%", "Det-Recall": "%", "Det-F1": "%",
    "Captured": "points", "Captured-%": "%", "Named": "points", "Named-%": "%",
}  # fmt: skip


@dataclass(frozen=True)
class EvalSettings:
    """What to evaluate and with which thresholds.

    Attributes:
        distance_px: CLEAR MOT / IDF1 match threshold τ in pixels [OURS: ``mot_dist_px`` = 40].
        sensitivity_px: extra thresholds at which MOTA, MOTP and their -In variants are reported
            (``trackfw eval --sensitivity`` asks for 20 and 60).
        detections: also score the head detections of frames.csv against heads.csv.
        detection_match_ratio: a detection matches a head within this share of the head's size
            (:mod:`trackfw_plugins.maths.head_matching`).
        hota_zero_distance_px: HOTA point similarity reaches 0 here; default ``2 * distance_px``.
    """

    distance_px: float = 40.0
    sensitivity_px: tuple[float, ...] = ()
    detections: bool = False
    detection_match_ratio: float = MATCH_RATIO
    hota_zero_distance_px: float | None = None


@dataclass
class VideoEvaluation:
    """All counts of one video; the metrics are derived from them."""

    name: str
    n_frames: int
    clear: ClearMotCounts
    clear_in: ClearMotCounts | None
    n_intervals: int
    identity: IdentityCounts
    hota: HotaCounts
    infoless: InfolessCounts | None
    frames_not_evaluated: int
    gt_points_in_intervals: int
    detection: DetectionCounts | None = None
    sensitivity: dict[float, tuple[ClearMotCounts, ClearMotCounts | None]] = field(
        default_factory=dict
    )
    capture: CaptureCounts | None = None
    given: GivenIdentityCounts | None = None


def _percent(value: float) -> float:
    return 100.0 * value


def _metrics_row(
    *,
    clear: ClearMotCounts,
    clear_in: ClearMotCounts | None,
    identity: IdentityCounts,
    hota: HotaCounts,
    infoless: InfolessCounts | None,
    detection: DetectionCounts | None,
    sensitivity: dict[float, tuple[ClearMotCounts, ClearMotCounts | None]],
    with_detection: bool,
    capture: CaptureCounts | None = None,
    given: GivenIdentityCounts | None = None,
) -> dict[str, float]:
    """One table row from counts: ratios in percent, MOTP in pixels, NaN where undefined."""
    nan = float("nan")
    summary = hota.summary()
    row = {
        "MOTA": _percent(clear.mota),
        "MOTP": clear.motp,
        "MOTA-In": _percent(clear_in.mota) if clear_in is not None else nan,
        "MOTP-In": clear_in.motp if clear_in is not None else nan,
        "IDF1": _percent(identity.idf1),
        "IDP": _percent(identity.idp),
        "IDR": _percent(identity.idr),
        "HOTA": _percent(summary["HOTA"]),
        "DetA": _percent(summary["DetA"]),
        "AssA": _percent(summary["AssA"]),
        "LocA": _percent(summary["LocA"]),
        "GT": float(clear.n_objects),
        "FP": float(clear.n_false_positives),
        "FN": float(clear.n_misses),
        "IDSW": float(clear.n_switches),
        "IDSW-In": float(clear_in.n_switches) if clear_in is not None else nan,
        # What MOTA-In loses, split as IDSW-In is: misses and false positives on (a, b, b+1).
        "FP-In": float(clear_in.n_false_positives) if clear_in is not None else nan,
        "FN-In": float(clear_in.n_misses) if clear_in is not None else nan,
        "MT": float(clear.mostly_tracked),
        "PT": float(clear.partially_tracked),
        "ML": float(clear.mostly_lost),
        "FM": float(clear.n_fragmentations),
        # A run without a classifier labels no frame: its info-less scores are undefined, not 0.
        "IL-Precision": _percent(infoless.precision) if infoless is not None else nan,
        "IL-Recall": _percent(infoless.recall) if infoless is not None else nan,
        "IL-F1": _percent(infoless.f1) if infoless is not None else nan,
        "IL-Misclassified": float(infoless.misclassified) if infoless is not None else nan,
        # Reported points on a bystander's head (capture.py); needs heads.csv.
        "Captured": float(capture.captured) if capture is not None else nan,
        "Captured-%": _percent(capture.share) if capture is not None else nan,
        # Ground-truth points reported under the id they were given (given_identity.py); only
        # for runs whose targets were given with the ground truth's ids.
        "Named": float(given.named) if given is not None else nan,
        "Named-%": _percent(given.share) if given is not None else nan,
    }
    if with_detection:
        row["Det-Precision"] = _percent(detection.precision) if detection is not None else nan
        row["Det-Recall"] = _percent(detection.recall) if detection is not None else nan
        row["Det-F1"] = _percent(detection.f1) if detection is not None else nan
    for distance, (extra, extra_in) in sorted(sensitivity.items()):
        label = f"@{distance:g}"
        row["MOTA" + label] = _percent(extra.mota)
        row["MOTP" + label] = extra.motp
        row["MOTA-In" + label] = _percent(extra_in.mota) if extra_in is not None else nan
        row["MOTP-In" + label] = extra_in.motp if extra_in is not None else nan
    return row


@dataclass
class DatasetEvaluation:
    """Per-video evaluations plus the settings; rows and writers derive from them."""

    settings: EvalSettings
    videos: list[VideoEvaluation]
    pipeline: str | None = None
    pipeline_hash: str | None = None

    def video_rows(self) -> list[dict[str, Any]]:
        """One row of metrics per video (ratios in %, MOTP in pixels)."""
        rows = []
        for video in self.videos:
            metrics = _metrics_row(
                clear=video.clear,
                clear_in=video.clear_in,
                identity=video.identity,
                hota=video.hota,
                infoless=video.infoless,
                detection=video.detection,
                sensitivity=video.sensitivity,
                with_detection=self.settings.detections,
                capture=video.capture,
                given=video.given,
            )
            rows.append({"video": video.name, **metrics})
        return rows

    def mean_row(self) -> dict[str, Any]:
        """The mean over videos of every per-video value, ignoring undefined (NaN) ones.

        MOTA-In and MOTP-In are therefore averaged over the videos that have an interval.
        """
        rows = self.video_rows()
        mean: dict[str, Any] = {"video": "mean"}
        for key in rows[0] if rows else []:
            if key == "video":
                continue
            values = np.asarray([row[key] for row in rows], dtype=np.float64)
            finite = values[np.isfinite(values)]
            mean[key] = float(finite.mean()) if len(finite) else float("nan")
        return mean

    def pooled_row(self) -> dict[str, Any]:
        """Metrics of the summed counts of all videos."""
        clear = ClearMotCounts()
        identity = IdentityCounts()
        infoless: InfolessCounts | None = None
        clear_in: ClearMotCounts | None = None
        detection: DetectionCounts | None = None
        hota: HotaCounts | None = None
        sensitivity: dict[float, tuple[ClearMotCounts, ClearMotCounts | None]] = {}
        capture: CaptureCounts | None = None
        given: GivenIdentityCounts | None = None
        for video in self.videos:
            if video.capture is not None:
                capture = video.capture if capture is None else capture + video.capture
            if video.given is not None:
                given = video.given if given is None else given + video.given
            clear = clear + video.clear
            identity = identity + video.identity
            if video.infoless is not None:
                infoless = video.infoless if infoless is None else infoless + video.infoless
            hota = video.hota if hota is None else hota + video.hota
            if video.clear_in is not None:
                clear_in = video.clear_in if clear_in is None else clear_in + video.clear_in
            if video.detection is not None:
                detection = video.detection if detection is None else detection + video.detection
            for distance, (extra, extra_in) in video.sensitivity.items():
                total, total_in = sensitivity.get(distance, (ClearMotCounts(), None))
                if extra_in is not None:
                    total_in = extra_in if total_in is None else total_in + extra_in
                sensitivity[distance] = (total + extra, total_in)
        metrics = _metrics_row(
            clear=clear,
            clear_in=clear_in,
            identity=identity,
            hota=hota if hota is not None else HotaCounts(),
            infoless=infoless,
            detection=detection,
            sensitivity=sensitivity,
            with_detection=self.settings.detections,
            capture=capture,
            given=given,
        )
        return {"video": "pooled", **metrics}

    def rows(self) -> list[dict[str, Any]]:
        """Per-video rows, then the mean and the pooled row."""
        return [*self.video_rows(), self.mean_row(), self.pooled_row()]


# ----------------------------------------------------------------------------------- evaluation


def _split_ground_truth(
    video: VideoContext,
) -> tuple[dict[int, dict[int, tuple[float, float]]], int]:
    """The objects of the evaluation and the number of GT points found inside intervals."""
    ground_truth = video.ground_truth
    if ground_truth is None or not ground_truth.targets:
        raise UserError(
            f"{video.path}: no ground truth; expected gt.csv with the people of interest."
        )
    infoless = ground_truth.infoless_frames()
    targets = {
        frame: points for frame, points in ground_truth.targets.items() if frame not in infoless
    }
    dropped = sum(
        len(points) for frame, points in ground_truth.targets.items() if frame in infoless
    )
    return targets, dropped


def _check_settings(settings: EvalSettings) -> None:
    named = [("--dist", settings.distance_px)]
    named += [("a sensitivity distance", value) for value in settings.sensitivity_px]
    for name, value in named:
        if not math.isfinite(value) or value <= 0:
            raise UserError(f"{name} is {value}; expected a positive number of pixels.")
    ratio = settings.detection_match_ratio
    if not math.isfinite(ratio) or ratio <= 0:
        raise UserError(
            f"the detection match ratio is {ratio}; expected a positive share of a head's size."
        )


def evaluate_video(
    video: VideoContext, run: RunRecord, settings: EvalSettings | None = None
) -> VideoEvaluation:
    """Evaluate one video's run against its ground truth."""
    settings = settings or EvalSettings()
    _check_settings(settings)
    targets, dropped = _split_ground_truth(video)
    assert video.ground_truth is not None
    intervals = [(interval.a, interval.b) for interval in video.ground_truth.intervals]
    sequence: list[FrameObservations] = build_sequence(targets, run.tracks)
    windows = interval_windows(intervals, video.n_frames)

    def clear_at(distance: float) -> tuple[ClearMotCounts, ClearMotCounts | None]:
        return (
            clear_mot(sequence, "point", distance),
            clear_mot_windows(sequence, windows, "point", distance),
        )

    clear, clear_in = clear_at(settings.distance_px)
    zero_distance = settings.hota_zero_distance_px or 2.0 * settings.distance_px
    ok = run.frames.ok
    evaluated_frames = run.frames.frames[ok]
    truth = infoless_truth(intervals, evaluated_frames)
    # A classifier gives every frame it saw a probability; a run without one (a batch tracker's)
    # leaves the column empty, and its info-less labels are no decisions.
    classified = bool(np.isfinite(run.frames.infoless_probability[ok]).any())
    detection: DetectionCounts | None = None
    if settings.detections and video.ground_truth.heads:
        detection = DetectionCounts()
        empty = np.zeros((0, 3))
        frame_rows = zip(
            run.frames.frames.tolist(), run.frames.detections, ok.tolist(), strict=True
        )
        for frame, points, is_ok in frame_rows:
            if is_ok:
                heads = video.ground_truth.heads.get(frame, empty)
                detection = detection + frame_detection_counts(
                    points, heads, settings.detection_match_ratio
                )
    return VideoEvaluation(
        name=video.name,
        n_frames=video.n_frames,
        clear=clear,
        clear_in=clear_in,
        n_intervals=len(windows),
        identity=identity_counts(sequence, "point", settings.distance_px),
        hota=hota_counts(sequence, "point", zero_distance),
        infoless=infoless_counts(run.frames.infoless[ok], truth) if classified else None,
        frames_not_evaluated=video.n_frames - int(ok.sum()),
        gt_points_in_intervals=dropped,
        detection=detection,
        sensitivity={distance: clear_at(distance) for distance in settings.sensitivity_px},
        capture=capture_counts(
            sequence, video.ground_truth.heads, settings.distance_px, settings.detection_match_ratio
        )
        if video.ground_truth.heads
        else None,
        given=given_identity_counts(sequence, settings.distance_px)
        if isinstance(run.summary, dict) and run.summary.get("initialised_from") == "gt"
        else None,
    )


def evaluate_dataset(
    dataset_dir: Path,
    runs_dir: Path,
    settings: EvalSettings | None = None,
    progress: Callable[[str], None] | None = None,
) -> DatasetEvaluation:
    """Evaluate every video of a dataset; a video without a run folder is an error.

    Args:
        dataset_dir: a dataset folder (or one video folder).
        runs_dir: the runs folder, one sub-folder per video name.
        settings: thresholds and options.
        progress: called with each video's name once it is evaluated.
    """
    settings = settings or EvalSettings()
    _check_settings(settings)
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        raise UserError(
            f"{runs_dir}: no such folder; expected a runs folder with one sub-folder per video."
        )
    videos = [load_video(path) for path in list_videos(Path(dataset_dir))]
    # The ground truth passes the same rules as `trackfw dataset check`, or nothing is scored.
    problems = [line for video in videos for line in check_ground_truth(video)]
    if problems:
        raise UserError(*problems)
    missing = [video.name for video in videos if not (runs_dir / video.name).is_dir()]
    if missing:
        raise UserError(
            f"{runs_dir}: no run for video(s) {', '.join(missing)}; expected a sub-folder per video"
            f" of {dataset_dir}."
        )
    # Every run complete and of one configuration before any is scored.
    summaries = {
        video.name: check_complete_run(runs_dir / video.name, video.n_frames) for video in videos
    }
    pipeline, pipeline_hash = _one_configuration(runs_dir, summaries)
    evaluations = []
    for video in videos:
        run = read_run(runs_dir / video.name, video.n_frames)
        evaluations.append(evaluate_video(video, run, settings))
        if progress is not None:
            progress(video.name)
    return DatasetEvaluation(
        settings=settings, videos=evaluations, pipeline=pipeline, pipeline_hash=pipeline_hash
    )


def _one_configuration(
    runs_dir: Path, summaries: dict[str, dict[str, Any]]
) -> tuple[str | None, str | None]:
    """The pipeline name and hash shared by every run; a UserError when runs mix configurations.

    Re-running into a folder with another ``--set`` and stopping midway leaves videos of two
    configurations side by side; their scores would describe neither.
    """
    groups: dict[str | None, list[str]] = {}
    for name, summary in summaries.items():
        value = summary.get("pipeline_hash")
        groups.setdefault(value if isinstance(value, str) else None, []).append(name)
    if len(groups) > 1:
        described = "; ".join(
            f"{'no hash' if key is None else 'hash ' + key}: {', '.join(names)}"
            for key, names in groups.items()
        )
        raise UserError(
            f"{runs_dir}: runs of {len(groups)} pipeline configurations side by side ({described});"
            " expected one configuration per runs folder: re-run these videos with one pipeline"
            " and --set, or into an empty --output."
        )
    pipeline_hash = next(iter(groups), None)
    names = {
        str(summary.get("pipeline")) for summary in summaries.values() if summary.get("pipeline")
    }
    return (names.pop() if len(names) == 1 else None), pipeline_hash


# ------------------------------------------------------------------------------------- writers


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "" if not math.isfinite(value) else f"{value:.4f}"
    return str(value)


def csv_text(evaluation: DatasetEvaluation) -> str:
    """eval.csv: one row per video, then ``mean`` and ``pooled``; undefined values are empty."""
    rows = evaluation.rows()
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    columns = list(rows[0]) if rows else ["video"]
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(column, "")) for column in columns])
    return buffer.getvalue()


def _json_value(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(key): _json_value(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(item) for item in value]
    return value


def json_document(evaluation: DatasetEvaluation) -> dict[str, Any]:
    """eval.json: settings, units, the rows (undefined values as null) and each video's counts."""
    counts = []
    for video in evaluation.videos:
        counts.append(
            {
                "video": video.name,
                "n_frames": video.n_frames,
                "n_intervals": video.n_intervals,
                "frames_not_evaluated": video.frames_not_evaluated,
                "gt_points_in_intervals": video.gt_points_in_intervals,
                "clear": asdict(video.clear),
                "clear_in": asdict(video.clear_in) if video.clear_in is not None else None,
                "identity": asdict(video.identity),
                "hota": video.hota.summary(),
                "infoless": asdict(video.infoless) if video.infoless is not None else None,
                "detection": asdict(video.detection) if video.detection is not None else None,
            }
        )
    return _json_value(
        {
            "pipeline": evaluation.pipeline,
            "pipeline_hash": evaluation.pipeline_hash,
            "settings": asdict(evaluation.settings),
            "units": UNITS,
            "videos": evaluation.video_rows(),
            "mean": evaluation.mean_row(),
            "pooled": evaluation.pooled_row(),
            "counts": counts,
        }
    )


def write_reports(evaluation: DatasetEvaluation, out_dir: Path) -> tuple[Path, Path]:
    """Write eval.csv and eval.json atomically into ``out_dir``; returns their paths."""
    out_dir = Path(out_dir)
    csv_path, json_path = out_dir / EVAL_CSV, out_dir / EVAL_JSON
    write_text(csv_path, csv_text(evaluation))
    write_json(json_path, json_document(evaluation))
    return csv_path, json_path


#: Two-line headers of the terminal table, narrow enough for an 80-column terminal.
TABLE_HEADERS = {
    "MOTA": "MOTA\n%", "MOTP": "MOTP\npx", "MOTA-In": "MOTA\nIn %", "MOTP-In": "MOTP\nIn px",
    "IDF1": "IDF1\n%", "HOTA": "HOTA\n%", "IL-Precision": "IL P\n%", "IL-Recall": "IL R\n%",
    "IL-F1": "IL F1\n%", "IL-Misclassified": "IL\nmiss", "Det-Precision": "Det P\n%",
    "Det-Recall": "Det R\n%",
}  # fmt: skip


def render_table(evaluation: DatasetEvaluation, columns: Sequence[str] | None = None) -> Any:
    """A :class:`rich.table.Table` of the per-video, mean and pooled rows.

    IL P / R / F1 are the info-less classifier's frame precision, recall and F1; IL miss its
    misclassified frames.
    """
    from rich import box
    from rich.table import Table

    rows = evaluation.rows()
    shown = list(columns or TABLE_COLUMNS)
    if evaluation.settings.detections:
        shown += ["Det-Precision", "Det-Recall"]
    table = Table(
        title=f"trackfw eval (match distance {evaluation.settings.distance_px:g} px)",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    # Minimum widths keep every number whole; a narrow terminal wraps lines rather than eliding.
    names = [str(row["video"]) for row in rows]
    table.add_column("video", no_wrap=True, min_width=max(map(len, names), default=5))
    for column in shown:
        table.add_column(
            TABLE_HEADERS.get(column, column), justify="right", no_wrap=True, min_width=5
        )
    for index, row in enumerate(rows):
        cells = []
        for column in shown:
            value = row.get(column, float("nan"))
            digits = 0 if column == "IL-Misclassified" else 1
            cells.append("-" if not math.isfinite(value) else f"{value:.{digits}f}")
        table.add_row(str(row["video"]), *cells, end_section=index == len(rows) - 3)
    return table

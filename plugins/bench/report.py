"""The benchmark table: the paper's Table 1 plus IDF1, HOTA, info-less F1 and speed.

One row per pipeline, each value the mean over the videos that pipeline completed (the paper's
way; MOTA-In and MOTP-In over the videos that have an interval). Metrics come from the evaluation
plugin (``trackfw_plugins.evaluation``, a declared dependency of this one); speed from each run's summary.json and bench.json:

* ``fps``: frames per second of the whole run. When the detector and classifier were replayed
  from the stage cache, their recorded time is added back, so the figure stays that of a run
  that computed them;
* ``ms <stage>``: mean milliseconds per call of each stage (summary.json's ``ms_per_frame``).

Written as ``table.md`` (Markdown), ``table.csv`` and ``table.png`` (grouped bars per metric).
Each pipeline's runs folder also receives the evaluation plugin's ``eval.csv`` and ``eval.json``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

from trackfw.atomic import atomic_open, write_text
from trackfw.formats.run import SUMMARY_FILE, read_run
from trackfw.formats.text import read_json
from trackfw.stages import STAGE_KINDS
from trackfw_plugins.bench.jobs import BENCH_FILE, is_done
from trackfw_plugins.bench.sweep import SweepPlan
from trackfw_plugins.evaluation.report import (
    DatasetEvaluation,
    EvalSettings,
    evaluate_video,
    write_reports,
)

TABLE_MARKDOWN = "table.md"
TABLE_CSV = "table.csv"
TABLE_PNG = "table.png"
#: Quality columns of the table, in order: the paper's Table 1, then the extras.
METRICS = ("MOTA", "MOTP", "MOTA-In", "MOTP-In", "IDF1", "HOTA", "IL-F1")
PERCENT_METRICS = ("MOTA", "MOTA-In", "IDF1", "HOTA", "IL-F1")
PIXEL_METRICS = ("MOTP", "MOTP-In")
#: "Captured by a non-target" (trackfw_plugins.evaluation.capture), shown where it is defined.
CAPTURED = "Captured-%"
#: Ground-truth points reported under the id they were given
#: (trackfw_plugins.evaluation.given_identity), shown where it is defined.
NAMED = "Named-%"
SPEED = ("fps", *(f"ms {kind}" for kind in STAGE_KINDS))
PAPER_PREFIX = "paper "
#: The paper's figures beside ours in table.md (every quoted one goes to table.csv).
PAPER_COLUMNS = ("paper MOTA", "paper MOTA-In")
HEADERS = {
    "MOTA": "MOTA %", "MOTP": "MOTP px", "MOTA-In": "MOTA-In %", "MOTP-In": "MOTP-In px",
    "IDF1": "IDF1 %", "HOTA": "HOTA %", "IL-F1": "IL-F1 %", "fps": "fps",
    "ms detector": "ms det", "ms classifier": "ms cls", "ms tracker": "ms trk",
    "ms gap_matcher": "ms gap", CAPTURED: "captured %", NAMED: "named %", "paper MOTA": "paper MOTA %", "paper MOTA-In": "paper MOTA-In %",
}  # fmt: skip


@dataclass
class TableRow:
    """One pipeline's row.

    Attributes:
        pipeline: the pipeline's name (with its hash when two rows share a name).
        pipeline_hash: its content hash.
        videos_done: videos with a complete run.
        videos_total: videos of the dataset.
        metrics: the evaluation's mean row (every metric it has; NaN when undefined).
        speed: ``fps`` and ``ms <stage>``, means over the completed videos (NaN when none).
        paper: the paper's figures for this row when a table file quotes them.
    """

    pipeline: str
    pipeline_hash: str
    videos_done: int
    videos_total: int
    metrics: dict[str, float] = field(default_factory=dict)
    speed: dict[str, float] = field(default_factory=dict)
    paper: dict[str, float] = field(default_factory=dict)

    def value(self, column: str) -> float:
        """A metric, speed or ``paper <metric>`` value; NaN when absent."""
        if column in self.speed:
            return self.speed[column]
        if column.startswith(PAPER_PREFIX):
            return self.paper.get(column.removeprefix(PAPER_PREFIX), math.nan)
        return float(self.metrics.get(column, math.nan))


def _mean(values: list[float]) -> float:
    finite = [value for value in values if value is not None and math.isfinite(value)]
    return sum(finite) / len(finite) if finite else math.nan


def _speed(run_dirs: list[Path]) -> dict[str, float]:
    """fps and mean ms per stage over completed runs."""
    rates: list[float] = []
    per_stage: dict[str, list[float]] = {kind: [] for kind in STAGE_KINDS}
    for run_dir in run_dirs:
        summary = read_json(run_dir / SUMMARY_FILE)
        frames = float(summary.get("n_frames") or 0)
        seconds = float(summary.get("seconds") or 0.0)
        bench_path = run_dir / BENCH_FILE
        if bench_path.is_file():
            bench = read_json(bench_path)
            seconds = float(bench.get("wall_seconds", seconds)) + float(
                bench.get("replayed_seconds", 0.0)
            )
        if frames and seconds > 0:
            rates.append(frames / seconds)
        for kind, value in (summary.get("ms_per_frame") or {}).items():
            if kind in per_stage and value is not None:
                per_stage[kind].append(float(value))
    speed = {"fps": _mean(rates)}
    speed.update({f"ms {kind}": _mean(values) for kind, values in per_stage.items()})
    return speed


def build_table(
    plan: SweepPlan,
    distance_px: float = 40.0,
    paper: dict[Path, dict[str, float]] | None = None,
) -> list[TableRow]:
    """Evaluate every pipeline's completed runs; one row per pipeline, in the plan's order.

    ``paper`` maps a pipeline file (resolved) to the paper's figures quoted for it (table files).
    Also writes eval.csv and eval.json into each pipeline's runs folder.
    """
    paper = paper or {}

    settings = EvalSettings(distance_px=distance_px)
    names = [entry.pipeline.name for entry in plan.pipelines]
    rows: list[TableRow] = []
    for entry in plan.pipelines:
        done_dirs: list[Path] = []
        evaluations = []
        for video in plan.videos:
            run_dir = entry.runs_dir / video.name
            if not is_done(run_dir):
                continue
            done_dirs.append(run_dir)
            evaluations.append(evaluate_video(video, read_run(run_dir, video.n_frames), settings))
        label = entry.pipeline.name
        if names.count(label) > 1:
            label = f"{label} ({entry.pipeline.content_hash})"
        row = TableRow(label, entry.pipeline.content_hash, len(done_dirs), len(plan.videos))
        if evaluations:
            dataset_evaluation = DatasetEvaluation(settings=settings, videos=evaluations)
            row.metrics = {
                key: float(value)
                for key, value in dataset_evaluation.mean_row().items()
                if key != "video"
            }
            write_reports(dataset_evaluation, entry.runs_dir)
        row.speed = _speed(done_dirs)
        row.paper = dict(paper.get(entry.file.resolve(), {}))
        rows.append(row)
    return rows


def _format(value: float, column: str) -> str:
    if not math.isfinite(value):
        return "-"
    if column == "fps":
        return f"{value:.0f}" if value >= 100 else f"{value:.1f}"
    if column.startswith("ms "):
        return f"{value:.3f}" if value < 1 else f"{value:.1f}"
    return f"{value:.1f}"


def markdown_table(rows: list[TableRow], distance_px: float = 40.0) -> str:
    """The table in Markdown, with a line that says how it was computed."""
    quoted = PAPER_COLUMNS if any(row.paper for row in rows) else ()
    # Only a dataset with heads.csv can say whether a target sat on a bystander.
    captured = [CAPTURED] if any(math.isfinite(row.value(CAPTURED)) for row in rows) else []
    # Only a run started from the ground truth's ids can be read by the names it was given.
    named = [NAMED] if any(math.isfinite(row.value(NAMED)) for row in rows) else []
    columns = [*METRICS, *captured, *named, *quoted, *SPEED]
    header = ["pipeline", "videos", *(HEADERS.get(column, column) for column in columns)]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join(["---", "---:", *(["---:"] * len(columns))]) + "|",
    ]
    for row in rows:
        cells = [row.pipeline, f"{row.videos_done}/{row.videos_total}"]
        cells += [_format(row.value(column), column) for column in columns]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(
        f"Means over videos; match distance {distance_px:g} px; MOTA-In/MOTP-In over the frames"
        " (a, b, b+1) of each interval; IL-F1: info-less frame classification; fps and ms per"
        " stage call from summary.json (cached detector/classifier time counted)."
        + (" captured: reported points on a bystander's head." if captured else "")
        + (" named: ground-truth points reported under the id they were given." if named else "")
        + (
            " paper: Yu et al. 2018, Table 1 (their detector and data), as quoted by the table file."
            if quoted
            else ""
        )
    )
    return "\n".join(lines) + "\n"


def _cell(value: float) -> str:
    return f"{value:.6g}" if math.isfinite(value) else ""


def csv_table(rows: list[TableRow]) -> str:
    """table.csv: the table's columns first, then every other metric of the mean row."""
    extra: list[str] = []
    for row in rows:
        extra.extend(key for key in row.metrics if key not in METRICS and key not in extra)
    quoted = [
        f"{PAPER_PREFIX}{metric}"
        for metric in ("MOTA", "MOTP", "MOTA-In", "MOTP-In")
        if any(metric in row.paper for row in rows)
    ]
    columns = [*METRICS, *quoted, *SPEED, *extra]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["pipeline", "pipeline_hash", "videos_done", "videos_total", *columns])
    for row in rows:
        writer.writerow(
            [
                row.pipeline,
                row.pipeline_hash,
                row.videos_done,
                row.videos_total,
                *(_cell(row.value(column)) for column in columns),
            ]
        )
    return buffer.getvalue()


def write_chart(rows: list[TableRow], path: Path) -> Path:
    """table.png: grouped bars, one group per metric and one bar per pipeline (Agg, no pyplot)."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 4.8), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(1, 2, width_ratios=[len(PERCENT_METRICS), len(PIXEL_METRICS) + 0.6])
    count = max(len(rows), 1)
    width = 0.8 / count
    palette = [f"C{index % 10}" for index in range(count)]
    for axis, metrics, unit in (
        (axes[0], PERCENT_METRICS, "%"),
        (axes[1], PIXEL_METRICS, "pixels (lower is better)"),
    ):
        positions = np.arange(len(metrics), dtype=float)
        for index, row in enumerate(rows):
            values = [row.value(metric) for metric in metrics]
            heights = [value if math.isfinite(value) else 0.0 for value in values]
            offsets = positions - 0.4 + width * (index + 0.5)
            axis.bar(offsets, heights, width, label=row.pipeline, color=palette[index])
        axis.set_xticks(positions, list(metrics))
        axis.set_ylabel(unit)
        axis.grid(axis="y", alpha=0.3)
        axis.set_axisbelow(True)
    axes[0].set_title("tracking and info-less recognition (mean over videos)")
    axes[1].set_title("position error")
    if rows:
        figure.legend(
            *axes[0].get_legend_handles_labels(),
            loc="outside lower center",
            ncols=min(4, len(rows)),
            fontsize="small",
        )
    with atomic_open(path, "wb") as stream:
        figure.savefig(stream, format="png", dpi=110)
    return path


def write_table(rows: list[TableRow], out_dir: Path, distance_px: float = 40.0) -> dict[str, Path]:
    """Write table.md, table.csv and table.png into ``out_dir``; returns their paths by kind."""
    out_dir = Path(out_dir)
    paths = {
        "markdown": out_dir / TABLE_MARKDOWN,
        "csv": out_dir / TABLE_CSV,
        "png": out_dir / TABLE_PNG,
    }
    write_text(paths["markdown"], markdown_table(rows, distance_px))
    write_text(paths["csv"], csv_table(rows))
    write_chart(rows, paths["png"])
    return paths


__all__ = [
    "METRICS",
    "SPEED",
    "TableRow",
    "build_table",
    "csv_table",
    "markdown_table",
    "write_chart",
    "write_table",
]

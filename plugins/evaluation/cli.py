"""The ``trackfw eval`` command."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add the ``eval`` command to the root ``trackfw`` application."""
    app.command(name="eval")(eval_command)


def eval_command(
    dataset: Annotated[
        Path, typer.Option("--dataset", "-d", help="Dataset folder (one sub-folder per video).")
    ],
    runs: Annotated[
        Path, typer.Option("--runs", help="Runs folder (one sub-folder per video name).")
    ],
    dist: Annotated[
        float,
        typer.Option("--dist", help="CLEAR MOT / IDF1 match threshold in pixels (mot_dist_px)."),
    ] = 40.0,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Where to write eval.csv and eval.json (default: --runs)."),
    ] = None,
    detections: Annotated[
        bool,
        typer.Option("--detections", help="Also score frames.csv detections against heads.csv."),
    ] = False,
    sensitivity: Annotated[
        bool, typer.Option("--sensitivity", help="Also report MOTA/MOTP(-In) at 20 px and 60 px.")
    ] = False,
) -> None:
    """MOTA, MOTP, MOTA-In, MOTP-In, IDF1, HOTA and info-less precision/recall/F1 of a runs folder."""
    from rich.console import Console

    from trackfw.atomic import check_output_folder
    from trackfw.dataset import list_videos
    from trackfw.progress import progress_bar
    from trackfw_plugins.evaluation.report import (
        EvalSettings,
        evaluate_dataset,
        render_table,
        write_reports,
    )

    settings = EvalSettings(
        distance_px=dist,
        sensitivity_px=(20.0, 60.0) if sensitivity else (),
        detections=detections,
    )
    # eval.csv and eval.json are written after every video is scored: say first if they cannot be.
    if out is not None:
        check_output_folder(out, "--out")
    elif runs.is_dir():
        check_output_folder(runs, "--runs")
    console = Console()
    n_videos = len(list_videos(dataset))
    with progress_bar(console, "videos", "remaining") as progress:
        task = progress.add_task("evaluating videos", total=n_videos)
        evaluation = evaluate_dataset(
            dataset, runs, settings, progress=lambda _name: progress.advance(task)
        )
    table = render_table(evaluation)
    # Wider than the terminal wraps lines, but never elides a number.
    width = max(console.width, console.measure(table).maximum)
    console.print(table, width=width, crop=False)
    csv_path, json_path = write_reports(evaluation, out if out is not None else runs)
    console.print(f"wrote {csv_path} and {json_path}")

"""``trackfw dataset wear``: the command line of :mod:`trackfw_plugins.datasets.wear`."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import typer

from trackfw.atomic import check_output_folder
from trackfw.errors import UserError
from trackfw_plugins.datasets.wear import (
    PREVIEW_FOLDER,
    FrameFormat,
    WearSettings,
    generate_dataset,
)


def parse_size(text: str) -> tuple[int, int]:
    """``"640x480"`` -> ``(640, 480)``.

    >>> parse_size("320x240")
    (320, 240)
    """
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if match is None or min(int(match[1]), int(match[2])) < 16:
        raise UserError(
            f"--size is {text!r}; expected WIDTHxHEIGHT like 640x480, each at least 16."
        )
    return int(match[1]), int(match[2])


def wear_command(
    mot: Annotated[
        Path, typer.Option("--mot", help="MOTChallenge sequence folder (img1/ + gt/gt.txt).")
    ],
    out: Annotated[Path, typer.Option("--out", help="Dataset folder to write.")],
    seed: Annotated[
        int, typer.Option(help="Random seed; the same seed gives the same videos.")
    ] = 0,
    videos: Annotated[int, typer.Option(help="Videos to make from the sequence.")] = 1,
    intervals: Annotated[
        int | None, typer.Option(help="Info-less intervals per video (default: one per 80 frames).")
    ] = None,
    frame_format: Annotated[
        FrameFormat, typer.Option("--format", help="video.mp4 (mp4v) or img1/ JPEGs.")
    ] = FrameFormat.mp4,
    size: Annotated[
        str | None, typer.Option(help="Output WIDTHxHEIGHT (default: the sequence's).")
    ] = None,
    min_length: Annotated[int, typer.Option(help="Shortest interval, frames.")] = 15,
    max_length: Annotated[int, typer.Option(help="Longest interval, frames.")] = 60,
    force: Annotated[
        bool, typer.Option(help="Write into a non-empty --out, replacing same-name videos.")
    ] = False,
    targets: Annotated[
        int | None,
        typer.Option(
            "--targets",
            help="People of interest per video: the K nearest a random person on frame 1"
            " (default: 5 to 10); the others are bystanders, in heads.csv and not in gt.csv.",
        ),
    ] = None,
) -> None:
    """Make virtual-wearer videos (sway, pose jumps, sky/group/path intervals) of a MOT sequence."""
    from rich.console import Console

    from trackfw.progress import progress_bar

    if intervals is not None and intervals < 1:
        raise UserError(f"--intervals is {intervals}; expected at least 1.")
    check_output_folder(out, "--out")
    if targets is not None and targets < 1:
        raise UserError(f"--targets is {targets}; expected at least 1 person of interest.")
    if not 3 <= min_length <= max_length:
        raise UserError(
            f"--min-length {min_length} / --max-length {max_length}; expected 3 <= min <= max."
        )
    settings = WearSettings(
        n_intervals=intervals,
        min_interval=min_length,
        max_interval=max_length,
        output_size=parse_size(size) if size else None,
        frame_format=frame_format,
        n_targets=targets,
    )
    console = Console(stderr=True)
    with progress_bar(console) as bar:
        tasks: dict[str, Any] = {}

        def report(name: str, done: int, total: int) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=total)
            bar.update(tasks[name], completed=done)

        written = generate_dataset(mot, out, seed, videos, settings, force, report)
    for folder in written:
        console.print(f"wrote {folder}")
    console.print(f"previews in {out / PREVIEW_FOLDER}")


def register(dataset_app: typer.Typer) -> None:
    """Add ``wear`` to the ``trackfw dataset`` command group."""
    dataset_app.command("wear")(wear_command)

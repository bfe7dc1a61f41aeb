"""The ``trackfw render`` command."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add ``render`` to the root ``trackfw`` application."""
    app.command(name="render")(render_command)


def _frame_numbers(text: str | None) -> list[int]:
    from trackfw.errors import UserError

    if not text:
        return []
    numbers = []
    for part in text.split(","):
        part = part.strip()
        if not part.isdigit() or int(part) < 1:
            raise UserError(
                f"--png-frames {text!r}: {part!r} is not a frame number; expected 1-based frame"
                " numbers separated by commas, e.g. 1,50,120."
            )
        numbers.append(int(part))
    return numbers


def render_command(
    run_dir: Annotated[
        Path, typer.Argument(help="A video's run folder, or a runs folder with --video.")
    ],
    video: Annotated[
        str | None, typer.Option("--video", help="Video name inside a runs folder.")
    ] = None,
    dataset: Annotated[
        Path | None,
        typer.Option(
            "--dataset", "-d", help="Dataset folder with the video (default: summary.json)."
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="MP4 file (default: <run folder>/render.mp4)."),
    ] = None,
    png_frames: Annotated[
        str | None,
        typer.Option("--png-frames", help="Also save these 1-based frames as PNG: 1,50,120."),
    ] = None,
    png_panels: Annotated[
        bool, typer.Option("--png-panels", help="Also save every interval panel as PNG.")
    ] = False,
    panel_frames: Annotated[
        int | None,
        typer.Option(
            "--panel-frames", min=0, help="Frames each interval panel is held (default: 1 s)."
        ),
    ] = None,
    trail: Annotated[int, typer.Option("--trail", min=0, help="Frames of trail per target.")] = 15,
) -> None:
    """Draw a run as an MP4: tracks, identities, info-less frames and interval panels.

    Each target's point, box, identity colour and trail; info-less frames marked; before each
    frame b, frame a beside frame b with a line linking each identity across the interval.
    """
    from rich.console import Console

    from trackfw_plugins.render.render import render_run

    result = render_run(
        run_dir,
        out=out,
        dataset=dataset,
        video=video,
        panel_frames=panel_frames,
        png_frames=_frame_numbers(png_frames),
        png_panels=png_panels,
        trail=trail,
    )
    console = Console()
    console.print(
        f"wrote {result.video} ({result.frames_written} frames, {result.panels} interval panels)",
        highlight=False,
        soft_wrap=True,
    )
    for path in result.pngs:
        console.print(f"wrote {path}", highlight=False, soft_wrap=True)

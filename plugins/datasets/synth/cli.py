"""``trackfw dataset synth``: the command line of the synthetic dataset generator."""

from __future__ import annotations

import re
import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from trackfw.atomic import check_output_folder, write_json
from trackfw.errors import UserError

from .generate import FORMATS, VideoResult, generate_dataset
from .presets import (
    LEAVE_MIN_FRAMES,
    VideoPlan,
    WearerConfig,
    custom_plan,
    paper_plan,
    with_leavers,
    with_options,
)

PRESETS = ("paper", "paper-leave")
#: Most targets per video ``--leave`` may send away (every preset has at least 5).
MAX_LEAVE = 5
#: Most people of interest ``--targets`` may ask for (a group larger walks apart).
MAX_TARGETS = 12


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` -> ``(1280, 720)``; even sizes from 160x90 to 3840x2160.

    >>> parse_size("1920x1080")
    (1920, 1080)
    """
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match:
        raise UserError(f"--size {text!r}: expected WIDTHxHEIGHT, for example 1280x720.")
    width, height = int(match.group(1)), int(match.group(2))
    if not (160 <= width <= 3840 and 90 <= height <= 2160) or width % 2 or height % 2:
        raise UserError(
            f"--size {text!r}: expected even sizes between 160x90 and 3840x2160."
        )
    return width, height


def parse_range(text: str, option: str) -> tuple[float, float]:
    """``"0.7,1.4"`` -> ``(0.7, 1.4)``; both positive, low <= high.

    >>> parse_range("0.7,1.4", "--scale-range")
    (0.7, 1.4)
    """
    parts = text.split(",")
    try:
        low, high = (float(part) for part in parts)
    except ValueError:
        raise UserError(f"{option} {text!r}: expected two numbers LOW,HIGH such as 0.7,1.4.") from None
    if not 0 < low <= high:
        raise UserError(f"{option} {text!r}: expected 0 < LOW <= HIGH.")
    return low, high


def wearer_config(max_pan: float, max_roll: float, scale_range: str) -> WearerConfig:
    """Head-motion limits from the command line options (validated)."""
    if not 0 <= max_pan <= 60:
        raise UserError(f"--max-pan {max_pan}: expected 0 to 60 degrees.")
    if not 0 <= max_roll <= 30:
        raise UserError(f"--max-roll {max_roll}: expected 0 to 30 degrees.")
    low, high = parse_range(scale_range, "--scale-range")
    if low < 0.3 or high > 3.0:
        raise UserError(f"--scale-range {scale_range!r}: expected factors within 0.3..3.0.")
    return WearerConfig(max_pan_change=max_pan, min_pan_change=min(6.0, max_pan),
                        max_roll_change=max_roll, scale_range=(low, high))


def build_plans(
    preset: str | None,
    seed: int,
    videos: int | None,
    frames: int | None,
    intervals: int | None,
    size: tuple[int, int],
    fps: float,
    trajectories: Path | None,
    background: Path | None,
    wearer: WearerConfig | None = None,
    leave: int | None = None,
    targets: int | None = None,
) -> list[VideoPlan]:
    """The plans the command line asks for (validated, nothing written)."""
    if preset is not None and preset not in PRESETS:
        raise UserError(f"--preset {preset!r}: expected one of {', '.join(PRESETS)}.")
    if videos is not None and videos < 1:
        raise UserError(f"--videos {videos}: expected at least 1.")
    if frames is not None and frames < 40:
        raise UserError(f"--frames {frames}: expected at least 40 frames.")
    if intervals is not None and intervals < 0:
        raise UserError(f"--intervals {intervals}: expected 0 or more.")
    if leave is not None and not 0 <= leave <= MAX_LEAVE:
        raise UserError(f"--leave {leave}: expected 0 to {MAX_LEAVE} targets per video.")
    if targets is not None and not 1 <= targets <= MAX_TARGETS:
        raise UserError(f"--targets {targets}: expected 1 to {MAX_TARGETS} people of interest.")
    if targets is not None and leave is not None and leave > targets:
        raise UserError(f"--leave {leave}: expected at most --targets ({targets}) leavers.")
    if not 1.0 <= fps <= 240.0:
        raise UserError(f"--fps {fps}: expected a frame rate between 1 and 240.")
    if trajectories is not None and not trajectories.exists():
        raise UserError(f"--trajectories {trajectories}: no such file or folder.")
    if background is not None and not background.is_file():
        raise UserError(f"--background {background}: no such image file.")
    width, height = size
    if preset in ("paper", "paper-leave"):
        plans = paper_plan(seed, videos=videos, frames=frames, intervals=intervals, width=width,
                           height=height, fps=fps)
    else:
        plans = custom_plan(seed, videos=videos or 1, frames=frames or 300,
                            intervals=1 if intervals is None else intervals, width=width,
                            height=height, fps=fps)
    if targets is not None:
        # Fewer people of interest among the same bystanders: the case of a guard following two
        # people in a crowd.
        plans = [replace(plan, n_targets=targets) for plan in plans]
    if preset == "paper-leave":
        # The paper's videos, one target each walking out of view and back; short videos get a
        # longer tail so that the walk fits.
        plans = with_leavers(plans, 1 if leave is None else leave, preset,
                             None if frames is not None else LEAVE_MIN_FRAMES)
    elif leave:
        plans = with_leavers(plans, leave)
    return with_options(plans, None if trajectories is None else str(trajectories),
                        None if background is None else str(background), wearer=wearer)


def run_synth(
    out: Path,
    preset: str | None = None,
    seed: int = 0,
    videos: int | None = None,
    frames: int | None = None,
    intervals: int | None = None,
    size: str = "1280x720",
    fps: float = 30.0,
    trajectories: Path | None = None,
    background: Path | None = None,
    output_format: str = "mp4",
    jobs: int = 2,
    preview: bool | None = None,
    force: bool = False,
    echo: bool = True,
    max_pan: float = 30.0,
    max_roll: float = 10.0,
    scale_range: str = "0.7,1.4",
    leave: int | None = None,
    targets: int | None = None,
) -> list[VideoResult]:
    """Generate a synthetic dataset; what ``trackfw dataset synth`` runs."""
    started = time.perf_counter()
    if output_format not in FORMATS:
        raise UserError(f"--format {output_format!r}: expected one of {', '.join(FORMATS)}.")
    plans = build_plans(preset, seed, videos, frames, intervals, parse_size(size), fps,
                        trajectories, background, wearer_config(max_pan, max_roll, scale_range),
                        leave, targets)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: is a file; expected a folder for the dataset.")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"--out {out}: the folder is not empty; choose another one or add --force.")
    check_output_folder(out, "--out")
    show_preview = (preset is not None) if preview is None else preview
    total_frames = sum(plan.n_frames for plan in plans)
    if echo:
        typer.echo(f"Generating {len(plans)} video(s), {total_frames} frames, into {out}"
                   f" with {jobs} process(es)...")

    def progress(result: VideoResult, done: int, total: int) -> None:
        if echo:
            typer.echo(f"  [{done}/{total}] {result.name}: {result.n_frames} frames,"
                       f" {result.n_intervals} interval(s), {result.seconds:.1f} s")

    results = generate_dataset(plans, out, output_format=output_format, jobs=jobs,
                               preview=show_preview, force=force, progress=progress)
    write_json(out / "synth.json", {
        "generator": "trackfw dataset synth",
        "preset": preset,
        "seed": seed,
        "size": size,
        "fps": fps,
        "format": output_format,
        "trajectories": None if trajectories is None else str(trajectories),
        "background": None if background is None else str(background),
        # Only written when targets leave, so that the files of every other dataset stay as
        # they were before the option existed.
        **({"leave": plans[0].leave} if plans[0].leave else {}),
        "videos": [{"name": plan.name, "n_frames": plan.n_frames, "site": plan.site.name,
                    "intervals": [[i.start + 1, i.end + 1, i.kind] for i in plan.intervals]}
                   for plan in plans],
    })
    if echo:
        elapsed = time.perf_counter() - started
        typer.echo(f"Done: {len(results)} video(s), {total_frames} frames in {elapsed:.1f} s"
                   f"{' (previews in ' + str(out / 'preview') + ')' if show_preview else ''}.")
    return results


def register(dataset_app: typer.Typer) -> None:
    """Add the ``synth`` command to the ``trackfw dataset`` group."""

    @dataset_app.command("synth")
    def synth(
        out: Annotated[Path, typer.Option("--out", help="Dataset folder to create.")],
        preset: Annotated[str | None, typer.Option(
            help="'paper': 30 videos from 10 sites like Yu et al. 2018 (26 with an interval);"
            " 'paper-leave': the same with one target per video walking out of view and back"
            " (videos of at least 450 frames).")] = None,
        seed: Annotated[int, typer.Option(help="Random seed; the same seed gives the same data.")] = 0,
        videos: Annotated[int | None, typer.Option(help="Number of videos (paper: 30, else 1).")] = None,
        frames: Annotated[int | None, typer.Option(
            help="Frames per video (paper: 90-351 each, else 300).")] = None,
        intervals: Annotated[int | None, typer.Option(
            help="Info-less intervals per video (paper: 1 for 26 videos, else 1).")] = None,
        size: Annotated[str, typer.Option(help="Frame size WIDTHxHEIGHT.")] = "1280x720",
        fps: Annotated[float, typer.Option(help="Frame rate.")] = 30.0,
        trajectories: Annotated[Path | None, typer.Option(
            help="ETH/UCY 'frame id x y' file or folder for real walking motion.")] = None,
        background: Annotated[Path | None, typer.Option(
            help="Ground image (a top view, or an OpenTraj reference.png with H.txt beside it).")] = None,
        output_format: Annotated[str, typer.Option("--format", help="mp4 (video.mp4) or jpg (img1/).")] = "mp4",
        jobs: Annotated[int, typer.Option(help="Parallel processes, one video each.")] = 2,
        preview: Annotated[bool | None, typer.Option(
            "--preview/--no-preview", help="Save preview PNGs in OUT/preview (default: on for a preset).",
            show_default=False)] = None,
        force: Annotated[bool, typer.Option(help="Write into a non-empty folder, replacing videos.")] = False,
        max_pan: Annotated[float, typer.Option(
            help="Largest pan change across an interval (degrees).")] = 30.0,
        max_roll: Annotated[float, typer.Option(
            help="Largest roll change across an interval (degrees).")] = 10.0,
        scale_range: Annotated[str, typer.Option(
            help="Scale factor range across an interval, LOW,HIGH.")] = "0.7,1.4",
        leave: Annotated[int | None, typer.Option(
            help="Targets per video that walk out of view and come back (0-5; paper-leave: 1,"
            " else 0).")] = None,
        targets: Annotated[int | None, typer.Option(
            "--targets", help="People of interest per video (1-12; default: 5 to 10); the other"
            " pedestrians are bystanders, in heads.csv and not in gt.csv.")] = None,
    ) -> None:
        """Render a synthetic wearable-camera dataset with ground truth."""
        run_synth(out, preset=preset, seed=seed, videos=videos, frames=frames, intervals=intervals,
                  size=size, fps=fps, trajectories=trajectories, background=background,
                  output_format=output_format, jobs=jobs, preview=preview, force=force,
                  max_pan=max_pan, max_roll=max_roll, scale_range=scale_range, leave=leave,
                  targets=targets)

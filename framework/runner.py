"""Glue between the command line and the engine: resolve inputs, check, run, write.

Everything that can be wrong with the user's input is checked in :func:`prepare_run`, before any
output file or folder is created.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from trackfw.atomic import check_output_folder
from trackfw.dataset import list_videos, load_video
from trackfw.engine import Engine, VideoRun, check_videos
from trackfw.errors import UserError
from trackfw.formats.run import SUMMARY_FILE, write_run
from trackfw.formats.text import read_json
from trackfw.pipeline import Pipeline, load_pipeline
from trackfw.progress import progress_bar
from trackfw.records import VideoContext
from trackfw.registry import Registry, unknown_name_message
from trackfw.targets import TargetChooser

BUILTIN_PREFIX = "builtin:"


@dataclass
class PreparedRun:
    """A run whose pipeline and inputs were fully checked."""

    pipeline: Pipeline
    videos: list[VideoContext]
    output: Path


def resolve_input(registry: Registry, value: str, where: str) -> Path:
    """A path from ``builtin:NAME`` or a filesystem path; ``where`` names the field for errors."""
    if value.startswith(BUILTIN_PREFIX):
        name = value[len(BUILTIN_PREFIX) :]
        entry = registry.inputs.get(name)
        if entry is None:
            raise UserError(
                f"{where}: {unknown_name_message('input', name, sorted(registry.inputs))}."
            )
        return Path(entry.factory())
    path = Path(value).expanduser()
    if not path.exists():
        raise UserError(
            f"{where}: {value!r} does not exist; expected a video file, a video folder or a dataset folder."
        )
    return path


def prepare_run(
    registry: Registry,
    pipeline_path: Path,
    input_value: str | None,
    output: Path | None,
    overrides: Sequence[str],
) -> PreparedRun:
    """Validate the pipeline, resolve and read every input video; writes nothing."""
    pipeline = load_pipeline(pipeline_path, registry, overrides)
    # Checked before the videos are read: a run must not end in "cannot write" after the work.
    destination = output or Path("runs") / pipeline.name
    check_output_folder(destination, "--output" if output is not None else "output (default)")
    if input_value is not None:
        source = resolve_input(registry, input_value, "--input")
    elif pipeline.input is not None:
        source = resolve_input(registry, pipeline.input, f"{pipeline_path}: input")
    else:
        raise UserError(
            f"{pipeline_path}: input: missing; give --input or set 'input:' in the pipeline."
        )
    videos = [load_video(path) for path in list_videos(source)]
    check_videos(pipeline.build(), videos)
    if pipeline.is_batch and pipeline.engine.init in ("region", "targets"):
        raise UserError(
            f"{pipeline_path}: engine.init: {pipeline.engine.init}: the batch pipeline"
            f" {pipeline.name!r} tracks every detection; choosing targets applies to segment"
            " pipelines."
        )
    TargetChooser(pipeline.engine).check(videos)
    return PreparedRun(pipeline, videos, destination)


def replaced_runs(prepared: PreparedRun) -> list[str]:
    """One sentence per video folder of ``prepared`` that holds another pipeline's run.

    Re-running a pipeline into its own folder is common and says nothing; a run of another
    pipeline there is most likely a mistyped ``-o`` and is about to be replaced.
    """
    messages = []
    for video in prepared.videos:
        summary = prepared.output / video.name / SUMMARY_FILE
        if not summary.is_file():
            continue
        try:
            previous = read_json(summary)
        except UserError:
            continue  # an unreadable summary names no pipeline to warn about
        if isinstance(previous, dict) and previous.get("pipeline") not in (
            None,
            prepared.pipeline.name,
        ):
            messages.append(
                f"{summary.parent} holds a run of pipeline {previous['pipeline']!r}; this run of"
                f" {prepared.pipeline.name!r} replaces it."
            )
    return messages


def run_prepared(
    prepared: PreparedRun,
    registry: Registry,
    show_progress: bool = True,
    console: Any = None,
) -> list[tuple[VideoRun, Path]]:
    """Run every video and write its outputs; returns the runs and their folders."""
    engine = Engine(prepared.pipeline, registry)
    results: list[tuple[VideoRun, Path]] = []
    if not show_progress:
        for video in prepared.videos:
            run = engine.run_video(video)
            results.append((run, write_run(run, prepared.pipeline, prepared.output / video.name)))
        return results
    total = sum(video.n_frames for video in prepared.videos)
    with progress_bar(console, "frames", "remaining") as progress:
        task = progress.add_task(prepared.pipeline.name, total=total)
        done = 0
        for video in prepared.videos:
            progress.update(task, description=f"{prepared.pipeline.name}: {video.name}")
            offset = done

            def advance(t: int, offset: int = offset) -> None:
                progress.update(task, completed=offset + t + 1)

            run = engine.run_video(video, progress=advance)
            done += video.n_frames
            results.append((run, write_run(run, prepared.pipeline, prepared.output / video.name)))
    return results

"""A sweep: every (pipeline, video) job of a benchmark, planned, run and recorded.

Output layout under ``out``::

    runs/<pipeline name>-<content hash>/pipeline.json     the resolved pipeline
    runs/<pipeline name>-<content hash>/<video>/          tracks.txt, frames.csv, gaps.json,
                                                          bench.json, summary.json (last)
    cache/<video>-<key>.npz                               detector and classifier outputs
    failures.json                                         the jobs that raised or timed out
    manifest.json                                         every job's result of the last sweep

Everything the user can get wrong (pipelines, overrides, the dataset, ground truth or frames a
stage needs) is checked by :func:`plan_sweep` before anything is written.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from trackfw.atomic import check_output_folder, write_json
from trackfw.dataset import list_videos, load_video
from trackfw.engine import check_videos
from trackfw.errors import UserError
from trackfw.pipeline import Pipeline, load_pipeline
from trackfw.records import VideoContext
from trackfw.registry import Registry
from trackfw.stage_cache import StageCache, cache_key
from trackfw.yaml_loading import parse_yaml
from trackfw_plugins.bench.jobs import Job, JobResult, is_done

RUNS_FOLDER = "runs"
CACHE_FOLDER = "cache"
FAILURES_FILE = "failures.json"
MANIFEST_FILE = "manifest.json"
PIPELINE_FILE = "pipeline.json"


@dataclass
class PlannedPipeline:
    """A validated pipeline of the sweep and its runs folder."""

    pipeline: Pipeline
    file: Path
    runs_dir: Path

    @property
    def label(self) -> str:
        """``<name>-<hash>``: the runs folder's name."""
        return self.runs_dir.name


@dataclass
class SweepPlan:
    """Every job of a sweep, checked and ready to run.

    Attributes:
        dataset: the dataset folder.
        out_dir: the output folder.
        cache_dir: the stage cache folder, or None.
        pipelines: the pipelines, in command-line order, without duplicates.
        videos: the dataset's videos.
        jobs: one per (pipeline, video), pipeline by pipeline.
        cache_keys: job label -> stage cache key (empty without a cache).
        detector_keys: job label -> the key of its detector alone, for the jobs that record it
            for a batch pipeline of the plan (``Job.share_detector``).
    """

    dataset: Path
    out_dir: Path
    cache_dir: Path | None
    pipelines: list[PlannedPipeline]
    videos: list[VideoContext]
    jobs: list[Job]
    cache_keys: dict[str, str] = field(default_factory=dict)
    detector_keys: dict[str, str] = field(default_factory=dict)


@dataclass
class SweepResult:
    """The plan and one result per job (in the plan's order)."""

    plan: SweepPlan
    results: list[JobResult]
    seconds: float = 0.0

    def count(self, status: str) -> int:
        """How many jobs ended with ``status`` (done, skipped, failed)."""
        return sum(1 for result in self.results if result.status == status)

    @property
    def failures(self) -> list[JobResult]:
        """The failed jobs."""
        return [result for result in self.results if result.status == "failed"]


def runs_folder_name(pipeline: Pipeline) -> str:
    """``<name>-<content hash>`` with characters unsafe in a folder name replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", pipeline.name) + f"-{pipeline.content_hash}"


def split_overrides(
    overrides: Sequence[str], pipeline_files: Sequence[Path]
) -> dict[Path, list[str]]:
    """Per pipeline file, the ``--set`` values that apply to it.

    ``PATH=VALUE`` applies to every pipeline; ``NAME:PATH=VALUE`` only to the pipeline whose file
    stem or ``name`` is NAME (``proposed-oracle:stages.gap_matcher.params.lambda2=0``).

    Raises:
        UserError: a NAME that matches no pipeline.
    """
    names: dict[Path, set[str]] = {}
    for path in pipeline_files:
        aliases = {path.stem}
        if path.is_file():
            try:
                data = parse_yaml(path.read_text(encoding="utf-8"), str(path))
            except (UserError, OSError, UnicodeDecodeError):
                data = None  # load_pipeline reports it properly
            if isinstance(data, dict) and isinstance(data.get("name"), str):
                aliases.add(data["name"])
        names[path] = aliases
    selected: dict[Path, list[str]] = {path: [] for path in pipeline_files}
    for override in overrides:
        target, equals, _ = override.partition("=")
        prefix, colon, _ = target.partition(":")
        if not equals or not colon:
            for values in selected.values():
                values.append(override)
            continue
        matching = [path for path, aliases in names.items() if prefix.strip() in aliases]
        if not matching:
            known = sorted({alias for aliases in names.values() for alias in aliases})
            raise UserError(
                f"--set {override!r}: no pipeline is named {prefix.strip()!r};"
                f" expected one of {', '.join(known)} before ':'."
            )
        for path in matching:
            selected[path].append(override[len(prefix) + 1 :].strip())
    return selected


def plan_sweep(
    registry: Registry,
    pipeline_files: Sequence[Path],
    dataset: Path,
    out_dir: Path,
    overrides: Sequence[str] = (),
    cache_dir: Path | None = None,
    use_cache: bool = True,
    timeout_s: float | None = None,
) -> SweepPlan:
    """Load and check every pipeline and video, and list the jobs; writes nothing.

    Args:
        registry: the plugin registry.
        pipeline_files: pipeline YAML files.
        dataset: a dataset folder (or one video folder).
        out_dir: the output folder.
        overrides: ``--set`` values (see :func:`split_overrides`).
        cache_dir: the stage cache folder; default ``<out>/cache``.
        use_cache: False disables the stage cache.
        timeout_s: per-job time limit in seconds, or None.

    Raises:
        UserError: every problem with the pipelines; the first problem with the dataset.
    """
    if not pipeline_files:
        raise UserError("trackfw bench: no pipeline given; expected one or more YAML files.")
    if timeout_s is not None and not timeout_s > 0:
        raise UserError(f"--timeout is {timeout_s}; expected a positive number of seconds.")
    dataset = Path(dataset)
    # Absolute paths: jobs may run in processes (or on machines) with another working folder.
    out_dir = Path(out_dir).resolve()
    check_output_folder(out_dir, "--out")
    if use_cache and cache_dir is not None:
        check_output_folder(cache_dir, "--cache-dir")
    per_file = split_overrides(overrides, [Path(path) for path in pipeline_files])
    planned = _load_pipelines(registry, per_file, out_dir)
    videos = _load_videos(dataset)
    for entry in planned:
        check_videos(entry.pipeline.build(), videos)
    if use_cache:
        cache_dir = Path(cache_dir).resolve() if cache_dir is not None else out_dir / CACHE_FOLDER
    else:
        cache_dir = None
    jobs, keys, detector_keys = _list_jobs(registry, planned, videos, cache_dir, timeout_s)
    return SweepPlan(dataset, out_dir, cache_dir, planned, videos, jobs, keys, detector_keys)


def _load_pipelines(
    registry: Registry, per_file: dict[Path, list[str]], out_dir: Path
) -> list[PlannedPipeline]:
    """Each file's pipeline with its overrides, once per configuration; every problem at once."""
    problems: list[str] = []
    planned: list[PlannedPipeline] = []
    seen: set[str] = set()
    for path, selected in per_file.items():
        try:
            pipeline = load_pipeline(path, registry, selected)
        except UserError as error:
            problems.extend(error.lines)
            continue
        entry = PlannedPipeline(pipeline, path, out_dir / RUNS_FOLDER / runs_folder_name(pipeline))
        if entry.label not in seen:  # the same configuration twice is one set of jobs
            seen.add(entry.label)
            planned.append(entry)
    if problems:
        raise UserError(*problems)
    return planned


def _load_videos(dataset: Path) -> list[VideoContext]:
    """The dataset's videos, refused when two share a name (their runs would share a folder)."""
    videos = [load_video(path) for path in list_videos(dataset)]
    names = [video.name for video in videos]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise UserError(
            f"{dataset}: several videos are named {', '.join(duplicates)}; expected unique names."
        )
    return videos


def _list_jobs(
    registry: Registry,
    planned: Sequence[PlannedPipeline],
    videos: Sequence[VideoContext],
    cache_dir: Path | None,
    timeout_s: float | None,
) -> tuple[list[Job], dict[str, str], dict[str, str]]:
    """One job per (pipeline, video), and each job's stage cache keys when the cache is used.

    Returns:
        The jobs, each job's key, and the key of the detector alone of the jobs of pipelines
        with a classifier whose detector a batch pipeline of the plan uses (those jobs record
        it: ``Job.share_detector``).
    """
    jobs: list[Job] = []
    keys: dict[str, str] = {}
    detector_keys: dict[str, str] = {}
    batch_keys: set[str] = set()
    for entry in planned:
        for video in videos:
            job = Job(
                pipeline_name=entry.pipeline.name,
                pipeline_hash=entry.pipeline.content_hash,
                pipeline_config=entry.pipeline.config,
                pipeline_file=str(entry.file.resolve()),
                video_name=video.name,
                video_path=str(Path(video.path).resolve()),
                run_dir=str(entry.runs_dir / video.name),
                cache_dir=None if cache_dir is None else str(cache_dir),
                timeout_s=timeout_s,
            )
            jobs.append(job)
            if cache_dir is None:
                continue
            keys[job.label] = cache_key(entry.pipeline, video, registry)
            if entry.pipeline.is_batch:
                batch_keys.add(keys[job.label])
            else:  # a segment pipeline: detector + classifier
                detector_keys[job.label] = cache_key(entry.pipeline, video, registry, ("detector",))
    # Only where a batch pipeline of the plan reads it is the detector recorded alone.
    detector_keys = {label: key for label, key in detector_keys.items() if key in batch_keys}
    jobs = [replace(job, share_detector=job.label in detector_keys) for job in jobs]
    return jobs, keys, detector_keys


def schedule(plan: SweepPlan, pending: Sequence[Job]) -> list[list[Job]]:
    """Split pending jobs into waves so that detection runs once per video and configuration.

    The first wave holds every job whose stage outputs are cached already (or that uses no
    cache) and one job per missing cache entry; the second the jobs that will replay what the
    first wave records. A job that records its detector alone for a batch pipeline
    (``Job.share_detector``) is placed first, so that the batch job replays it.
    Without a cache there is one wave.
    """
    if plan.cache_dir is None:
        return [list(pending)] if pending else []
    cache = StageCache(plan.cache_dir)
    first: list[Job] = []
    second: list[Job] = []
    coming: set[str] = set()  # entries a first-wave job will write
    for job in sorted(pending, key=lambda job: job.label not in plan.detector_keys):
        key = plan.cache_keys.get(job.label)
        if key is not None and not cache.contains(key, job.video_name):
            if key in coming:
                second.append(job)
                continue
            coming.add(key)
        first.append(job)
        detector_key = plan.detector_keys.get(job.label)
        if detector_key is not None and not cache.contains(detector_key, job.video_name):
            coming.add(detector_key)
    return [wave for wave in (first, second) if wave]


def _failure_entries(results: Sequence[JobResult]) -> list[dict[str, Any]]:
    return [
        {
            "pipeline": result.pipeline,
            "pipeline_hash": result.pipeline_hash,
            "video": result.video,
            "run_dir": result.run_dir,
            "error_type": result.error_type,
            "error_message": result.error_message,
            "seconds": round(result.seconds, 3),
            "worker": result.worker,
            "traceback": result.traceback,
        }
        for result in results
        if result.status == "failed"
    ]


def write_manifest(result: SweepResult, executor_name: str = "") -> Path:
    """manifest.json: the plan and every job's result."""
    plan = result.plan
    path = plan.out_dir / MANIFEST_FILE
    write_json(
        path,
        {
            "dataset": str(plan.dataset),
            "executor": executor_name,
            "cache_dir": None if plan.cache_dir is None else str(plan.cache_dir),
            "seconds": round(result.seconds, 3),
            "counts": {status: result.count(status) for status in ("done", "skipped", "failed")},
            "pipelines": [
                {
                    "name": entry.pipeline.name,
                    "hash": entry.pipeline.content_hash,
                    "file": str(entry.file),
                    "runs_dir": str(entry.runs_dir),
                }
                for entry in plan.pipelines
            ],
            "videos": [video.name for video in plan.videos],
            "jobs": [
                {key: value for key, value in item.to_dict().items() if key != "traceback"}
                for item in result.results
            ],
        },
    )
    return path


def run_sweep(
    plan: SweepPlan,
    executor: Any,
    on_result: Callable[[JobResult], None] | None = None,
    executor_name: str = "",
) -> SweepResult:
    """Run every job that is not done; failures are recorded in failures.json as they happen.

    Args:
        plan: from :func:`plan_sweep`.
        executor: an object with ``run(jobs, on_result)`` (see :mod:`trackfw_plugins.bench.executor`).
        on_result: called with each job's result (progress display).
        executor_name: recorded in manifest.json.
    """
    started = time.perf_counter()
    for entry in plan.pipelines:
        write_json(entry.runs_dir / PIPELINE_FILE, entry.pipeline.config)
    results: dict[str, JobResult] = {}
    failures_path = plan.out_dir / FAILURES_FILE

    def record(result: JobResult) -> None:
        label = f"{result.pipeline}-{result.pipeline_hash}/{result.video}"
        results[label] = result
        if result.status == "failed":
            write_json(failures_path, _failure_entries(list(results.values())))
        if on_result is not None:
            on_result(result)

    pending: list[Job] = []
    for job in plan.jobs:
        if is_done(job.run_dir):
            record(JobResult.for_job(job, "skipped"))
        else:
            pending.append(job)
    try:
        for wave in schedule(plan, pending):
            executor.run(wave, record)
    finally:
        close = getattr(executor, "close", None)
        if callable(close):
            close()
    for job in plan.jobs:
        if job.label not in results:
            record(
                JobResult.failure(job, RuntimeError("the executor returned no result for this job"))
            )
    ordered = [results[job.label] for job in plan.jobs]
    write_json(failures_path, _failure_entries(ordered))
    sweep = SweepResult(plan, ordered, time.perf_counter() - started)
    write_manifest(sweep, executor_name)
    return sweep


__all__ = [
    "CACHE_FOLDER",
    "FAILURES_FILE",
    "MANIFEST_FILE",
    "RUNS_FOLDER",
    "PlannedPipeline",
    "SweepPlan",
    "SweepResult",
    "plan_sweep",
    "run_sweep",
    "runs_folder_name",
    "schedule",
    "split_overrides",
]

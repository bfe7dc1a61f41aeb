"""The benchmark's unit of work: one pipeline over one video.

A :class:`Job` is plain data (it travels to worker processes and Dask workers) and idempotent: its
output folder derives from the job (``<out>/runs/<pipeline name>-<content hash>/<video>/``), a
job whose ``summary.json`` exists is done and skipped, and a run's files are written atomically
with ``summary.json`` last, so a sweep killed at any moment resumes without taking a half-written
result as done. :func:`run_job` never raises for a job's own failure: it returns a failed
:class:`JobResult` and the sweep goes on.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trackfw.atomic import write_json
from trackfw.formats.run import SUMMARY_FILE

if TYPE_CHECKING:
    from trackfw.registry import Registry

#: Per-run record of the benchmark (cache use, replayed stage time), written before summary.json.
BENCH_FILE = "bench.json"
#: Environment that keeps numeric libraries to one thread per worker process.
SINGLE_THREAD_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "VECLIB_MAXIMUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
}


class JobTimeoutError(Exception):
    """A job ran past its time limit."""


@dataclass(frozen=True)
class Job:
    """One pipeline over one video.

    Attributes:
        pipeline_name: the pipeline's name.
        pipeline_hash: :attr:`trackfw.pipeline.Pipeline.content_hash` of the resolved config.
        pipeline_config: the resolved configuration (``Pipeline.config``), validated again by the
            worker.
        pipeline_file: the YAML file it came from (recorded in summary.json), or None.
        video_name: the video's name.
        video_path: the video folder or file.
        run_dir: where the run's files go.
        cache_dir: the stage cache folder, or None for no cache.
        timeout_s: time limit in seconds, or None.
        share_detector: also record the detector's outputs alone in the cache, for a batch
            pipeline of the same sweep that uses the same detector without a classifier.
    """

    pipeline_name: str
    pipeline_hash: str
    pipeline_config: dict[str, Any] = field(compare=False, hash=False)
    pipeline_file: str | None
    video_name: str
    video_path: str
    run_dir: str
    cache_dir: str | None = None
    timeout_s: float | None = None
    share_detector: bool = field(default=False, compare=False)

    @property
    def label(self) -> str:
        """``<pipeline name>-<hash>/<video>``, unique within a sweep."""
        return f"{self.pipeline_name}-{self.pipeline_hash}/{self.video_name}"


@dataclass
class JobResult:
    """What became of a job.

    Attributes:
        pipeline, pipeline_hash, video, run_dir: which job.
        status: ``done`` (ran now), ``skipped`` (done by an earlier sweep) or ``failed``.
        seconds: wall-clock time of the job.
        cache: ``hit`` (detector and classifier replayed), ``miss`` (computed and stored),
            ``off``, or None when the job did not run.
        error_type, error_message, traceback: for failed jobs.
        worker: ``host:pid`` that ran it.
    """

    pipeline: str
    pipeline_hash: str
    video: str
    run_dir: str
    status: str
    seconds: float = 0.0
    cache: str | None = None
    error_type: str | None = None
    error_message: str | None = None
    traceback: str | None = None
    worker: str = ""

    @classmethod
    def for_job(cls, job: Job, status: str, **values: Any) -> JobResult:
        """A result naming ``job``."""
        return cls(
            job.pipeline_name, job.pipeline_hash, job.video_name, job.run_dir, status, **values
        )

    @classmethod
    def failure(cls, job: Job, error: BaseException, seconds: float = 0.0) -> JobResult:
        """A failed result from an exception (message and the last lines of the traceback)."""
        lines = traceback.format_exception(type(error), error, error.__traceback__)
        return cls.for_job(
            job,
            "failed",
            seconds=seconds,
            error_type=type(error).__name__,
            error_message=str(error).strip() or type(error).__name__,
            traceback="".join(lines)[-4000:],
            worker=worker_name(),
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return asdict(self)


def worker_name() -> str:
    """``host:pid`` of this process."""
    return f"{socket.gethostname()}:{os.getpid()}"


def is_done(run_dir: str | os.PathLike[str]) -> bool:
    """True when the run folder holds a complete run (summary.json, written last, parses)."""
    summary = Path(run_dir) / SUMMARY_FILE
    if not summary.is_file():
        return False
    try:
        return isinstance(json.loads(summary.read_text(encoding="utf-8")), dict)
    except (OSError, ValueError):
        return False


def pin_threads() -> None:
    """Keep this process to one thread per library (worker initialiser).

    Sets the usual environment variables for libraries loaded later, limits already loaded BLAS
    and OpenMP pools (threadpoolctl, when installed) and OpenCV. onnxruntime sessions take their
    thread count from the pipeline (``intra_op_threads``, default 1).
    """
    os.environ.update(SINGLE_THREAD_ENVIRONMENT)
    try:
        import cv2

        cv2.setNumThreads(1)
    except ImportError:  # pragma: no cover - OpenCV is a dependency
        pass
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:  # pragma: no cover - optional
        pass


_worker_registry: Registry | None = None


def worker_registry() -> Registry:
    """The plugin registry of this process, loaded on first use."""
    global _worker_registry
    if _worker_registry is None:
        from trackfw.registry import load_registry

        _worker_registry = load_registry()
    return _worker_registry


@contextmanager
def deadline(timeout_s: float | None) -> Iterator[Callable[[int], None]]:
    """A progress callback that raises :class:`JobTimeoutError` once ``timeout_s`` has passed.

    The engine calls it on every frame, which works in any thread (Dask runs tasks in threads).
    In a process's main thread a SIGALRM timer also interrupts a stage stuck inside one frame.
    """
    if timeout_s is None or timeout_s <= 0:
        yield lambda t: None
        return
    limit = time.monotonic() + timeout_s

    def check(t: int) -> None:
        if time.monotonic() > limit:
            raise JobTimeoutError(f"ran past the time limit of {timeout_s:g} s (at frame {t + 1})")

    use_alarm = threading.current_thread() is threading.main_thread() and hasattr(
        signal, "setitimer"
    )
    previous: Any = None
    if use_alarm:

        def on_alarm(signum: int, frame: Any) -> None:
            raise JobTimeoutError(f"ran past the time limit of {timeout_s:g} s")

        previous = signal.signal(signal.SIGALRM, on_alarm)
        # A little later than the per-frame check, which names the frame.
        signal.setitimer(signal.ITIMER_REAL, timeout_s + 0.5)
    try:
        yield check
    finally:
        if use_alarm:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)


def run_job(job: Job, registry: Registry | None = None) -> JobResult:
    """Run one job unless it is done; never raises for the job's own failure.

    Args:
        job: the job.
        registry: the plugin registry; default the process's own (:func:`worker_registry`).
    """
    started = time.perf_counter()
    if is_done(job.run_dir):
        return JobResult.for_job(job, "skipped", worker=worker_name())
    try:
        with deadline(job.timeout_s) as check:
            cache_state = _run(job, registry or worker_registry(), check)
    except Exception as error:
        return JobResult.failure(job, error, time.perf_counter() - started)
    return JobResult.for_job(
        job,
        "done",
        seconds=time.perf_counter() - started,
        cache=cache_state,
        worker=worker_name(),
    )


def _run(job: Job, registry: Registry, progress: Callable[[int], None]) -> str:
    """Run the engine and write the run; returns the cache state."""
    from trackfw.dataset import load_video
    from trackfw.engine import Engine
    from trackfw.errors import UserError
    from trackfw.formats.run import write_run
    from trackfw.pipeline import validate_pipeline
    from trackfw.stage_cache import CACHED_KINDS, StageCache

    source = Path(job.pipeline_file) if job.pipeline_file else None
    pipeline = validate_pipeline(
        job.pipeline_config,
        registry,
        source=str(source or job.pipeline_name),
        build_check=False,
        path=source,
    )
    if pipeline.content_hash != job.pipeline_hash:
        raise UserError(
            f"{job.pipeline_file or job.pipeline_name}: the pipeline resolves to hash"
            f" {pipeline.content_hash} on worker {worker_name()}, expected {job.pipeline_hash};"
            " the worker has other plugin versions."
        )
    video = load_video(Path(job.video_path))
    cache = StageCache(job.cache_dir, job.share_detector) if job.cache_dir else None
    run = Engine(pipeline, registry).run_video(video, progress=progress, cache=cache)
    state = "off" if cache is None else ("hit" if cache.hits else "miss")
    replayed_ms = (
        sum(record.milliseconds.get(kind, 0.0) for record in run.frames for kind in CACHED_KINDS)
        if state == "hit"
        else 0.0
    )
    run_dir = Path(job.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    # summary.json marks completion; remove a stale one before anything else is rewritten.
    (run_dir / SUMMARY_FILE).unlink(missing_ok=True)
    write_json(
        run_dir / BENCH_FILE,
        {
            "job": job.label,
            "cache": state,
            "wall_seconds": round(run.seconds, 6),
            # On a hit the detector and classifier were not run: their recorded time is added so
            # that speed figures stay comparable with a run that computed them.
            "replayed_seconds": round(replayed_ms / 1e3, 6),
            "frames": len(run.frames),
            "worker": worker_name(),
        },
    )
    write_run(run, pipeline, run_dir)
    return state


__all__ = [
    "BENCH_FILE",
    "SINGLE_THREAD_ENVIRONMENT",
    "Job",
    "JobResult",
    "JobTimeoutError",
    "deadline",
    "is_done",
    "pin_threads",
    "run_job",
    "worker_name",
    "worker_registry",
]

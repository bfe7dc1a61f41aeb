"""Scaling of ``trackfw bench`` with the local executor: 1 worker versus 2 (or ``--workers``).

Builds a point-only dataset and sweeps the proposed method (oracle detector and intervals, no
appearance term, so no pixels) over it, without the stage cache so every job does the same work.
The 1-worker sweep runs in this process (what ``--jobs 1`` does); the N-worker sweep in a pool of
spawned worker processes, start-up included. Every process is pinned to one thread. Prints both times, the speed-up, the CPU count and
the load average (the speed-up cannot exceed the idle cores). Usage::

    python benchmarks/bench_scaling.py [--videos 12] [--frames 300] [--intervals 4] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from trackfw.registry import load_registry
from trackfw_plugins.bench.executor import ExecutorOptions, make_executor
from trackfw_plugins.bench.jobs import pin_threads
from trackfw_plugins.bench.sweep import plan_sweep, run_sweep
from trackfw_plugins.datasets.points import make_points_video

REPO = Path(__file__).resolve().parents[1]
PIPELINE = REPO / "pipelines" / "proposed-oracle.yaml"
# Point-only videos: neither the appearance term nor re-acquisition's appearance check.
OVERRIDES = [
    "stages.gap_matcher.params.lambda2=0",
    "stages.tracker.params.appearance.descriptor=none",
]


def _sweep(dataset: Path, out: Path, workers: int) -> tuple[float, float]:
    registry = load_registry()
    plan = plan_sweep(registry, [PIPELINE], dataset, out, OVERRIDES, use_cache=False)
    executor = make_executor(registry, "local", ExecutorOptions(jobs=workers, registry=registry))
    started = time.perf_counter()
    result = run_sweep(plan, executor)
    seconds = time.perf_counter() - started
    if result.failures or result.count("done") != len(plan.jobs):
        raise SystemExit(f"sweep with {workers} worker(s) failed: {result.failures[:1]}")
    return seconds, sum(job.seconds for job in result.results) / len(result.results)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--videos", type=int, default=12)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--intervals", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    arguments = parser.parse_args()
    spacing = arguments.frames // (arguments.intervals + 1)
    intervals = [(spacing * (i + 1), spacing * (i + 1) + 20) for i in range(arguments.intervals)]
    with tempfile.TemporaryDirectory() as folder:
        dataset = Path(folder) / "dataset"
        for index in range(arguments.videos):
            make_points_video(
                dataset / f"v{index:02d}",
                n_frames=arguments.frames,
                intervals=intervals,
                seed=index,
            )
        load_before = os.getloadavg()
        # One thread per process in both sweeps (the workers pin themselves the same way), so
        # the comparison is between processes, not between BLAS thread pools.
        pin_threads()
        serial, serial_job = _sweep(dataset, Path(folder) / "one", 1)
        parallel, parallel_job = _sweep(dataset, Path(folder) / "many", arguments.workers)
        load_after = os.getloadavg()
    jobs = arguments.videos
    print(
        f"proposed-oracle (lambda2=0), {jobs} jobs of {arguments.frames} frames and"
        f" {arguments.intervals} intervals each, no stage cache"
    )
    print(f"1 worker (in process): {serial:.2f} s (mean {serial_job:.2f} s per job)")
    print(
        f"{arguments.workers} workers (process pool, start-up included): {parallel:.2f} s"
        f" (mean {parallel_job:.2f} s per job)"
    )
    print(f"speed-up: {serial / parallel:.2f}x")
    print(
        f"cpu count {os.cpu_count()}; load average before {load_before[0]:.2f},"
        f" after {load_after[0]:.2f} (1-minute)"
    )


if __name__ == "__main__":
    main()

"""Time ``trackfw dataset synth --preset paper`` (30 videos, 1280x720) and print the figures.

Usage: ``python benchmarks/synth_speed.py [--jobs 2] [--videos 30] [--size 1280x720] [--keep DIR]``.
The target is under 3 minutes on a 2-core machine with ``--jobs 2``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from trackfw_plugins.datasets.synth.cli import run_synth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--videos", type=int, default=None, help="fewer videos for a quick look")
    parser.add_argument("--size", default="1280x720")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", type=Path, default=None, help="write here and keep the data")
    arguments = parser.parse_args()
    out = arguments.keep or Path(tempfile.mkdtemp(prefix="synth_speed_"))
    try:
        started = time.perf_counter()
        cpu_started = os.times()
        results = run_synth(
            out / "data",
            preset="paper",
            seed=arguments.seed,
            videos=arguments.videos,
            size=arguments.size,
            jobs=arguments.jobs,
            preview=True,
            echo=False,
        )
        elapsed = time.perf_counter() - started
        cpu = os.times()
        cpu_seconds = (cpu.children_user + cpu.children_system + cpu.user + cpu.system) - (
            cpu_started.children_user
            + cpu_started.children_system
            + cpu_started.user
            + cpu_started.system
        )
        frames = sum(result.n_frames for result in results)
        print(
            f"preset paper: {len(results)} videos, {frames} frames at {arguments.size},"
            f" jobs={arguments.jobs}"
        )
        print(
            f"elapsed {elapsed:.1f} s ({frames / elapsed:.1f} frames/s),"
            f" CPU {cpu_seconds:.1f} s ({1000 * cpu_seconds / frames:.1f} ms CPU per frame),"
            f" load average before/now: {os.getloadavg()[0]:.1f}"
        )
        print(f"target: < 180 s -> {'OK' if elapsed < 180 else 'SLOWER'}")
    finally:
        if arguments.keep is None:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()

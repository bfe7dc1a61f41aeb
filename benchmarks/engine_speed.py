"""Engine throughput with oracle stages (no pixels decoded): frames per second.

Issue target: >= 2000 frames/s with 10 targets. Usage::

    python benchmarks/engine_speed.py [--frames 3000] [--targets 10] [--repeats 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.pipeline import validate_pipeline
from trackfw.registry import load_registry
from trackfw_plugins.datasets.points import make_points_video

PIPELINE = {
    "name": "engine-benchmark",
    "stages": {
        "detector": {"type": "oracle", "params": {"jitter_px": 1.0, "false_positives": 2.0}},
        "classifier": {"type": "oracle"},
        "tracker": {"type": "kalman", "params": {"association": "hungarian"}},
        "gap_matcher": {"type": "assignment", "params": {"predictor": {"type": "kalman"}}},
    },
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=3000)
    parser.add_argument("--targets", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    arguments = parser.parse_args()
    registry = load_registry()
    pipeline = validate_pipeline(PIPELINE, registry)
    with tempfile.TemporaryDirectory() as folder:
        intervals = [(start, start + 40) for start in range(200, arguments.frames - 60, 500)]
        video_dir = make_points_video(
            Path(folder) / "bench",
            n_frames=arguments.frames,
            n_targets=arguments.targets,
            n_others=4,
            intervals=intervals,
        )
        video = load_video(video_dir)
        engine = Engine(pipeline, registry)
        rates = []
        for _ in range(arguments.repeats):
            started = time.perf_counter()
            run = engine.run_video(video)
            rates.append(len(run.frames) / (time.perf_counter() - started))
    print(
        f"engine, oracle detector+classifier, kalman/hungarian, {arguments.targets} targets, "
        f"{arguments.frames} frames, {len(intervals)} intervals, no pixels decoded"
    )
    print(
        f"frames per second: best {max(rates):.0f}, median {sorted(rates)[len(rates) // 2]:.0f} over {arguments.repeats} runs"
    )


if __name__ == "__main__":
    main()

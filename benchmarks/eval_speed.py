"""Time a full ``trackfw eval`` on a dataset-sized input (target: under 5 s for 30 videos).

Without arguments it writes a synthetic dataset and runs folder in the real formats to a temporary
folder: 30 videos of 200 frames, 8 walking targets, one or two info-less intervals each, tracks with
noise, a few identity swaps and false positives, and frames.csv with detections. With
``--dataset DIR --runs DIR`` it times those folders instead.

    python benchmarks/eval_speed.py [--videos 30] [--frames 200] [--targets 8] [--detections]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from trackfw.dataset import write_meta
from trackfw.formats.annotations import write_annotations
from trackfw.formats.run import FRAMES_FILE, GAPS_FILE, SUMMARY_FILE, TRACKS_FILE, frames_header
from trackfw.records import Interval
from trackfw_plugins.evaluation.report import EvalSettings, evaluate_dataset, write_reports

FRAMES_HEADER = ",".join(frames_header())


def write_synthetic(
    root: Path, n_videos: int, n_frames: int, n_targets: int, seed: int = 0
) -> tuple[Path, Path]:
    """Write ``root/dataset`` and ``root/runs``; returns both paths."""
    generator = np.random.default_rng(seed)
    dataset, runs = root / "dataset", root / "runs"
    for index in range(n_videos):
        name = f"video_{index:03d}"
        video, run = dataset / name, runs / name
        (video / "img1").mkdir(parents=True)
        run.mkdir(parents=True)
        write_meta(
            video / "meta.json", {"n_frames": n_frames, "width": 1920, "height": 1080, "fps": 30}
        )
        start = generator.uniform([200, 300], [1700, 800], size=(n_targets, 2))
        velocity = generator.normal(0.0, 1.5, size=(n_targets, 2))
        times = np.arange(n_frames)[:, None, None]
        positions = start[None] + velocity[None] * times  # (T, K, 2)
        n_intervals = 1 + index % 2
        intervals = []
        for slot in range(n_intervals):
            a = int(40 + slot * 80 + generator.integers(0, 20))
            intervals.append(Interval(a=a, b=a + int(generator.integers(18, 40)), kind="sky"))
        infoless = np.zeros(n_frames, dtype=bool)
        for interval in intervals:
            infoless[interval.a + 1 : interval.b] = True
        targets = {
            t: {k + 1: (float(x), float(y)) for k, (x, y) in enumerate(positions[t])}
            for t in range(n_frames)
            if not infoless[t]
        }
        heads = [
            (t, k, x, y, 80.0) for t, points in targets.items() for k, (x, y) in points.items()
        ]
        write_annotations(video, targets, heads, intervals)
        # Tracks: noisy copies, a swap after the first interval, a false positive now and then.
        track_ids = np.arange(1, n_targets + 1)
        lines = []
        frame_rows = [FRAMES_HEADER]
        for t in range(n_frames):
            if t >= intervals[0].b:
                track_ids = track_ids.copy()
                track_ids[[0, 1]] = [2, 1]
            points = positions[t] + generator.normal(0.0, 3.0, size=(n_targets, 2))
            if not infoless[t]:
                for track_id, (x, y) in zip(track_ids.tolist(), points, strict=True):
                    lines.append(
                        f"{t + 1},{track_id},{x - 40:.2f},{y - 40:.2f},80.00,80.00,1.00,-1,-1,-1"
                    )
                if t % 17 == 0:
                    lines.append(
                        f"{t + 1},99,{generator.uniform(0, 1800):.2f},50.00,80.00,80.00,1.00,-1,-1,-1"
                    )
            detections = ";".join(f"{x:.1f} {y:.1f}" for x, y in points)
            label = int(infoless[t] != (t % 29 == 0))
            frame_rows.append(
                f"{t + 1},ok,{0.8 if label else 0.2},{label},{n_targets},{detections},5,1,1,0"
            )
        (run / TRACKS_FILE).write_text("\n".join(lines) + "\n", encoding="utf-8")
        (run / FRAMES_FILE).write_text("\n".join(frame_rows) + "\n", encoding="utf-8")
        (run / SUMMARY_FILE).write_text("{}\n", encoding="utf-8")
        (run / GAPS_FILE).write_text("[]\n", encoding="utf-8")
    return dataset, runs


def main() -> None:
    """Parse the arguments, build or take the input, print the evaluation time."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path)
    parser.add_argument("--runs", type=Path)
    parser.add_argument("--videos", type=int, default=30)
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--targets", type=int, default=8)
    parser.add_argument("--detections", action="store_true", help="also score head detections")
    arguments = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        if arguments.dataset is not None and arguments.runs is not None:
            dataset, runs = arguments.dataset, arguments.runs
        else:
            dataset, runs = write_synthetic(
                Path(temporary), arguments.videos, arguments.frames, arguments.targets
            )
        started, cpu_started = time.perf_counter(), time.process_time()
        evaluation = evaluate_dataset(dataset, runs, EvalSettings(detections=arguments.detections))
        evaluated = time.perf_counter()
        write_reports(evaluation, Path(temporary) / "out")
        finished, cpu_finished = time.perf_counter(), time.process_time()
    pooled = evaluation.pooled_row()
    print(f"videos: {len(evaluation.videos)}")
    print(
        f"pooled MOTA {pooled['MOTA']:.1f} %, MOTA-In {pooled['MOTA-In']:.1f} %, HOTA {pooled['HOTA']:.1f} %"
    )
    print(f"evaluation (read + metrics): {evaluated - started:.2f} s")
    print(f"full evaluation incl. eval.csv/eval.json: {finished - started:.2f} s (target < 5 s)")
    # CPU time is the fairer figure on a shared machine.
    print(f"CPU time of the full evaluation: {cpu_finished - cpu_started:.2f} s")


if __name__ == "__main__":
    main()

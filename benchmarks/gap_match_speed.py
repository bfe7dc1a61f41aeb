"""Seconds per gap match of the window-based TPS-RPM association (ALGORITHMS.md §4).

One gap match = build the windows of V once, then associate three candidate predictions U
(the AR orders 1–3, |U| = 8) with V, and pick the best. Scenes: a group of 8 people after a
camera-pose change (rotation up to ±15°, scale 0.8–1.25, 6 px noise) among clutter laid out
uniformly or in clusters, with |V| = 30 and 50 detections. Threads are pinned to one.

Targets (one core): under 1 s at |V| = 30 and under 5 s at |V| = 50. Usage::

    python benchmarks/gap_match_speed.py [--repeats 1] [--precision float64 float32]
"""

from __future__ import annotations

import argparse
import os
import time

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402 - after pinning the BLAS threads

from trackfw_plugins.maths.tps_rpm import TpsRpmSettings  # noqa: E402
from trackfw_plugins.maths.window_association import (  # noqa: E402
    WindowAssociationParams,
    associate_candidates,
    build_windows,
    select_candidate,
)

IMAGE = np.array([1920.0, 1080.0])


def make_scene(
    detection_count: int, clustered: bool, seed: int, size: int = 8
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Three candidate predictions (size, 2), detections (N, 2) and the true rows of V."""
    rng = np.random.default_rng(seed)
    while True:
        pattern = rng.uniform([0, 0], [500, 300], (size, 2))
        gaps = np.sqrt(np.sum((pattern[:, None] - pattern[None]) ** 2, axis=2))
        np.fill_diagonal(gaps, np.inf)
        if gaps.min() > 60:
            break
    angle, scale = rng.uniform(-0.26, 0.26), rng.uniform(0.8, 1.25)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    observed = (pattern - pattern.mean(axis=0)) @ rotation.T * scale
    observed += rng.uniform([700, 400], [1200, 700]) + rng.normal(0, 6, (size, 2))
    low, high = observed.min(axis=0) - 40, observed.max(axis=0) + 40
    centres = rng.uniform([0, 0], IMAGE, (4, 2))
    clutter: list[np.ndarray] = []
    while len(clutter) < detection_count - size:
        if clustered:
            point = centres[rng.integers(4)] + rng.normal(0, 150, 2)
        else:
            point = rng.uniform([0, 0], IMAGE)
        inside_group = np.all((point >= low) & (point <= high))
        if not inside_group and np.all((point >= 0) & (point <= IMAGE)):
            clutter.append(point)
    detections = np.vstack([observed, np.array(clutter)])
    permutation = rng.permutation(detection_count)
    predicted = pattern - pattern.mean(axis=0) + observed.mean(axis=0)
    candidates = [predicted + rng.normal(0, 6, (size, 2)) for _ in range(3)]
    return candidates, detections[permutation], np.argsort(permutation)[:size]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1, help="timed gap matches per scene")
    parser.add_argument("--counts", type=int, nargs="+", default=[30, 50], help="|V| values")
    parser.add_argument(
        "--precision", nargs="+", default=["float64", "float32"], choices=["float64", "float32"]
    )
    parser.add_argument("--seed", type=int, default=0)
    arguments = parser.parse_args()

    print(
        f"{'|V|':>4} {'layout':9} {'precision':9} | {'windows':>7} {'dedup':>6} {'size ok':>7} "
        f"| {'s/gap':>6} {'build s':>7} | {'order':>5} {'correct':>7}"
    )
    for count in arguments.counts:
        for clustered in (False, True):
            candidates, detections, truth = make_scene(count, clustered, arguments.seed + count)
            for precision in arguments.precision:
                params = WindowAssociationParams(rpm=TpsRpmSettings(precision=precision))
                timings, build_timings = [], []
                for _ in range(arguments.repeats):
                    start = time.process_time()
                    windows = build_windows(detections, len(truth), params)
                    built = time.process_time()
                    results = associate_candidates(candidates, detections, None, params, windows)
                    best = select_candidate(results)
                    timings.append(time.process_time() - start)
                    build_timings.append(built - start)
                correct = float(np.mean(results[best].matched_detection == truth))
                print(
                    f"{count:>4} {'clustered' if clustered else 'uniform':9} {precision:9} | "
                    f"{windows.total:>7} {windows.after_dedup:>6} {windows.after_size:>7} | "
                    f"{min(timings):6.2f} {min(build_timings):7.3f} | {best + 1:>5} "
                    f"{correct:7.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()

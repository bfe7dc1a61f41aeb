"""Seconds per gap match of the window-based TPS-RPM association.

See docs/algorithms/gap-matchers.md#window-tps-rpm.

One gap match = build the windows of V once, then associate three candidate predictions U
(the AR orders 1–3, |U| = 8) with V, and pick the best. With ``--camera-aware`` the camera-aware
predictor's positioned candidates are scored too (docs/algorithms/gap-matchers.md#positioned-candidates):
three ``reg-ar`` candidates (the group's true place plus 10 px noise, gate 100 px) and one
``continuity`` candidate (gate 80 px), all in one cost with lambda3 = 1; the scene registration
itself (two ORB frames) is timed by ``--registration``. Scenes: a group of 8 people after a
camera-pose change (rotation up to ±15°, scale 0.8–1.25, 6 px noise) among clutter laid out
uniformly or in clusters, with |V| = 30 and 50 detections. Threads are pinned to one.

Targets (one core): under 1 s at |V| = 30 and under 5 s at |V| = 50; with the camera-aware
candidates (issue 18), under 0.2 s at |V| = 30 and under 1 s at |V| = 50. Usage::

    python benchmarks/gap_match_speed.py [--repeats 1] [--precision float64 float32] [--camera-aware]
"""

from __future__ import annotations

import argparse
import os
import time

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402 - after pinning the BLAS threads

from trackfw.records import Prediction  # noqa: E402
from trackfw_plugins.datasets.points import gap_scene  # noqa: E402
from trackfw_plugins.gap_matchers.window_tps_rpm import score_candidates  # noqa: E402
from trackfw_plugins.maths.candidate_windows import build_windows  # noqa: E402
from trackfw_plugins.maths.tps_rpm_template import TpsRpmSettings  # noqa: E402
from trackfw_plugins.maths.window_association import (  # noqa: E402
    WindowAssociationParams,
    associate_candidates,
    select_candidate,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1, help="timed gap matches per scene")
    parser.add_argument("--counts", type=int, nargs="+", default=[30, 50], help="|V| values")
    parser.add_argument(
        "--precision", nargs="+", default=["float64", "float32"], choices=["float64", "float32"]
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--scenes", type=int, default=3, help="scenes per setting (the window count varies a lot)"
    )
    parser.add_argument(
        "--camera-aware", action="store_true", help="add the positioned candidates (issue 18)"
    )
    arguments = parser.parse_args()

    print(
        f"{'|V|':>4} {'layout':9} {'seed':>5} {'precision':9} | {'windows':>7} {'dedup':>6} {'size ok':>7} "
        f"| {'s/gap':>6} {'build s':>7} | {'order':>5} {'correct':>7}"
    )
    for count in arguments.counts:
        for clustered, scene in ((c, k) for c in (False, True) for k in range(arguments.scenes)):
            seed = arguments.seed + count + 1000 * scene
            candidates, detections, truth = gap_scene(
                count, seed, clustered=clustered, candidates=3
            )
            for precision in arguments.precision:
                params = WindowAssociationParams(rpm=TpsRpmSettings(precision=precision))
                timings, build_timings = [], []
                for _ in range(arguments.repeats):
                    start = time.process_time()
                    windows = build_windows(detections, len(truth), params)
                    built = time.process_time()
                    if arguments.camera_aware:
                        predictions = _camera_aware(candidates, detections[truth], seed)
                        results, _ = score_candidates(
                            predictions, detections, None, params, windows, lambda3=1.0
                        )
                    else:
                        results = associate_candidates(
                            candidates, detections, None, params, windows
                        )
                    best = select_candidate(results)
                    timings.append(time.process_time() - start)
                    build_timings.append(built - start)
                correct = float(np.mean(results[best].matched_detection == truth))
                print(
                    f"{count:>4} {'clustered' if clustered else 'uniform':9} {seed:>5} {precision:9} | "
                    f"{windows.total:>7} {windows.after_dedup:>6} {windows.after_size:>7} | "
                    f"{min(timings):6.2f} {min(build_timings):7.3f} | {best + 1:>5} "
                    f"{correct:7.2f}",
                    flush=True,
                )


def _camera_aware(candidates: list[np.ndarray], placed: np.ndarray, seed: int) -> list[Prediction]:
    """The AR candidates, three registered copies near the true place and a continuity one."""
    rng = np.random.default_rng(seed + 7)
    free = [Prediction(f"ar{k + 1}", u) for k, u in enumerate(candidates)]
    registered = [
        Prediction(f"reg-ar{k + 1}", placed + rng.normal(0, 10.0, placed.shape), gate=100.0)
        for k in range(len(candidates))
    ]
    return [*free, *registered, Prediction("continuity", candidates[0], gate=80.0)]


if __name__ == "__main__":
    main()

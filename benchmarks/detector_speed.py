"""Speed of a detector per 1280x720 frame (edgebox-cnn split into proposals and CNN scoring).

Usage::

    python benchmarks/detector_speed.py [--video DIR] [--frames 20] [--threads 0] [--sequential]
        [--set blob_scales_per_octave=3 ...]
    python benchmarks/detector_speed.py --detector yolox [--threads 2] [--set input_size=640 ...]

``--detector`` is ``edgebox-cnn`` (default), ``yolox`` or ``light-person-192`` (the yolox
detector's small model); ``--set`` then changes a parameter of that detector.

``--video`` is a trackfw video folder (frames are resized to 1280x720 when they differ); without it
a synthetic 1280x720 frame (textured ground, 30 disc "heads") is used. Single process, onnxruntime
with ``--threads`` onnxruntime intra-op threads (default 0: the detector's automatic choice, all cores
up to 4 unless OMP_NUM_THREADS says otherwise); EdgeBoxes runs in its own thread unless
``--sequential``. ``--set KEY=VALUE`` changes an edgebox-cnn parameter (repeatable).
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from stage_overrides import add_set_option, parse_overrides

from trackfw_plugins.detectors.edgebox_cnn import EdgeBoxCnnDetector, EdgeBoxCnnParams
from trackfw_plugins.detectors.yolox import YoloxDetector, YoloxParams

WIDTH, HEIGHT = 1280, 720


def synthetic_frames(count: int) -> list[np.ndarray]:
    """Textured 1280x720 frames with 30 disc heads each (when no video is given)."""
    rng = np.random.default_rng(0)
    frames = []
    for _ in range(count):
        noise = rng.normal(128, 20, (HEIGHT // 8, WIDTH // 8, 3)).clip(0, 255).astype(np.uint8)
        frame = cv2.resize(noise, (WIDTH, HEIGHT), interpolation=cv2.INTER_CUBIC)
        for x, y in zip(
            rng.uniform(20, WIDTH - 20, 30), rng.uniform(20, HEIGHT - 20, 30), strict=True
        ):
            colour = tuple(int(c) for c in rng.integers(0, 255, 3))
            cv2.circle(frame, (int(x), int(y)), int(rng.integers(5, 15)), colour, -1)
        frames.append(frame)
    return frames


def video_frames(video: Path, count: int) -> list[np.ndarray]:
    """Up to ``count`` frames of a video folder, spread over its length, at 1280x720."""
    from trackfw.dataset import load_video
    from trackfw.video_io import iter_frames

    context = load_video(video)
    step = max(1, context.n_frames // count)
    frames = []
    for t, image, status in iter_frames(context, decode=True):
        if t % step == 0 and status == "ok" and image is not None:
            if image.shape[:2] != (HEIGHT, WIDTH):
                image = cv2.resize(image, (WIDTH, HEIGHT), interpolation=cv2.INTER_AREA)
            frames.append(image)
    return frames[:count]


def time_yolox(
    arguments: argparse.Namespace, frames: list[np.ndarray], overrides: dict[str, object]
) -> None:
    """Time the yolox detector (whole detect_image: letterbox, network, decoding, NMS)."""
    import os

    if arguments.detector == "light-person-192":
        overrides = {"model": "light-person-192", **overrides}
    params = YoloxParams(threads=arguments.threads, **overrides)  # type: ignore[arg-type]
    detector = YoloxDetector(params)
    detector.detect_image(frames[0])  # warm-up (onnxruntime allocations)
    totals, found = [], []
    cpu_started = time.process_time()
    for frame in itertools.islice(itertools.cycle(frames), arguments.frames):
        started = time.perf_counter()
        found.append(len(detector.detect_image(frame)))
        totals.append(time.perf_counter() - started)
    # CPU seconds of this process per frame: on a loaded machine the wall time includes waiting
    # for a core, while the CPU time (summed over onnxruntime's threads) does not.
    cpu = (time.process_time() - cpu_started) / max(len(totals), 1)
    source = arguments.video or "synthetic frames"
    print(
        f"yolox ({params.model}, input {detector.side}, tiles {params.tiles}) on {len(totals)}"
        f" frames of {source} at {WIDTH}x{HEIGHT}, 1 process, onnxruntime threads"
        f" {params.threads or 'auto'}, load average {os.getloadavg()[0]:.1f}"
    )
    print(
        f"  total {1000 * statistics.mean(totals):6.1f} ms (median"
        f" {1000 * statistics.median(totals):.1f}) -> {1 / statistics.mean(totals):.1f} fps,"
        f" {statistics.mean(found):.1f} detections per frame"
    )
    print(f"  CPU time {1000 * cpu:6.1f} ms per frame (all threads of this process)")


def parse_arguments() -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--video", type=Path, default=None, help="trackfw video folder")
    parser.add_argument("--frames", type=int, default=20, help="frames to time")
    parser.add_argument(
        "--threads", type=int, default=0, help="onnxruntime intra-op threads (0: auto)"
    )
    add_set_option(parser, "edgebox-cnn")
    parser.add_argument(
        "--sequential", action="store_true", help="no EdgeBoxes thread (overlap_proposals off)"
    )
    parser.add_argument(
        "--detector", default="edgebox-cnn", choices=["edgebox-cnn", "yolox", "light-person-192"]
    )
    return parser.parse_args()


def time_edgebox(
    params: EdgeBoxCnnParams, frames: list[np.ndarray], count: int
) -> dict[str, list[float]]:
    """Seconds of each step of ``count`` edgebox-cnn calls (after a warm-up), and the numbers
    of proposals and detections, per call."""
    detector = EdgeBoxCnnDetector(params)
    detector.detect_image(frames[0])  # warm-up (onnxruntime allocations)
    steps = ("proposals", "scoring", "edge_boxes", "blobs", "proposed")
    timings: dict[str, list[float]] = {key: [] for key in ("total", *steps, "found")}
    for frame in itertools.islice(itertools.cycle(frames), count):
        started = time.perf_counter()
        detections = detector.detect_image(frame)
        timings["total"].append(time.perf_counter() - started)
        for key in steps:
            timings[key].append(detector.last_timing[key])
        timings["found"].append(len(detections))
    return timings


def main() -> None:
    arguments = parse_arguments()
    frames = (
        video_frames(arguments.video, arguments.frames)
        if arguments.video
        else synthetic_frames(arguments.frames)
    )
    overrides = parse_overrides(arguments.overrides)
    if arguments.detector != "edgebox-cnn":
        time_yolox(arguments, frames, overrides)
        return
    params = EdgeBoxCnnParams(
        intra_op_threads=arguments.threads,
        overlap_proposals=not arguments.sequential,
        **overrides,
    )
    timings = time_edgebox(params, frames, arguments.frames)
    totals, proposals, scoring = timings["total"], timings["proposals"], timings["scoring"]

    def ms(values: list[float]) -> str:
        return f"{1000 * statistics.mean(values):6.1f} ms (median {1000 * statistics.median(values):.1f})"

    source = arguments.video or "synthetic frames"
    print(f"edgebox-cnn on {len(totals)} frames of {source} at {WIDTH}x{HEIGHT}, 1 process,")
    print(
        f"  work_width {params.work_width}, blob_width {params.blob_width},"
        f" threads {params.intra_op_threads}, EdgeBoxes in its own thread: {params.overlap_proposals}"
    )
    print(f"  total      {ms(totals)}  -> {1 / statistics.mean(totals):.1f} fps")
    print(
        f"  proposals  {ms(proposals)}  ({statistics.mean(timings['proposed']):.0f} boxes per frame; waited for)"
    )
    print(f"    EdgeBoxes  {ms(timings['edge_boxes'])}")
    print(f"    DoG blobs  {ms(timings['blobs'])}")
    print(f"  scoring    {ms(scoring)}")
    print(
        f"  rest (NMS, merging) {ms([t - p - s for t, p, s in zip(totals, proposals, scoring, strict=True)])}"
    )
    print(f"  detections {statistics.mean(timings['found']):.1f} per frame")


if __name__ == "__main__":
    main()

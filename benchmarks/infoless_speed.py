"""Speed of the ``svm`` info-less classifier per 1280x720 frame (target: under 10 ms).

Times what the stage does on each frame, decoding excluded: greyscale conversion and resizing,
optical flow, the 11-d feature and the SVM with its Platt probability. Frames are a panning crop
of a smooth random texture (or the TUD-Stadtmitte frames with ``--frames DIR``), resized to
1280x720.

Usage::

    python benchmarks/infoless_speed.py [--model FILE] [--frames DIR] [--count 60]
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import cv2
import numpy as np

from trackfw.records import Detections, FrameData, VideoContext
from trackfw_plugins.classifiers.svm import SvmClassifier, SvmParams

WIDTH, HEIGHT = 1280, 720


def synthetic_frames(count: int) -> list[np.ndarray]:
    """``count`` BGR frames panning 6 pixels per frame over a smooth texture."""
    rng = np.random.default_rng(0)
    noise = rng.random((HEIGHT, WIDTH + 6 * count)).astype(np.float32)
    texture = cv2.GaussianBlur(noise, (0, 0), 4.0)
    texture = (255 * (texture - texture.min()) / np.ptp(texture)).astype(np.uint8)
    return [
        cv2.cvtColor(np.ascontiguousarray(texture[:, 6 * t : 6 * t + WIDTH]), cv2.COLOR_GRAY2BGR)
        for t in range(count)
    ]


def folder_frames(folder: Path, count: int) -> list[np.ndarray]:
    """The first ``count`` images of ``folder`` resized to 1280x720."""
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".jpg", ".png"))[:count]
    frames = [cv2.imread(str(path)) for path in files]
    return [cv2.resize(f, (WIDTH, HEIGHT)) for f in frames if f is not None]


def time_classifier(params: SvmParams, frames: list[np.ndarray]) -> np.ndarray:
    """Milliseconds of ``classify`` per frame (the first frame excluded)."""
    video = VideoContext("bench", "bench", len(frames), WIDTH, HEIGHT)
    classifier = SvmClassifier(params)
    classifier.start(video)
    rng = np.random.default_rng(1)
    timings = []
    for t, image in enumerate(frames):
        detections = Detections.from_points(rng.random((8, 2)) * [WIDTH, HEIGHT])
        started = time.perf_counter()
        classifier.classify(FrameData(t, image, video, first=t == 0), detections)
        timings.append((time.perf_counter() - started) * 1e3)
    return np.asarray(timings[1:])


def main() -> None:
    """Print the per-frame timings of several flow settings."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model file (default: the shipped one)")
    parser.add_argument("--frames", type=Path, default=None, help="folder of images to use")
    parser.add_argument("--count", type=int, default=60, help="frames to time")
    parser.add_argument("--threads", type=int, default=1, help="OpenCV threads (engine: 1)")
    arguments = parser.parse_args()
    cv2.setNumThreads(arguments.threads)
    # Overriding the model's flow settings is the point here: silence the mismatch warning.
    logging.getLogger("trackfw_plugins.classifiers.svm").setLevel(logging.ERROR)
    frames = (
        folder_frames(arguments.frames, arguments.count)
        if arguments.frames is not None
        else synthetic_frames(arguments.count)
    )
    stage = SvmClassifier(SvmParams(model=arguments.model))
    model = stage.model
    print(
        f"{len(frames)} frames {WIDTH}x{HEIGHT}, OpenCV threads {arguments.threads},"
        f" model with {len(model.support_vectors)} support vectors"
    )
    print(f"online rules (timed with them): {stage.rules.as_dict()}")
    settings = [
        ("dis", 320, "ultrafast"),
        ("dis", 320, "fast"),
        ("dis", 640, "ultrafast"),
        ("farneback", 640, "ultrafast"),
    ]
    for flow, width, preset in settings:
        params = SvmParams(model=arguments.model, flow=flow, flow_width=width, dis_preset=preset)
        timings = time_classifier(params, frames)
        label = f"{flow}{'-' + preset if flow == 'dis' else ''} @ {width}px"
        print(
            f"{label:24s} median {np.median(timings):6.2f} ms   p90"
            f" {np.percentile(timings, 90):6.2f} ms"
        )
    features = np.zeros((1, 11))
    started = time.perf_counter()
    for _ in range(200):
        model.probability(features)
    print(f"{'svm + platt alone':24s} {(time.perf_counter() - started) / 200 * 1e3:6.3f} ms")


if __name__ == "__main__":
    main()

"""Precision and recall of the head detectors on annotated videos.

Usage::

    python benchmarks/detector_accuracy.py [--dataset DIR ...] [--mot SEQ ...] [--frame-step 6]
        [--detectors edgebox-cnn,edgebox-only,hog,onnx-dense] [--model head_cnn.onnx]
        [--set blob_scales_per_octave=3 ...]

A detection matches a head when it lies within 0.5 head size (Hungarian, one-to-one); heads
smaller than the detector's minimum (8 px at 1080p, scaled by height/1080) are left out, and so
are detections on them. MOT sequences use the head proxy (left + w/2, top + 0.08 h), size 0.12 h.
Each detector is scored on all frames and on the informative ones (outside the ground-truth
info-less intervals: the frames whose detections the tracker uses); ``--thresholds`` adds rows for
the edgebox-cnn detector at other score thresholds, and ``--set KEY=VALUE`` changes one of its
parameters (repeatable). All edgebox-cnn rows are read from one run per frame, so only the first
row's ms/frame (all frames) is a detection time.
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from stage_overrides import add_set_option, parse_overrides

from trackfw.records import Detections
from trackfw_plugins.detectors.edgebox_cnn import EdgeBoxCnnDetector, EdgeBoxCnnParams
from trackfw_plugins.detectors.hog import HogDetector, HogParams
from trackfw_plugins.detectors.onnx_detector import OnnxDetector, OnnxDetectorParams
from trackfw_plugins.detectors.training.evaluate import evaluate
from trackfw_plugins.detectors.training.sampling import (
    AnnotatedFrame,
    iter_dataset_frames,
    iter_mot_frames,
)

DENSE_MODEL = Path(__file__).resolve().parents[1] / "plugins/detectors/models/head_cnn_dense.onnx"


class ThresholdSweep:
    """One edgebox-cnn run per frame, read at several score thresholds.

    NMS and the centre rule go through the boxes best first, so a box scoring below a threshold
    never removes one above it: the detections at threshold ``t`` are those of a run at a lower
    threshold that score at least ``t``. Each frame is detected once instead of once per row.
    """

    def __init__(self, detector: EdgeBoxCnnDetector) -> None:
        self.detector = detector
        self.cache: dict[int, tuple[np.ndarray, Detections]] = {}

    def at(self, threshold: float) -> Callable[[np.ndarray], Detections]:
        """A detect function giving the detections scoring at least ``threshold``."""

        def detect(image: np.ndarray) -> Detections:
            # Keyed by identity, and the image is kept, so that a key is never reused.
            cached = self.cache.get(id(image))
            if cached is None or cached[0] is not image:
                cached = (image, self.detector.detect_image(image))
                self.cache[id(image)] = cached
            detections = cached[1]
            return detections.subset(detections.scores >= threshold)

        return detect


def detectors(
    names: list[str],
    model: str,
    height: int,
    thresholds: list[float],
    overrides: dict[str, object] | None = None,
) -> dict[str, Callable]:
    """The detect functions to compare, by name; ``overrides`` are edgebox-cnn parameters."""
    built: dict[str, Callable[[np.ndarray], Detections]] = {}
    edgebox_params: dict[str, object] = dict(overrides or {})
    for name in names:
        if name == "edgebox-cnn":
            default = EdgeBoxCnnParams(model=model, **edgebox_params)
            lowest = min([default.score_threshold, *thresholds])
            sweep = ThresholdSweep(
                EdgeBoxCnnDetector(default.model_copy(update={"score_threshold": lowest}))
            )
            built[name] = sweep.at(default.score_threshold)
            for threshold in thresholds:
                built[f"{name}@{threshold:g}"] = sweep.at(threshold)
        elif name == "edgebox-only":
            params = EdgeBoxCnnParams(model=model, blob_width=0)
            built[name] = EdgeBoxCnnDetector(params).detect_image
        elif name == "hog":
            built[name] = HogDetector(HogParams(scale=1.05)).detect_image
        elif name == "hog-0.15":
            built[name] = HogDetector(HogParams(scale=1.05, head_offset=0.15)).detect_image
        elif name == "onnx-dense":
            # The shipped classifier run densely: a 32-px window sees a head of 27 px; heads of
            # 8..40 px at this height need the frame scaled by 27/size.
            scales = tuple(
                float(s) for s in 27.0 / np.geomspace(8 * height / 720, 40 * height / 720, 6)
            )
            params = OnnxDetectorParams(
                model=str(DENSE_MODEL),
                decoding="score_map",
                logits=True,
                scales=scales,
                mean=(0.5, 0.5, 0.5),
                std=(0.25, 0.25, 0.25),
            )
            built[name] = OnnxDetector(params).detect_image
    return built


def frames_of(arguments: argparse.Namespace) -> Iterator[tuple[str, list[AnnotatedFrame]]]:
    """Named frame lists: one per dataset and per MOT sequence."""
    for dataset in arguments.dataset:
        frames = list(iter_dataset_frames(dataset, arguments.frame_step))
        yield str(dataset), frames
    for sequence in arguments.mot:
        yield str(sequence), list(iter_mot_frames(sequence, arguments.frame_step))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path, action="append", default=[])
    parser.add_argument("--mot", type=Path, action="append", default=[])
    parser.add_argument("--frame-step", type=int, default=6)
    parser.add_argument("--max-frames", type=int, default=60)
    parser.add_argument("--detectors", default="edgebox-cnn,edgebox-only,hog")
    parser.add_argument("--model", default="", help="ONNX classifier (default: shipped)")
    parser.add_argument(
        "--thresholds", default="", help="extra edgebox-cnn score thresholds, comma-separated"
    )
    add_set_option(parser, "edgebox-cnn")
    arguments = parser.parse_args()
    overrides = parse_overrides(arguments.overrides)
    for source, frames in frames_of(arguments):
        frames = list(itertools.islice(frames, arguments.max_frames))
        if not frames:
            continue
        height = frames[0].image.shape[0]
        minimum = 8.0 * height / 1080.0
        print(f"{source}: {len(frames)} frames, {frames[0].image.shape[1]}x{height}")
        thresholds = [float(value) for value in arguments.thresholds.split(",") if value]
        informative = [frame for frame in frames if frame.informative]
        for name, detect in detectors(
            arguments.detectors.split(","),
            arguments.model,
            height,
            thresholds,
            overrides,
        ).items():
            score = evaluate(detect, frames, min_head_size=minimum)
            print(f"  {name:17s} all frames         {score.summary()}")
            if 0 < len(informative) < len(frames):
                score = evaluate(detect, informative, min_head_size=minimum)
                print(f"  {name:17s} informative frames {score.summary()}")


if __name__ == "__main__":
    main()

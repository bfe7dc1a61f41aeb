"""Precision and recall of the head detectors on annotated videos.

Usage::

    python benchmarks/detector_accuracy.py [--dataset DIR ...] [--frame-step 6]
        [--detectors edgebox-cnn,edgebox-only,hog,onnx-dense] [--model head_cnn.onnx]
        [--set blob_scales_per_octave=3 ...]
    python benchmarks/detector_accuracy.py --mot SEQ [--mot SEQ ...]
        [--detectors yolox,light-person-192,edgebox-cnn,hog] [--thresholds 0.2,0.4]
        [--yolox-set input_size=640 ...]

**Real frames** (``--mot``, a MOTChallenge sequence with ``gt/gt.txt``): every frame with ground
truth is detected once per detector. A person detector's boxes match the ground-truth body boxes
one-to-one at IoU >= 0.5 (Hungarian on 1 - IoU; box precision / recall); every detector's head
points are also scored as below against the head proxy of each body box. ``yolox`` names the
``yolox`` detector with its defaults, ``yolox-640`` one with input_size 640, ``light-person-192``
the small model; ``--yolox-set`` changes a parameter of all of them and ``--thresholds`` adds rows
at other score thresholds (read off the same run). The yolox rows also score the head point at
0.116 of the box height (the Oxford Town Centre figure) beside the model's own fraction. Each
person detector also gets a line saying why boxes were missed (more than half hidden by nearer
people, at the frame border, found but drawn differently, other) and what its false boxes overlap
(see :class:`Breakdown`).

**Datasets** (``--dataset``):

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
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
from stage_overrides import add_set_option, parse_overrides

from trackfw.formats import MEASURED_HEAD_FRACTION, body_head_points
from trackfw.records import Detections
from trackfw_plugins.datasets.mot import load_mot_sequence
from trackfw_plugins.detectors.edgebox_cnn import EdgeBoxCnnDetector, EdgeBoxCnnParams
from trackfw_plugins.detectors.hog import HogDetector, HogParams
from trackfw_plugins.detectors.onnx_detector import OnnxDetector, OnnxDetectorParams
from trackfw_plugins.detectors.training.evaluate import evaluate
from trackfw_plugins.detectors.training.sampling import (
    AnnotatedFrame,
    iter_dataset_frames,
    mot_heads,
)
from trackfw_plugins.detectors.yolox import YoloxDetector, YoloxParams
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.box_overlap import box_iou
from trackfw_plugins.maths.head_matching import match_heads

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
    yolox_overrides: dict[str, object] | None = None,
) -> dict[str, Callable]:
    """The detect functions to compare, by name; ``overrides`` are edgebox-cnn parameters."""
    built: dict[str, Callable[[np.ndarray], Detections]] = {}
    edgebox_params: dict[str, object] = dict(overrides or {})
    for name in names:
        if name.startswith(("yolox", "light-person-192")):
            built[name] = yolox_detector(name, yolox_overrides or {}).detect_image
            continue
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
    """Named frame lists: one per dataset."""
    for dataset in arguments.dataset:
        frames = list(iter_dataset_frames(dataset, arguments.frame_step))
        yield str(dataset), frames


def match_boxes(boxes: np.ndarray, truth: np.ndarray, iou: float = 0.5) -> int:
    """True positives: ``(N, 4)`` boxes paired one-to-one with ``(M, 4)`` truth at IoU >= ``iou``.

    >>> match_boxes(np.array([[0.0, 0, 10, 10], [1.0, 0, 10, 10]]), np.array([[0.0, 0, 10, 11]]))
    1
    """
    if len(boxes) == 0 or len(truth) == 0:
        return 0
    assignment = hungarian(1.0 - box_iou(truth, boxes), gate=1.0 - iou)
    return int(np.count_nonzero(assignment >= 0))


def occluded_share(truth: np.ndarray) -> np.ndarray:
    """Share of each ``(M, 4)`` truth box covered by the boxes of nearer people, in [0, 1].

    A person whose box ends lower in the frame stands nearer the camera (people on one ground
    plane), so the overlap of a box whose bottom is lower hides part of this one; the covered
    shares are summed (an upper bound where occluders overlap each other) and clipped at 1.

    >>> occluded_share(np.array([[0.0, 0, 10, 20], [5.0, 0, 10, 30]])).tolist()
    [0.5, 0.0]
    """
    bottoms = truth[:, 1] + truth[:, 3]
    overlap = np.zeros((len(truth), len(truth)))
    for index, box in enumerate(truth):
        low = np.maximum(box[:2], truth[:, :2])
        high = np.minimum(box[:2] + box[2:], truth[:, :2] + truth[:, 2:])
        overlap[index] = np.clip(high - low, 0.0, None).prod(axis=1) / (box[2] * box[3])
    nearer = bottoms[None, :] > bottoms[:, None]
    return np.clip((overlap * nearer).sum(axis=1), 0.0, 1.0)


class Breakdown:
    """Why ground-truth boxes are missed and why detections are false, summed over frames.

    Misses: ``occluded`` (more than half the box hidden by nearer people), ``border`` (the box
    touches the frame edge), ``drawn`` (a detection overlaps it at IoU 0.3-0.5: found, but its box
    is drawn differently, e.g. the visible part only) and ``other``. False detections: ``part``
    (IoU 0.1-0.5 with a ground-truth box) and ``none`` (no ground-truth box within IoU 0.1: a
    person the ground truth leaves out, or a false detection).

    >>> breakdown = Breakdown()
    >>> truth = np.array([[0.0, 0, 10, 20], [50.0, 50, 10, 20], [52.0, 52, 10, 20]])
    >>> breakdown.add(np.array([[0.0, 0, 10, 20], [80.0, 10, 5, 5]]), truth, 100, 100)
    >>> breakdown.summary()
    'missed: occluded 1 (of 1), border 0, drawn differently 0, other 1; false: partial overlap 0, no truth box 1'
    """

    def __init__(self) -> None:
        self.counts = dict.fromkeys(("occluded", "border", "drawn", "other", "part", "none"), 0)
        self.occluded_truth = 0

    def add(self, boxes: np.ndarray, truth: np.ndarray, width: int, height: int) -> None:
        """Count one frame's ``(N, 4)`` detections against its ``(M, 4)`` truth boxes."""
        iou = box_iou(truth, boxes) if len(boxes) and len(truth) else np.zeros((len(truth), 0))
        assignment = hungarian(1.0 - iou, gate=0.5) if iou.size else -np.ones(len(truth), dtype=int)
        hidden = occluded_share(truth) if len(truth) else np.zeros(0)
        self.occluded_truth += int(np.count_nonzero(hidden > 0.5))
        right, bottom = truth[:, 0] + truth[:, 2], truth[:, 1] + truth[:, 3]
        at_border = (
            (truth[:, 0] < 2) | (truth[:, 1] < 2) | (right > width - 2) | (bottom > height - 2)
        )
        best = iou.max(axis=1) if iou.shape[1] else np.zeros(len(truth))
        for index in np.flatnonzero(assignment < 0):
            reason = (
                "occluded" if hidden[index] > 0.5
                else "border" if at_border[index]
                else "drawn" if best[index] >= 0.3
                else "other"
            )  # fmt: skip
            self.counts[reason] += 1
        matched = set(assignment[assignment >= 0].tolist())
        overlap = iou.max(axis=0) if iou.shape[0] else np.zeros(len(boxes))
        for index in range(len(boxes)):
            if index not in matched:
                self.counts["part" if overlap[index] >= 0.1 else "none"] += 1

    def summary(self) -> str:
        """``missed: occluded a, border b, ...; false: part c, none d``."""
        c = self.counts
        return (
            f"missed: occluded {c['occluded']} (of {self.occluded_truth}), border {c['border']},"
            f" drawn differently"
            f" {c['drawn']}, other {c['other']}; false: partial overlap {c['part']},"
            f" no truth box {c['none']}"
        )


class Counts:
    """True positives, detections and ground truth summed over frames."""

    def __init__(self) -> None:
        self.tp = self.found = self.truth = 0

    def add(self, tp: int, found: int, truth: int) -> None:
        """Count one frame."""
        self.tp, self.found, self.truth = self.tp + tp, self.found + found, self.truth + truth

    def summary(self) -> str:
        """``P x.xxx R x.xxx (tp/detections/truth)``."""
        precision = self.tp / self.found if self.found else 1.0
        recall = self.tp / self.truth if self.truth else 1.0
        return f"P {precision:.3f} R {recall:.3f} ({self.tp}/{self.found}/{self.truth})"


def yolox_detector(name: str, overrides: dict[str, object]) -> YoloxDetector:
    """``yolox`` (defaults), ``yolox-640`` (input_size 640) or ``light-person-192``."""
    params: dict[str, object] = {"model": "light-person-192"} if name.startswith("light") else {}
    size = name.rsplit("-", 1)[1] if name.startswith("yolox-") else ""
    if size:
        params["input_size"] = int(size)
    params.update(overrides)
    return YoloxDetector(YoloxParams(**params))  # type: ignore[arg-type]


def mot_detectors(
    names: list[str], model: str, yolox_overrides: dict[str, object]
) -> dict[str, Callable[[np.ndarray], tuple[np.ndarray | None, Detections]]]:
    """Per name, a function image -> (body boxes or None for head detectors, detections)."""
    built: dict[str, Callable[[np.ndarray], tuple[np.ndarray | None, Detections]]] = {}
    for name in names:
        if name.startswith(("yolox", "light-person-192")):
            detector = yolox_detector(name, yolox_overrides)

            def bodies(
                image: np.ndarray, detector: YoloxDetector = detector
            ) -> tuple[np.ndarray | None, Detections]:
                boxes, scores = detector.detect_bodies(image)
                return boxes, Detections(
                    points=body_head_points(boxes, detector.head_fraction), scores=scores
                )

            built[name] = bodies
        elif name == "hog":
            hog = HogDetector(HogParams(scale=1.05))

            def hog_bodies(
                image: np.ndarray, hog: HogDetector = hog
            ) -> tuple[np.ndarray | None, Detections]:
                detections = hog.detect_image(image)
                return detections.boxes if detections.boxes is not None else np.zeros(
                    (0, 4)
                ), detections

            built[name] = hog_bodies
        elif name == "edgebox-cnn":
            edgebox = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=model))
            built[name] = lambda image, edgebox=edgebox: (None, edgebox.detect_image(image))
        else:
            raise SystemExit(f"--detectors: unknown detector {name!r} for --mot")
    return built


class MotTally:
    """One detector's counts over a sequence: boxes and head points per score level, the head
    point at 0.116 of the box height, and the :class:`Breakdown` of its misses.

    Args:
        name: the detector's name (``hog`` gets no 0.116 proxy row).
        levels: the score levels read off one run; None is the detector's own threshold.
        configured: the detector's own score threshold.
    """

    def __init__(self, name: str, levels: list[float | None], configured: float) -> None:
        self.name, self.levels, self.configured = name, levels, configured
        self.person_model = name.startswith(("yolox", "light"))
        self.boxes = {level: Counts() for level in levels}
        self.heads = {level: Counts() for level in levels}
        self.proxy = Counts()
        self.breakdown = Breakdown()
        self.has_bodies = False

    def add(
        self,
        bodies: np.ndarray | None,
        detections: Detections,
        truth: np.ndarray,
        truth_heads: np.ndarray,
        size: tuple[int, int],
    ) -> None:
        """Count one frame: ``(N, 4)`` body boxes (None for a head detector), the detections,
        the ``(M, 4)`` true body boxes and ``(K, 3)`` true heads, in an image of ``size``."""
        self.has_bodies = bodies is not None
        for level in self.levels:
            keep = (
                np.ones(len(detections), dtype=bool)
                if not self.person_model
                else detections.scores >= (self.configured if level is None else level)
            )
            if bodies is not None:
                self.boxes[level].add(match_boxes(bodies[keep], truth), int(keep.sum()), len(truth))
            self.heads[level].add(
                match_heads(detections.points[keep], truth_heads).n_matched,
                int(keep.sum()),
                len(truth_heads),
            )
        if bodies is None:
            return
        kept = detections.scores >= self.configured
        self.breakdown.add(bodies[kept] if self.person_model else bodies, truth, *size)
        if self.name != "hog":
            proxy = body_head_points(bodies[kept], MEASURED_HEAD_FRACTION)
            self.proxy.add(match_heads(proxy, truth_heads).n_matched, len(proxy), len(truth_heads))

    def print(self, milliseconds: float) -> None:
        """The detector's rows: one per level, the 0.116 proxy, the breakdown."""
        for level in self.levels:
            label = self.name if level is None else f"{self.name}@{level:g}"
            box = self.boxes[level].summary() if self.has_bodies else "n/a (head boxes)"
            timing = f"  {milliseconds:.1f} ms/frame" if level is None else ""
            print(
                f"  {label:22s} boxes@IoU0.5 {box:32s} head points {self.heads[level].summary()}{timing}"
            )
        if self.proxy.found or self.proxy.truth:
            print(
                f"  {self.name + ' (head 0.116)':22s} {'':45s} head points {self.proxy.summary()}"
            )
        if self.has_bodies:
            print(f"  {'':22s} boxes {self.breakdown.summary()}")


def mot_report(
    sequence: Path,
    names: list[str],
    model: str,
    thresholds: list[float],
    yolox_overrides: dict[str, object],
) -> None:
    """Box and head-point precision / recall of each detector on every frame with ground truth."""
    mot = load_mot_sequence(sequence)
    heads = mot_heads(sequence / "gt" / "gt.txt")
    frames = sorted(frame for frame, boxes in mot.boxes.items() if len(boxes))
    print(
        f"{sequence}: {len(frames)} frames with ground truth, {mot.width}x{mot.height},"
        f" {sum(len(mot.boxes[f]) for f in frames)} body boxes"
    )
    minimum = 8.0 * mot.height / 1080.0
    configured = float(
        yolox_overrides.get("score_threshold", YoloxParams().score_threshold)  # type: ignore[arg-type]
    )
    if thresholds:
        # One run at the lowest threshold; each row keeps the boxes scoring at least its own
        # (NMS goes best first, so a box below a threshold never removed one above it).
        yolox_overrides = {**yolox_overrides, "score_threshold": min(configured, *thresholds)}
    for name, detect in mot_detectors(names, model, yolox_overrides).items():
        person_model = name.startswith(("yolox", "light"))
        tally = MotTally(name, [None, *thresholds] if person_model else [None], configured)
        seconds = 0.0
        for frame in frames:
            image = cv2.imread(str(mot.frame_paths[frame]))
            started = time.perf_counter()
            bodies, detections = detect(image)
            seconds += time.perf_counter() - started
            truth_heads = heads.get(frame, np.zeros((0, 3)))
            truth_heads = truth_heads[truth_heads[:, 2] >= minimum]
            tally.add(
                bodies, detections, mot.boxes[frame][:, 1:5], truth_heads, (mot.width, mot.height)
            )
        tally.print(1000.0 * seconds / max(len(frames), 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path, action="append", default=[])
    parser.add_argument("--mot", type=Path, action="append", default=[])
    parser.add_argument("--frame-step", type=int, default=6)
    parser.add_argument("--max-frames", type=int, default=60)
    parser.add_argument("--detectors", default="")
    parser.add_argument("--model", default="", help="ONNX classifier (default: shipped)")
    parser.add_argument(
        "--thresholds", default="", help="extra edgebox-cnn score thresholds, comma-separated"
    )
    add_set_option(parser, "edgebox-cnn")
    parser.add_argument(
        "--yolox-set",
        dest="yolox_overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a yolox parameter for the --mot rows (repeatable)",
    )
    arguments = parser.parse_args()
    overrides = parse_overrides(arguments.overrides)
    for sequence in arguments.mot:
        mot_report(
            sequence,
            (arguments.detectors or "yolox,light-person-192,edgebox-cnn,hog").split(","),
            arguments.model,
            [float(value) for value in arguments.thresholds.split(",") if value],
            parse_overrides(arguments.yolox_overrides),
        )
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
            (arguments.detectors or "edgebox-cnn,edgebox-only,hog").split(","),
            arguments.model,
            height,
            thresholds,
            overrides,
            parse_overrides(arguments.yolox_overrides),
        ).items():
            score = evaluate(detect, frames, min_head_size=minimum)
            print(f"  {name:17s} all frames         {score.summary()}")
            if 0 < len(informative) < len(frames):
                score = evaluate(detect, informative, min_head_size=minimum)
                print(f"  {name:17s} informative frames {score.summary()}")


if __name__ == "__main__":
    main()

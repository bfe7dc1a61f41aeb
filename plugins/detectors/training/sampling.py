"""Head and non-head crops for training the head classifier (NumPy/OpenCV only, no torch).

Sources of annotated frames:

* trackfw datasets with ``heads.csv`` (``{frame: (M, 3) x, y, head_size}``), e.g. the synthetic
  generator's output;
* MOTChallenge sequences (``gt/gt.txt`` body boxes). The head proxy is the head-point rule
  (:mod:`trackfw.formats.head_point`, ``(left + w/2, top + 0.08 h)``) with head size ``0.12 h``:
  on TUD-Stadtmitte the body height is the stable measure (widths change with arms and stride),
  and 0.12 h outlines the heads when drawn.

Every candidate box is labelled by the same rule, relative to the nearest head of side ``s``:
positive when its centre lies within ``0.25 s`` and its size within ×[0.6, 1.7] of the head (the
detection point is the box centre, so the centre matters more than the size); negative when no
head has its centre within ``0.6 s`` with a size within ×[0.45, 2.2]; otherwise it is ambiguous
and dropped. Candidates are jittered head boxes, near misses (shifted or wrongly scaled
boxes, so that the classifier also localises), random head-sized boxes, and EdgeBoxes proposals
(the hard negatives the detector meets at run time).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from trackfw.dataset import list_videos, load_video
from trackfw.errors import UserError
from trackfw.formats import body_heads, boxes_by_frame, read_mot_ground_truth
from trackfw.formats.annotations import HEADS_FILE
from trackfw_plugins.detectors.head_scorer import extract_crops
from trackfw_plugins.detectors.proposals import HeadProposer

#: Head size of a MOT body box as a share of its height, for labelling training crops. The
#: head-point rule's default size is 0.13 h; the crops of the shipped models were labelled with
#: 0.12 h, which outlines TUD-Stadtmitte's heads when drawn, so training keeps it.
MOT_HEAD_SIZE_RATIO = 0.12


@dataclass(frozen=True)
class AnnotatedFrame:
    """One frame with its heads.

    Attributes:
        image: ``(H, W, 3)`` uint8 BGR.
        heads: ``(M, 3)`` head centres and sizes ``x, y, head_size`` in pixels.
        source: where it came from (for messages).
        informative: False on a frame inside a ground-truth info-less interval.
    """

    image: NDArray[np.uint8]
    heads: NDArray[np.float64]
    source: str
    informative: bool = True


@dataclass(frozen=True)
class SamplingSettings:
    """How many crops of each kind one frame gives.

    ``min_head_size`` is in px at 1080p (scaled by the frame height), like the proposals' smallest
    box: smaller heads get no jittered positives or near misses.
    """

    input_size: int = 32
    context: float = 16.0
    min_crop: float = 0.0
    positives_per_head: int = 4
    near_misses_per_head: int = 3
    random_per_frame: int = 12
    proposals_per_frame: int = 60
    min_head_size: float = 8.0
    max_negative_ratio: float = 3.0


def mot_heads(gt_path: Path) -> dict[int, NDArray[np.float64]]:
    """Head proxies of a MOTChallenge ``gt.txt``: ``{0-based frame: (M, 3) x, y, head_size}``.

    The boxes that count (:func:`trackfw.formats.read_mot_ground_truth`: in the MOT16/17 layout
    flag 1 and class 1), each frame in the file's order, through the head-point rule with the
    training's head size :data:`MOT_HEAD_SIZE_RATIO`.
    """
    boxes = boxes_by_frame(read_mot_ground_truth(gt_path), sort_ids=False)
    return {
        frame: body_heads(rows[:, 1:], size_fraction=MOT_HEAD_SIZE_RATIO)
        for frame, rows in boxes.items()
    }


def _iter_video_frames(
    video_dir: Path, heads: dict[int, NDArray[np.float64]], frame_step: int
) -> Iterator[AnnotatedFrame]:
    from trackfw.video_io import iter_frames

    video = load_video(video_dir)
    infoless = video.ground_truth.infoless_frames() if video.ground_truth is not None else set()
    for t, image, status in iter_frames(video, decode=True):
        if t % frame_step or status != "ok" or image is None:
            continue
        yield AnnotatedFrame(
            image=image,
            heads=heads.get(t, np.zeros((0, 3))),
            source=f"{video_dir}#{t}",
            informative=t not in infoless,
        )


def iter_dataset_frames(dataset: Path, frame_step: int = 5) -> Iterator[AnnotatedFrame]:
    """Every ``frame_step``-th frame of every video of a trackfw dataset that has ``heads.csv``."""
    for video_dir in list_videos(Path(dataset)):
        if not (video_dir / HEADS_FILE).is_file():
            continue
        video = load_video(video_dir)
        heads = video.ground_truth.heads if video.ground_truth is not None else {}
        yield from _iter_video_frames(video_dir, heads, frame_step)


def iter_mot_frames(sequence: Path, frame_step: int = 2) -> Iterator[AnnotatedFrame]:
    """Every ``frame_step``-th frame of a MOTChallenge sequence, heads from its body boxes."""
    gt_path = Path(sequence) / "gt" / "gt.txt"
    if not gt_path.is_file():
        raise UserError(f"{gt_path}: not found; expected a MOTChallenge sequence with gt/gt.txt.")
    yield from _iter_video_frames(Path(sequence), mot_heads(gt_path), frame_step)


def head_boxes(heads: NDArray[np.float64]) -> NDArray[np.float64]:
    """Square ``(M, 4)`` boxes ``(left, top, side, side)`` of ``(M, 3)`` heads ``x, y, size``.

    >>> head_boxes(np.array([[10.0, 20.0, 4.0]])).tolist()
    [[8.0, 18.0, 4.0, 4.0]]
    """
    heads = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
    half = 0.5 * heads[:, 2]
    return np.stack([heads[:, 0] - half, heads[:, 1] - half, heads[:, 2], heads[:, 2]], axis=1)


def label_boxes(boxes: NDArray[np.float64], heads: NDArray[np.float64]) -> NDArray[np.int8]:
    """Label ``(N, 4)`` boxes against ``(M, 3)`` heads: 1 head, 0 background, -1 ambiguous.

    >>> heads = np.array([[50.0, 50.0, 20.0]])
    >>> boxes = np.array([[41, 41, 20, 20], [80, 80, 20, 20], [46, 46, 10, 10.0]])
    >>> label_boxes(boxes, heads).tolist()
    [1, 0, -1]
    """
    count = len(boxes)
    if len(heads) == 0:
        return np.zeros(count, dtype=np.int8)
    centres = boxes[:, :2] + 0.5 * boxes[:, 2:]
    sizes = np.sqrt(np.maximum(boxes[:, 2] * boxes[:, 3], 1e-9))
    distance = np.linalg.norm(centres[:, None, :] - heads[None, :, :2], axis=2) / heads[None, :, 2]
    ratio = sizes[:, None] / heads[None, :, 2]
    positive = (distance < 0.25) & (ratio > 0.6) & (ratio < 1.7)
    close = (distance < 0.6) & (ratio > 0.45) & (ratio < 2.2)
    labels = np.full(count, -1, dtype=np.int8)
    labels[positive.any(axis=1)] = 1
    labels[~close.any(axis=1)] = 0
    return labels


def candidate_boxes(
    frame: AnnotatedFrame,
    rng: np.random.Generator,
    settings: SamplingSettings,
    proposer: HeadProposer | None = None,
) -> NDArray[np.float64]:
    """Candidate ``(N, 4)`` boxes of one frame (jittered heads, near misses, random, proposals)."""
    height, width = frame.image.shape[:2]
    # The same smallest head as the proposals and the detection benchmark (px at 1080p): a
    # fixed pixel size would leave the smallest heads the detector must find without positives.
    smallest = settings.min_head_size * height / 1080.0
    heads = frame.heads[frame.heads[:, 2] >= smallest] if len(frame.heads) else np.zeros((0, 3))
    parts: list[NDArray[np.float64]] = []
    for head_x, head_y, size in heads:
        count = settings.positives_per_head
        shift = rng.uniform(-0.15, 0.15, size=(count, 2)) * size
        side = size * np.exp(rng.uniform(-0.25, 0.25, size=(count, 1)))
        aspect = np.exp(rng.uniform(-0.1, 0.1, size=(count, 1)))
        box_w, box_h = side * aspect, side / aspect
        centre = np.array([head_x, head_y]) + shift
        parts.append(np.hstack([centre - 0.5 * np.hstack([box_w, box_h]), box_w, box_h]))
        count = settings.near_misses_per_head
        angle = rng.uniform(0, 2 * np.pi, size=count)
        radius = rng.uniform(0.65, 1.3, size=count) * size
        side = size * np.exp(rng.uniform(-0.3, 0.3, size=count))
        scale_miss = size * rng.choice([0.35, 2.5], size=count) * rng.uniform(0.85, 1.15, count)
        shifted = rng.random(count) < 0.6
        side = np.where(shifted, side, scale_miss)
        centre_x = head_x + np.where(shifted, radius * np.cos(angle), 0.0)
        centre_y = head_y + np.where(shifted, radius * np.sin(angle), 0.0)
        parts.append(np.stack([centre_x - side / 2, centre_y - side / 2, side, side], axis=1))
    size_scale = height / 1080.0
    count = settings.random_per_frame
    side = np.exp(rng.uniform(np.log(10 * size_scale), np.log(120 * size_scale), size=count))
    parts.append(
        np.stack([rng.uniform(0, width - side), rng.uniform(0, height - side), side, side], axis=1)
    )
    if proposer is not None and settings.proposals_per_frame > 0:
        proposals = proposer.propose(frame.image)
        # Every proposal near a head is kept (they are the positives the detector will see).
        labels = label_boxes(proposals, heads)
        parts.append(proposals[labels == 1])
        proposals = proposals[labels != 1]
        if len(proposals) > settings.proposals_per_frame:
            proposals = proposals[
                rng.choice(len(proposals), settings.proposals_per_frame, replace=False)
            ]
        parts.append(proposals)
    return np.concatenate(parts, axis=0) if parts else np.zeros((0, 4))


def sample_crops(
    frame: AnnotatedFrame,
    rng: np.random.Generator,
    settings: SamplingSettings,
    proposer: HeadProposer | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Labelled crops of one frame.

    Returns:
        ``(crops, labels)``: ``(N, s, s, 3)`` uint8 BGR crops at the input size and ``(N,)``
        labels (1 head, 0 background); at most ``max_negative_ratio`` negatives per positive
        (at least ``random_per_frame`` on frames without heads).
    """
    boxes = candidate_boxes(frame, rng, settings, proposer)
    labels = label_boxes(boxes, frame.heads.reshape(-1, 3))
    positives = np.flatnonzero(labels == 1)
    negatives = np.flatnonzero(labels == 0)
    limit = max(settings.random_per_frame, int(settings.max_negative_ratio * len(positives)))
    if len(negatives) > limit:
        negatives = rng.choice(negatives, limit, replace=False)
    chosen = np.concatenate([positives, negatives])
    size = (settings.input_size, settings.input_size)
    crops = extract_crops(frame.image, boxes[chosen], size, settings.context, settings.min_crop)
    return crops, labels[chosen].astype(np.uint8)

"""Small helpers shared by the detectors of this plugin: NMS, detections from boxes, pixels.

The head point of a box follows the project's one rule, :mod:`trackfw.formats.head_point`.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, BoxAnchor, box_points
from trackfw.records import Detections, FrameData


def non_maximum_suppression(
    boxes: NDArray[np.float64], scores: NDArray[np.float64], score_threshold: float, iou: float
) -> NDArray[np.int64]:
    """Indices kept by ``cv2.dnn.NMSBoxes`` (score threshold then greedy IoU suppression).

    Args:
        boxes: ``(N, 4)`` boxes as ``(left, top, width, height)``.
        scores: ``(N,)`` scores.
        score_threshold: boxes scoring below it are dropped.
        iou: overlap above which the lower-scoring box is suppressed.

    Returns:
        ``(K,)`` indices into ``boxes``, best score first.

    >>> import numpy as np
    >>> boxes = np.array([[0, 0, 10, 10], [1, 1, 10, 10], [50, 50, 10, 10]], dtype=float)
    >>> non_maximum_suppression(boxes, np.array([0.9, 0.8, 0.7]), 0.5, 0.3).tolist()
    [0, 2]
    """
    if len(boxes) == 0:
        return np.zeros(0, dtype=np.int64)
    kept = cv2.dnn.NMSBoxes(
        boxes.astype(np.float32).tolist(), scores.astype(np.float32).tolist(), score_threshold, iou
    )
    return np.asarray(kept, dtype=np.int64).reshape(-1)


def suppress_nested_centres(
    boxes: NDArray[np.float64], order: NDArray[np.int64], ratio: float
) -> NDArray[np.int64]:
    """Drop each box whose centre lies near the centre of a better box [OURS].

    IoU NMS keeps a box twice the size of a better one on the same head (their IoU is 0.25),
    and a small box on the edge of a larger head box; both then report a second point on that
    head. Here a box is dropped when its centre is closer than ``ratio`` times the larger of the
    two boxes' sides to the centre of a box kept before it. Two neighbouring heads of similar
    size are about one side apart, so they survive ``ratio`` < 1.

    Args:
        boxes: ``(N, 4)`` boxes as ``(left, top, width, height)``.
        order: indices into ``boxes``, best first (what :func:`non_maximum_suppression` returns).
        ratio: share of the larger side; 0 keeps every box.

    Returns:
        The indices of ``order`` that survive, in the same order.

    >>> import numpy as np
    >>> boxes = np.array([[0, 0, 10, 10], [-5, -5, 20, 20], [12, 0, 10, 10]], dtype=float)
    >>> suppress_nested_centres(boxes, np.array([0, 1, 2]), 0.5).tolist()
    [0, 2]
    """
    if ratio <= 0 or len(order) < 2:
        return order
    chosen = boxes[order]
    centres = chosen[:, :2] + 0.5 * chosen[:, 2:]
    sides = np.sqrt(chosen[:, 2] * chosen[:, 3])
    distance = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
    close = distance < ratio * np.maximum(sides[:, None], sides[None, :])
    keep = np.ones(len(order), dtype=bool)
    for index in range(len(order)):
        if keep[index]:
            later = close[index].copy()
            later[: index + 1] = False
            keep &= ~later
    return order[keep]


def detections_from_boxes(
    boxes: NDArray[np.float64],
    scores: NDArray[np.float64],
    point: BoxAnchor | str,
    body_fraction: float = HEAD_FRACTION,
) -> Detections:
    """Detections with the given boxes, scores and head points taken as ``point``.

    Args:
        boxes: ``(N, 4)`` boxes ``(left, top, width, height)``.
        scores: ``(N,)`` scores.
        point: what a box outlines (:func:`trackfw.formats.box_points`): ``body``, ``centre``
            or ``top``.
        body_fraction: for ``body``, the head centre below the box's top as a share of its
            height (the project's one head-point rule, default 0.08).
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    return Detections(
        points=box_points(boxes, point, body_fraction), scores=scores, boxes=boxes
    )


def frame_pixels(frame: FrameData, detector: str) -> NDArray[np.uint8]:
    """The decoded ``(H, W, 3)`` image of ``frame``; a frame without one is a UserError.

    Args:
        frame: the frame handed to a detector's ``detect``.
        detector: the detector's registered name, for the message.
    """
    if frame.image is None:
        raise UserError(
            f"{frame.video.path}: frame {frame.t} has no pixels; the {detector} detector needs"
            " decoded frames."
        )
    return frame.image

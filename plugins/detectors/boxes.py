"""Small helpers shared by the detectors of this plugin: NMS, detections from boxes, pixels.

The head point of a box follows the project's one rule, :mod:`trackfw.formats.head_point`.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.errors import UserError
from trackfw.formats import (
    HEAD_FRACTION,
    HEAD_SIZE_FRACTION,
    BoxAnchor,
    body_head_points,
    box_points,
)
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


def head_boxes_from_bodies(
    boxes: NDArray[np.float64], fraction: float = HEAD_FRACTION
) -> NDArray[np.float64]:
    """Square ``(N, 4)`` head boxes centred on each body box's head point.

    The head point and size follow :mod:`trackfw.formats.head_point` (centre at ``fraction`` of
    the height below the top, side ``HEAD_SIZE_FRACTION`` of the height); a detector of people
    hands these on so that later stages read a head size from its boxes, as from a head detector.

    >>> import numpy as np
    >>> head_boxes_from_bodies(np.array([[10.0, 20.0, 40.0, 100.0]])).round(2).tolist()
    [[23.5, 21.5, 13.0, 13.0]]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    points = body_head_points(boxes, fraction)
    side = HEAD_SIZE_FRACTION * boxes[:, 3]
    return np.stack([points[:, 0] - side / 2, points[:, 1] - side / 2, side, side], axis=1)


def body_boxes_from_heads(
    points: NDArray[np.float64],
    sizes: NDArray[np.float64],
    aspect: float = 0.5,
    fraction: float = HEAD_FRACTION,
) -> NDArray[np.float64]:
    """Whole-body ``(N, 4)`` boxes of people with ``(N, 2)`` head points and ``(N,)`` head sizes.

    The inverse of :func:`head_boxes_from_bodies` for the height (``h = size /
    HEAD_SIZE_FRACTION``, top at ``y - fraction h``); the width is ``aspect h`` (0.5: the 1:2
    crops re-ID networks take).

    >>> import numpy as np
    >>> body_boxes_from_heads(np.array([[30.0, 28.0]]), np.array([13.0])).round(2).tolist()
    [[5.0, 20.0, 50.0, 100.0]]
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    height = np.asarray(sizes, dtype=np.float64).reshape(-1) / HEAD_SIZE_FRACTION
    width = aspect * height
    top = points[:, 1] - fraction * height
    return np.stack([points[:, 0] - width / 2, top, width, height], axis=1)


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
    return Detections(points=box_points(boxes, point, body_fraction), scores=scores, boxes=boxes)


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

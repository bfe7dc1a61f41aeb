"""Overlap of axis-aligned ``(left, top, width, height)`` boxes: intersection areas and IoU.

Shared by the batch trackers (ByteTrack's and DPNMS's box association), the segment tracker's
appearance memory (how much of a person another one covers), the box metrics of the evaluation
and the detector accuracy benchmark.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import FloatArray

__all__ = ["box_intersection", "box_iou"]


def box_iou(boxes_a: FloatArray, boxes_b: FloatArray) -> FloatArray:
    """``(P, Q)`` intersection over union of ``(left, top, width, height)`` boxes.

    >>> box_iou(np.array([[0.0, 0, 80, 80]]), np.array([[26.0, 0, 80, 80]])).round(3).tolist()
    [[0.509]]
    >>> box_iou(np.array([[0.0, 0, 2, 2]]), np.array([[1.0, 0, 2, 2], [5.0, 5, -1, 2]])).round(4).tolist()
    [[0.3333, 0.0]]
    """
    boxes_a = np.asarray(boxes_a, dtype=np.float64).reshape(-1, 4)
    boxes_b = np.asarray(boxes_b, dtype=np.float64).reshape(-1, 4)
    intersection = box_intersection(boxes_a, boxes_b)
    # A box of negative width or height (a malformed row of a tracks file) covers nothing.
    area_a = np.prod(np.clip(boxes_a[:, 2:], 0.0, None), axis=1)
    area_b = np.prod(np.clip(boxes_b[:, 2:], 0.0, None), axis=1)
    union = area_a[:, None] + area_b[None, :] - intersection
    return np.divide(intersection, union, out=np.zeros_like(intersection), where=union > 0)


def box_intersection(boxes_a: FloatArray, boxes_b: FloatArray) -> FloatArray:
    """``(P, Q)`` intersection areas of ``(left, top, width, height)`` boxes."""
    boxes_a = np.asarray(boxes_a, dtype=np.float64).reshape(-1, 4)
    boxes_b = np.asarray(boxes_b, dtype=np.float64).reshape(-1, 4)
    left = np.maximum(boxes_a[:, None, 0], boxes_b[None, :, 0])
    top = np.maximum(boxes_a[:, None, 1], boxes_b[None, :, 1])
    right = np.minimum(
        boxes_a[:, None, 0] + boxes_a[:, None, 2], boxes_b[None, :, 0] + boxes_b[None, :, 2]
    )
    bottom = np.minimum(
        boxes_a[:, None, 1] + boxes_a[:, None, 3], boxes_b[None, :, 1] + boxes_b[None, :, 3]
    )
    return np.clip(right - left, 0.0, None) * np.clip(bottom - top, 0.0, None)

"""The camera's roll from the frame itself, so that person crops can be cut upright.

See docs/algorithms/segment-tracker.md#upright-crops. A head-worn camera rolls with its wearer's
head, and every segment after a look-away may hold a different roll. Deep re-ID embedders are
trained on upright people: on TUD-Stadtmitte a person turned by 10 (15) degrees lies a median
0.07 (0.13, cosine) from itself upright, where the tracker's look limits are 0.25-0.4. The
world's verticals (building edges, poles, door frames, people) stay near-vertical lines in the
image, turned by the roll; the length-weighted median of the near-vertical segments' lean is the
roll, to about a degree where a scene has such lines.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike

from trackfw.arrays import FloatArray, UInt8Array

#: Lines leaning further than this from the vertical (degrees) are not taken for verticals.
MAX_LEAN_DEGREES = 30.0
#: Rows the frame is resized to before line detection (fewer rows: faster, coarser).
ANALYSIS_ROWS = 480
#: Shortest line segment kept, in pixels at ANALYSIS_ROWS.
MIN_SEGMENT_PX = 20
#: Total length of near-vertical segments (px at ANALYSIS_ROWS) below which the roll is unknown.
MIN_SUPPORT_PX = 150.0


def weighted_median(values: ArrayLike, weights: ArrayLike) -> float:
    """The value at which the cumulative weight of the sorted ``(N,)`` values reaches half.

    >>> weighted_median([1.0, 2.0, 10.0], [1.0, 1.0, 1.0])
    2.0
    >>> weighted_median([1.0, 2.0, 10.0], [1.0, 1.0, 5.0])
    10.0
    """
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    weights = np.asarray(weights, dtype=np.float64).reshape(-1)
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, cumulative[-1] / 2.0)])


def segment_leans(segments: ArrayLike) -> FloatArray:
    """Lean from the vertical, in degrees in [-90, 90), of each ``(N, 4)`` segment
    ``(x1, y1, x2, y2)`` in image coordinates (y down); positive when the top leans left.

    >>> segment_leans([[0, 0, 0, 10], [0, 10, 10, 0], [0, 0, 10, 0]]).round(1).tolist()
    [0.0, -45.0, -90.0]
    """
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    dx = segments[:, 2] - segments[:, 0]
    dy = segments[:, 3] - segments[:, 1]
    lean = np.degrees(np.arctan2(dx, dy))
    return (lean + 90.0) % 180.0 - 90.0


@lru_cache(maxsize=1)
def _line_detector() -> Any:
    """OpenCV-contrib's fast line detector (one per process; it holds no per-frame state)."""
    return cv2.ximgproc.createFastLineDetector(length_threshold=MIN_SEGMENT_PX)


def upright_angle(image: UInt8Array) -> float | None:
    """Degrees to turn ``image`` (counter-clockwise, OpenCV's sign) for its verticals to stand
    upright: minus the camera's roll. None when the frame holds too few near-vertical lines.

    Args:
        image: ``(H, W, 3)`` uint8 BGR frame (or ``(H, W)`` grey).
    """
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    scale = ANALYSIS_ROWS / grey.shape[0]
    if scale < 1.0:
        grey = cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    lines = _line_detector().detect(np.ascontiguousarray(grey))
    if lines is None:
        return None
    segments = lines.reshape(-1, 4)
    lean = segment_leans(segments)
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    near_vertical = np.abs(lean) <= MAX_LEAN_DEGREES
    if length[near_vertical].sum() < MIN_SUPPORT_PX:
        return None
    return -weighted_median(lean[near_vertical], length[near_vertical])


__all__ = ["MAX_LEAN_DEGREES", "segment_leans", "upright_angle", "weighted_median"]

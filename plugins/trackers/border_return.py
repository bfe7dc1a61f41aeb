"""Where a target that left the image comes back: the geometry of the image border.

Used by :class:`trackfw_plugins.trackers.lifecycle.Lifecycle` (the re-entry rule of
docs/algorithms/segment-tracker.md#target-lifecycle): which edge a position outside the image
lies beyond, which lost targets were last seen at an edge, and the cost of a detection near an
edge for a target that left through one.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray


def image_edge(positions: FloatArray, width: int, height: int) -> IntArray:
    """``(M,)`` image edge each ``(M, 2)`` position outside a ``width`` x ``height`` image lies
    beyond (0 left, 1 right, 2 top, 3 bottom): the one it is farthest beyond.

    >>> image_edge(np.array([[-5.0, 10.0], [20.0, 130.0]]), 100, 100).tolist()
    [0, 3]
    """
    beyond = np.column_stack(
        [
            -positions[:, 0],
            positions[:, 0] - (width - 1),
            -positions[:, 1],
            positions[:, 1] - (height - 1),
        ]
    )
    return (
        np.argmax(beyond, axis=1).astype(np.int64)
        if len(positions)
        else np.zeros(0, dtype=np.int64)
    )


def near_edge(
    positions: FloatArray, width: int, height: int, margins: FloatArray
) -> tuple[BoolArray, FloatArray]:
    """Which ``(M, 2)`` positions lie within ``(M,)`` ``margins`` pixels of an image edge, and
    each position moved to just beyond its nearest edge (``(M,)`` bool, ``(M, 2)``).

    >>> near, beyond = near_edge(np.array([[3.0, 50.0], [50.0, 50.0], [97.0, 40.0]]), 100, 100,
    ...                          np.array([5.0, 5.0, 5.0]))
    >>> near.tolist(), beyond[[0, 2]].tolist()
    ([True, False, True], [[-1.0, 50.0], [100.0, 40.0]])
    """
    inside = np.column_stack(
        [
            positions[:, 0],
            (width - 1) - positions[:, 0],
            positions[:, 1],
            (height - 1) - positions[:, 1],
        ]
    )
    nearest = np.argmin(inside, axis=1)
    near = inside[np.arange(len(positions)), nearest] <= margins
    beyond = positions.copy()
    # One pixel outside the edge: inside() is false there, and image_edge names that edge.
    outside = np.array([-1.0, float(width), -1.0, float(height)])
    axis = np.array([0, 0, 1, 1])
    beyond[np.arange(len(positions)), axis[nearest]] = outside[nearest]
    return near, beyond


def border_return_cost(
    exit_sides: IntArray,
    expected: FloatArray,
    gates: FloatArray,
    points: FloatArray,
    margin: float,
    width: int,
    height: int,
) -> FloatArray:
    """``(M, N)`` cost of a return through the border near where each target left: infinite
    unless the detection lies within ``margin`` px of an image edge, else its distance to the
    point of the exit edge nearest the expected place (the door) over the target's gate. Any
    edge counts because a target that left near a corner may come back round it (measured: out
    through the right edge, back 190 px away through the bottom).

    The group's offsets place a returner poorly: the camera has turned while it was away and the
    path it comes back on meets the image border somewhere else along that edge (measured on the
    paper-leave synth set: 170 to 430 px at 720p from the exit point).

    Args:
        exit_sides: ``(M,)`` edge each target left through (:func:`image_edge`), -1 for none.
        expected: ``(M, 2)`` where each target is expected.
        gates: ``(M,)`` each target's re-entry gate in pixels.
        points: ``(N, 2)`` detections.
        margin: how near an edge, in pixels, a returning head may be.
        width, height: the image size.
    """
    cost = np.full((len(exit_sides), len(points)), np.inf)
    if not (exit_sides >= 0).any():
        return cost
    size = np.array([width - 1.0, height - 1.0])
    # Distance inside each edge: left, right, top, bottom.
    depth = np.column_stack(
        [points[:, 0], size[0] - points[:, 0], points[:, 1], size[1] - points[:, 1]]
    )
    near = depth.min(axis=1) <= margin
    for m in np.flatnonzero(exit_sides >= 0):
        side = int(exit_sides[m])
        door = np.clip(expected[m], 0.0, size)
        door[side // 2] = 0.0 if side % 2 == 0 else size[side // 2]
        cost[m, near] = np.linalg.norm(points[near] - door, axis=1) / gates[m]
    return cost

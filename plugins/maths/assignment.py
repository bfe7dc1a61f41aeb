"""Point-to-point association: gated Hungarian and greedy nearest neighbour.

See docs/algorithms/segment-tracker.md#hungarian-association and
docs/algorithms/segment-tracker.md#nearest-neighbour-association.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import BoolArray, FloatArray, IntArray

#: Cost given to gated-out pairs before solving; any pair at this cost is dropped afterwards.
FORBIDDEN_COST = 1.0e6


def linear_sum_assignment(cost: NDArray[Any]) -> tuple[IntArray, IntArray]:
    """scipy's optimal assignment of the ``(K, N)`` ``cost``: ``(min(K, N),)`` rows and columns.

    Every module that solves an assignment calls this one: scipy.optimize is imported on first
    use, not when the plugins are registered, because its import (about 0.6 s) would otherwise
    slow every command of the CLI, ``trackfw --help`` included.

    >>> [index.tolist() for index in linear_sum_assignment(np.array([[4.0, 1.0], [2.0, 3.0]]))]
    [[0, 1], [1, 0]]
    """
    from scipy.optimize import linear_sum_assignment as solve

    rows, columns = solve(cost)
    return np.asarray(rows, dtype=np.int64), np.asarray(columns, dtype=np.int64)


def distance_matrix(predictions: FloatArray, detections: FloatArray) -> FloatArray:
    """``(K, N)`` Euclidean distances between ``(K, 2)`` predictions and ``(N, 2)`` detections.

    >>> distance_matrix(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0], [0.0, 1.0]])).tolist()
    [[5.0, 1.0]]
    """
    predictions = np.asarray(predictions, dtype=np.float64).reshape(-1, 2)
    detections = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
    difference = predictions[:, None, :] - detections[None, :, :]
    return np.sqrt(np.einsum("kni,kni->kn", difference, difference))


def _unassigned(cost: FloatArray) -> tuple[FloatArray, IntArray]:
    """The ``(K, N)`` cost as float64 and a ``(K,)`` assignment with every row unassigned (-1)."""
    cost = np.asarray(cost, dtype=np.float64)
    return cost, np.full(cost.shape[0], -1, dtype=np.int64)


def hungarian(
    cost: FloatArray, gate: float | None = None, *, unmatched_cost: float | None = None
) -> IntArray:
    """Optimal one-to-one assignment; returns ``(K,)`` column per row, ``-1`` when unassigned.

    Entries above ``gate`` are set to a large constant before solving and any pair that still
    lands on one is dropped. The solver then matches as many rows as the gate allows, before it
    looks at the cost: one row without its own column can push a chain of rows onto their
    neighbours' columns. With ``unmatched_cost`` a row may instead stay unmatched at that cost
    (ByteTrack's ``lapjv`` cost limit), so a chain is taken only when it costs less than the
    row it matches.

    >>> hungarian(np.array([[1.0, 9.0], [2.0, 3.0]])).tolist()
    [0, 1]
    >>> hungarian(np.array([[1.0, 90.0], [2.0, 80.0]]), gate=50.0).tolist()
    [0, -1]
    >>> chain = np.array([[1.0, 40.0], [45.0, 99.0]])
    >>> hungarian(chain, gate=50.0).tolist()
    [1, 0]
    >>> hungarian(chain, gate=50.0, unmatched_cost=50.0).tolist()
    [0, -1]
    """
    cost, assignment = _unassigned(cost)
    if cost.size == 0:
        return assignment
    gated = cost if gate is None else np.where(cost > gate, FORBIDDEN_COST, cost)
    columns = cost.shape[1]
    if unmatched_cost is not None:
        # One private "unmatched" column per row, at unmatched_cost on its diagonal.
        alone = np.full((len(cost), len(cost)), FORBIDDEN_COST)
        np.fill_diagonal(alone, unmatched_cost)
        gated = np.concatenate([gated, alone], axis=1)
    row_index, column_index = linear_sum_assignment(gated)
    for row, column in zip(row_index, column_index, strict=True):
        if column >= columns or (gate is not None and cost[row, column] > gate):
            continue
        assignment[row] = column
    return assignment


def match_ratios(cost: FloatArray, assignment: IntArray) -> FloatArray:
    """How clearly each row's assigned column stood out: its cost over the row's cheapest other.

    Below 1 no other column fitted that row as well; 1 or more, another fitted at least as
    well (the assignment gave it to someone else, or the two tie). A ratio test, as in feature
    matching, read off the assignment's own cost matrix.

    Args:
        cost: ``(K, N)`` non-negative costs.
        assignment: ``(K,)`` column of each row, ``-1`` when unassigned.

    Returns:
        ``(K,)`` ratios; NaN for an unassigned row and where the row has no other column.

    >>> match_ratios(np.array([[1.0, 4.0, 2.0], [3.0, 3.75, 9.0]]), np.array([0, 1])).tolist()
    [0.5, 1.25]
    >>> match_ratios(np.array([[1.0], [2.0]]), np.array([0, -1])).tolist()
    [nan, nan]
    """
    cost = np.asarray(cost, dtype=np.float64)
    ratios = np.full(len(assignment), np.nan)
    if cost.ndim != 2 or cost.shape[1] < 2:
        return ratios
    rows = np.flatnonzero(assignment >= 0)
    columns = assignment[rows]
    others = cost[rows].copy()
    others[np.arange(len(rows)), columns] = np.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios[rows] = cost[rows, columns] / others.min(axis=1)
    return ratios


def outnumbered(cost: FloatArray, gate: float | None = None) -> tuple[BoolArray, IntArray]:
    """Rows that share their nearest column with other rows that have no other column to take.

    Two people standing close together often give one detection between them: whichever takes
    it takes the other's motion too. Rows with the same nearest column (within ``gate``) form
    a group; each column counts for the row nearest to it; a group with fewer columns than
    rows is outnumbered. Returns ``(K,)`` whether each row of the ``(K, N)`` cost is in an
    outnumbered group, and ``(K,)`` its nearest column (``-1``: none within the gate).

    >>> rows, nearest = outnumbered(np.array([[6.0, 40.0], [21.0, 30.0], [50.0, 2.0]]))
    >>> rows.tolist(), nearest.tolist()
    ([True, True, False], [0, 0, 1])
    >>> outnumbered(np.array([[12.0, 34.0], [9.0, 22.0]]))[0].tolist()  # a column each
    [False, False]
    >>> outnumbered(np.array([[6.0], [21.0]]), gate=20.0)[0].tolist()
    [False, False]
    """
    count = cost.shape[0]
    limit = np.inf if gate is None else gate
    nearest = np.full(count, -1, dtype=np.int64)
    flagged = np.zeros(count, dtype=bool)
    if cost.size == 0:
        return flagged, nearest
    best = np.argmin(cost, axis=1)
    inside = cost[np.arange(count), best] <= limit
    nearest[inside] = best[inside]
    owner = np.argmin(cost, axis=0)
    owned = cost[owner, np.arange(cost.shape[1])] <= limit
    for column in np.unique(nearest[nearest >= 0]):
        group = np.flatnonzero(nearest == column)
        if len(group) >= 2 and np.count_nonzero(owned & np.isin(owner, group)) < len(group):
            flagged[group] = True
    return flagged, nearest


def greedy_nearest(cost: FloatArray, gate: float | None = None) -> IntArray:
    """Greedy nearest-neighbour assignment (Kalman2): globally smallest pair first.

    Ties break by the lower (row, column) index, for determinism.

    >>> greedy_nearest(np.array([[1.0, 2.0], [1.5, 9.0]])).tolist()
    [0, 1]
    >>> greedy_nearest(np.array([[1.0, 2.0], [1.5, 9.0]]), gate=5.0).tolist()
    [0, -1]
    """
    cost, assignment = _unassigned(cost)
    if cost.size == 0:
        return assignment
    rows, columns = cost.shape
    # A stable sort on the flattened (row-major) matrix gives the (row, column) tie-break.
    order = np.argsort(cost, axis=None, kind="stable")
    row_taken = np.zeros(rows, dtype=bool)
    column_taken = np.zeros(columns, dtype=bool)
    for flat in order:
        row, column = divmod(int(flat), columns)
        if gate is not None and cost[row, column] > gate:
            break
        if row_taken[row] or column_taken[column]:
            continue
        assignment[row] = column
        row_taken[row] = True
        column_taken[column] = True
        if row_taken.all() or column_taken.all():
            break
    return assignment

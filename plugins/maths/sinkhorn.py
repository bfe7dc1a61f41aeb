"""Batched Sinkhorn normalisation with constant outlier slack (TPS-RPM's softassign).

See docs/algorithms/tps-rpm.md#algorithm.

The correspondence of each data set is kept as scaling vectors, ``H = diag(a) E diag(b)``, over
affinities E of shape (K, N, B) with the batch innermost. Every data set stops by the authors'
rule on its own, so a batch gives the same result as one data set at a time. Each sweep writes
to its own slab of a preallocated workspace and a data set's result is read once, from the sweep
where it stopped.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import DTypeLike, NDArray

from trackfw.arrays import FloatArray, IntArray


class SinkhornWorkspace:
    """Buffers of :func:`_sinkhorn` for one (K, N, B) shape, reused across its many calls.

    Sweep s writes its scalings into slab s of a history, so a data set that meets the
    stopping test needs no copy when it stops: its sweep is noted and its scalings are
    gathered once, at the end.
    """

    def __init__(self, rows: int, columns: int, batch: int, sweeps: int, dtype: DTypeLike) -> None:
        self.shape = (rows, columns, batch)
        self.row_history: FloatArray = np.empty((sweeps + 1, rows, batch), dtype=dtype)
        self.column_history: FloatArray = np.empty((sweeps + 1, columns, batch), dtype=dtype)
        self.sums: FloatArray = np.empty((rows + columns, batch), dtype=dtype)
        self.error: FloatArray = np.empty(batch, dtype=dtype)
        self.stopping: NDArray[np.bool_] = np.empty(batch, dtype=bool)
        # Flat index of entry (p, b) within one history slab, for the final gather.
        self.row_base: IntArray = np.arange(rows * batch).reshape(rows, batch)
        self.column_base: IntArray = np.arange(columns * batch).reshape(columns, batch)


def gather_sweep(history: FloatArray, slab: IntArray, base: IntArray | None = None) -> FloatArray:
    """``history[slab[b], :, b]`` for every column b, as a (rows, B) array.

    Args:
        history: (S, rows, B) slabs.
        slab: (B,) slab of each column.
        base: (rows, B) flat index of each entry within a slab (computed when None).

    >>> history = np.arange(12.0).reshape(3, 2, 2)
    >>> gather_sweep(history, np.array([2, 0])).tolist()
    [[8.0, 1.0], [10.0, 3.0]]
    """
    _, rows, width = history.shape
    if base is None:
        base = np.arange(rows * width).reshape(rows, width)
    # One take on flat indices is several times faster than the mixed fancy index.
    return np.take(history.reshape(-1), base + slab * (rows * width))


def sinkhorn(
    affinity: FloatArray,
    row_slack: FloatArray,
    column_slack: FloatArray,
    max_sweeps: int,
    tolerance: float,
    initial_row_scale: float,
    workspace: SinkhornWorkspace | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Scaling vectors of the two-way normalisation with constant outlier slack.

    Args:
        affinity: (K, N, B) non-negative affinities E.
        row_slack: (B,) outlier-column entry m_out divided by initial_row_scale.
        column_slack: (B,) outlier-row entry m_out.
        max_sweeps: maximum row+column sweeps.
        tolerance: per data set, stop once mean((s-1)², (t-1)²) < tolerance².
        initial_row_scale: factor that turns E into the code's raw m (T^-1/2); it only matters
            for the first sweep's stopping test, which is not scale-invariant.
        workspace: buffers for this shape and ``max_sweeps`` (allocated when None).

    Returns:
        Row scaling (K, B) and column scaling (N, B): H = a_p E_pq b_q.
    """
    rows, columns, batch = affinity.shape
    dtype = affinity.dtype
    if workspace is None or workspace.shape != affinity.shape:
        workspace = SinkhornWorkspace(rows, columns, batch, max_sweeps, dtype)
    row_history, column_history = workspace.row_history, workspace.column_history
    sums, error, stopping = workspace.sums, workspace.error, workspace.stopping
    row_sums, column_sums = sums[:rows], sums[rows:]
    row_history[0] = initial_row_scale
    column_history[0] = 1.0
    limit = tolerance * tolerance * (rows + columns)
    # A data set that meets the test keeps riding along (its later values are ignored): only
    # its stopping sweep is noted, and its scalings are read from that sweep's history slab at
    # the end. Most data sets stop in the last few sweeps, so compacting the arrays, or copying
    # columns out as they stop, costs more than the sweeps it would save.
    stopped_at = np.full(batch, max_sweeps)
    active = np.ones(batch, dtype=bool)
    # Slack as full (K, B) and (N, B) arrays: adding a (B,) vector across rows is a slow
    # numpy path, and the slack is added once per sweep.
    row_slack = np.repeat(row_slack[None, :].astype(dtype, copy=False), rows, axis=0)
    column_slack = np.repeat(column_slack[None, :].astype(dtype, copy=False), columns, axis=0)
    for sweep in range(1, max_sweeps + 1):
        previous_row, previous_column = row_history[sweep - 1], column_history[sweep - 1]
        # Row p's slack is row_slack·a_p (never column-normalised); column q's is
        # column_slack·b_q (never row-normalised).
        if sweep == 1:
            # The column scaling starts at 1, so the first row sums are plain sums.
            np.add.reduce(affinity, axis=1, out=row_sums)
        else:
            np.einsum("knb,nb->kb", affinity, previous_column, out=row_sums)
        row_sums += row_slack
        row_sums *= previous_row
        new_row = np.divide(previous_row, row_sums, out=row_history[sweep])
        np.einsum("knb,kb->nb", affinity, new_row, out=column_sums)
        column_sums += column_slack
        column_sums *= previous_column
        np.divide(previous_column, column_sums, out=column_history[sweep])
        # Stopping test on the K+N contiguous rows at once (an einsum would reduce over the
        # strided axis, which is slow).
        sums -= 1.0
        np.square(sums, out=sums)
        np.add.reduce(sums, axis=0, out=error)
        np.less(error, limit, out=stopping)
        stopping &= active
        if not stopping.any():
            continue
        np.putmask(stopped_at, stopping, sweep)
        active &= ~stopping
        if not active.any():
            break
    return (
        gather_sweep(row_history, stopped_at, workspace.row_base),
        gather_sweep(column_history, stopped_at, workspace.column_base),
    )

"""Decisions read off look matrices: appearance distances of targets to detections.

Shared by the kalman tracker's searches by look (:mod:`trackfw_plugins.trackers.kalman`): a
detection that stands out from the rest of the frame, a ratio test against the next nearest one,
and the hand-over of a detection between two targets by the order of their looks.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.records import NO_MATCH


def _with_second_nearest(look: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``look`` with NaN as infinity, and ``(M,)`` each row's second smallest (inf if none)."""
    known = np.where(np.isnan(look), np.inf, look)
    second = np.sort(known, axis=1)[:, 1] if look.shape[1] > 1 else np.full(len(look), np.inf)
    return known, second


def stands_out(look: FloatArray, margin: float) -> BoolArray:
    """``(M, N)``: where detection n is nearer in look to target m than every other one by ``margin``.

    ``look`` is ``(M, N)`` appearance distances over every detection of the frame (NaN: nothing
    known, never stands out). A bystander rarely stands out from the rest of a crowd that clearly,
    so a match by look alone, with no place to check it against, asks for this.

    >>> stands_out(np.array([[0.1, 0.4, 0.5], [0.40, 0.45, 0.9]]), 0.15).tolist()
    [[True, False, False], [False, False, False]]
    >>> stands_out(np.array([[np.nan, np.nan]]), 0.15).tolist()
    [[False, False]]
    """
    known, second = _with_second_nearest(look)
    return np.isfinite(known) & (known + margin <= second[:, None])


def nearer_by_ratio(look: FloatArray, ratio: float) -> BoolArray:
    """``(M, N)``: where detection n's distance to target m (in look, or in pixels) is at most
    ``ratio`` times the next nearest detection's (a ratio test, as in feature matching; NaN
    never qualifies).

    Scale-free, unlike :func:`stands_out`: person re-ID distances between the rendered people
    of the synth preset are several times smaller than between TUD heads.

    >>> nearer_by_ratio(np.array([[0.06, 0.53, 0.6], [0.44, 0.45, 0.5]]), 0.8).tolist()
    [[True, False, False], [False, False, False]]
    >>> nearer_by_ratio(np.array([[np.nan, np.nan], [0.3, np.nan]]), 0.8).tolist()
    [[False, False], [True, False]]
    """
    known, second = _with_second_nearest(look)
    return np.isfinite(known) & (known <= ratio * second[:, None])


def hand_over(
    rows: IntArray,
    claimants: IntArray,
    holders: IntArray,
    own: FloatArray,
    theirs: FloatArray,
    margin: float,
) -> IntArray:
    """Move held detections to the claimants that look more like them.

    Args:
        rows: ``(M,)`` detection of each target (-1: none).
        claimants: ``(K,)`` targets without one, each claiming the detection of ``holders[k]``.
        holders: ``(K,)`` the targets holding the claimed detections.
        own: ``(K,)`` the claimant's look distance to the claimed detection (NaN: unknown).
        theirs: ``(K,)`` the holder's look distance to it.
        margin: how much nearer the claimant's look must be.

    Returns:
        ``rows`` with each won detection moved to its claimant and its holder left without
        (a copy when any moved). The clearest claim goes first; a detection changes hands once.

    >>> rows = np.array([0, -1, -1])
    >>> hand_over(rows, np.array([1, 2]), np.array([0, 0]), np.array([0.3, 0.1]),
    ...           np.array([0.5, 0.5]), 0.05).tolist()
    [-1, -1, 0]
    >>> hand_over(rows, np.array([1]), np.array([0]), np.array([0.48]), np.array([0.5]), 0.05)
    array([ 0, -1, -1])
    """
    won = np.isfinite(own) & np.isfinite(theirs) & (own + margin < theirs)
    if not won.any():
        return rows
    rows = rows.copy()
    order = np.flatnonzero(won)
    for claim in order[np.argsort(-(theirs - own)[order], kind="stable")]:
        claimant, holder = claimants[claim], holders[claim]
        if rows[holder] >= 0 and rows[claimant] < 0:
            rows[claimant], rows[holder] = rows[holder], NO_MATCH
    return rows


__all__ = ["hand_over", "nearer_by_ratio", "stands_out"]

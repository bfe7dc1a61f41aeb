"""A detection contested by look: the target hidden behind it against the target that took it.

Used on every frame by :meth:`trackfw_plugins.trackers.kalman.KalmanTracker.step`
(docs/algorithms/segment-tracker.md, ``appearance.contest_margin``).
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import FloatArray, IntArray, UInt8Array
from trackfw.records import Detections
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory
from trackfw_plugins.trackers.lifecycle import Lifecycle
from trackfw_plugins.trackers.look_rules import hand_over


def contest_hidden(
    memory: AppearanceMemory,
    life: Lifecycle,
    image: UInt8Array | None,
    margin: float | None,
    active: IntArray,
    positions: FloatArray,
    rows: IntArray,
    detections: Detections,
    sides: FloatArray,
) -> IntArray:
    """Give a detection to the target hidden behind it when it looks more like that one.

    Two people crossing give one detection; the Hungarian hands it to whichever prediction
    lies nearer, and the other target, left without, is lost after a few frames and rarely
    found again in a crowd. Each target left without a detection (``active`` rows with
    ``rows`` -1) and hidden behind a detection another target took
    (:meth:`Lifecycle.hidden_behind_which`) contests it by look: when its own look at the
    detection is nearer than the holder's by ``margin`` (``appearance.contest_margin``), the
    detection changes hands. Deciding between the two targets' own descriptors asks less of the
    embedder than a fixed limit: on crowded low-resolution footage the same person a second
    later and another person overlap in distance, but rarely in order.

    Args:
        memory: the targets' descriptors.
        life: the targets' lifecycle (who is hidden behind which detection).
        image: the frame's pixels.
        margin: how much nearer the claimant's look must be; None: no contest.
        active: ``(M,)`` the associated targets' rows.
        positions: ``(K, 2)`` every target's predicted position.
        rows: ``(M,)`` detection row of each of ``active`` (-1: none).
        detections: the frame's detections.
        sides: the detections' ``(N,)`` box sides.

    Returns:
        ``rows`` with the contested detections moved (:func:`hand_over`).
    """
    hit = rows >= 0
    if margin is None or image is None or not memory.active:
        return rows
    if hit.all() or not hit.any():
        return rows
    holders, missing = np.flatnonzero(hit), np.flatnonzero(~hit)
    taken = rows[holders]
    behind = life.hidden_behind_which(
        active[missing], positions[active[missing]], detections.points[taken], sides[taken]
    )
    hidden = behind >= 0
    claimants, held_by = missing[hidden], holders[behind[hidden]]
    if len(claimants) == 0:
        return rows
    columns = np.unique(rows[held_by])
    targets = np.concatenate([active[claimants], active[held_by]])
    look = memory.looks(image, targets, detections, columns)
    pairs = np.arange(len(claimants))
    column = np.searchsorted(columns, rows[held_by])
    own, theirs = look[pairs, column], look[len(claimants) + pairs, column]
    return hand_over(rows, claimants, held_by, own, theirs, margin)

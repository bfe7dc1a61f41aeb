"""The people seen beside a target when it was lost, so that the search by look does not take one.

See docs/algorithms/segment-tracker.md#people-seen-beside-a-lost-target. A lost target is re-found
anywhere in the image by the detection that looks most like it; on virtual-wearer TUD videos most
of those finds that took someone else took a person who was in view, away from the target, in the
second before it was lost: a neighbour in the same crowd, dressed alike. The bystander track that
followed that person usually broke in the meantime, so "seen apart" (:mod:`.bystanders`) no
longer knows it. Its look is kept instead: on the first frame a tracked target is lost, every
free detection far from both its expected place and its last detection is described, and a later
find by look is refused when the detection looks at least as much like one of them as like the
target. Two heads seen at once are two people, whatever became of the track.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray, UInt8Array
from trackfw.records import Detections
from trackfw_plugins.maths.assignment import distance_matrix
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory

#: Descriptors kept per target: a loss in a crowd sees a dozen heads at most; later losses add.
NEIGHBOURS_KEPT = 32

#: Seen apart: farther than this many of the target's head sides (or the bystanders'
#: ``apart_gates``, whichever is more) from its expected place and its last detection. A target
#: lost for a few frames has walked on from both (on TUD-Campus wear videos, 46 px from its last
#: detection at 480p, two gates being 44 px).
NEIGHBOUR_APART_SIDES = 3.0

Metric = Callable[[FloatArray, FloatArray], FloatArray]


@dataclass
class NeighbourLooks:
    """Per target, the looks of the people seen apart from it when it was lost.

    Attributes:
        descriptors: per target a ``(P, D)`` array of descriptors (None: none kept).
        tracked: ``(K,)`` whether each target was tracked (had a detection or a re-acquisition
            behind it) at the end of the previous frame: only such a target is known to be
            near its expected place when it is lost. Placed at b by a gap matcher, or out of
            view, it may be anywhere in the frame, among the detections.
    """

    descriptors: list[FloatArray | None]
    tracked: BoolArray

    @classmethod
    def start(cls, count: int) -> NeighbourLooks:
        """Nothing kept for ``count`` targets, all tracked (given on the first frame)."""
        return cls([None] * count, np.ones(count, dtype=bool))

    def remember(self, row: int, descriptors: FloatArray) -> None:
        """Add ``(P, D)`` descriptors of people seen apart from target ``row`` as it was lost;
        the oldest go beyond :data:`NEIGHBOURS_KEPT`."""
        if len(descriptors) == 0:
            return
        old = self.descriptors[row]
        kept = descriptors if old is None else np.concatenate([old, descriptors])
        self.descriptors[row] = kept[-NEIGHBOURS_KEPT:]

    def end_frame(self, tracked: BoolArray, inactive: BoolArray) -> IntArray:
        """``(K,)`` which targets are tracked, and which lost or out of view, at the end of this
        frame. The tracked ones are followed again: whom they were lost beside says nothing now
        (a wrong find would otherwise keep the true target among them).

        Returns:
            The targets lost on this frame after being tracked on the previous one.

        >>> looks = NeighbourLooks.start(3)
        >>> looks.end_frame(np.array([True, False, True]), np.array([False, True, False])).tolist()
        [1]
        >>> looks.end_frame(np.array([True, False, False]), np.array([False, True, True])).tolist()
        [2]
        """
        lost = np.flatnonzero(self.tracked & inactive)
        for row in np.flatnonzero(tracked):
            self.descriptors[int(row)] = None
        self.tracked = np.asarray(tracked, dtype=bool).copy()
        return lost

    def remember_apart(
        self,
        memory: AppearanceMemory,
        image: UInt8Array | None,
        detections: Detections,
        free: IntArray,
        rows: IntArray,
        places: tuple[FloatArray, ...],
        reach: FloatArray,
        limit: float,
    ) -> None:
        """Keep, for each target of ``rows``, the looks of the detections ``free`` (rows of
        ``detections`` no target holds) farther than ``reach[m]`` pixels from each of its
        ``places`` (``(M, 2)`` arrays: where it may be), unless within ``limit`` of its
        descriptor (the search by look would take them for it)."""
        if len(rows) == 0 or image is None or not memory.active:
            return
        points = detections.points[free]
        apart = np.ones((len(rows), len(free)), dtype=bool)
        for place in places:
            apart &= distance_matrix(place, points) > reach[:, None]
        wanted = np.flatnonzero(apart.any(axis=0))
        look, described = memory.described_distances(image, rows, detections, free[wanted])
        if described is None:
            return
        for m, row in enumerate(rows):
            # NaN (the target never described) keeps nothing: nothing to compare with.
            self.remember(int(row), described[apart[m, wanted] & (look[m] > limit)])

    def distances(self, rows: IntArray, described: FloatArray, metric: Metric) -> FloatArray:
        """``(M, N)`` distance of each of ``(N, D)`` descriptors ``described`` to the nearest
        person kept for target ``rows[m]`` (inf: none kept), in the descriptor's ``metric``.

        >>> looks = NeighbourLooks.start(2)
        >>> looks.remember(1, np.array([[0.0, 1.0], [1.0, 1.0]]))
        >>> def euclid(a, b):
        ...     return np.linalg.norm(a[:, None] - b[None], axis=2)
        >>> looks.distances(np.array([0, 1]), np.array([[0.0, 0.0], [1.0, 2.0]]), euclid).tolist()
        [[inf, inf], [1.0, 1.0]]
        """
        result = np.full((len(rows), len(described)), np.inf)
        if len(described) == 0:
            return result
        for m, row in enumerate(rows):
            kept = self.descriptors[int(row)]
            if kept is not None:
                result[m] = metric(kept, described).min(axis=0)
        return result


__all__ = ["NEIGHBOURS_KEPT", "NEIGHBOUR_APART_SIDES", "NeighbourLooks"]

"""Under the name it was given: how often each person of interest is reported as themselves.

A user gives the people of interest on the first frame (clicks, or a dataset's gt.csv) and reads
the output by those names. CLEAR MOT counts a swap of two names once (one identity switch each)
and IDF1 maps the reported identities to the people as a whole, so two targets that swap names
on the start frame and keep them cost almost nothing there, while the user follows the wrong
person from then on. This diagnostic reads the names as given: a ground-truth point of person
``k`` counts as *named* when the run reports track ``k`` within the match distance of it on that
frame. It means something only when the run's targets were given with the ground truth's ids
(summary.json ``initialised_from: gt``, as ``trackfw bench`` starts every run on a dataset with
gt.csv); the evaluation reports it for those runs only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from trackfw_plugins.evaluation.clear_mot import FrameObservations
from trackfw_plugins.maths.confusion import PooledCounts, ratio


@dataclass
class GivenIdentityCounts(PooledCounts):
    """Ground-truth target points and those reported under their own id, pooled with ``+``.

    >>> total = GivenIdentityCounts(points=10, named=9) + GivenIdentityCounts(points=10, named=1)
    >>> total.points, total.named, total.share
    (20, 10, 0.5)
    """

    points: int = 0
    named: int = 0

    @property
    def share(self) -> float:
        """Named / ground-truth points; NaN when there is no ground-truth point."""
        return ratio(self.named, self.points)


def frame_named(observation: FrameObservations, distance_px: float) -> int:
    """How many ground-truth points of one frame have their own id reported within
    ``distance_px``.

    >>> import numpy as np
    >>> frame = FrameObservations(0, np.array([1, 2]), np.array([[0.0, 0.0], [100.0, 0.0]]),
    ...                           np.array([1, 2]), np.array([[100.0, 0.0], [0.0, 0.0]]))
    >>> frame_named(frame, 40.0)  # the two names swapped: each on the other's head
    0
    """
    if len(observation.gt_ids) == 0 or len(observation.hyp_ids) == 0:
        return 0
    same = observation.gt_ids[:, None] == observation.hyp_ids[None, :]
    near = observation.distances("point") <= distance_px
    return int((same & near).any(axis=1).sum())


def given_identity_counts(
    sequence: Sequence[FrameObservations], distance_px: float
) -> GivenIdentityCounts:
    """Counts over a video's evaluated frames (points)."""
    points = sum(len(observation.gt_ids) for observation in sequence)
    named = sum(frame_named(observation, distance_px) for observation in sequence)
    return GivenIdentityCounts(points=int(points), named=int(named))


__all__ = ["GivenIdentityCounts", "frame_named", "given_identity_counts"]

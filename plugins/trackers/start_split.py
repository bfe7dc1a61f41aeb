"""A target given on a box it shares with a passer-by: when the box splits, the target is the head
whose path leads back to where it was given.

See docs/algorithms/segment-tracker.md#a-start-on-a-shared-box. A target is given by a point on
the start frame (a user's click, a dataset's ground truth). When a passer-by stands in front of
it then, the detector often finds one box for the two people, placed on the passer-by, and
nothing for the target: the target takes that box, and as the passer-by walks on, the box (and
the target with it) goes along. A few frames later the two heads come apart and the target's own
head is detected beside its given point, where the bystander tracks
(:mod:`.bystanders`) pick it up as somebody else.

The box may also be the target's on the first frames and slide onto the passer-by as the two
heads come apart (the passer-by's head is the larger, so the detector keeps its box), leaving the
target's own head to be detected alone a few frames later.

This check watches the first half second. A bystander track born after the start and seen on
every frame since is traced back to the start frame along its own walk (constant velocity). When
that path passes the given point much nearer than the detection the target took on its first
step, or than the target now lies from it, and within half a head side (the new head's box, or
the target's first box when that is larger: a head coming free of the passer-by has a small,
shifted box), the target and that track trade places: the target goes on from the new head, the
bystander track from the box, the target's look and size are learnt afresh, and its reports since
the start are withdrawn (:meth:`trackfw.stages.Tracker.withdrawn`). The trace back keeps a
walking target given in front of a stander on its own box: the stander's path leads back to where
the stander stood, a head apart from the given point (more than half a side), however far the
walker has gone since. Near the image border neither clue holds: a head cut by the border gets
a box whose head point lies far from the given point, and a head that appears there is somebody
walking in. So a target given within its first box's side of the border never trades, and a
track whose first detection lay within its box's side of the border is never traded for.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.assignment import distance_matrix, greedy_nearest
from trackfw_plugins.trackers.border_return import near_edge
from trackfw_plugins.trackers.bystanders import Bystanders


class StartSplitSettings(FiniteModel):
    """How long after the start a split is looked for, and how near its path must lead."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    within_s: float = Field(
        0.5,
        gt=0.0,
        description="seconds after the start frame during which a target may trade places",
    )
    follow_s: float = Field(
        0.16,
        gt=0.0,
        description="seconds a new head is followed (a detection on every frame) before its"
        " path is traced back to the start frame",
    )
    back_ratio: float = Field(
        0.5,
        gt=0.0,
        le=1.0,
        description="the traced-back path must pass the given point this many times nearer"
        " than the target's detection on its first step, or the target now, lies from it",
    )
    back_sides: float = Field(
        0.5,
        gt=0.0,
        description="and within this many head sides: the new head's box side, or the"
        " target's first box side when that is larger",
    )


def traced_back(
    first: FloatArray, now: FloatArray, followed: IntArray, back: IntArray
) -> FloatArray:
    """Where heads walking at constant velocity stood ``back`` frames before their first point.

    Args:
        first: ``(M, 2)`` each head's first point.
        now: ``(M, 2)`` its point ``followed`` frames later.
        followed: ``(M,)`` frames between the two points (at least 1).
        back: ``(M,)`` frames from the start frame to each first point.

    Returns:
        ``(M, 2)`` the points on the start frame.

    >>> import numpy as np
    >>> traced_back(np.array([[10.0, 5.0]]), np.array([[14.0, 5.0]]), np.array([4]), np.array([3])).tolist()
    [[7.0, 5.0]]
    """
    velocity = (now - first) / np.maximum(followed, 1)[:, None]
    return np.asarray(first - velocity * np.reshape(back, (-1, 1)), dtype=np.float64)


@dataclass
class StartSplit:
    """The given points of one segment start and the targets' first detections.

    Attributes:
        settings: the window and the margins.
        given: ``(K, 2)`` each target's given point.
        start: the start frame.
        size: the image's ``(width, height)``.
        within: frames after ``start`` during which a trade may happen.
        follow: frames a bystander track must have been followed.
        first_error: ``(K,)`` distance from each target's given point to the detection it took
            on its first step (infinite until then, or when it took none).
        open: ``(K,)`` whether each target may still trade places.
        stepped: whether the tracker's first step after the start was seen.
        withdrawn: ``(target row, first frame)`` withdrawals of the trades since the last
            :meth:`take_withdrawn`.
    """

    settings: StartSplitSettings
    given: FloatArray
    start: int
    size: tuple[int, int]
    within: int
    follow: int
    first_error: FloatArray = field(default_factory=lambda: np.zeros(0))
    first_side: FloatArray = field(default_factory=lambda: np.zeros(0))
    open: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    stepped: bool = False
    withdrawn: list[tuple[int, int]] = field(default_factory=list)

    def close(self) -> None:
        """No target trades any more (an interval: the paths no longer lead back to the
        start frame's camera pose)."""
        self.open[:] = False

    @classmethod
    def begin(
        cls,
        settings: StartSplitSettings,
        fps: float,
        size: tuple[int, int],
        start: int,
        given: FloatArray,
    ) -> StartSplit:
        """Targets given at ``(K, 2)`` points on frame ``start`` of a ``fps`` video of
        ``size`` (width, height)."""
        count = len(given)
        return cls(
            settings,
            np.asarray(given, dtype=np.float64).reshape(-1, 2).copy(),
            start,
            size,
            within=max(1, round(settings.within_s * fps)),
            follow=max(1, round(settings.follow_s * fps)),
            first_error=np.full(count, np.inf),
            first_side=np.zeros(count),
            open=np.ones(count, dtype=bool),
        )

    def first_step(self, t: int, targets: IntArray, points: FloatArray, sides: FloatArray) -> None:
        """On the tracker's first step after the start (frame ``t``, whatever frames were
        info-less before it), ``targets`` took detections at ``(M, 2)`` points of ``(M,)`` box
        sides; those given within that side of the border never trade."""
        if self.stepped:
            return
        self.stepped = True
        self.first_error[targets] = np.hypot(*(points - self.given[targets]).T)
        self.first_side[targets] = np.nan_to_num(sides, nan=0.0)
        cut, _ = near_edge(self.given[targets], *self.size, self.first_side[targets])
        self.open[targets[cut]] = False

    def due(
        self,
        t: int,
        targets: IntArray,
        positions: FloatArray,
        tracks: Bystanders,
        points: FloatArray,
        sides: FloatArray,
    ) -> list[tuple[int, int]]:
        """``(target row, bystander track row)`` pairs that trade places on frame ``t``; each
        traded target's reports from the frame after the start on are withdrawn.

        Args:
            t: the frame.
            targets: rows of the targets that may trade (tracked ones).
            positions: ``(M, 2)`` their positions on this frame.
            tracks: the bystander tracks, after this frame's update.
            points: ``(N, 2)`` this frame's detections.
            sides: ``(N,)`` their box sides.
        """
        since = t - self.start
        if since > self.within:
            self.close()
        if not self.open.any():
            return []
        # Seen on every frame since its birth (so on this one too), born after the start.
        rows = np.flatnonzero(
            (tracks.age >= self.follow) & (tracks.hits == tracks.age + 1) & (tracks.age < since)
        )
        mine = self.open[targets]
        targets, positions = targets[mine], positions[mine]
        if len(rows) == 0 or len(targets) == 0:
            return []
        columns = tracks.claimed[rows]
        walked_in, _ = near_edge(tracks.first[rows], *self.size, sides[columns])
        rows, columns = rows[~walked_in], columns[~walked_in]
        if len(rows) == 0:
            return []
        now = points[columns]
        start_points = traced_back(
            tracks.first[rows], now, tracks.age[rows], since - tracks.age[rows]
        )
        off = distance_matrix(self.given[targets], start_points)
        drifted = np.hypot(*(positions - self.given[targets]).T)
        # A box placed on the passer-by lay off the given point on the first step; a box that
        # was the target's first and slid onto the passer-by has taken the target off it since.
        away = np.maximum(self.first_error[targets], drifted)
        # A head coming free of the passer-by has a small box whose head point lies off.
        side = np.maximum(sides[columns][None, :], self.first_side[targets][:, None])
        here = distance_matrix(self.given[targets], now)
        near = (
            (off < self.settings.back_ratio * away[:, None])
            & (off < self.settings.back_sides * side)
            & (here < drifted[:, None])
        )
        if not near.any():
            return []
        # Nearest path first, one track per target; only the near pairs are possible.
        chosen = greedy_nearest(np.where(near, off, np.inf), gate=float(off[near].max()))
        traded = np.flatnonzero(chosen >= 0)
        self.open[targets[traded]] = False
        trades = [(int(targets[m]), int(rows[chosen[m]])) for m in traded]
        self.withdrawn.extend((row, self.start + 1) for row, _ in trades)
        return trades

    def take_withdrawn(self) -> list[tuple[int, int]]:
        """The withdrawals recorded since the last call: (target row, first frame)."""
        withdrawn, self.withdrawn = self.withdrawn, []
        return withdrawn

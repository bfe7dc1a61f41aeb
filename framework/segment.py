"""A segment: the stretch of informative frames between two info-less intervals.

The segment knows the fixed set of targets (their ids), where each was on every frame of the
segment (its history, which the motion predictors fit), and its last informative frame, which
becomes frame ``a`` when an interval begins. The gap problem is built from it; after the interval
a new segment starts on frame ``b`` for the same targets.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw.front import Observation
from trackfw.records import GapProblem, Interval, LookBack, TargetState, VideoContext


@dataclass
class Segment:
    """The targets through one segment.

    Attributes:
        target_ids: ``(K,)`` identities, in the order of every per-target array.
        lookback_frames: how many frames before ``a`` the gap problem's look-back lies.
        positions: per frame of the segment, oldest first, ``(K, 2)`` tracked positions.
    """

    target_ids: IntArray
    lookback_frames: int = 0
    positions: list[FloatArray] = field(default_factory=list)
    # The latest frames, oldest first (the last len(recent) rows of positions): the look-back
    # is the oldest, so only lookback_frames + 1 frames' pixels are held.
    recent: deque[Observation] = field(default_factory=deque)

    @property
    def last(self) -> Observation | None:
        """The segment's latest frame (frame ``a`` once an interval begins), or None before its
        first frame."""
        return self.recent[-1] if self.recent else None

    def add(self, observation: Observation, positions: FloatArray) -> None:
        """Record the ``(K, 2)`` tracked positions on an informative frame."""
        self.positions.append(positions)
        self.recent.append(observation)
        while observation.t - self.recent[0].t > self.lookback_frames:
            self.recent.popleft()

    def histories(self) -> list[FloatArray]:
        """Per target, ``(n, 2)`` positions over the segment, oldest first."""
        if not self.positions:
            return [np.zeros((0, 2)) for _ in range(len(self.target_ids))]
        stacked = np.stack(self.positions)  # (n, K, 2)
        return [stacked[:, k, :].copy() for k in range(len(self.target_ids))]

    def interval_to(self, b: int) -> Interval:
        """The interval from this segment's last frame ``a`` to frame ``b``."""
        if self.last is None:
            raise ValueError("an interval needs a segment with at least one frame")
        return Interval(a=self.last.t, b=b)

    def gap_problem(
        self,
        b: Observation,
        states: list[TargetState],
        video: VideoContext,
        rows: IntArray | None = None,
    ) -> GapProblem:
        """The gap matcher's problem from this segment's frame ``a`` to frame ``b``.

        Args:
            b: the first informative frame after the interval.
            states: the tracker's state of every target at ``a``.
            video: the video.
            rows: the targets that take part (indices into ``target_ids``); all when None.
        """
        a = self.last
        if a is None:
            raise ValueError("a gap problem needs a segment with at least one frame")
        taking_part = np.arange(len(self.target_ids)) if rows is None else np.asarray(rows)
        histories = self.histories()
        earliest = self.recent[0]  # a frame was added, so there is one
        lookback = (
            LookBack(
                t=earliest.t,
                image=earliest.image,
                detections=earliest.detections,
                positions=self.positions[-len(self.recent)][taking_part],
            )
            if earliest.t < a.t
            else None
        )
        return GapProblem(
            interval=self.interval_to(b.t),
            target_ids=self.target_ids[taking_part],
            histories=[histories[k] for k in taking_part],
            states=[states[k] for k in taking_part],
            detections=b.detections,
            frame_a=a.image,
            detections_a=a.detections,
            frame_b=b.image,
            video=video,
            lookback=lookback,
        )

    def next(self) -> Segment:
        """A new, empty segment for the same targets (after an interval)."""
        return Segment(self.target_ids, self.lookback_frames)


__all__ = ["Segment"]

"""The end (and the start) of an interval decided in hindsight [OURS].

See docs/algorithms/infoless-classifier.md#hindsight.

A head-worn camera that turns back to the group arrives there moving: the optical flow into the
first informative frame b, ``M_b``, is still a turn's, and the SVM's feature carries it for five
frames. A strictly online decision therefore calls b, and often a few frames after it, info-less,
and those frames (a, b, b+1) are exactly the ones that decide an interval crossing. One frame
later the answer is plain: the camera stood still from b to b+1 and people are in view.

:class:`EndHindsight` keeps the last few frames' decisions, motion and detection count. When the
classifier leaves an interval on frame t, it walks back from t - 1 over the frames decided
info-less, and turns each one informative while the camera did not move from it to the next
frame (``M`` of the next frame at most ``max_motion``) and it shows at least ``min_detections``
detections. The walk stops at the first frame that fails, so it never crosses the turn back, and
reaches at most ``frames`` frames. A false interval on a steady view (a blur, people briefly
hidden) is undone whole. The stage stays online with a delay of at most ``frames`` frames, and
only on frames decided info-less.
"""

from __future__ import annotations

from collections import deque


class EndHindsight:
    """Revises the last info-less decisions when a classifier leaves an interval.

    Args:
        frames: the most frames one revision may reach back (0: never revise).
        max_motion: the largest ``M`` (working-resolution pixels) from a revised frame to the
            next one: the camera stood still.
        min_detections: the fewest detections a revised frame shows: people are in view.

    >>> hindsight = EndHindsight(frames=4, max_motion=4.0, min_detections=1)
    >>> # (info-less, M_t, N_t): a turn away, the view away, the turn back arriving on frame 5
    >>> frames = [(False, 1, 4), (True, 30, 0), (True, 2, 0), (True, 40, 0), (True, 22, 4)]
    >>> [hindsight.push(*frame) for frame in frames]
    [0, 0, 0, 0, 0]
    >>> hindsight.push(True, 1.5, 4), hindsight.push(False, 1.2, 4)
    (0, 2)
    """

    def __init__(self, frames: int, max_motion: float, min_detections: int) -> None:
        if frames < 0:
            raise ValueError(f"hindsight frames must be at least 0, got {frames}")
        self.frames = frames
        self.max_motion = max_motion
        self.min_detections = min_detections
        # (info-less, M_t, N_t) of the latest frames, newest last; one more than can be revised,
        # because the newest is the informative frame a revision starts from.
        self._recent: deque[list[float | bool]] = deque(maxlen=frames + 1)

    def reset(self) -> None:
        """Start a new video."""
        self._recent.clear()

    def push(self, infoless: bool, motion: float, detections: float) -> int:
        """Record the newest frame's final decision; return how many frames before it turn informative.

        Args:
            infoless: the classifier's decision on the newest frame.
            motion: its ``M_t``, the optical flow from the previous frame.
            detections: its ``N_t``.

        Returns:
            0 unless the frame is informative and follows info-less ones that pass the test.
        """
        self._recent.append([infoless, float(motion), float(detections)])
        if infoless or self.frames == 0:
            return 0
        revised = 0
        motion_after = float(motion)
        for entry in list(self._recent)[-2::-1]:
            was_infoless, frame_motion, frame_detections = entry
            if (
                not was_infoless
                or motion_after > self.max_motion
                or frame_detections < self.min_detections
            ):
                break
            entry[0] = False
            revised += 1
            motion_after = float(frame_motion)
        return revised


class OnsetHindsight:
    """Revises the last informative decisions when a classifier enters an interval.

    A camera that starts to turn away has already moved on the frame before the classifier's
    probability crosses its threshold: on TUD virtual-wearer videos the first frame of every
    interval scored at least 0.3, and a third of the decided intervals began one frame late.
    That frame then becomes frame a, whose crops and tracked places are the turn's, not the
    group's. When the classifier enters an interval on frame t, :class:`OnsetHindsight` walks
    back from t - 1 over the frames decided informative and turns each one info-less while its
    probability is at least ``min_probability``; the walk stops at the first frame that fails,
    at a frame that ended an interval itself, at the first frame of the video, and after
    ``frames`` frames.

    Args:
        frames: the most frames one revision may reach back (0: never revise).
        min_probability: the smallest info-less probability of a revised frame.

    >>> onset = OnsetHindsight(frames=2, min_probability=0.3)
    >>> # (info-less, probability, ended an interval): steady, steady, the turn begins, away
    >>> [onset.push(*frame) for frame in [(False, 0.1, False), (False, 0.12, False)]]
    [0, 0]
    >>> onset.push(False, 0.45, False), onset.push(True, 0.9, False), onset.push(True, 0.95, False)
    (0, 1, 0)
    """

    def __init__(self, frames: int, min_probability: float) -> None:
        if frames < 0:
            raise ValueError(f"onset frames must be at least 0, got {frames}")
        self.frames = frames
        self.min_probability = min_probability
        # [info-less, probability, may be revised] of the frames a revision may reach, newest last.
        self._recent: deque[list[float | bool]] = deque(maxlen=frames)

    def reset(self) -> None:
        """Start a new video."""
        self._recent.clear()

    def push(self, infoless: bool, probability: float, fixed: bool) -> int:
        """Record the newest frame's decision; return how many frames before it turn info-less.

        Args:
            infoless: the classifier's decision on the newest frame.
            probability: its info-less probability.
            fixed: whether its decision may never be revised (the first frame of the video,
                or a frame that ended an interval in hindsight).

        Returns:
            0 unless the frame is info-less and follows informative ones that pass the test
            (inside an interval the walk stops at once, on the info-less frame before).
        """
        revised = 0
        if infoless:
            for entry in reversed(self._recent):
                was_infoless, frame_probability, revisable = entry
                if was_infoless or not revisable or frame_probability < self.min_probability:
                    break
                entry[0] = True
                revised += 1
        self._recent.append([infoless, float(probability), not fixed])
        return revised


__all__ = ["EndHindsight", "OnsetHindsight"]

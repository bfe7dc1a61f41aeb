"""The matches at b checked by the walk after them: a person who walks back is not the target.

See docs/algorithms/segment-tracker.md#the-walk-after-b. After a look-away the gap matcher hands
each target a head of frame b by look, and two passers-by can look as alike as one person before
and after the interval. The walk often tells them apart: people in a street keep their direction
through a few seconds of looking away, so the person a target was matched to should walk, over
the first half second after b, the way the target walked over the half second before a. Both
walks are measured against the scene (the camera's own motion registered out, as the
camera-aware predictor does), because a wearer's head sways and settles around a look-away. A
match whose person clearly walks back (both walks faster than a limit, mostly sideways, in
opposite directions) is undone: the target is lost, with the descriptor it had at b, and its
reports since b are withdrawn (:meth:`trackfw.stages.Tracker.withdrawn`), so that a target lost
before the interval can take that person by look. A target left without a match at b and found
by look within that half second is a match at b made a few frames late (the reports between are
filled back to b): its person's walk is checked the same way, from the frame it was found.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray, UInt8Array
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.scene_registration import SceneRegistration, register_scene
from trackfw_plugins.trackers.camera_motion import consecutive_frames_registration

#: Frame height the speed limit is given at.
REFERENCE_HEIGHT = 1080.0


class WalkCheckSettings(FiniteModel):
    """How long the walks are, and how fast both must be to count."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    after_s: float = Field(
        0.48,
        gt=0.0,
        description="seconds of walk on each side: before a, and after b (when the match at b"
        " is checked)",
    )
    min_speed_px_s_at_1080: float = Field(
        56.25,
        gt=0.0,
        description="both walks must be faster than this sideways (pixels per second at 1080"
        " rows; 56.25 is 1 px per frame at 480 rows and 25 fps)",
    )


def walked_back(before: FloatArray, since_b: FloatArray, min_speed: float) -> bool:
    """Whether a person walked back from the target's walk: opposite sideways, both clearly.

    Args:
        before: ``(2,)`` the target's velocity before a (pixels per frame).
        since_b: ``(2,)`` its person's velocity since b (pixels per frame).
        min_speed: the least sideways speed that counts (pixels per frame).

    >>> import numpy as np
    >>> walked_back(np.array([2.5, 0.0]), np.array([-2.0, 0.3]), 1.0)
    True
    >>> walked_back(np.array([2.5, 0.0]), np.array([2.0, 0.3]), 1.0)  # the same way
    False
    >>> walked_back(np.array([0.5, 0.0]), np.array([-2.0, 0.3]), 1.0)  # the target stood still
    False
    >>> walked_back(np.array([2.5, 0.0]), np.array([-1.2, 3.0]), 1.0)  # mostly up the image
    False
    """
    sideways, upright = float(since_b[0]), float(since_b[1])
    ahead = float(before[0])
    return bool(
        ahead * sideways < 0.0
        and abs(ahead) > min_speed
        and abs(sideways) > min_speed
        and abs(sideways) > abs(upright)
    )


@dataclass
class Snapshot:
    """One tracked frame as the walk needs it.

    Attributes:
        t: the frame.
        image: its pixels (None without pixels).
        boxes: ``(N, 4)`` its detection boxes (people kept out of the registration), or None.
        positions: ``(K, 2)`` every target's position on it.
        held: ``(K,)`` whether each target held a detection on it (None: not known).
    """

    t: int
    image: UInt8Array | None
    boxes: FloatArray | None
    positions: FloatArray
    held: BoolArray | None = None


@dataclass
class PendingCheck:
    """A match at b waiting for its walk.

    Attributes:
        before: ``(2,)`` the target's walk before a (pixels per frame, the scene's motion out).
        descriptor: its appearance descriptor at b (restored when the match is undone).
        described_at: the frame that descriptor was taken on.
        start: the frame the person's walk is measured from (None: frame b).
    """

    before: FloatArray
    descriptor: FloatArray | None
    described_at: int
    start: Snapshot | None = None


class WalkCheck:
    """The recent frames of one tracker, the checks of the last b, and what they withdrew."""

    def __init__(self, settings: WalkCheckSettings, fps: float, height: int) -> None:
        self.frames = max(1, round(settings.after_s * fps))
        # Pixels per frame at this video's height and frame rate.
        self.min_speed = settings.min_speed_px_s_at_1080 * height / REFERENCE_HEIGHT / fps
        # The registration of consecutive frames, given half a second's room to zoom.
        self.registration = consecutive_frames_registration().model_copy(
            update={"max_area_change": 1.3}
        )
        self.recent: list[Snapshot] = []
        self.at_b: Snapshot | None = None
        self.pending: dict[int, PendingCheck] = {}
        # Targets left without a match at b, checked when found within the half second after it.
        self.late: dict[int, PendingCheck] = {}
        self.withdrawn: list[tuple[int, int]] = []

    def remember(self, snapshot: Snapshot) -> None:
        """Keep a tracked frame; only the last ``frames + 1`` are kept."""
        self.recent.append(snapshot)
        del self.recent[: -(self.frames + 1)]

    def _walks(self, first: Snapshot, last: Snapshot) -> FloatArray | None:
        """``(K, 2)`` every target's walk from ``first`` to ``last`` (pixels per frame), the
        camera's motion registered out; None when the two frames do not register."""
        registration = self._register(first, last)
        if registration is None:
            return None
        return registration.walks(first.positions, last.positions, max(last.t - first.t, 1))

    def _register(self, first: Snapshot, last: Snapshot) -> SceneRegistration | None:
        if first.image is None or last.image is None:
            return None
        registration = register_scene(
            first.image, last.image, first.boxes, last.boxes, self.registration
        )
        return registration if registration.ok else None

    def arm(
        self,
        at_b: Snapshot,
        rows: IntArray,
        descriptors: list[FloatArray | None],
        described_at: IntArray,
        unmatched: IntArray | None = None,
    ) -> None:
        """Start checking the targets ``rows`` matched at b; the previous gap's checks end.

        Args:
            at_b: frame b, with every target's position on it.
            rows: the targets matched at b.
            descriptors: every target's descriptor (None where none).
            described_at: ``(K,)`` the frame each descriptor was taken on.
            unmatched: the targets tracked on frame a left without a match at b: each is
                checked from the frame it is found by look, when that is within the half second
                after b (:meth:`found`), if its walk before a is its detections' (it held one on
                at least half of that walk's frames).
        """
        recent, self.recent = self.recent, []
        before = self._walks(recent[0], recent[-1]) if len(recent) > 1 else None
        self.at_b = at_b
        self.pending, self.late = {}, {}
        if before is None:
            return  # no walk before a to compare with

        def check(row: int) -> PendingCheck:
            return PendingCheck(before[row], descriptors[row], int(described_at[row]))

        self.pending = {int(row): check(int(row)) for row in rows}
        # How many of the walk's frames each target held a detection on (None: not known).
        helds = [snapshot.held for snapshot in recent if snapshot.held is not None]
        held = np.sum(helds, axis=0) if len(helds) == len(recent) else None
        self.late = {
            int(row): check(int(row))
            for row in ([] if unmatched is None else unmatched)
            if held is None or held[row] * 2 >= len(recent)
        }

    def found(self, now: Snapshot, rows: IntArray) -> None:
        """Targets ``rows`` were found by look on frame ``now``: those left without a match at b
        are checked from here, when ``now`` lies within the half second after b."""
        at_b = self.at_b
        if at_b is None or not self.late:
            return
        if now.t - at_b.t > self.frames:
            self.late = {}
            return
        for row in rows:
            check = self.late.pop(int(row), None)
            if check is not None:
                self.pending[int(row)] = replace(check, start=now)

    def due(self, now: Snapshot, rows: IntArray) -> list[tuple[int, PendingCheck]]:
        """The checks of the targets ``rows`` (those still on their match) whose person walked
        back by frame ``now``; every check is over once its walk is long enough."""
        at_b = self.at_b
        if at_b is None or not self.pending:
            return []
        ready = {
            row: check
            for row, check in self.pending.items()
            if now.t - (check.start or at_b).t >= self.frames
        }
        for row in ready:
            del self.pending[row]
        held = {int(row) for row in rows}
        # One registration per frame a walk starts on, only for the targets still on their match.
        walks: dict[int, FloatArray | None] = {}
        back = []
        for row, check in ready.items():
            if row not in held:
                continue
            start = check.start or at_b
            if start.t not in walks:
                walks[start.t] = self._walks(start, now)
            walk = walks[start.t]
            if walk is not None and walked_back(check.before, walk[row], self.min_speed):
                back.append((row, check))
        return back

    def withdraw(self, row: int) -> None:
        """Record that target ``row``'s reports from frame b on are withdrawn."""
        assert self.at_b is not None
        self.withdrawn.append((row, self.at_b.t))

    def take_withdrawn(self) -> list[tuple[int, int]]:
        """The withdrawals recorded since the last call: (target row, first frame)."""
        withdrawn, self.withdrawn = self.withdrawn, []
        return withdrawn


__all__ = ["PendingCheck", "Snapshot", "WalkCheck", "WalkCheckSettings", "walked_back"]

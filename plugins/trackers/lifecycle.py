"""Target lifecycle of the segment tracker: tracked, lost, out-of-view, tentative, re-acquired.

See docs/algorithms/segment-tracker.md#target-lifecycle. The tracker associates its ``tracked``
and ``tentative`` targets as before; this module decides their state from the association, keeps
where a lost target is expected (from its offsets to the group, not from its own drifting
prediction) and re-acquires lost and out-of-view targets on the detections left over. It never
creates a target: the people of interest are the fixed set given on the first frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.records import LOST, OUT_OF_VIEW, TENTATIVE, TRACKED, VideoContext
from trackfw.stages import FiniteModel

#: States whose targets the tracker associates on every frame.
ACTIVE = (TRACKED, TENTATIVE)


class LifecycleSettings(FiniteModel):
    """When a target is lost, confirmed or re-acquired (times in seconds, scaled by fps)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    lost_after_s: float | None = Field(
        0.2,
        ge=0.0,
        description="a tracked target without a detection for this long is lost; null = never",
    )
    confirm_within_s: float = Field(
        0.5,
        ge=0.0,
        description="a tentative target (unmatched at b) is lost unless a detection supports it"
        " within this time",
    )
    reacquire_gate_px_at_1080: float = Field(
        40.0, gt=0.0, description="re-acquisition gate just after the loss, pixels at 1080p"
    )
    reacquire_growth_px_per_s_at_1080: float = Field(
        20.0, ge=0.0, description="growth of the re-acquisition gate per second lost, px at 1080p"
    )
    reacquire_max_px_at_1080: float = Field(
        80.0, gt=0.0, description="largest re-acquisition gate, pixels at 1080p"
    )
    size_ratio_max: float | None = Field(
        1.5,
        ge=1.0,
        description="a detection whose box is this many times larger or smaller than the"
        " target's last one is not its head; null = no size check",
    )


@dataclass
class Lifecycle:
    """The state of every target and what re-acquisition needs.

    Attributes:
        settings: the parameters.
        fps: frames per second of the video.
        scale: image height / 1080 (the gates are given at 1080p).
        width, height: the image size.
        status: ``(K,)`` state names.
        since: ``(K,)`` frame on which the current state began.
        last_matched: ``(K,)`` frame of the last detection that supported the target.
        anchor: ``(K, 2)`` position at the last supporting detection.
        offsets: ``(K, K, 2)`` position of target k minus that of target j, the last time both
            had a detection on the same frame.
        known: ``(K, K)`` whether ``offsets[k, j]`` was ever measured.
        size: ``(K,)`` box side (square root of the area) of the last supporting detection, NaN
            when the detector gives no boxes.
    """

    settings: LifecycleSettings
    fps: float
    scale: float
    width: int
    height: int
    status: np.ndarray
    since: IntArray
    last_matched: IntArray
    anchor: FloatArray
    offsets: FloatArray
    known: BoolArray
    size: FloatArray

    @classmethod
    def start(
        cls, settings: LifecycleSettings, video: VideoContext, t: int, positions: FloatArray
    ) -> Lifecycle:
        """Every target tracked at ``(K, 2)`` positions on frame ``t``."""
        count = len(positions)
        lifecycle = cls(
            settings,
            float(video.fps) if video.fps > 0 else 30.0,
            video.height / 1080.0,
            video.width,
            video.height,
            np.full(count, TRACKED, dtype=object),
            np.full(count, t, dtype=np.int64),
            np.full(count, t, dtype=np.int64),
            positions.copy(),
            np.zeros((count, count, 2)),
            np.zeros((count, count), dtype=bool),
            np.full(count, np.nan),
        )
        lifecycle.supported(t, np.arange(count), positions, np.full(count, np.nan))
        return lifecycle

    def frames(self, seconds: float) -> float:
        """``seconds`` in frames of this video."""
        return seconds * self.fps

    def active(self) -> IntArray:
        """Rows of the targets the tracker associates (tracked and tentative)."""
        return np.flatnonzero(np.isin(self.status, ACTIVE))

    def inactive(self) -> IntArray:
        """Rows of the lost and out-of-view targets."""
        return np.flatnonzero(~np.isin(self.status, ACTIVE))

    def inside(self, positions: FloatArray) -> BoolArray:
        """``(K,)`` whether each ``(K, 2)`` position lies inside the image."""
        return (
            (positions[:, 0] >= 0)
            & (positions[:, 0] < self.width)
            & (positions[:, 1] >= 0)
            & (positions[:, 1] < self.height)
        )

    def set(self, rows: IntArray, status: str, t: int) -> None:
        """Put ``rows`` into ``status`` (the clock restarts only on a change)."""
        changed = rows[self.status[rows] != status]
        self.status[changed] = status
        self.since[changed] = t

    def supported(self, t: int, rows: IntArray, positions: FloatArray, sizes: FloatArray) -> None:
        """``rows`` had a detection at ``(M, 2)`` positions of ``(M,)`` box sides (NaN when
        unknown) on frame ``t``: they are tracked."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(rows) == 0:
            return
        self.set(rows, TRACKED, t)
        self.last_matched[rows] = t
        self.anchor[rows] = positions
        known = ~np.isnan(sizes)
        self.size[rows[known]] = sizes[known]
        # Offsets between targets seen together: the group's pattern, which moves with the
        # camera and so places a lost target after a sway or a pose jump.
        seen = np.flatnonzero(self.last_matched == t)
        together = self.anchor[seen][None, :, :]
        self.offsets[np.ix_(rows, seen)] = positions[:, None, :] - together
        self.offsets[np.ix_(seen, rows)] = -self.offsets[np.ix_(rows, seen)].transpose(1, 0, 2)
        self.known[np.ix_(rows, seen)] = True
        self.known[np.ix_(seen, rows)] = True

    def unsupported(self, t: int, rows: IntArray, predicted: FloatArray) -> None:
        """Active ``rows`` without a detection on frame ``t``, at ``(M, 2)`` predictions.

        Call it after :meth:`supported` for the frame's matched targets: a target leaving the
        image is anchored where it was predicted to leave, relative to them.
        """
        settings = self.settings
        inside = self.inside(predicted)
        self._left(t, rows[~inside], predicted[~inside])
        rows = rows[inside]
        tentative = rows[self.status[rows] == TENTATIVE]
        expired = tentative[t - self.since[tentative] > self.frames(settings.confirm_within_s)]
        self.set(expired, LOST, t)
        if settings.lost_after_s is None:
            return
        tracked = rows[self.status[rows] == TRACKED]
        gone = tracked[t - self.last_matched[tracked] > self.frames(settings.lost_after_s)]
        self.set(gone, LOST, t)

    def _left(self, t: int, rows: IntArray, predicted: FloatArray) -> None:
        """``rows`` are predicted outside the image: out of view, expected where they left."""
        self.set(rows, OUT_OF_VIEW, t)
        self.anchor[rows] = predicted
        seen = np.flatnonzero(self.last_matched == t)
        self.offsets[np.ix_(rows, seen)] = predicted[:, None, :] - self.anchor[seen][None, :, :]
        self.known[np.ix_(rows, seen)] = True

    def expected(self, rows: IntArray, positions: FloatArray, anchors: IntArray) -> FloatArray:
        """Where inactive ``rows`` should be: ``(M, 2)``.

        The median over the ``anchors`` (targets with a detection now, at ``(K, 2)`` positions)
        of the anchor's position plus the last offset measured to it; the last supported
        position when no anchor has a measured offset.
        """
        result = self.anchor[rows].copy()
        for out, row in enumerate(rows):
            usable = anchors[self.known[row, anchors] & (anchors != row)]
            if len(usable):
                result[out] = np.median(positions[usable] + self.offsets[row, usable], axis=0)
        return result

    def rescale_sizes(self, rows: IntArray, sizes: FloatArray) -> float:
        """Carry every target's head size through the camera's change of scale across a gap.

        ``sizes`` are the ``(M,)`` box sides matched to ``rows`` at b (NaN when none). After a
        look-away the camera may stand nearer or farther, so every head changes size by about
        the same factor: the median of the matched ratios (with two or more of them) rescales
        every stored size, and the per-target check then compares like with like.

        Returns:
            The factor applied (1.0 when fewer than two matches have a known size).

        >>> import numpy as np
        >>> life = Lifecycle.__new__(Lifecycle)
        >>> life.size = np.array([20.0, 25.0, 30.0])
        >>> life.rescale_sizes(np.array([0, 1, 2]), np.array([32.0, 40.0, np.nan]))
        1.6
        >>> life.size.tolist()
        [32.0, 40.0, 48.0]
        """
        known = ~np.isnan(sizes) & ~np.isnan(self.size[rows]) & (self.size[rows] > 0)
        if known.sum() < 2:
            return 1.0
        factor = float(np.median(sizes[known] / self.size[rows][known]))
        self.size = self.size * factor
        return factor

    def size_mismatch(self, rows: IntArray, sizes: FloatArray) -> BoolArray:
        """``(M, N)``: whether detection n (box side ``sizes[n]``) is too large or too small to
        be target ``rows[m]``'s head. Unknown sizes never mismatch.

        Heads of one person change size slowly; a bystander's head next to a vanished target
        often has a very different size (nearer or farther from the camera).
        """
        ratio_max = self.settings.size_ratio_max
        mismatch = np.zeros((len(rows), len(sizes)), dtype=bool)
        if ratio_max is None or len(rows) == 0 or len(sizes) == 0:
            return mismatch
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.abs(np.log(self.size[rows][:, None] / sizes[None, :]))
        return np.nan_to_num(ratio, nan=0.0) > np.log(ratio_max)

    def gates(self, t: int, rows: IntArray) -> FloatArray:
        """``(M,)`` re-acquisition gates in pixels, growing with the seconds lost."""
        settings = self.settings
        seconds = (t - self.last_matched[rows]) / self.fps
        gate = (
            settings.reacquire_gate_px_at_1080
            + settings.reacquire_growth_px_per_s_at_1080 * np.maximum(seconds, 0.0)
        )
        return np.minimum(gate, settings.reacquire_max_px_at_1080) * self.scale

    def reacquire_cost(
        self, t: int, expected: FloatArray, rows: IntArray, points: FloatArray, sizes: FloatArray
    ) -> FloatArray:
        """``(M, N)`` cost of giving each inactive target of ``rows`` each of ``points`` (box
        sides ``sizes``); a pair is possible where the cost is at most 1.

        The cost is the distance over the target's gate, so a target lost longer reaches
        farther; an out-of-view target comes back through the edge near where it is expected.
        Heads of another size are refused (infinite cost).
        """
        cost = np.linalg.norm(expected[:, None, :] - points[None, :, :], axis=2)
        cost = cost / self.gates(t, rows)[:, None]
        cost[self.size_mismatch(rows, sizes)] = np.inf
        return cost

    def place(self, t: int, rows: IntArray, expected: FloatArray) -> None:
        """Inactive ``rows`` not re-acquired: out of view when expected outside, lost otherwise."""
        inside = self.inside(expected)
        self.set(rows[~inside], OUT_OF_VIEW, t)
        self.set(rows[inside], LOST, t)


__all__ = ["ACTIVE", "Lifecycle", "LifecycleSettings"]

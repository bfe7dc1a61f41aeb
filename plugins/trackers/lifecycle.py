"""Target lifecycle of the segment tracker: tracked, lost, out-of-view, tentative, re-acquired.

See docs/algorithms/segment-tracker.md#target-lifecycle. The tracker associates its ``tracked``
and ``tentative`` targets as before; this module decides their state from the association, keeps
where a lost target is expected (from its offsets to the group, not from its own drifting
prediction) and how large its head should be. It never creates a target: the people of interest
are the fixed set given on the first frame. Re-finding lost and out-of-view targets on the
detections left over is :mod:`trackfw_plugins.trackers.reacquisition`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.records import LOST, OUT_OF_VIEW, TENTATIVE, TRACKED, VideoContext
from trackfw.stages import FiniteModel
from trackfw_plugins.trackers.border_return import image_edge, near_edge

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
    hidden_hold_s: float | None = Field(
        None,
        ge=0.0,
        description="a tracked target without a detection whose prediction lies within"
        " hidden_reach head sides of a detection another target took is hidden behind that"
        " person, not gone: it stays tracked until this long after its last detection (longer"
        " than lost_after_s to help); null = off",
    )
    edge_exit_sides: float | None = Field(
        None,
        ge=0.0,
        description="a tracked target lost while its last detection lay within this many of its"
        " head sides of an image edge walked out through that edge: out of view, not lost"
        " inside the image (a person leaving is detected, cut by the edge, until the head is"
        " gone); null = lost where its prediction is",
    )
    scale_offsets_at_b: bool = Field(
        False,
        description="at b, the group's stored offsets between targets follow the camera's change"
        " of scale (the factor that rescales the head sizes): a lost target is then expected"
        " where the zoomed pattern puts it, not where the old one did",
    )
    hidden_reach: float = Field(
        1.0,
        gt=0.0,
        description="how near (in head sides, the larger of the two heads) a detection another"
        " target took must be for a missing target to count as hidden behind it",
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
        " target's last one (on re-acquisition: than the size expected at the detection's"
        " place) is not its head; null = no size check",
    )
    size_refused_at_b: Literal["tentative", "lost"] = Field(
        "tentative",
        description="a target whose match at b fails the size check: 'tentative' at the gap"
        " matcher's position (that head's), or 'lost', as a match the look at b refused: it"
        " takes a free head by look at b when appearance.gap_max_distance is set, else waits"
        " for re-acquisition",
    )
    reentry_margin_px_at_1080: float | None = Field(
        None,
        gt=0.0,
        description="a target that left through an image edge is also re-found by a detection"
        " at most this far inside that edge, px at 1080p (60 on the leave set); null = off, only"
        " near its expected place (it took bystanders on TUD-Stadtmitte)",
    )
    reentry_growth_px_per_s_at_1080: float = Field(
        200.0,
        ge=0.0,
        description="growth per second lost of the re-entry gate along that edge, px at 1080p",
    )
    reentry_max_px_at_1080: float = Field(
        900.0, gt=0.0, description="largest re-entry gate along the exit edge, px at 1080p"
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
        relative_size: ``(K,)`` that side over the head size the group's line (below) gave at the
            target's place then: how much larger than its neighbours' heads this head is.
        size_line: ``(2,)`` head side = a + b·y fitted to the targets supported on the latest
            frame (heads on a ground plane grow linearly with the image row).
        exit_side: ``(K,)`` image edge a target left through (0 left, 1 right, 2 top, 3
            bottom), -1 while it has not left.
        started_at: frame on which the targets were given (their start positions).
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
    relative_size: FloatArray
    size_line: FloatArray
    exit_side: IntArray
    started_at: int

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
            np.ones(count),
            np.array([np.nan, 0.0]),
            np.full(count, -1, dtype=np.int64),
            t,
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

    def placed_at_b(self, t: int, rows: IntArray, positions: FloatArray) -> None:
        """``rows`` were placed at b without a detection, at their ``(M, 2)`` ``positions``:
        tentative, with the confirmation clock started at b, or out of view outside the image."""
        outside = ~self.inside(positions)
        self.set(rows[outside], OUT_OF_VIEW, t)
        self.set(rows[~outside], TENTATIVE, t)
        self.since[rows[~outside]] = t

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
        self.exit_side[rows] = -1
        # Offsets between targets seen together: the group's pattern, which moves with the
        # camera and so places a lost target after a sway or a pose jump.
        seen = np.flatnonzero(self.last_matched == t)
        together = self.anchor[seen][None, :, :]
        self.offsets[np.ix_(rows, seen)] = positions[:, None, :] - together
        self.offsets[np.ix_(seen, rows)] = -self.offsets[np.ix_(rows, seen)].transpose(1, 0, 2)
        self.known[np.ix_(rows, seen)] = True
        self.known[np.ix_(seen, rows)] = True
        if self.settings.reentry_margin_px_at_1080 is not None:
            # Only a return through the border reads the size line: no fit on every frame
            # while that rule is off.
            self.size_line = size_line(self.anchor[seen, 1], self.size[seen])
            self.relative_size[rows[known]] = sizes[known] / self.line_size(positions[known, 1])

    def line_size(self, ys: FloatArray) -> FloatArray:
        """Head side the group's line gives at image rows ``ys`` (any shape; NaN when unknown)."""
        a, b = self.size_line
        # A line fitted to a few heads can cross zero far from them: never below a tenth of a.
        return np.maximum(a + b * np.asarray(ys, dtype=np.float64), 0.1 * abs(a))

    def unsupported(
        self, t: int, rows: IntArray, predicted: FloatArray, hidden: BoolArray | None = None
    ) -> None:
        """Active ``rows`` without a detection on frame ``t``, at ``(M, 2)`` predictions.

        Call it after :meth:`supported` for the frame's matched targets: a target leaving the
        image is anchored where it was predicted to leave, relative to them. ``hidden`` (``(M,)``,
        see :meth:`hidden_behind`) marks the rows hidden behind a detected person: they are lost
        only after ``hidden_hold_s``.
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
        hold = np.full(len(rows), self.frames(settings.lost_after_s))
        if hidden is not None and settings.hidden_hold_s is not None:
            hold[hidden[inside]] = max(
                self.frames(settings.hidden_hold_s), self.frames(settings.lost_after_s)
            )
        tracked = self.status[rows] == TRACKED
        gone = rows[tracked & (t - self.last_matched[rows] > hold)]
        if settings.edge_exit_sides is not None and len(gone):
            margins = settings.edge_exit_sides * np.nan_to_num(self.size[gone], nan=0.0)
            at_edge, beyond = near_edge(self.anchor[gone], self.width, self.height, margins)
            self._left(t, gone[at_edge], beyond[at_edge])
            gone = gone[~at_edge]
        self.set(gone, LOST, t)

    def hidden_behind(
        self, rows: IntArray, predicted: FloatArray, taken: FloatArray, taken_sides: FloatArray
    ) -> BoolArray:
        """``(M,)``: whether each of ``rows`` (without a detection, at ``(M, 2)`` predictions) is
        hidden behind a person another target was detected as this frame (``(N, 2)`` ``taken``
        points with ``(N,)`` box sides): within ``hidden_reach`` of the larger of the two heads.

        Two walkers crossing give one detection for both; the hidden one is not gone, and
        losing it at once lets its expected place drift from where it walks on.

        >>> import numpy as np
        >>> life = Lifecycle.__new__(Lifecycle)
        >>> life.settings = LifecycleSettings(hidden_hold_s=0.5)
        >>> life.size = np.array([20.0, 20.0])
        >>> taken = np.array([[100.0, 100.0]])
        >>> life.hidden_behind(np.array([0, 1]), np.array([[112.0, 100.0], [130.0, 100.0]]),
        ...                    taken, np.array([24.0])).tolist()
        [True, False]
        """
        if self.settings.hidden_hold_s is None:
            return np.zeros(len(rows), dtype=bool)
        return np.asarray(self.hidden_behind_which(rows, predicted, taken, taken_sides) >= 0)

    def hidden_behind_which(
        self, rows: IntArray, predicted: FloatArray, taken: FloatArray, taken_sides: FloatArray
    ) -> IntArray:
        """``(M,)``: the row of ``taken`` each of ``rows`` is hidden behind, the nearest one within
        ``hidden_reach`` (as :meth:`hidden_behind`, whether or not the hold is on); -1 for none.

        >>> import numpy as np
        >>> life = Lifecycle.__new__(Lifecycle)
        >>> life.settings = LifecycleSettings()
        >>> life.size = np.array([20.0, 20.0])
        >>> taken = np.array([[100.0, 100.0], [118.0, 100.0]])
        >>> life.hidden_behind_which(np.array([0, 1]), np.array([[112.0, 100.0], [160.0, 100.0]]),
        ...                          taken, np.array([24.0, 24.0])).tolist()
        [1, -1]
        """
        if len(rows) == 0 or len(taken) == 0:
            return np.full(len(rows), -1, dtype=np.int64)
        distance = np.linalg.norm(predicted[:, None, :] - taken[None, :, :], axis=2)
        own = np.nan_to_num(self.size[rows], nan=0.0)
        reach = self.settings.hidden_reach * np.maximum(own[:, None], taken_sides[None, :])
        reachable = np.where(distance <= reach, distance, np.inf)
        nearest = np.argmin(reachable, axis=1)
        return np.where(np.isfinite(reachable[np.arange(len(rows)), nearest]), nearest, -1)

    def _left(self, t: int, rows: IntArray, predicted: FloatArray) -> None:
        """``rows`` are predicted outside the image: out of view, expected where they left."""
        self.set(rows, OUT_OF_VIEW, t)
        self.exit_side[rows] = self.edge(predicted)
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

    def group_places(
        self, t: int, rows: IntArray, positions: FloatArray
    ) -> tuple[IntArray, FloatArray]:
        """Where the group places those of ``rows`` that missed their detection on frame
        ``t - 1``: from their offsets to at least two of ``rows`` seen on that frame, at their
        ``positions`` (``(K, 2)``, every target's). A second prediction that a coasting
        target's own drifting filter does not move.

        Returns:
            The ``(C,)`` indices into ``rows`` placed, and their ``(C, 2)`` places.
        """
        previous = self.last_matched[rows]
        coasting = np.flatnonzero(previous < t - 1)
        anchors = rows[previous == t - 1]
        if len(coasting) == 0 or len(anchors) < 2:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
        coasting = coasting[self.known[np.ix_(rows[coasting], anchors)].sum(axis=1) >= 2]
        return coasting, self.expected(rows[coasting], positions, anchors)

    def rescale_sizes(self, rows: IntArray, sizes: FloatArray) -> float:
        """Carry every target's head size through the camera's change of scale across a gap.

        ``sizes`` are the ``(M,)`` box sides matched to ``rows`` at b (NaN when none). After a
        look-away the camera may stand nearer or farther, so every head changes size by about
        the same factor: the median of the matched ratios (with two or more of them) rescales
        every stored size, and the per-target check then compares like with like. With
        ``scale_offsets_at_b`` the stored offsets between targets, pixels of the same camera,
        are rescaled by it too.

        Returns:
            The factor applied (1.0 when fewer than two matches have a known size).

        >>> import numpy as np
        >>> life = Lifecycle.__new__(Lifecycle)
        >>> life.settings = LifecycleSettings(scale_offsets_at_b=True)
        >>> life.size = np.array([20.0, 25.0, 30.0])
        >>> life.offsets = np.zeros((3, 3, 2))
        >>> life.offsets[0, 1] = [100.0, -20.0]
        >>> life.rescale_sizes(np.array([0, 1, 2]), np.array([32.0, 40.0, np.nan]))
        1.6
        >>> life.size.tolist(), life.offsets[0, 1].tolist()
        ([32.0, 40.0, 48.0], [160.0, -32.0])
        """
        known = ~np.isnan(sizes) & ~np.isnan(self.size[rows]) & (self.size[rows] > 0)
        if known.sum() < 2:
            return 1.0
        factor = float(np.median(sizes[known] / self.size[rows][known]))
        self.size = self.size * factor
        if self.settings.scale_offsets_at_b:
            self.offsets = self.offsets * factor
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

    def unseen(self, rows: IntArray) -> BoolArray:
        """``(M,)`` whether no detection has supported each of ``rows`` since its given start.

        Given start positions (a dataset's gt, a user's clicks) are not where the detector puts
        the same heads, nor are the offsets measured between them.
        """
        return self.last_matched[rows] <= self.started_at

    def place(self, t: int, rows: IntArray, expected: FloatArray) -> None:
        """Inactive ``rows`` not re-acquired: out of view when expected outside, lost otherwise."""
        inside = self.inside(expected)
        self.set(rows[~inside], OUT_OF_VIEW, t)
        self.set(rows[inside], LOST, t)
        # A target lost inside the image whose place the camera has turned away from will come
        # back through the edge its place crossed.
        entering = ~inside & (self.exit_side[rows] < 0)
        self.exit_side[rows[entering]] = self.edge(expected[entering])

    def edge(self, positions: FloatArray) -> IntArray:
        """``(M,)`` image edge each ``(M, 2)`` position outside the image lies beyond
        (:func:`~trackfw_plugins.trackers.border_return.image_edge`)."""
        return image_edge(positions, self.width, self.height)


def size_line(ys: FloatArray, sizes: FloatArray) -> FloatArray:
    """``(2,)`` (a, b) of head side = a + b·y fitted to ``(N,)`` rows ``ys`` and sides ``sizes``.

    NaN sides are left out; with fewer than two heads, or rows less than a head apart, the
    line is flat at their median (a = NaN when there is none).

    >>> size_line(np.array([100.0, 300.0]), np.array([20.0, 40.0])).round(3).tolist()
    [10.0, 0.1]
    """
    known = ~np.isnan(sizes)
    ys, sizes = ys[known], sizes[known]
    if len(sizes) == 0:
        return np.array([np.nan, 0.0])
    if len(sizes) < 2 or np.ptp(ys) < np.median(sizes):
        return np.array([float(np.median(sizes)), 0.0])
    b, a = np.polyfit(ys, sizes, 1)
    return np.array([a, b])


__all__ = ["ACTIVE", "Lifecycle", "LifecycleSettings", "size_line"]

"""Records passed between the engine and the stages.

All positions are image pixels, ``(x, y)`` with x to the right and y downward, at the video's
native resolution. Frame indices are 0-based inside trackfw (``t = 0 .. T-1``); files on disk use
1-based frame numbers (MOTChallenge convention) and the readers and writers convert.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import BoolArray, FloatArray, IntArray

#: Marker for "no detection" in integer index arrays.
NO_MATCH = -1

#: Target lifecycle (docs/algorithms/segment-tracker.md#target-lifecycle): followed and reported.
TRACKED = "tracked"
#: No detection supported it for a while; its prediction is kept for re-acquisition, not reported.
LOST = "lost"
#: Its predicted position is outside the image; kept for re-acquisition, not reported.
OUT_OF_VIEW = "out-of-view"
#: Placed by the gap matcher without a detection at b; reported once a detection confirms it.
TENTATIVE = "tentative"
#: Every target state, in the order of the frames.csv count columns.
TARGET_STATES = (TRACKED, LOST, OUT_OF_VIEW, TENTATIVE)
#: Seconds before frame ``a`` of the segment frame a gap problem carries as its look-back
#: (:class:`LookBack`): long enough for a walker to move several pixels, short enough for the
#: camera's sway to stay one registration.
LOOKBACK_S = 0.4


@dataclass(frozen=True)
class Detections:
    """Head detections on one frame.

    Attributes:
        points: ``(N, 2)`` head centres in pixels.
        scores: ``(N,)`` confidence in [0, 1] (1 when the detector has none).
        boxes: ``(N, 4)`` boxes as ``(left, top, width, height)``, or None.
        index: ``(N,)`` stable detection index: the position of each detection in the detector's
            output for this frame. It survives subsetting, so every later stage (and frames.csv,
            gaps.json) can name a detection unambiguously.
    """

    points: FloatArray
    scores: FloatArray
    boxes: FloatArray | None = None
    index: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=np.float64).reshape(-1, 2)
        count = len(points)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "scores", np.asarray(self.scores, dtype=np.float64).reshape(count))
        if self.boxes is not None:
            object.__setattr__(
                self, "boxes", np.asarray(self.boxes, dtype=np.float64).reshape(count, 4)
            )
        index = np.asarray(self.index, dtype=np.int64).reshape(-1)
        if len(index) != count:
            index = np.arange(count, dtype=np.int64)
        object.__setattr__(self, "index", index)

    def __len__(self) -> int:
        return len(self.points)

    @classmethod
    def empty(cls) -> Detections:
        """No detection at all."""
        return cls(points=np.zeros((0, 2)), scores=np.zeros(0))

    @classmethod
    def from_points(
        cls, points: Any, scores: Any | None = None, boxes: Any | None = None
    ) -> Detections:
        """Build detections from a sequence of points; scores default to 1.

        >>> Detections.from_points([[1, 2], [3, 4]]).index.tolist()
        [0, 1]
        """
        points_array = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if scores is None:
            scores = np.ones(len(points_array))
        return cls(points=points_array, scores=np.asarray(scores, dtype=np.float64), boxes=boxes)

    def subset(self, mask_or_indices: Any) -> Detections:
        """Keep some detections; the stable index travels with them."""
        selector = np.asarray(mask_or_indices)
        return Detections(
            points=self.points[selector],
            scores=self.scores[selector],
            boxes=None if self.boxes is None else self.boxes[selector],
            index=self.index[selector],
        )


@dataclass
class FrameData:
    """One frame as a stage sees it.

    Attributes:
        t: 0-based frame index.
        image: ``(H, W, 3)`` uint8 BGR pixels, or None when no stage of the pipeline needs
            pixels (the engine then does not decode the video).
        video: the video this frame belongs to.
        first: whether this is the run's first readable frame, the one the targets are
            initialised on: it is informative whatever a classifier says (the engine enforces
            it; a classifier with recursive state decides it informative too).
    """

    t: int
    image: NDArray[np.uint8] | None
    video: VideoContext
    first: bool = False


@dataclass(frozen=True)
class Interval:
    """An info-less interval: frames ``a+1 .. b-1`` carry no information.

    ``a`` is the last informative frame before the interval and ``b`` the first after it, both
    0-based. ``b`` may equal ``n_frames`` when the interval runs to the end of the video.
    """

    a: int
    b: int
    kind: str = "unknown"

    @property
    def horizon(self) -> int:
        """Prediction horizon ``h = b - a`` in frames."""
        return self.b - self.a

    def contains(self, t: int) -> bool:
        """True when ``t`` lies strictly inside the interval (an info-less frame)."""
        return self.a < t < self.b


@dataclass
class GroundTruth:
    """Ground truth of one video, as far as the dataset provides it.

    Attributes:
        targets: frame index -> ``{target id: (x, y)}`` for the people of interest.
        heads: frame index -> ``(M, 3)`` array of ``(x, y, head_size)`` for every person whose
            head is visible (detector training and oracle detections); empty when unknown.
        intervals: ground-truth info-less intervals.
    """

    targets: dict[int, dict[int, tuple[float, float]]] = field(default_factory=dict)
    heads: dict[int, FloatArray] = field(default_factory=dict)
    intervals: list[Interval] = field(default_factory=list)

    def infoless_frames(self) -> set[int]:
        """Every 0-based frame index inside a ground-truth interval."""
        frames: set[int] = set()
        for interval in self.intervals:
            frames.update(range(interval.a + 1, interval.b))
        return frames


@dataclass
class VideoContext:
    """What a stage may know about the video being processed.

    Attributes:
        name: the video's name (its folder name).
        path: the video folder or file.
        n_frames: number of frames.
        width, height: frame size in pixels.
        fps: frames per second.
        ground_truth: present when the dataset ships one (oracle stages require it).
        meta: the rest of meta.json.
    """

    name: str
    path: str
    n_frames: int
    width: int
    height: int
    fps: float = 30.0
    ground_truth: GroundTruth | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ClassifierDecision:
    """Output of an info-less classifier for one frame.

    Attributes:
        probability: probability (or a score mapped to [0, 1]) that the frame is info-less.
        infoless: the decision.
        features: optional feature vector, for logging and caching.
        revises: on an informative frame, how many of the frames just before it, decided
            info-less, are informative after all: a decision in hindsight at the end of an
            interval, at most the classifier's ``hindsight_frames``
            (docs/algorithms/index.md#the-online-loop).
        onset: on an info-less frame, how many of the frames just before it, decided
            informative, are info-less after all: a decision in hindsight at the start of an
            interval, at most the classifier's ``onset_frames``.
    """

    probability: float
    infoless: bool
    features: FloatArray | None = None
    revises: int = 0
    onset: int = 0


@dataclass
class TargetState:
    """A tracked target at one frame.

    Attributes:
        target_id: the identity given by the annotation of the first frame.
        position: ``(2,)`` position in pixels.
        velocity: ``(2,)`` pixels per frame, or None when the tracker has no motion model.
        covariance: ``(4, 4)`` state covariance of ``(x, y, vx, vy)``, or None.
        matched_detection: stable index of the detection that corrected it on this frame, or
            ``NO_MATCH``.
        status: its lifecycle state, one of :data:`TARGET_STATES`. A lost or out-of-view target
            takes no part in a gap match (the engine leaves it out of the problem).
    """

    target_id: int
    position: FloatArray
    velocity: FloatArray | None = None
    covariance: FloatArray | None = None
    matched_detection: int = NO_MATCH
    status: str = TRACKED


@dataclass
class LookBack:
    """A frame shortly before ``a`` in the same segment, for the walkers' own motion.

    Between it and ``a`` the camera sways; registering its scene onto frame ``a`` separates
    that sway from the people's walking, which the positions alone mix.

    Attributes:
        t: its 0-based frame index (``t < a``).
        image: its pixels, or None when no stage needs pixels.
        detections: its detections (their boxes keep the people out of the registration).
        positions: ``(K, 2)`` the targets' tracked positions on it, in the problem's order.
    """

    t: int
    image: NDArray[np.uint8] | None
    detections: Detections
    positions: FloatArray


@dataclass
class GapProblem:
    """Everything a gap matcher may use to re-link the targets after an interval.

    Attributes:
        interval: the interval, with ``a`` and ``b``.
        target_ids: ``(K,)`` identities, in the order used by every per-target array.
        histories: per target, ``(n_k, 2)`` tracked (posterior) positions over the current segment,
            oldest first, ending at frame ``a``.
        states: per target, the tracker's state at ``a``.
        detections: detections on frame ``b`` (the set V).
        frame_a: pixels of frame ``a`` or None when no stage needs pixels.
        frame_b: pixels of frame ``b`` or None.
        video: the video.
        detections_a: detections on frame ``a`` (head sizes at ``a``, appearance), if known.
        lookback: the segment's frame :data:`LOOKBACK_S` before ``a`` (or its first frame when
            the segment is shorter), or None when the segment has a single frame.
    """

    interval: Interval
    target_ids: IntArray
    histories: list[FloatArray]
    states: list[TargetState]
    detections: Detections
    frame_a: NDArray[np.uint8] | None
    frame_b: NDArray[np.uint8] | None
    video: VideoContext
    detections_a: Detections | None = None
    lookback: LookBack | None = None

    @property
    def horizon(self) -> int:
        """Frames from ``a`` to ``b``."""
        return self.interval.horizon

    @property
    def positions_at_a(self) -> FloatArray:
        """``(K, 2)`` positions of the targets at frame ``a``."""
        return np.array([state.position for state in self.states], dtype=np.float64).reshape(-1, 2)


@dataclass
class Prediction:
    """One candidate prediction of the targets on frame ``b``.

    Attributes:
        label: short name of the candidate, such as ``"ar2"`` or ``"kalman"``.
        positions: ``(K, 2)`` predicted positions U on frame ``b``.
        diagnostics: JSON-serialisable details (fallbacks per target, ...).
        gate: None when the candidate keeps frame a's image geometry (where the pattern lies on
            b is unknown, the paper's assumption); else the candidate is *positioned*: it is in
            frame-b pixels up to this many pixels (a scene registration, continuity).
    """

    label: str
    positions: FloatArray
    diagnostics: dict[str, Any] = field(default_factory=dict)
    gate: float | None = None


@dataclass
class GapSolution:
    """The targets on frame ``b``.

    Attributes:
        positions: ``(K, 2)`` position of every target on frame ``b``.
        matched_detection: ``(K,)`` stable detection index matched to each target, or
            ``NO_MATCH`` when the target was placed without a detection.
        cost: the cost of the chosen solution (meaning depends on the matcher), or None.
        chosen: label of the chosen prediction candidate (``"ar2"``...), or None.
        diagnostics: JSON-serialisable details recorded in gaps.json.
        match_ratios: ``(K,)``, for a matcher that can say it, how clearly each match stood
            out: the matched detection's cost over the cheapest other detection's for that
            target (below 1: no other detection fitted as well); NaN for a target without a
            match or where it is not known (a single detection). None: not given.
    """

    positions: FloatArray
    matched_detection: IntArray
    cost: float | None = None
    chosen: str | None = None
    diagnostics: dict[str, Any] = field(default_factory=dict)
    match_ratios: FloatArray | None = None


@dataclass(frozen=True)
class Tracks:
    """Tracks with the tracker's own identities, one row per (track, frame), sorted by both.

    Attributes:
        ids: ``(M,)`` track identity.
        frames: ``(M,)`` frame index.
        points: ``(M, 2)`` position (head point) in pixels.
        observed: ``(M,)`` True where the position is a detection (or was corrected by one),
            False where the tracker filled it in (interpolated, extrapolated or predicted).
    """

    ids: IntArray
    frames: IntArray
    points: FloatArray
    observed: BoolArray

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        count = len(ids)
        frames = np.asarray(self.frames, dtype=np.int64).reshape(count)
        points = np.asarray(self.points, dtype=np.float64).reshape(count, 2)
        observed = np.asarray(self.observed, dtype=bool).reshape(count)
        order = np.lexsort((frames, ids))
        object.__setattr__(self, "ids", ids[order])
        object.__setattr__(self, "frames", frames[order])
        object.__setattr__(self, "points", points[order])
        object.__setattr__(self, "observed", observed[order])

    @classmethod
    def empty(cls) -> Tracks:
        """No tracks at all."""
        none = np.zeros(0, dtype=np.int64)
        return cls(none, none, np.zeros((0, 2)), np.zeros(0, dtype=bool))

    @classmethod
    def concatenate(cls, pieces: list[Tracks]) -> Tracks:
        """Join track tables whose identities do not clash."""
        if not pieces:
            return cls.empty()
        return cls(
            np.concatenate([piece.ids for piece in pieces]),
            np.concatenate([piece.frames for piece in pieces]),
            np.concatenate([piece.points for piece in pieces]),
            np.concatenate([piece.observed for piece in pieces]),
        )

    def __len__(self) -> int:
        return len(self.ids)

    def track_ids(self) -> IntArray:
        """The distinct identities, ascending."""
        return np.unique(self.ids)

    def track(self, track_id: int) -> tuple[IntArray, FloatArray, BoolArray]:
        """Frames ``(L,)``, points ``(L, 2)`` and observed flags ``(L,)`` of one track."""
        rows = self.ids == track_id
        return self.frames[rows], self.points[rows], self.observed[rows]

    def renumbered(self) -> Tracks:
        """Identities renumbered 1, 2, ... in order of each track's first frame (then old id).

        >>> tracks = Tracks(np.array([7, 3]), np.array([5, 2]), np.zeros((2, 2)), np.ones(2))
        >>> tracks.renumbered().ids.tolist()
        [1, 2]
        """
        if len(self) == 0:
            return self
        unique, inverse = np.unique(self.ids, return_inverse=True)
        first = np.full(len(unique), np.iinfo(np.int64).max)
        np.minimum.at(first, inverse, self.frames)
        rank = np.empty(len(unique), dtype=np.int64)
        rank[np.lexsort((unique, first))] = np.arange(1, len(unique) + 1)
        return Tracks(rank[inverse], self.frames, self.points, self.observed)

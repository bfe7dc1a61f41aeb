"""What each target looked like, for re-acquiring it with its old identity.

See docs/algorithms/segment-tracker.md#re-acquisition. While a target is tracked its descriptor
is refreshed from its detection about once per ``refresh_s``; when a lost target meets a
candidate detection inside its gate, the candidate is described and refused when it looks too
different. Two descriptors are offered: ``patch``, the paper's colour/texture patch descriptor
(mean RGB and HSV, uniform LBP, HOG; :mod:`trackfw_plugins.maths.appearance`), and
``person-reid``, a pretrained deep embedder (:mod:`trackfw_plugins.maths.person_reid`).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np
from pydantic import ConfigDict, Field, model_validator

from trackfw.arrays import BoolArray, FloatArray, IntArray, UInt8Array
from trackfw.records import Detections
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.appearance import (
    PATCH_SIZE,
    appearance_descriptors,
    appearance_distance_matrix,
)
from trackfw_plugins.maths.box_overlap import box_intersection
from trackfw_plugins.maths.camera_roll import upright_angle
from trackfw_plugins.maths.person_reid import (
    PersonReidEmbedder,
    body_boxes,
    cosine_distance_matrix,
)
from trackfw_plugins.maths.reid_crop import head_size


class AppearanceSettings(FiniteModel):
    """The appearance check of re-acquisition."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    descriptor: Literal["none", "patch", "person-reid"] = Field(
        "none",
        description="'patch' (the paper's colour/texture descriptor), 'person-reid' (deep"
        " embedder) or 'none' (re-acquire by position alone; no pixels read)",
    )
    max_distance: float = Field(
        0.3,
        gt=0.0,
        description="a candidate farther than this from the target's descriptor is refused"
        " (patch: Euclidean, 0..1.41; person-reid: cosine, 0..2)",
    )
    reentry_max_distance: float = Field(
        0.4,
        gt=0.0,
        description="a target coming back through the image border away from its expected place"
        " needs a descriptor and a candidate at most this far from it",
    )
    gap_max_distance: float | None = Field(
        None,
        gt=0.0,
        description="at b, a gap matcher's match farther than this from the target's descriptor is"
        " refused and the target is lost (re-found later by re-acquisition); None keeps every match",
    )
    gap_weak_ratio: float | None = Field(
        None,
        gt=0.0,
        description="at b, a gap matcher's match whose cost is more than this times the"
        " target's cost to its nearest other detection (the matcher's match_ratios) barely beat"
        " it: its look must be within gap_weak_max_distance; None: every match is held to"
        " gap_max_distance",
    )
    gap_weak_max_distance: float | None = Field(
        None,
        gt=0.0,
        description="the look limit of such a weak match at b (refused: lost, and not handed"
        " the same detection again by the re-match by look); None: gap_max_distance",
    )
    gap_continuity_fallback: bool = Field(
        False,
        description="at b, a target whose gap-matcher match is refused (size, seen apart at a,"
        " look) first takes the detection continuity proposes (its Kalman state at a carried"
        " over the interval, Hungarian on distance, as the 'assignment' gap matcher with the"
        " 'kalman' predictor) when that one passes the same checks",
    )
    gap_rematch_ratio: float | None = Field(
        0.8,
        gt=0.0,
        le=1.0,
        description="at b, a refused target re-matched by look alone takes a detection only when"
        " its look distance is at most this times the next nearest detection's; None: the"
        " nearest within gap_max_distance",
    )
    gap_rematch_inactive: bool = Field(
        False,
        description="at b, the lost and out-of-view targets join the re-match by look of the"
        " refused ones (same limit and ratio test): after a look-away their old place means"
        " nothing, their look still does",
    )
    gap_rematch_out_of_view: bool = Field(
        True,
        description="with gap_rematch_inactive, the targets that walked out through an image"
        " edge before the interval join too; false: only the lost ones",
    )
    anywhere_max_distance: float | None = Field(
        None,
        gt=0.0,
        description="a lost or out-of-view target is also re-found anywhere in the image by the"
        " free detection that looks most like it, when at most this far and clearly nearer than"
        " every other detection (anywhere_margin); None: only near its expected place",
    )
    anywhere_margin: float = Field(
        0.15,
        ge=0.0,
        description="how much nearer in look that detection must be than the next one",
    )
    neighbour_margin: float | None = Field(
        None,
        ge=0.0,
        description="that detection is also refused unless it looks nearer, by at least this"
        " margin, to the target than to every person seen apart from the target on the frame"
        " it was lost (two heads seen at once are two people), and so is a match at b against"
        " the people seen apart from it on frame a; None: never checked",
    )
    refresh_s: float = Field(
        1.0, gt=0.0, description="seconds between two descriptors of a tracked target"
    )
    refresh_cover_max: float | None = Field(
        None,
        gt=0.0,
        le=1.0,
        description="a due refresh waits while more than this fraction of the target's body box"
        " is covered by the body box of a detection with a head at least as large (nearer the"
        " camera); a target's first descriptor never waits; None: refresh whatever covers it",
    )
    swap_max_distance: float | None = Field(
        None,
        gt=0.0,
        description="a tracked target whose refreshed crop lies farther than this from its"
        " descriptor, and again on a second crop swap_recheck_s later, has been taken over by"
        " someone else: it is lost (its descriptor kept); None: never checked",
    )
    contest_margin: float | None = Field(
        None,
        ge=0.0,
        description="a tracked target left without a detection, hidden behind the detection"
        " another target took, takes that detection over when its look is nearer than the"
        " holder's by this margin (the holder goes without); None: never contested",
    )
    swap_recheck_s: float = Field(
        0.2, ge=0.0, description="seconds from a crop unlike the target to the second check"
    )
    reid_model: str = Field(
        "0287", description="person-reid: embedder '0287', '0248' or an ONNX path"
    )
    upright_crops: bool = Field(
        False,
        description="person-reid: cut every crop upright, turned by the camera's roll as the"
        " frame's near-vertical lines show it (the last roll found when a frame shows none);"
        " False: crops as the frame stands",
    )

    @model_validator(mode="after")
    def _upright_needs_person_reid(self) -> AppearanceSettings:
        # Only the deep embedder's body crops are cut upright; elsewhere the option would do
        # nothing while seeming on.
        if self.upright_crops and self.descriptor != "person-reid":
            raise ValueError(
                "upright_crops cuts person-reid crops; expected descriptor: person-reid"
                f" (descriptor is {self.descriptor!r})"
            )
        return self


@lru_cache(maxsize=2)
def _embedder(model: str) -> PersonReidEmbedder:
    """One onnxruntime session per model for the process (a tracker restarts per video)."""
    return PersonReidEmbedder(model, 0)


class AppearanceMemory:
    """The last descriptor of every target, and the appearance veto of re-acquisition.

    A refresh of a target half hidden by someone nearer the camera may wait for a clear view
    (``refresh_cover_max``), and a refreshed crop unlike the target twice in a row says the
    target's detection is someone else's (``swap_max_distance``). See
    docs/algorithms/segment-tracker.md#re-acquisition.
    """

    def __init__(self, settings: AppearanceSettings, count: int, height: int, fps: float) -> None:
        self.settings = settings
        self.embedder = (
            _embedder(settings.reid_model) if settings.descriptor == "person-reid" else None
        )
        self.fallback_size = head_size(height)
        self.refresh_frames = settings.refresh_s * fps
        # Per target a (1, D) descriptor (None: never described).
        self.descriptors: list[FloatArray | None] = [None] * count
        self.described_at = np.full(count, -(10**9), dtype=np.int64)
        # Frame of a first crop unlike the target, awaiting the second check (-1: none).
        self.unlike_at = np.full(count, -1, dtype=np.int64)
        self.recheck_frames = settings.swap_recheck_s * fps
        # The descriptors of the detections described on the last frame, by row: the look
        # checks of one frame (refresh, veto, search by look, neighbours) describe the same
        # crops, each crop on its own, so a second description is the first one again.
        self._frame: tuple[UInt8Array, Detections, dict[int, FloatArray]] | None = None
        # The upright angle of the last frame looked at, and the last one found (a frame
        # without near-vertical lines keeps it: the roll changes little within a segment).
        self._upright: tuple[UInt8Array | None, float] = (None, 0.0)

    @property
    def active(self) -> bool:
        """Whether a descriptor is configured."""
        return self.settings.descriptor != "none"

    def describe(self, image: UInt8Array, detections: Detections, rows: IntArray) -> FloatArray:
        """``(M, D)`` descriptors of the detections ``rows`` (each described once per frame)."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(rows) == 0:
            return self._describe(image, detections, rows)
        frame = self._frame
        if frame is None or frame[0] is not image or frame[1] is not detections:
            frame = self._frame = (image, detections, {})
        known = frame[2]
        missing = np.unique(rows[[int(row) not in known for row in rows]])
        if len(missing):
            for row, descriptor in zip(
                missing, self._describe(image, detections, missing), strict=True
            ):
                known[int(row)] = descriptor
        return np.stack([known[int(row)] for row in rows])

    def _describe(self, image: UInt8Array, detections: Detections, rows: IntArray) -> FloatArray:
        """``(M, D)`` descriptors of the detections ``rows``, described now."""
        points = detections.points[rows]
        if self.embedder is not None:
            boxes = body_boxes(points, detections, rows, self.fallback_size)
            return self.embedder.describe(image, boxes, self._upright_angle(image))
        return appearance_descriptors(image, points)

    def _upright_angle(self, image: UInt8Array) -> float:
        """The angle that turns ``image``'s people upright (``upright_crops``; 0 when off),
        found once per frame."""
        if not self.settings.upright_crops:
            return 0.0
        seen, angle = self._upright
        if seen is not image:
            found = upright_angle(image)
            angle = angle if found is None else found
            self._upright = (image, angle)
        return angle

    def remember(
        self,
        t: int,
        image: UInt8Array | None,
        targets: IntArray,
        detections: Detections,
        rows: IntArray,
    ) -> IntArray:
        """Targets ``targets`` matched detections ``rows`` on frame ``t``: refresh when due.

        Returns:
            The targets whose crop was unlike them twice in a row (``swap_max_distance``): the
            detection is someone else's. Their descriptors are left as they were.
        """
        none = np.zeros(0, dtype=np.int64)
        if not self.active or image is None or len(targets) == 0:
            return none
        suspect = self.unlike_at[targets] >= 0
        due = np.where(
            suspect,
            t - self.unlike_at[targets] >= self.recheck_frames,
            t - self.described_at[targets] >= self.refresh_frames,
        )
        if self.settings.refresh_cover_max is not None and due.any():
            covered = covered_fractions(self.body_boxes(detections))
            # The first descriptor is taken whatever covers the target: without one, nothing
            # vetoes a bystander.
            unknown = np.array([self.descriptors[int(k)] is None for k in targets], dtype=bool)
            due &= (covered[rows] <= self.settings.refresh_cover_max) | unknown
        if not due.any():
            return none
        described = self.describe(image, detections, rows[due])
        swapped = [
            int(k) for k, d in zip(targets[due], described, strict=True) if self._add(t, k, d)
        ]
        return np.array(swapped, dtype=np.int64)

    def forget(self, target: int) -> None:
        """Target ``target`` was described from someone else's crops (a start split): its next
        crop describes it afresh."""
        self.descriptors[target] = None
        self.described_at[target] = -(10**9)
        self.unlike_at[target] = -1

    def _add(self, t: int, target: int, descriptor: FloatArray) -> bool:
        """Keep target ``target``'s fresh ``(D,)`` descriptor unless it looks like someone else.

        Returns whether this is the second crop in a row unlike the target (a swap).
        """
        old = self.descriptors[target]
        limit = self.settings.swap_max_distance
        fresh = descriptor[None, :]
        if old is not None and limit is not None and self.distance_matrix(old, fresh).min() > limit:
            second = bool(self.unlike_at[target] >= 0)
            self.unlike_at[target] = -1 if second else t
            return second
        self.unlike_at[target] = -1
        self.descriptors[target] = fresh
        self.described_at[target] = t
        return False

    def body_boxes(self, detections: Detections) -> FloatArray:
        """``(N, 4)`` body boxes of every detection (as :meth:`describe` crops them)."""
        rows = np.arange(len(detections))
        return body_boxes(detections.points, detections, rows, self.fallback_size)

    def distances(
        self, image: UInt8Array | None, targets: IntArray, detections: Detections, columns: IntArray
    ) -> FloatArray:
        """``(M, N)`` distance of target ``targets[m]``'s descriptor to detection ``columns[n]``.

        NaN where nothing can be said: no descriptor configured, no image, or a target never
        described. Only the ``columns`` detections are described.
        """
        return self.described_distances(image, targets, detections, columns)[0]

    def described_distances(
        self, image: UInt8Array | None, targets: IntArray, detections: Detections, columns: IntArray
    ) -> tuple[FloatArray, FloatArray | None]:
        """:meth:`distances`, and the ``(N, D)`` descriptors of the ``columns`` detections (None
        where :meth:`distances` described nothing)."""
        distance = np.full((len(targets), len(columns)), np.nan)
        known = np.array([self.descriptors[int(k)] is not None for k in targets], dtype=bool)
        if not self.active or image is None or not known.any() or len(columns) == 0:
            return distance, None
        described = self.describe(image, detections, columns)
        query = np.concatenate([self.descriptors[int(k)] for k in targets[known]])
        distance[known] = self.distance_matrix(query, described)
        return distance, described

    def distance_matrix(self, first: FloatArray, second: FloatArray) -> FloatArray:
        """``(M, N)`` distances of ``(M, D)`` to ``(N, D)`` descriptors in this descriptor's metric."""
        if self.embedder is not None:
            return cosine_distance_matrix(first, second)
        return appearance_distance_matrix(first, second)

    def veto(
        self,
        image: UInt8Array | None,
        targets: IntArray,
        detections: Detections,
        columns: IntArray,
        candidates: BoolArray,
        entering: BoolArray | None = None,
    ) -> BoolArray:
        """``(M, N)``: where candidate pair (target, detection ``columns[n]``) looks too different.

        Only the detections of some candidate pair are described; a target without a descriptor
        vetoes nothing, except the ``entering`` pairs (``(M, N)``: found only through the border
        rule), which need a descriptor within ``reentry_max_distance``: on virtual-wearer TUD
        videos people keep walking in through the edge a target left by.
        """
        veto = np.zeros(candidates.shape, dtype=bool) if entering is None else entering.copy()
        known = np.array([self.descriptors[int(k)] is not None for k in targets], dtype=bool)
        wanted = candidates[known].any(axis=0) if known.any() else np.zeros(0, dtype=bool)
        if not self.active or image is None or not wanted.any():
            return veto
        rows, wanted_columns = np.flatnonzero(known), np.flatnonzero(wanted)
        distance = self.distances(image, targets[known], detections, columns[wanted])
        limit = np.full(distance.shape, self.settings.max_distance)
        if entering is not None:
            limit[entering[np.ix_(rows, wanted_columns)]] = self.settings.reentry_max_distance
        veto[np.ix_(rows, wanted_columns)] = distance > limit
        if self.embedder is None:
            # A patch cut by the image border is partly replicated border pixels: its distance
            # says little (a returner entering through an edge measured 0.35 to 0.63 from its
            # own descriptor on the paper-leave synth set), so it vetoes nothing.
            cut = self._cut(image, detections.points[columns])
            veto[:, cut] = False if entering is None else entering[:, cut]
        return veto

    def looks(
        self, image: UInt8Array | None, targets: IntArray, detections: Detections, columns: IntArray
    ) -> FloatArray:
        """:meth:`distances`, with NaN also for a ``patch`` cut by the image border (says little)."""
        return self.described_looks(image, targets, detections, columns)[0]

    def described_looks(
        self, image: UInt8Array | None, targets: IntArray, detections: Detections, columns: IntArray
    ) -> tuple[FloatArray, FloatArray | None]:
        """:meth:`looks`, and the descriptors of :meth:`described_distances`."""
        distance, described = self.described_distances(image, targets, detections, columns)
        if self.embedder is None and image is not None and len(columns):
            distance[:, self._cut(image, detections.points[columns])] = np.nan
        return distance, described

    @staticmethod
    def _cut(image: UInt8Array, points: FloatArray) -> BoolArray:
        """``(N,)`` whether the patch around each ``(N, 2)`` point crosses the image border."""
        half = PATCH_SIZE / 2.0
        height, width = image.shape[:2]
        return (
            (points[:, 0] < half)
            | (points[:, 1] < half)
            | (points[:, 0] > width - half)
            | (points[:, 1] > height - half)
        )


def covered_fractions(boxes: FloatArray) -> FloatArray:
    """``(N,)`` largest fraction of each ``(N, 4)`` ``(left, top, width, height)`` box covered by
    one other box at least 0.9 times as tall (a person as near the camera or nearer).

    >>> import numpy as np
    >>> boxes = np.array([[0.0, 0.0, 10.0, 20.0], [5.0, 0.0, 10.0, 20.0], [0.0, 0.0, 2.0, 4.0]])
    >>> covered_fractions(boxes).tolist()
    [0.5, 0.5, 1.0]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    area = np.maximum(boxes[:, 2] * boxes[:, 3], 1e-9)
    share = box_intersection(boxes, boxes) / area[:, None]
    nearer = boxes[None, :, 3] >= 0.9 * boxes[:, None, 3]
    np.fill_diagonal(nearer, False)
    share[~nearer] = 0.0
    return share.max(axis=1, initial=0.0)


__all__ = ["AppearanceMemory", "AppearanceSettings", "covered_fractions"]

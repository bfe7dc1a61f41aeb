"""ByteTrack (Zhang et al., ECCV 2022) on trackfw's Kalman and assignment maths.

The modern row beside the paper's trackers. Every frame:

1. predict every live track with a constant-velocity Kalman filter on the box centre (the box
   size is the last matched detection's);
2. split the frame's detections by score: *high* (``>= high_threshold``) and *low*
   (``>= low_threshold`` and below high);
3. first association: confirmed tracks (tracked and lost) against the high detections, Hungarian
   on ``1 - IoU`` with IoU at least ``first_iou``;
4. second association: tracks still unmatched that were tracked on the previous frame against
   the low detections, IoU at least ``second_iou``; tracked tracks left over become *lost*;
5. unconfirmed tracks (born on the previous frame) against the high detections left, IoU at least
   ``unconfirmed_iou``; a match confirms them, no match removes them;
6. high detections still free with score ``>= activation_threshold`` start unconfirmed tracks
   (confirmed at once on the video's first frame with detections);
7. lost tracks unmatched for more than ``lost_buffer_s`` seconds are removed.

Choices that differ from the reference implementations, and why: the filter state is the point
``(x, y, vx, vy)`` of :mod:`trackfw_plugins.maths.kalman` (the paper's boxes are fixed 80x80, so a
box-aspect state adds nothing); the reference's duplicate-track removal between tracked and lost
sets is left out. As in the reference (ByteTrack's ``is_activated``; the roboflow ``trackers``
package's ``tracker_id`` -1 before ``minimum_consecutive_frames``), a track is output from the
frame that confirms it, so its birth detection is not (``report_birth`` adds it). Only observed
positions are reported (ByteTrack never fills gaps).

See ``docs/algorithms/batch-trackers.md#bytetrack``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray, IntArray
from trackfw.stages import StageParams
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.box_overlap import box_iou
from trackfw_plugins.maths.kalman import KalmanBank


class ByteTrackParams(StageParams):
    """ByteTrack settings; thresholds follow the roboflow ``trackers`` defaults."""

    high_threshold: float = Field(0.6, ge=0.0, le=1.0, description="score of a high detection")
    low_threshold: float = Field(0.1, ge=0.0, le=1.0, description="lowest score used at all")
    activation_threshold: float = Field(
        0.7, ge=0.0, le=1.0, description="a free high detection starts a track from this score"
    )
    first_iou: float = Field(0.1, gt=0.0, lt=1.0, description="least IoU of a first-stage match")
    second_iou: float = Field(0.5, gt=0.0, lt=1.0, description="least IoU of a second-stage match")
    unconfirmed_iou: float = Field(
        0.3, gt=0.0, lt=1.0, description="least IoU confirming a track born on the previous frame"
    )
    lost_buffer_s: float = Field(
        1.0, gt=0.0, description="a lost track is removed after this many seconds unmatched"
    )
    position_noise: float = Field(
        16.0, gt=0.0, description="Kalman observation variance R in px² (4 px std at 80 px boxes)"
    )
    process_noise: float = Field(1.0, gt=0.0, description="Kalman transition variance Q in px²")
    initial_variance: float = Field(1000.0, gt=0.0, description="Kalman initial variance P0")
    confirm_first_frame: bool = Field(
        True,
        description="tracks born on the first frame with detections are confirmed at once (the"
        " original ByteTrack); false: like any birth (the roboflow trackers package)",
    )
    report_birth: bool = Field(
        False,
        description="a confirmed track also reports the detection it was born on (the reference"
        " outputs a track from its confirmation on)",
    )


@dataclass
class _Live:
    """The live tracks: one Kalman row, size and status per track."""

    bank: KalmanBank
    ids: list[int] = field(default_factory=list)
    sizes: list[FloatArray] = field(default_factory=list)
    confirmed: list[bool] = field(default_factory=list)
    tracked: list[bool] = field(default_factory=list)
    last_seen: list[int] = field(default_factory=list)

    def boxes(self) -> FloatArray:
        """``(T, 4)`` predicted boxes (left, top, width, height)."""
        if not self.ids:
            return np.zeros((0, 4))
        sizes = np.array(self.sizes)
        return np.hstack([self.bank.means[:, :2] - 0.5 * sizes, sizes])

    def keep(self, rows: IntArray) -> None:
        self.bank.keep(rows)
        for name in ("ids", "sizes", "confirmed", "tracked", "last_seen"):
            values = getattr(self, name)
            setattr(self, name, [values[row] for row in rows.tolist()])


def track_bytetrack(
    detections: VideoDetections, fps: float, params: ByteTrackParams | None = None
) -> Tracks:
    """Run ByteTrack over a video.

    Args:
        detections: all detections (boxes and scores are used).
        fps: frames per second of the video (sets the lost buffer in frames).
        params: settings; defaults when None.

    Returns:
        Confirmed tracks, observed points only, numbered in order of birth.
    """
    run = _ByteTrackRun(detections, fps, params or ByteTrackParams())
    bounds = detections.frame_bounds()
    for frame in range(detections.n_frames):
        run.step(frame, np.arange(bounds[frame], bounds[frame + 1]))
    if not run.out_rows:
        return Tracks.empty()
    taken = np.array(run.out_rows, dtype=np.int64)
    return Tracks(
        np.array(run.out_ids),
        detections.frames[taken],
        detections.points[taken],
        np.ones(len(taken), dtype=bool),
    ).renumbered()


class _ByteTrackRun:
    """ByteTrack through one video: the live tracks and the (track id, detection row) reported."""

    def __init__(self, detections: VideoDetections, fps: float, params: ByteTrackParams) -> None:
        self.detections = detections
        self.params = params
        self.buffer_frames = max(1, round(params.lost_buffer_s * fps))
        self.live = _Live(
            KalmanBank.start(
                np.zeros((0, 2)),
                params.initial_variance,
                params.process_noise,
                params.position_noise,
            )
        )
        self.all_boxes = detections.boxes()
        self.out_ids: list[int] = []
        self.out_rows: list[int] = []
        self.pending: dict[int, int] = {}  # birth row of tracks not yet confirmed
        self.next_id = 1
        self.seen_detections = False

    def step(self, frame: int, rows: IntArray) -> None:
        """One frame: predict, the three associations, updates, removals and births."""
        live, params = self.live, self.params
        scores = self.detections.scores[rows]
        live.bank.predict()
        high = rows[scores >= params.high_threshold]
        low = rows[(scores >= params.low_threshold) & (scores < params.high_threshold)]
        matched_row, free_high = self._associate_stages(high, low)
        self._update_matched(frame, matched_row)
        self._drop_unmatched(frame, matched_row)
        self._start_tracks(frame, free_high)
        self.seen_detections = self.seen_detections or len(rows) > 0

    def _associate_stages(self, high: IntArray, low: IntArray) -> tuple[IntArray, IntArray]:
        """The detection row matched to each live track (-1: none) and the high rows left."""
        live, params, all_boxes = self.live, self.params, self.all_boxes
        predicted = live.boxes()
        matched_row = np.full(len(live.ids), -1, dtype=np.int64)
        confirmed = np.array(live.confirmed, dtype=bool)
        tracked = np.array(live.tracked, dtype=bool)
        # Stage 1: confirmed tracks (tracked and lost) against high detections.
        free_high = _associate(
            np.flatnonzero(confirmed), high, predicted, all_boxes, params.first_iou, matched_row
        )
        # Stage 2: tracks tracked until now, still unmatched, against low detections.
        _associate(
            np.flatnonzero(confirmed & tracked & (matched_row < 0)),
            low,
            predicted,
            all_boxes,
            params.second_iou,
            matched_row,
        )
        # Stage 3: tracks born on the previous frame against the high detections left.
        free_high = _associate(
            np.flatnonzero(~confirmed),
            free_high,
            predicted,
            all_boxes,
            params.unconfirmed_iou,
            matched_row,
        )
        return matched_row, free_high

    def _update_matched(self, frame: int, matched_row: IntArray) -> None:
        """Correct the matched tracks and report them (a newly confirmed one with its birth
        detection too when ``report_birth``)."""
        live, detections = self.live, self.detections
        hit = np.flatnonzero(matched_row >= 0)
        live.bank.correct(hit, detections.points[matched_row[hit]])
        for index in hit.tolist():
            row = int(matched_row[index])
            track_id = live.ids[index]
            if not live.confirmed[index]:
                live.confirmed[index] = True
                birth = self.pending.pop(track_id)
                if self.params.report_birth:
                    self.out_ids.append(track_id)
                    self.out_rows.append(birth)
            live.sizes[index] = detections.sizes[row]
            live.tracked[index] = True
            live.last_seen[index] = frame
            self.out_ids.append(track_id)
            self.out_rows.append(row)

    def _drop_unmatched(self, frame: int, matched_row: IntArray) -> None:
        """Unmatched tracks become lost; unconfirmed ones and those lost too long go."""
        live = self.live
        count = len(matched_row)
        survivors = [
            index
            for index in range(count)
            if matched_row[index] >= 0
            or (live.confirmed[index] and frame - live.last_seen[index] <= self.buffer_frames)
        ]
        for index in range(count):
            if matched_row[index] < 0:
                live.tracked[index] = False
            if matched_row[index] < 0 and not live.confirmed[index]:
                self.pending.pop(live.ids[index], None)
        live.keep(np.array(survivors, dtype=np.int64))

    def _start_tracks(self, frame: int, free_high: IntArray) -> None:
        """Free high detections above the activation score start tracks (confirmed at once on
        the first frame with detections when ``confirm_first_frame``)."""
        live, detections = self.live, self.detections
        births = free_high[detections.scores[free_high] >= self.params.activation_threshold]
        if not len(births):
            return
        first = self.params.confirm_first_frame and not self.seen_detections
        live.bank.add(detections.points[births])
        for row in births.tolist():
            live.ids.append(self.next_id)
            live.sizes.append(detections.sizes[row])
            live.confirmed.append(first)
            live.tracked.append(True)
            live.last_seen.append(frame)
            if first:
                self.out_ids.append(self.next_id)
                self.out_rows.append(row)
            else:
                self.pending[self.next_id] = row
            self.next_id += 1


def _associate(
    tracks: IntArray,
    rows: IntArray,
    predicted: FloatArray,
    all_boxes: FloatArray,
    least_iou: float,
    matched_row: IntArray,
) -> IntArray:
    """Hungarian on ``1 - IoU`` between ``tracks`` and detection ``rows``; returns free rows.

    Matches are written into ``matched_row`` (one detection row per live track, -1 = none).
    """
    if len(tracks) == 0 or len(rows) == 0:
        return rows
    cost = 1.0 - box_iou(predicted[tracks], all_boxes[rows])
    assignment = hungarian(cost, gate=1.0 - least_iou)
    taken = assignment >= 0
    matched_row[tracks[taken]] = rows[assignment[taken]]
    free = np.ones(len(rows), dtype=bool)
    free[assignment[taken]] = False
    return rows[free]

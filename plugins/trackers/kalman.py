"""The ``kalman`` segment tracker: Kalman filter + association.

See docs/algorithms/segment-tracker.md#segment-tracker.

Kalman1 of the paper is ``association: hungarian``, Kalman2 ``association: nearest`` and Kalman3
``association: tps-rpm`` (TPS-RPM between all predictions and detections on every frame).
Its parameters are in :mod:`trackfw_plugins.trackers.kalman_params`. The filter maths lives in
:mod:`trackfw_plugins.maths.kalman`, the association in
:mod:`trackfw_plugins.maths.assignment`, the targets' states (tracked, lost, out-of-view,
tentative) and expected places in :mod:`trackfw_plugins.trackers.lifecycle`, the re-acquisition
of lost targets in :mod:`trackfw_plugins.trackers.reacquisition`, the bystanders'
anonymous tracks in :mod:`trackfw_plugins.trackers.bystanders`, the look check of the matches at b
in :mod:`trackfw_plugins.trackers.look_at_b`, the contest of a detection by look in
:mod:`trackfw_plugins.trackers.contest`, the walk check after b in
:mod:`trackfw_plugins.trackers.walk_check`, the start split in
:mod:`trackfw_plugins.trackers.start_split`, camera-motion compensation in
:mod:`trackfw_plugins.trackers.camera_motion`.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray, UInt8Array
from trackfw.records import (
    LOST,
    NO_MATCH,
    OUT_OF_VIEW,
    TRACKED,
    Detections,
    TargetState,
    VideoContext,
)
from trackfw.stages import Tracker
from trackfw_plugins.maths.assignment import (
    distance_matrix,
    greedy_nearest,
    hungarian,
    outnumbered,
)
from trackfw_plugins.maths.kalman import KalmanBank
from trackfw_plugins.maths.tps_rpm import match_points
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory
from trackfw_plugins.trackers.bystanders import Bystanders
from trackfw_plugins.trackers.camera_motion import FrameMotion
from trackfw_plugins.trackers.contest import contest_hidden
from trackfw_plugins.trackers.kalman_params import KalmanTrackerParams
from trackfw_plugins.trackers.lifecycle import Lifecycle
from trackfw_plugins.trackers.look_at_b import (
    box_sides,
    check_looks_at_b,
    continuity_rows,
    detection_indices,
    detection_rows_of,
    look_limits,
    matched_sides,
    record_at_b,
    refuse_by_size,
)
from trackfw_plugins.trackers.look_rules import nearer_by_ratio
from trackfw_plugins.trackers.neighbour_looks import NeighbourLooks
from trackfw_plugins.trackers.reacquisition import Reacquisition
from trackfw_plugins.trackers.start_split import StartSplit
from trackfw_plugins.trackers.walk_check import Snapshot, WalkCheck

#: Beyond the usual gate a not yet seen target takes only a detection at most this times as far
#: as the next one.
START_NEARER_RATIO = 1.0 / 3.0


class KalmanTracker(Tracker[KalmanTrackerParams]):
    """Constant-velocity Kalman filters with Hungarian or nearest-neighbour association."""

    name = "kalman"

    @property
    def needs_pixels(self) -> bool:
        params = self.params
        return params.appearance.descriptor != "none" or params.cmc or params.walk_check is not None

    def see(self, image: UInt8Array | None) -> None:
        self.image = image

    def see_match_ratios(self, ratios: FloatArray) -> None:
        """Kept for the next :meth:`reinitialise`: a weak match meets a stricter look limit
        (:func:`.look_limits`)."""
        self._match_ratios: FloatArray | None = np.asarray(ratios, dtype=np.float64).copy()

    def start(self, video: VideoContext) -> None:
        params = self.params
        self.video = video
        self.image = None
        self._frame = 0
        self._checked_at_b: dict[int, dict[str, object]] = {}
        self._match_ratios = None
        self.frame_motion = FrameMotion(params.cmc_registration) if params.cmc else None
        self.gate = (
            None
            if params.gate_px_at_1080 is None
            else params.gate_px_at_1080 * video.height / 1080.0
        )
        self.initialise(0, np.zeros(0, dtype=np.int64), np.zeros((0, 2)))

    def initialise(self, t: int, target_ids: IntArray, positions: FloatArray) -> None:
        params = self.params
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        self.target_ids = np.asarray(target_ids, dtype=np.int64)
        self._frame = t
        self.bank = KalmanBank.start(positions, params.P0, params.Q, params.R)
        self.matched = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)
        self.life = Lifecycle.start(params.lifecycle, self.video, t, positions)
        self.memory = AppearanceMemory(
            params.appearance, len(positions), self.video.height, self.life.fps
        )
        self.bystanders = (
            None
            if params.bystanders is None
            else Bystanders.start(
                params.bystanders, params.P0, params.Q, params.R, targets=len(positions)
            )
        )
        self.reacquisition = Reacquisition(
            params.appearance,
            self.life,
            self.memory,
            self.bank,
            self.gate,
            self.bystanders,
            None
            if params.appearance.neighbour_margin is None
            else NeighbourLooks.start(len(positions)),
        )
        if self.frame_motion is not None:
            self.frame_motion.remember(self.image, None)
        self.walk_check = (
            None
            if params.walk_check is None
            else WalkCheck(params.walk_check, self.life.fps, self.video.height)
        )
        self.start_split = (
            None
            if params.start_split is None or self.bystanders is None
            else StartSplit.begin(
                params.start_split,
                self.life.fps,
                (self.video.width, self.video.height),
                t,
                positions,
            )
        )

    def withdrawn(self) -> list[tuple[int, int]]:
        walks = [] if self.walk_check is None else self.walk_check.take_withdrawn()
        splits = [] if self.start_split is None else self.start_split.take_withdrawn()
        return walks + splits

    def _snapshot(self, t: int, detections: Detections | None) -> Snapshot:
        boxes = None if detections is None else detections.boxes
        held = self.matched != NO_MATCH
        return Snapshot(t, self.image, boxes, self.bank.means[:, :2].copy(), held)

    def _check_walks(self, t: int, detections: Detections, found: IntArray) -> None:
        """Undo the matches at b whose person walked back (:mod:`.walk_check`); ``found``: the
        targets found by look on this frame."""
        check = self.walk_check
        if check is None:
            return
        now = self._snapshot(t, detections)
        check.found(now, found)
        holding = (
            np.flatnonzero((self.life.status == TRACKED) & (self.matched != NO_MATCH))
            if check.pending
            else np.zeros(0, dtype=np.int64)
        )
        for row, pending in check.due(now, holding):
            self.reacquisition.not_the_target(self.image, detections, row, int(self.matched[row]))
            self.life.set(np.array([row]), LOST, t)
            self.matched[row] = NO_MATCH
            # The look it had at b: the one taken since may be the other person's.
            self.memory.descriptors[row] = pending.descriptor
            self.memory.described_at[row] = pending.described_at
            check.withdraw(row)
        check.remember(now)

    def associate(
        self, predicted: FloatArray, detections: Detections, rows: IntArray | None = None
    ) -> IntArray:
        """Row of ``detections`` for each predicted target, ``-1`` when none (gated).

        ``rows`` are the targets' rows (all when None); a detection whose box size does not fit
        the target's (``lifecycle.size_ratio_max``) is never its match.
        """
        if len(predicted) == 0 or len(detections) == 0:
            return np.full(len(predicted), NO_MATCH, dtype=np.int64)
        targets = np.arange(len(predicted)) if rows is None else rows
        mismatch = self.life.size_mismatch(targets, box_sides(detections))
        if self.params.association == "tps-rpm":
            matched, _, _ = match_points(predicted, detections.points, self.params.rpm)
            refused = np.flatnonzero(matched >= 0)
            refused = refused[mismatch[refused, matched[refused]]]
            matched[refused] = NO_MATCH
            return matched
        cost = distance_matrix(predicted, detections.points)
        cost[mismatch] = np.inf
        if self.params.coasting_group_cost != "none" and rows is not None:
            self._add_group_cost(cost, targets, detections.points)
        if self.params.association == "nearest":
            return greedy_nearest(cost, self.gate)
        start_gate = self._start_gate()
        # Until a detection supports a target its gate may be wider (Lifecycle.unseen).
        unseen = self.life.unseen(targets)
        if start_gate is None or self.gate is None or not unseen.any():
            return self._hungarian_with_bystanders(cost, self.gate, detections.points)
        # Beyond the usual gate only a clearly nearest detection: another one nearby may be a
        # bystander whose head the detector found while missing the target's.
        clear = nearer_by_ratio(cost, START_NEARER_RATIO)
        wide = unseen[:, None] & clear & (cost <= start_gate)
        gated = np.where((cost <= self.gate) | wide, cost, np.inf)
        return self._hungarian_with_bystanders(gated, start_gate, detections.points)

    def _start_gate(self) -> float | None:
        """``start_gate_px_at_1080`` in this video's pixels (None: not set)."""
        start = self.params.start_gate_px_at_1080
        return None if start is None else start * self.video.height / 1080.0

    def _add_group_cost(self, cost: FloatArray, targets: IntArray, points: FloatArray) -> None:
        """Blend into ``cost`` (``(K, N)``, rows ``targets``) the group's opinion on the targets
        that missed their detection on the previous frame (``coasting_group_cost``).

        docs/algorithms/segment-tracker.md#hungarian-association
        """
        coasting, places = self.life.group_places(self._frame, targets, self.bank.positions)
        group = distance_matrix(places, points)
        if self.params.coasting_group_cost == "max":
            cost[coasting] = np.maximum(cost[coasting], group)
        else:
            cost[coasting] = (cost[coasting] + group) / 2.0

    def _hungarian_with_bystanders(
        self, cost: FloatArray, gate: float | None, points: FloatArray
    ) -> IntArray:
        """Hungarian on the targets' ``(K, N)`` cost, with the competing bystander tracks'
        rows (gated by the usual gate) stacked under it; returns the targets' ``(K,)`` rows.

        docs/algorithms/segment-tracker.md#bystander-tracks
        """
        bystanders = self.bystanders
        multiple = self.params.unmatched_cost_gates
        unmatched = None if multiple is None or gate is None else multiple * gate
        if bystanders is None or len(bystanders.competing()) == 0:
            return hungarian(cost, gate, unmatched_cost=unmatched)
        rival = bystanders.rival_cost(points, self.gate)
        columns = hungarian(np.concatenate([cost, rival]), gate, unmatched_cost=unmatched)
        bystanders.claim(columns[len(cost) :])
        return columns[: len(cost)]

    def step(self, t: int, detections: Detections) -> None:
        """Predict, associate the tracked and tentative targets, re-acquire the others."""
        self._frame = t
        self._compensate(detections)
        self.bank.predict()
        if self.bystanders is not None:
            self.bystanders.predict()
        life = self.life
        active, inactive = life.active(), life.inactive()
        rows = self.associate(self.bank.positions[active], detections, active)
        sides = box_sides(detections)
        rows = self._contest(active, rows, detections, sides)
        held, shared, sharers = self._shared_at_start(active, detections)
        rows[held] = NO_MATCH
        hit = rows >= 0
        targets, taken = active[hit], rows[hit]
        self.bank.correct(targets, detections.points[taken])
        self.matched = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)
        self.matched[targets] = detections.index[taken]
        life.supported(t, targets, self.bank.positions[targets], sides[taken])
        swapped = self.memory.remember(t, self.image, targets, detections, taken)
        if len(swapped):
            # Someone else's detection: the target is lost rather than following them.
            life.set(swapped, LOST, t)
            self.matched[swapped] = NO_MATCH
        missing = active[~hit]
        predicted = self.bank.positions[missing]
        # A bystander track's detection hides a target as well as another target's does.
        claimed = (
            np.zeros(0, dtype=np.int64)
            if self.bystanders is None
            else self.bystanders.claimed_rows()
        )
        occluders = np.concatenate([taken, claimed])
        hidden = life.hidden_behind(
            missing, predicted, detections.points[occluders], sides[occluders]
        )
        life.unsupported(t, missing, predicted, hidden | held[~hit])
        if self.bystanders is not None:
            self.bystanders.claim_alone(detections.points, taken, self.gate)
        found, columns = self._reacquire(
            t, detections, inactive, targets, np.concatenate([taken, shared])
        )
        life.supported(t, found, self.bank.positions[found], sides[columns])
        if self.bystanders is not None:
            # A shared detection is the held targets': no anonymous track starts on it.
            holding = np.concatenate([taken, columns, shared])
            holders = np.concatenate([targets, found, sharers])
            self.bystanders.update(
                detections.points,
                holding,
                detections.points[holding],
                sides[holding],
                self.gate,
                holders,
            )
            self._split_start(t, detections, targets, taken, sides)
        self._check_walks(t, detections, found)
        self.reacquisition.end_frame(
            self.image, detections, np.concatenate([taken, columns, shared])
        )

    def _split_start(
        self, t: int, detections: Detections, targets: IntArray, taken: IntArray, sides: FloatArray
    ) -> None:
        """Trade places with the bystander track whose path leads back to a target's given
        point (:mod:`.start_split`); ``targets`` took detection rows ``taken`` this frame."""
        split, bystanders = self.start_split, self.bystanders
        if split is None or bystanders is None or not split.open.any():
            return  # every target traded, or the window is over
        split.first_step(t, targets, detections.points[taken], sides[taken])
        tracked = np.flatnonzero(self.life.status == TRACKED)
        trades = split.due(
            t, tracked, self.bank.positions[tracked], bystanders, detections.points, sides
        )
        for row, track in trades:
            column = int(bystanders.claimed[track])
            mean, covariance = bystanders.take_over(
                track, self.bank.means[row], self.bank.covariances[row]
            )
            self.bank.means[row], self.bank.covariances[row] = mean, covariance
            self.matched[row] = detections.index[column]
            self.life.supported(t, np.array([row]), detections.points[[column]], sides[[column]])
            # Its look and size so far were the passer-by's.
            self.memory.forget(row)

    def _shared_at_start(
        self, active: IntArray, detections: Detections
    ) -> tuple[BoolArray, IntArray, IntArray]:
        """``(M,)`` whether each ``active`` target holds at its given start position this frame,
        the detection rows they share and one holding target per shared row
        (``start_shared_hold``).

        Two targets not yet seen by the detector (:meth:`Lifecycle.unseen`) whose given points
        have the same nearest detection within the start gate, and no other detection that is
        nearer to one of them than to any other target, take nothing: on TUD-Stadtmitte
        two people 11 to 22 px apart on the start frame got one YOLOX box for 3 to 5 frames,
        the box moved with the walker, and the target nearer to it followed the walker while
        the other took the stander's head once the boxes split. Held at their given points
        (zero velocity), each takes its own once the boxes split (the usual association).
        """
        held = np.zeros(len(active), dtype=bool)
        none = np.zeros(0, dtype=np.int64)
        if not self.params.start_shared_hold or len(detections) == 0:
            return held, none, none
        unseen = np.flatnonzero(self.life.unseen(active))
        if len(unseen) < 2:
            return held, none, none
        cost = distance_matrix(self.bank.positions[active[unseen]], detections.points)
        start_gate = self._start_gate()
        sharing, nearest = outnumbered(cost, self.gate if start_gate is None else start_gate)
        held[unseen[sharing]] = True
        shared, first = np.unique(nearest[sharing], return_index=True)
        return held, shared, active[unseen[sharing][first]]

    def _contest(
        self, active: IntArray, rows: IntArray, detections: Detections, sides: FloatArray
    ) -> IntArray:
        """:func:`.contest_hidden` with this tracker's looks, lifecycle and predictions."""
        return contest_hidden(
            self.memory,
            self.life,
            self.image,
            self.params.appearance.contest_margin,
            active,
            self.bank.positions,
            rows,
            detections,
            sides,
        )

    def _compensate(self, detections: Detections) -> None:
        """Warp the filters by the camera motion from the previous frame (when it registers)."""
        if self.frame_motion is None:
            return
        if len(self.target_ids) == 0:
            # Nothing to warp: keep the frame for the next one without registering it.
            self.frame_motion.remember(self.image, detections.boxes)
            return
        matrix = self.frame_motion.motion(self.image, detections.boxes)
        if matrix is None:
            return
        self.bank.warp(matrix)
        if self.bystanders is not None:
            self.bystanders.warp(matrix)

    def _reacquire(
        self, t: int, detections: Detections, inactive: IntArray, anchors: IntArray, taken: IntArray
    ) -> tuple[IntArray, IntArray]:
        """:meth:`.Reacquisition.find`, the targets found restarted on their detections.

        Returns the rows found and the detection (row of ``detections``) of each.
        """
        found, columns = self.reacquisition.find(
            t, self.image, detections, inactive, anchors, taken
        )
        self._restart(found, detections.points[columns])
        self.matched[found] = detections.index[columns]
        return found, columns

    def _looks_at_b(
        self,
        active: IntArray,
        matched: IntArray,
        detection_rows: IntArray,
        positions: FloatArray,
        detections: Detections | None,
        refused: IntArray,
        checked_looks: FloatArray,
        continuity: IntArray,
    ) -> tuple[IntArray, IntArray]:
        """The matches at b checked by look and the refused and lost targets re-matched by look
        (:func:`.check_looks_at_b`; arrays updated in place), then by the people kept beside
        each target (:meth:`.Reacquisition.refuse_beside`).

        Returns:
            The refused targets left without a match, and the inactive targets found.
        """
        inactive = (
            self.life.inactive()
            if self.params.appearance.gap_rematch_inactive
            else np.zeros(0, dtype=np.int64)
        )
        if not self.params.appearance.gap_rematch_out_of_view:
            inactive = inactive[self.life.status[inactive] != OUT_OF_VIEW]
        matches_before = detection_rows.copy()
        unlike, returned = check_looks_at_b(
            self.memory,
            self.life,
            self.image,
            self.params.appearance,
            active,
            matched,
            detection_rows,
            positions,
            detections,
            inactive,
            refused,
            checked_looks,
            look_limits(self.params.appearance, self._match_ratios, len(matched)),
            continuity if self.params.appearance.gap_continuity_fallback else None,
        )
        # The re-match by look may hand a refused target a neighbour's head again.
        again = self.reacquisition.refuse_beside(
            self.image,
            np.flatnonzero(detection_rows != matches_before),
            matched,
            detection_rows,
            detections,
        )
        unlike, returned = (
            np.union1d(unlike, again[np.isin(again, active)]),
            np.setdiff1d(returned, again),
        )
        return unlike, returned

    def _restart(self, rows: IntArray, positions: FloatArray) -> None:
        """Restart the filters ``rows`` at ``(M, 2)`` positions with zero velocity and P0."""
        fresh = KalmanBank.start(positions, self.params.P0, self.params.Q, self.params.R)
        self.bank.means[rows] = fresh.means
        self.bank.covariances[rows] = fresh.covariances

    def reinitialise(
        self,
        t: int,
        positions: FloatArray,
        matched_detection: IntArray,
        detections: Detections | None = None,
    ) -> None:
        """Restart the tracked and tentative targets at b; unmatched ones become tentative.

        Lost and out-of-view targets were left out of the gap match and stay as they are. Every
        stored head size is first carried through the camera's change of scale (the median ratio
        of the matches); a match to a head of another size than that (``lifecycle.size_ratio_max``)
        counts as no match.
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2).copy()
        matched = np.asarray(matched_detection, dtype=np.int64).copy()
        proposed = matched.copy()
        if self.frame_motion is not None:
            self.frame_motion.remember(self.image, None if detections is None else detections.boxes)
        self._end_segment_state()
        active = self.life.active()
        detection_rows = detection_rows_of(matched, detections)
        continuity = self._continuity_at_b(t, active, detections, detection_rows)
        sides = matched_sides(detection_rows, detections)
        refused = refuse_by_size(self.life, active, matched, detection_rows, sides)
        by_size = np.flatnonzero((proposed != NO_MATCH) & (matched == NO_MATCH))
        self.reacquisition.neighbours_at_a(active)
        beside = self.reacquisition.refuse_beside(
            self.image, active, matched, detection_rows, detections
        )
        refused = np.union1d(refused, beside)
        looks = np.full(len(matched), np.nan)
        unlike, returned = self._looks_at_b(
            active, matched, detection_rows, positions, detections, refused, looks, continuity
        )
        sides = matched_sides(detection_rows, detections)
        if self.params.reinit_at_b:
            # The old velocity belongs to the pre-interval camera pose
            # (docs/algorithms/segment-tracker.md#re-initialisation-at-b).
            self._restart(active, positions[active])
        else:
            self.bank.predict()
            self.bank.means[active, :2] = positions[active]
        self._restart(returned, positions[returned])
        self.matched = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)
        self.matched[active] = matched[active]
        placed = np.setdiff1d(active[matched[active] == NO_MATCH], unlike)
        self.life.placed_at_b(t, placed, positions[placed])
        # A match that looks like someone else is no evidence of where the target is: it is
        # lost, and only re-acquisition (with the appearance check) brings it back.
        self.life.set(unlike, LOST, t)
        self.matched[returned] = matched[returned]
        supported = np.concatenate([active[matched[active] != NO_MATCH], returned])
        self.life.supported(t, supported, positions[supported], sides[supported])
        if self.walk_check is not None:
            self.walk_check.arm(
                self._snapshot(t, detections),
                active[matched[active] != NO_MATCH],
                self.memory.descriptors,
                self.memory.described_at,
                active[matched[active] == NO_MATCH],
            )
        self.reacquisition.end_gap()
        self._checked_at_b = record_at_b(
            proposed,
            self.matched,
            looks,
            {"size": by_size, "seen apart at a": beside},
            np.union1d(active, returned),
            self.statuses(),
            self._match_ratios,
            None if detections is None else detection_indices(continuity, detections),
        )
        self._match_ratios = None  # they belong to this gap's match

    def _continuity_at_b(
        self, t: int, active: IntArray, detections: Detections | None, detection_rows: IntArray
    ) -> IntArray:
        """``(K,)`` detection row continuity proposes at b for each active target where it
        differs from the gap matcher's (:func:`.continuity_rows`); all -1 when the fallback is
        off. The filters still hold their states at a, whose frame this reads; b then becomes
        the tracker's current frame."""
        continuity = np.full(len(self.target_ids), NO_MATCH, dtype=np.int64)
        if self.params.appearance.gap_continuity_fallback:
            continuity[active] = continuity_rows(
                self.bank.means[active], t - self._frame, detections, detection_rows[active]
            )
        self._frame = t
        return continuity

    def checked_at_b(self) -> dict[int, dict[str, object]]:
        """The gap matcher's matches at the last b as checked here (:func:`.record_at_b`)."""
        return self._checked_at_b

    def _end_segment_state(self) -> None:
        """At b the bystander tracks and the start split end: they belong to the camera pose
        before the interval."""
        if self.bystanders is not None:
            self.bystanders.clear()
        if self.start_split is not None:
            self.start_split.close()

    def positions(self) -> FloatArray:
        return self.bank.means[:, :2].copy()

    def statuses(self) -> list[str]:
        return [str(status) for status in self.life.status]

    def states(self) -> list[TargetState]:
        means, covariances = self.bank.means, self.bank.covariances
        return [
            TargetState(
                target_id=int(target_id),
                position=means[row, :2].copy(),
                velocity=means[row, 2:].copy(),
                covariance=covariances[row],
                matched_detection=int(self.matched[row]),
                status=str(self.life.status[row]),
            )
            for row, target_id in enumerate(self.target_ids)
        ]

"""Re-finding lost and out-of-view targets, never on someone seen apart from them.

See docs/algorithms/segment-tracker.md#re-acquisition. Inside a segment a lost or out-of-view
target takes a detection left over by the association when it lies where the group places it
(:func:`reacquire_cost`, the look vetoing a re-entry through the border), or,
periodically, the detection anywhere in the image that looks clearly most like it. Neither ever
takes a head that a bystander track seen apart from the target holds (:mod:`.bystanders`), and
the search by look never takes one that looks at least as much like a person seen apart from the
target when it was lost (:mod:`.neighbour_looks`). The same people are kept at b, from frame a, so
that the match at b does not hand the target one of them (:meth:`Reacquisition.refuse_beside`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray, UInt8Array
from trackfw.records import TRACKED, Detections
from trackfw_plugins.maths.assignment import hungarian
from trackfw_plugins.maths.kalman import KalmanBank
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory, AppearanceSettings
from trackfw_plugins.trackers.border_return import border_return_cost
from trackfw_plugins.trackers.bystanders import Bystanders
from trackfw_plugins.trackers.lifecycle import ACTIVE, Lifecycle
from trackfw_plugins.trackers.look_at_b import box_sides, refuse_beside
from trackfw_plugins.trackers.look_rules import stands_out
from trackfw_plugins.trackers.neighbour_looks import NEIGHBOUR_APART_SIDES, NeighbourLooks

#: Seconds between two searches of the whole frame for a lost target's look (each describes every
#: detection of the frame; a returner found within 0.2 s misses at most a few frames).
LOOK_ANYWHERE_PERIOD_S = 0.2

#: What the last frame stepped showed: its image, its detections and the rows of them the targets
#: held (the people seen apart from each target on frame a are taken from it at b).
LastFrame = tuple[UInt8Array | None, Detections, IntArray]


@dataclass
class Reacquisition:
    """The re-acquisition of one segment tracker's targets, sharing the tracker's state.

    Attributes:
        settings: the tracker's ``appearance`` parameters.
        life: the targets' states and expected places.
        memory: the targets' looks.
        bank: the targets' filters; a target not found waits, still, at its expected place.
        gate: the association gate in this video's pixels (None: ungated).
        bystanders: the bystanders' anonymous tracks (None when off).
        neighbours: the looks of the people seen apart from each lost target (None when
            ``appearance.neighbour_margin`` is unset).
        last_frame: the last frame stepped (kept only with ``neighbours``).
    """

    settings: AppearanceSettings
    life: Lifecycle
    memory: AppearanceMemory
    bank: KalmanBank
    gate: float | None
    bystanders: Bystanders | None
    neighbours: NeighbourLooks | None
    last_frame: LastFrame | None = field(default=None)

    def find(
        self,
        t: int,
        image: UInt8Array | None,
        detections: Detections,
        inactive: IntArray,
        anchors: IntArray,
        taken: IntArray,
    ) -> tuple[IntArray, IntArray]:
        """Re-find the ``inactive`` targets on the detections not ``taken``; ``anchors`` are
        the targets tracked on this frame (the group that places the others). A target not
        found waits at its expected place with zero velocity: its own velocity was measured
        before it vanished and would carry it away from the group.

        Returns:
            The rows found and the detection (row of ``detections``) of each; their filters are
            for the caller to restart.
        """
        none = np.zeros(0, dtype=np.int64)
        if len(inactive) == 0:
            return none, none
        life = self.life
        expected = life.expected(inactive, self.bank.positions, anchors)
        free = np.setdiff1d(np.arange(len(detections)), taken)
        cost, entering = reacquire_cost(
            life, t, expected, inactive, detections.points[free], box_sides(detections)[free]
        )
        # Through the border only with a look that agrees: without a descriptor (or with
        # 'none') a target never re-enters away from its expected place.
        veto = self.memory.veto(image, inactive, detections, free, cost <= 1.0, entering)
        cost[veto | (entering & (not self.memory.active or image is None))] = np.inf
        cost[self.seen_apart(inactive, free, len(detections))] = np.inf
        columns = hungarian(cost, 1.0)
        hit = columns >= 0
        found, chosen = inactive[hit], free[columns[hit]]
        by_look, looked = self._by_look(t, image, detections, inactive[~hit], free, chosen)
        hit[np.isin(inactive, by_look)] = True
        waiting = inactive[~hit]
        self.bank.means[waiting, :2] = expected[~hit]
        self.bank.means[waiting, 2:] = 0.0
        life.place(t, waiting, expected[~hit])
        return np.concatenate([found, by_look]), np.concatenate([chosen, looked])

    def _by_look(
        self,
        t: int,
        image: UInt8Array | None,
        detections: Detections,
        rows: IntArray,
        free: IntArray,
        taken: IntArray,
    ) -> tuple[IntArray, IntArray]:
        """Re-find inactive ``rows`` anywhere by look (``appearance.anywhere_max_distance``).

        The group's offsets go stale while a target is lost in a crowd that walks both ways, and
        its expected place drifts away from where it is; its look does not. A target takes the
        detection of ``free`` not ``taken`` that looks most like it when that one is within the
        limit and nearer in look than every other detection of the frame by ``anywhere_margin``
        (a bystander rarely stands out from the rest of the crowd that clearly), and nearer by
        ``neighbour_margin`` than every person seen apart from it when it was lost. Checked
        every :data:`LOOK_ANYWHERE_PERIOD_S`: it describes every detection of the frame.

        Returns:
            The rows found and the detection (row of ``detections``) of each.
        """
        settings = self.settings
        none = np.zeros(0, dtype=np.int64)
        period = max(1, round(LOOK_ANYWHERE_PERIOD_S * self.life.fps))
        if settings.anywhere_max_distance is None or len(rows) == 0 or t % period != 0:
            return none, none
        free = np.setdiff1d(free, taken)
        if len(free) == 0:
            return none, none
        look, described = self.memory.described_looks(
            image, rows, detections, np.arange(len(detections))
        )
        clear = stands_out(look, settings.anywhere_margin)
        cost = np.where(clear, look, np.inf)[:, free]
        cost[self.seen_apart(rows, free, len(detections))] = np.inf
        if self.neighbours is not None and described is not None:
            margin = settings.neighbour_margin or 0.0
            beside = self.neighbours.distances(rows, described[free], self.memory.distance_matrix)
            cost[~(cost + margin <= beside)] = np.inf
        columns = hungarian(cost, settings.anywhere_max_distance)
        hit = columns >= 0
        return rows[hit], free[columns[hit]]

    def seen_apart(self, rows: IntArray, columns: IntArray, count: int) -> BoolArray:
        """``(M, N)``: whether detection ``columns[n]`` (of ``count``) is held by a bystander
        track seen apart from target ``rows[m]``'s own detection, without a break since.

        Two heads seen on the same frame are two people, so that bystander is not the lost
        target (docs/algorithms/segment-tracker.md#bystander-tracks).
        """
        bystanders = self.bystanders
        if bystanders is None or not bystanders.settings.refuse_seen_apart:
            return np.zeros((len(rows), len(columns)), dtype=bool)
        return bystanders.seen_apart(rows, columns, count)

    def end_frame(self, image: UInt8Array | None, detections: Detections, held: IntArray) -> None:
        """At the end of a frame, keep the looks of the people seen apart from each target
        lost on it after being tracked (``held``: the rows of ``detections`` the targets hold),
        and the frame itself for b (:meth:`neighbours_at_a`)."""
        if self.neighbours is None:
            return
        lost = self._states_now(self.neighbours)
        self.last_frame = (image, detections, held)
        self._remember_apart(image, detections, held, lost)

    def end_gap(self) -> None:
        """After the matches at b: the targets tracked from b on start afresh (a target lost at
        b keeps the people seen apart from it on frame a)."""
        if self.neighbours is not None:
            self._states_now(self.neighbours)

    def not_the_target(
        self, image: UInt8Array | None, detections: Detections, row: int, column: int
    ) -> None:
        """Detection ``column`` was found not to be target ``row`` (its person walked back after
        b): its look joins the people seen apart from the target, so that the search by look
        does not hand the target that person again (none kept without the neighbour looks)."""
        neighbours = self.neighbours
        if neighbours is None or image is None or not self.memory.active:
            return
        neighbours.remember(row, self.memory.describe(image, detections, np.array([column])))

    def _states_now(self, neighbours: NeighbourLooks) -> IntArray:
        """:meth:`.NeighbourLooks.end_frame` with the targets' states now: who was just lost."""
        status = self.life.status
        return neighbours.end_frame(status == TRACKED, ~np.isin(status, ACTIVE))

    def neighbours_at_a(self, active: IntArray) -> None:
        """At b: keep the people seen apart from each of the ``active`` targets tracked on frame
        a (the last frame stepped): two heads seen at once there are two people."""
        neighbours, last = self.neighbours, self.last_frame
        self.last_frame = None
        if neighbours is not None and last is not None:
            image, before, held = last
            self._remember_apart(image, before, held, active[neighbours.tracked[active]])

    def _remember_apart(
        self, image: UInt8Array | None, detections: Detections, held: IntArray, rows: IntArray
    ) -> None:
        """:meth:`.NeighbourLooks.remember_apart` for targets ``rows``: apart is farther than
        :data:`.NEIGHBOUR_APART_SIDES` head sides (at least the bystanders' ``apart_gates``
        association gates) from both its filter's place and its last detection; the search's
        own limit (``anywhere_max_distance``) keeps a look that may be the target's out."""
        neighbours, bystanders, life = self.neighbours, self.bystanders, self.life
        limit = self.settings.anywhere_max_distance
        if neighbours is None or limit is None:
            return
        apart_gates = 2.0 if bystanders is None else bystanders.settings.apart_gates
        gates = np.inf if self.gate is None else apart_gates * self.gate
        reach = np.maximum(gates, NEIGHBOUR_APART_SIDES * np.nan_to_num(life.size[rows], nan=0.0))
        free = np.setdiff1d(np.arange(len(detections)), held)
        places = (self.bank.positions[rows], life.anchor[rows])
        neighbours.remember_apart(self.memory, image, detections, free, rows, places, reach, limit)

    def refuse_beside(
        self,
        image: UInt8Array | None,
        rows: IntArray,
        matched: IntArray,
        detection_rows: IntArray,
        detections: Detections | None,
    ) -> IntArray:
        """:func:`.refuse_beside` for targets ``rows`` at b (none without the neighbour looks)."""
        if self.neighbours is None:
            return np.zeros(0, dtype=np.int64)
        margin = self.settings.neighbour_margin or 0.0
        return refuse_beside(
            self.memory,
            self.neighbours,
            image,
            margin,
            rows,
            matched,
            detection_rows,
            detections,
        )


def expected_size_mismatch(
    life: Lifecycle, rows: IntArray, points: FloatArray, sizes: FloatArray
) -> BoolArray:
    """``(M, N)``: whether detection n (at ``points[n]``, box side ``sizes[n]``) is too large or
    too small for target ``rows[m]`` at that place.

    A returning head is compared with the size the group's current line gives at the
    detection's row times the target's own relative size, not with its box at exit: a target
    that walks out of the bottom edge comes back with a head far larger than when it left.
    """
    ratio_max = life.settings.size_ratio_max
    if ratio_max is None or np.isnan(life.size_line[0]):
        return life.size_mismatch(rows, sizes)
    expected = life.relative_size[rows][:, None] * life.line_size(points[:, 1])[None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.abs(np.log(expected / sizes[None, :]))
    return np.nan_to_num(ratio, nan=0.0) > np.log(ratio_max)


def _growing_gates(
    life: Lifecycle, t: int, rows: IntArray, growth_at_1080: float, largest_at_1080: float
) -> FloatArray:
    """``(M,)`` gates in pixels: the re-acquisition gate grown by ``growth_at_1080`` px per
    second lost, at most ``largest_at_1080`` (both at 1080p)."""
    seconds = np.maximum((t - life.last_matched[rows]) / life.fps, 0.0)
    gate = life.settings.reacquire_gate_px_at_1080 + growth_at_1080 * seconds
    return np.minimum(gate, largest_at_1080) * life.scale


def reacquire_gates(life: Lifecycle, t: int, rows: IntArray) -> FloatArray:
    """``(M,)`` re-acquisition gates in pixels, growing with the seconds lost."""
    settings = life.settings
    return _growing_gates(
        life,
        t,
        rows,
        settings.reacquire_growth_px_per_s_at_1080,
        settings.reacquire_max_px_at_1080,
    )


def reacquire_cost(
    life: Lifecycle,
    t: int,
    expected: FloatArray,
    rows: IntArray,
    points: FloatArray,
    sizes: FloatArray,
) -> tuple[FloatArray, BoolArray]:
    """``(M, N)`` cost of giving each inactive target of ``rows`` each of ``points`` (box
    sides ``sizes``), and ``(M, N)`` whether a possible pair is possible only through the
    border rule (:func:`reentry_cost`); a pair is possible where the cost is at most 1.

    The cost is the distance over the target's gate, so a target lost longer reaches
    farther; an out-of-view target comes back through the edge near where it is expected.
    Heads of another size are refused (infinite cost). A target not yet detected
    (:meth:`.Lifecycle.unseen`) is also looked for at its given start position, each pair taking the
    cheaper of the two places: offsets between given points carry a target that stands
    along with neighbours that walk.
    """
    cost, entering = _cost_from(life, t, expected, rows, points, sizes)
    unseen = life.unseen(rows)
    if unseen.any():
        given, given_entering = _cost_from(life, t, life.anchor[rows], rows, points, sizes)
        nearer = unseen[:, None] & (given < cost)
        cost = np.where(nearer, given, cost)
        entering = np.where(nearer, given_entering, entering)
    return cost, entering


def _cost_from(
    life: Lifecycle,
    t: int,
    expected: FloatArray,
    rows: IntArray,
    points: FloatArray,
    sizes: FloatArray,
) -> tuple[FloatArray, BoolArray]:
    """:func:`reacquire_cost` with each of ``rows`` expected at one ``(M, 2)`` place."""
    near = np.linalg.norm(expected[:, None, :] - points[None, :, :], axis=2)
    near = near / reacquire_gates(life, t, rows)[:, None]
    near[life.size_mismatch(rows, sizes)] = np.inf
    if life.settings.reentry_margin_px_at_1080 is None:
        return near, np.zeros(near.shape, dtype=bool)
    entry = reentry_cost(life, t, expected, rows, points)
    # Near its expected place a head is compared with its box at exit; through the border
    # with the size expected there. The line's looser check near the expected place let
    # bystanders in on TUD-Stadtmitte (seed 1: kalman1-ar-oracle MOTA 58.4 -> 53.7).
    entry[expected_size_mismatch(life, rows, points, sizes)] = np.inf
    cost = np.minimum(near, entry)
    return cost, (cost <= 1.0) & (near > 1.0)


def reentry_cost(
    life: Lifecycle, t: int, expected: FloatArray, rows: IntArray, points: FloatArray
) -> FloatArray:
    """``(M, N)`` cost of a return through the border near where each of ``rows`` left
    (:func:`~trackfw_plugins.trackers.border_return.border_return_cost`)."""
    settings = life.settings
    if settings.reentry_margin_px_at_1080 is None:
        return np.full((len(rows), len(points)), np.inf)
    gates = _growing_gates(
        life,
        t,
        rows,
        settings.reentry_growth_px_per_s_at_1080,
        settings.reentry_max_px_at_1080,
    )
    return border_return_cost(
        life.exit_side[rows],
        expected,
        gates,
        points,
        settings.reentry_margin_px_at_1080 * life.scale,
        life.width,
        life.height,
    )


__all__ = [
    "LOOK_ANYWHERE_PERIOD_S",
    "Reacquisition",
    "expected_size_mismatch",
    "reacquire_cost",
    "reacquire_gates",
    "reentry_cost",
]

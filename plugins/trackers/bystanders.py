"""Anonymous tracks of the heads no target holds, so that a target does not take them.

See docs/algorithms/segment-tracker.md#bystander-tracks. The people of interest are a fixed set
given on the first frame; everybody else the detector finds is a bystander. A tracker that follows
only the targets lets a target whose own head the detector missed take the head of a bystander
walking past, and then follow that bystander away. Following the bystanders too, as anonymous
constant-velocity filters, lets the association see that the head belongs to someone already being
followed: the bystander's prediction is nearer, so the target goes without a detection for that
frame instead of being captured. Bystander tracks are never reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.assignment import distance_matrix, hungarian
from trackfw_plugins.maths.kalman import KalmanBank


class BystanderSettings(FiniteModel):
    """When an anonymous bystander track starts, claims detections and ends."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    confirm_frames: int = Field(
        3,
        ge=1,
        description="frames in a row with a detection before a bystander track competes with the"
        " targets for detections (a single stray detection never does)",
    )
    end_after_frames: int = Field(
        3,
        ge=1,
        description="frames without a detection after which a competing bystander track ends",
    )
    near_target: float = Field(
        0.5,
        ge=0.0,
        description="a detection within this many head sides of a target's detection starts no"
        " track, and a track that comes that near a target's detection ends: a second detection"
        " of the target's own head is not a bystander",
    )
    refuse_seen_apart: bool = Field(
        True,
        description="a lost target never re-takes the head a bystander track holds when that"
        " track was last seen, without a break, apart from the target's own detection: two heads"
        " seen at once are two people",
    )
    apart_gates: float = Field(
        2.0,
        gt=0.0,
        description="seen apart: farther than this many association gates from the target's"
        " detection (a target's detection may be a neighbour's head, a noisy head point)",
    )


@dataclass
class Bystanders:
    """Kalman filters of the heads no target holds.

    Attributes:
        settings: when tracks start, compete and end.
        bank: ``(B, 4)`` constant-velocity filters, one per bystander track.
        hits: ``(B,)`` frames in a row each track had a detection.
        misses: ``(B,)`` frames in a row each track went without one.
        confirmed: ``(B,)`` whether each track once had ``confirm_frames`` hits in a row.
        claimed: ``(B,)`` row of the current frame's detections each track took (-1: none); in
            the joint assignment, then after :meth:`update` every track's.
        apart: ``(B, K)`` whether each track, since it last came within ``apart_gates``
            association gates of target k's detection or went a frame without a detection, was
            seen farther than that from target k's detection on some frame: then it is someone
            else.
        assigned: whether the joint assignment with the targets ran on the current frame.
        age: ``(B,)`` frames since each track's first detection.
        first: ``(B, 2)`` each track's first detection (NaN once it took over a target's
            filter: its path then tells nothing; :meth:`take_over`).
    """

    settings: BystanderSettings
    bank: KalmanBank
    hits: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    misses: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    confirmed: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    claimed: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    apart: BoolArray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    assigned: bool = False
    age: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    first: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))

    @classmethod
    def start(
        cls,
        settings: BystanderSettings,
        initial_variance: float,
        process: float,
        noise: float,
        targets: int = 0,
    ) -> Bystanders:
        """No tracks yet; filters started with these P0, Q and R, beside ``targets`` targets."""
        bank = KalmanBank.start(np.zeros((0, 2)), initial_variance, process, noise)
        return cls(settings, bank, apart=np.zeros((0, targets), dtype=bool))

    def __len__(self) -> int:
        return len(self.hits)

    def clear(self) -> None:
        """End every track (after an interval the camera pose has changed)."""
        self._keep(np.zeros(len(self), dtype=bool))

    def predict(self) -> None:
        """Advance every track by one frame; nothing is claimed yet."""
        self.bank.predict()
        self.claimed = np.full(len(self), -1, dtype=np.int64)
        self.assigned = False
        self.age = self.age + 1

    def take_over(
        self, row: int, mean: FloatArray, covariance: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Track ``row`` goes on from a target's ``(4,)`` filter mean and ``(4, 4)`` covariance
        (a start split: :mod:`.start_split`); returns the track's own, for the target."""
        own = self.bank.means[row].copy(), self.bank.covariances[row].copy()
        self.bank.means[row] = mean
        self.bank.covariances[row] = covariance
        self.first[row] = np.nan
        return own

    def warp(self, matrix: FloatArray) -> None:
        """Carry every track through the camera motion (see :meth:`KalmanBank.warp`)."""
        self.bank.warp(matrix)

    def claimed_rows(self) -> IntArray:
        """Rows of this frame's detections the tracks took in the joint assignment."""
        return self.claimed[self.claimed >= 0]

    def competing(self) -> IntArray:
        """Rows of the confirmed tracks that had a detection on the previous frame (a track
        coasting on its velocity may drift onto a target)."""
        return np.flatnonzero(self.confirmed & (self.misses == 0))

    def rival_cost(self, points: FloatArray, gate: float | None) -> FloatArray:
        """``(C, N)`` distances from the competing tracks' predictions to ``(N, 2)`` detections,
        infinite beyond ``gate``; stack it under the targets' cost before one assignment."""
        rivals = self.competing()
        cost = distance_matrix(self.bank.positions[rivals], points)
        if gate is not None:
            cost[cost > gate] = np.inf
        return cost

    def claim(self, columns: IntArray) -> None:
        """The joint assignment gave the competing tracks these ``(C,)`` detection rows (-1)."""
        self.claimed[self.competing()] = columns
        self.assigned = True

    def claim_alone(self, points: FloatArray, taken: IntArray, gate: float | None) -> None:
        """Where no joint assignment ran this frame (no target active, or an association
        without one), the competing tracks take the ``(N, 2)`` detections not in ``taken``."""
        if self.assigned:
            return
        rivals = self.competing()
        free = np.setdiff1d(np.arange(len(points)), taken)
        cost = distance_matrix(self.bank.positions[rivals], points[free])
        columns = hungarian(cost, gate)
        hit = columns >= 0
        self.claimed[rivals[hit]] = free[columns[hit]]
        self.assigned = True

    def seen_apart(self, targets: IntArray, columns: IntArray, count: int) -> BoolArray:
        """``(M, N)``: whether detection ``columns[n]`` (of the frame's ``count``) is held by a
        track seen apart from target ``targets[m]`` (see ``apart``).

        >>> import numpy as np
        >>> tracks = Bystanders.start(BystanderSettings(), 10.0, 1.0, 1.0, targets=2)
        >>> tracks.claimed = np.array([2, -1])
        >>> tracks.apart = np.array([[True, False], [True, True]])
        >>> tracks.seen_apart(np.array([0, 1]), np.array([0, 2]), 3).tolist()
        [[False, True], [False, False]]
        """
        holder = np.full(count, -1, dtype=np.int64)
        held = np.flatnonzero(self.claimed >= 0)
        holder[self.claimed[held]] = held
        by = holder[columns]
        result = np.zeros((len(targets), len(columns)), dtype=bool)
        some = by >= 0
        result[:, some] = self.apart[np.ix_(by[some], targets)].T
        return result

    def update(
        self,
        points: FloatArray,
        taken: IntArray,
        target_points: FloatArray,
        target_sides: FloatArray,
        gate: float | None,
        holders: IntArray | None = None,
    ) -> None:
        """Close the frame: correct, start and end tracks.

        Args:
            points: ``(N, 2)`` the frame's detections.
            taken: rows of ``points`` the targets hold, after every rule of the frame (a track
                whose claimed detection went to a target, re-acquired, ends).
            target_points: ``(M, 2)`` the targets' detections this frame.
            target_sides: ``(M,)`` their head sides (NaN: unknown).
            gate: association gate in pixels for the tracks the joint assignment did not serve.
            holders: ``(M,)`` the target (row) of each of ``target_points``; None: unknown
                (no track is then seen apart from any target).
        """
        claimed = self.claimed.copy()
        lost_to_target = np.isin(claimed, taken) & (claimed >= 0)
        claimed[lost_to_target] = -1
        held = np.concatenate([taken, claimed[claimed >= 0]])
        free = np.setdiff1d(np.arange(len(points)), held)
        # The tracks the joint assignment did not serve (or did not see: no target active)
        # take what nobody holds.
        waiting = np.flatnonzero((claimed < 0) & ~lost_to_target)
        cost = distance_matrix(self.bank.positions[waiting], points[free])
        found = hungarian(cost, gate)
        claimed[waiting[found >= 0]] = free[found[found >= 0]]
        hit = claimed >= 0
        self.bank.correct(np.flatnonzero(hit), points[claimed[hit]])
        self.hits = np.where(hit, self.hits + 1, 0)
        self.misses = np.where(hit, 0, self.misses + 1)
        self.confirmed |= self.hits >= self.settings.confirm_frames
        near = self._near(self.bank.positions, target_points, target_sides)
        coasting = self.confirmed & (self.misses < self.settings.end_after_frames)
        keep = ~lost_to_target & ~near & (hit | coasting)
        self.claimed = claimed
        self._keep(keep)
        rest = np.setdiff1d(free, claimed[hit])
        new = rest[~self._near(points[rest], target_points, target_sides)]
        self._add(points[new], new)
        self._see(target_points, holders, gate)

    def _near(
        self, positions: FloatArray, target_points: FloatArray, sides: FloatArray
    ) -> BoolArray:
        """``(K,)``: whether each position is within ``near_target`` head sides of a target's
        detection."""
        if len(positions) == 0 or len(target_points) == 0:
            return np.zeros(len(positions), dtype=bool)
        reach = self.settings.near_target * np.nan_to_num(sides, nan=0.0)
        return np.asarray((distance_matrix(positions, target_points) <= reach[None, :]).any(axis=1))

    def _keep(self, keep: BoolArray) -> None:
        self.bank.keep(keep)
        self.hits, self.misses = self.hits[keep], self.misses[keep]
        self.confirmed, self.claimed = self.confirmed[keep], self.claimed[keep]
        self.apart = self.apart[keep]
        self.age, self.first = self.age[keep], self.first[keep]

    def _see(self, target_points: FloatArray, holders: IntArray | None, gate: float | None) -> None:
        """Update ``apart`` at the end of the frame against the targets' detections
        ``target_points`` held by ``holders``: the tracks with a detection this frame (every new
        one included) are measured, the others may come back on someone else."""
        seen = self.hits > 0
        self.apart[~seen] = False
        rows = np.flatnonzero(seen)
        if holders is None or len(holders) == 0 or len(rows) == 0:
            return
        distance = distance_matrix(self.bank.positions[rows], target_points)
        reach = np.inf if gate is None else self.settings.apart_gates * gate
        self.apart[np.ix_(rows, holders)] = distance > reach

    def _add(self, positions: FloatArray, rows: IntArray) -> None:
        """Start tracks at ``(M, 2)`` positions, this frame's detection ``rows``."""
        self.bank.add(positions)
        count = len(positions)
        self.hits = np.concatenate([self.hits, np.ones(count, dtype=np.int64)])
        self.misses = np.concatenate([self.misses, np.zeros(count, dtype=np.int64)])
        confirmed = np.full(count, self.settings.confirm_frames <= 1)
        self.confirmed = np.concatenate([self.confirmed, confirmed])
        self.claimed = np.concatenate([self.claimed, np.asarray(rows, dtype=np.int64)])
        self.apart = np.concatenate(
            [self.apart, np.zeros((count, self.apart.shape[1]), dtype=bool)]
        )
        self.age = np.concatenate([self.age, np.zeros(count, dtype=np.int64)])
        self.first = np.concatenate([self.first, np.asarray(positions, dtype=np.float64)])

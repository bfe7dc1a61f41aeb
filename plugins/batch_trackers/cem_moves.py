"""CEM's state and its six jump moves (merge, grow, shrink, split, add, remove).

Written fresh from the method's description (Milan, Roth & Schindler, TPAMI 2014; the reference
code's licence forbids derivative works). Every move changes one or two targets and is accepted
only when it lowers the energy. A target's share of the energy
(:func:`~trackfw_plugins.batch_trackers.cem_energy.target_terms`: its own terms plus both ordered
exclusion pairs with every other target) is exactly what the total changes by when that target
alone changes, so a move is judged by the shares before and after it; cutting a target (grow,
shrink, split) is priced for every cut at once from cumulative sums of its per-frame terms.

Gates **[ORIG]** (of the reference's 2-D defaults; ``c`` is the target size): merge joins a
target that ends before another starts when the gap is under 15 frames, the ends are within
``5 c`` and the speed across the gap under ``3 c`` per frame, filling the gap linearly; grow
extends an end by 1 to 50 frames at its last velocity; shrink cuts 1 to 50 frames from an end,
keeping 3; split cuts a target of 6 or more frames in two pieces of 3 or more; add seeds a
3-frame target on a free detection (none within ``2 c``), velocity from the nearest detections on
the frames either side when closer than ``2 c``, up to 8 per call; remove deletes a target whose
share is positive. See ``docs/algorithms/batch-trackers.md#cem``.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw_plugins.batch_trackers.cem_energy import (
    FrameTerms,
    Lifespans,
    Scene,
    end_costs,
    frame_costs,
    range_energies,
    target_terms,
)
from trackfw_plugins.batch_trackers.cem_params import CemParams
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections

#: A move must lower the energy by more than this (rounding is no improvement).
_TOLERANCE = 1e-9
#: Shortest target shrink leaves and split makes.
MIN_LENGTH = 3


@dataclass(frozen=True)
class Packed:
    """Targets on a packed ``(W, K, 2)`` array of frames ``first .. first + W - 1``.

    Targets share a column when a dead frame separates them, so K is about the largest number of
    targets alive at once rather than the number of targets (the energy's pair and detection
    terms cost ``W K²`` and ``W K G``).

    Attributes:
        first: the array's first frame.
        positions: ``(W, K, 2)`` positions, 0 where dead.
        alive: ``(W, K)`` alive flags.
        spans: where each target lives (frames relative to ``first``; persistence as in the
            video).
        columns: target index -> column.
    """

    first: int
    positions: FloatArray
    alive: BoolArray
    spans: Lifespans
    columns: dict[int, int]


def pack(
    targets: list[tuple[int, tuple[int, FloatArray]]], window: tuple[int, int], n_frames: int
) -> Packed:
    """Pack ``(index, (start, points))`` targets, cut to frames ``window[0] .. window[1]``."""
    first, last = window
    ordered = sorted(targets, key=lambda item: item[1][0])
    starts = np.array([max(start, first) for _, (start, _) in ordered], dtype=np.int64)
    ends = np.array(
        [min(start + len(points) - 1, last) for _, (start, points) in ordered], dtype=np.int64
    )
    columns = pack_columns(starts, ends)
    width = int(columns.max()) + 1 if len(columns) else 1
    positions = np.zeros((last - first + 1, width, 2))
    alive = np.zeros((last - first + 1, width), dtype=bool)
    for (_, (start, points)), lo, hi, column in zip(ordered, starts, ends, columns, strict=True):
        positions[lo - first : hi - first + 1, column] = points[lo - start : hi - start + 1]
        alive[lo - first : hi - first + 1, column] = True
    starts_inside = np.array([start > 0 for _, (start, _) in ordered], dtype=bool)
    ends_inside = np.array(
        [start + len(points) < n_frames for _, (start, points) in ordered], dtype=bool
    )
    spans = Lifespans(columns, starts - first, ends - first, (starts_inside, ends_inside))
    mapping = {index: int(column) for (index, _), column in zip(ordered, columns, strict=True)}
    return Packed(first, positions, alive, spans, mapping)


class CemState:
    """The targets (first frame and ``(L, 2)`` positions each) and what they are measured on.

    ``touched`` holds the targets a jump move created or changed since the last descent.
    """

    def __init__(self, scene: Scene, params: CemParams, n_frames: int) -> None:
        self.scene = scene
        self.params = params
        self.n_frames = n_frames
        self.targets: list[tuple[int, FloatArray] | None] = []
        self.touched: set[int] = set()
        self._packed: Packed | None = None

    def add(self, start: int, points: FloatArray) -> None:
        """Append a target."""
        self.targets.append((start, np.array(points, dtype=np.float64)))
        self.touched.add(len(self.targets) - 1)
        self._packed = None

    def replace(self, index: int, start: int, points: FloatArray | None) -> None:
        """Change a target, or retire it (None) until :meth:`compact`."""
        self.targets[index] = None if points is None else (start, np.array(points, dtype=float))
        if points is None:
            self.touched.discard(index)
        else:
            self.touched.add(index)
        self._packed = None

    def compact(self) -> None:
        """Drop retired targets (indices change)."""
        kept = self.live()
        renumber = {old: new for new, old in enumerate(kept)}
        self.targets = [self.targets[index] for index in kept]
        self.touched = {renumber[index] for index in self.touched if index in renumber}
        self._packed = None

    def live(self) -> list[int]:
        """Indices of the targets not retired."""
        return [index for index, target in enumerate(self.targets) if target is not None]

    def target(self, index: int) -> tuple[int, FloatArray]:
        """A live target's first frame and positions."""
        target = self.targets[index]
        assert target is not None, "a retired target has no positions"
        return target

    def packed(self) -> Packed:
        """Every live target on one packed array of the whole video."""
        if self._packed is None:
            items = [(index, self.target(index)) for index in self.live()]
            self._packed = pack(items, (0, self.n_frames - 1), self.n_frames)
        return self._packed

    def dense(self) -> tuple[FloatArray, BoolArray]:
        """:meth:`packed`'s ``(F, K, 2)`` positions and ``(F, K)`` alive flags."""
        packed = self.packed()
        return packed.positions, packed.alive

    def set_positions(self, packed: Packed, positions: FloatArray) -> None:
        """Take the positions of ``packed``'s targets (whole lifespans) from its layout."""
        for index, column in packed.columns.items():
            start, points = self.target(index)
            rows = slice(start - packed.first, start - packed.first + len(points))
            self.targets[index] = (start, positions[rows, column].copy())
        self._packed = None

    def terms(self, start: int, points: FloatArray, exclude: Sequence[int]) -> FrameTerms:
        """Frame terms of a trajectory against every live target but ``exclude``."""
        packed = self.packed()
        frames = slice(start, start + len(points))
        others = packed.alive[frames].copy()
        for index in exclude:
            if self.targets[index] is None:
                continue
            first, own = self.target(index)
            lo, hi = max(first, start), min(first + len(own), start + len(points))
            others[lo - start : max(hi - start, lo - start), packed.columns[index]] = False
        return target_terms(
            start, points, (packed.positions[frames], others), self.scene, self.params
        )

    def cut_energies(self, terms: FrameTerms, lows: IntArray, highs: IntArray) -> FloatArray:
        """Shares of the trajectory cut to ``lows[r] .. highs[r]``."""
        return range_energies(terms, lows, highs, self.scene, self.params, self.n_frames)

    def share(self, start: int, points: FloatArray, exclude: Sequence[int]) -> float:
        """A whole trajectory's share of the energy."""
        terms = self.terms(start, points, exclude)
        last = np.array([len(points) - 1])
        return float(self.cut_energies(terms, np.zeros(1, dtype=np.int64), last)[0])

    def as_tracks(self, detections: VideoDetections) -> Tracks:
        """Tracks numbered by first frame; observed where a detection lies within ``c / 2``."""
        live = sorted((self.target(index) for index in self.live()), key=lambda t: t[0])
        if not live:
            return Tracks.empty()
        ids = np.repeat(np.arange(1, len(live) + 1), [len(points) for _, points in live])
        frames = np.concatenate([start + np.arange(len(points)) for start, points in live])
        points = np.concatenate([points for _, points in live])
        difference = points[:, None, :] - self.scene.detections[frames]
        squared = np.where(
            self.scene.scores[frames] > 0, np.einsum("pgk,pgk->pg", difference, difference), np.inf
        )
        observed = squared.min(axis=1) <= (0.5 * self.scene.target_size) ** 2
        return Tracks(ids, frames, points, observed)


def pack_columns(starts: IntArray, ends: IntArray) -> IntArray:
    """``(N,)`` columns for lifespans sorted by start, reusing one after a dead frame.

    >>> pack_columns(np.array([0, 0, 5, 6]), np.array([3, 9, 8, 7])).tolist()
    [0, 1, 0, 2]
    """
    free: list[tuple[int, int]] = []  # (first frame a column may take a new target, column)
    columns = np.zeros(len(starts), dtype=np.int64)
    width = 0
    for target, (start, end) in enumerate(zip(starts.tolist(), ends.tolist(), strict=True)):
        if free and free[0][0] <= start:
            columns[target] = heapq.heappop(free)[1]
        else:
            columns[target] = width
            width += 1
        heapq.heappush(free, (end + 2, int(columns[target])))
    return columns


def merge_move(state: CemState) -> bool:
    """Join pairs (one ends before the other starts), best energy drop first, until none helps."""
    fired = False
    while True:
        joined = False
        candidates = sorted(
            (_merge_delta(state, first, second)[0], first, second)
            for first, second in _merge_pairs(state)
        )
        for delta, first, second in candidates:
            if delta >= -_TOLERANCE or state.targets[first] is None:
                continue
            if state.targets[second] is None:
                continue
            # Earlier merges change the exclusion terms: price it again on the current state.
            delta, merged = _merge_delta(state, first, second)
            if delta < -_TOLERANCE:
                state.replace(first, state.target(first)[0], merged)
                state.replace(second, 0, None)
                joined = True
        state.compact()
        fired |= joined
        if not joined:
            return fired


def _merge_pairs(state: CemState) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` passing the gates: gap, distance between the ends, speed across."""
    if len(state.targets) < 2:
        return []
    params, size = state.params, state.scene.target_size
    starts = np.array([start for start, _ in map(state.target, state.live())])
    ends = np.array([start + len(points) - 1 for start, points in map(state.target, state.live())])
    firsts = np.array([points[0] for _, points in map(state.target, state.live())])
    lasts = np.array([points[-1] for _, points in map(state.target, state.live())])
    gap = starts[None, :] - ends[:, None] - 1
    distance = np.linalg.norm(firsts[None, :, :] - lasts[:, None, :], axis=2)
    allowed = (gap >= 0) & (gap < params.merge_max_gap)
    allowed &= distance < params.merge_max_distance * size
    allowed &= distance / np.maximum(gap + 1, 1) < params.merge_max_speed * size
    first, second = np.nonzero(allowed)
    return list(zip(first.tolist(), second.tolist(), strict=True))


def _merge_delta(state: CemState, first: int, second: int) -> tuple[float, FloatArray]:
    """Energy change of joining ``first`` then ``second`` (gap filled linearly), and the joint."""
    start, head = state.target(first)
    later, tail = state.target(second)
    gap = later - (start + len(head))
    if gap < 0:
        # An earlier merge in the same pass extended ``first`` past ``second``'s start.
        return np.inf, head
    fill = np.linspace(head[-1], tail[0], gap + 2)[1:-1]
    merged = np.vstack([head, fill, tail])
    before = state.share(start, head, [first]) + state.share(later, tail, [second])
    return state.share(start, merged, [first, second]) - before, merged


def _best_cut(
    state: CemState, index: int, start: int, points: FloatArray, cuts: tuple[IntArray, IntArray]
) -> bool:
    """Keep the cheapest cut ``points[low : high + 1]``; cut 0 must be the target as it is."""
    lows, highs = cuts
    energies = state.cut_energies(state.terms(start, points, [index]), lows, highs)
    best = int(np.argmin(energies))
    if energies[best] >= energies[0] - _TOLERANCE:
        return False
    state.replace(index, start + int(lows[best]), points[lows[best] : highs[best] + 1])
    return True


def _target_ends(state: CemState) -> Iterator[tuple[int, bool, int, FloatArray]]:
    """Each live target's two ends in turn: ``(index, at_end, start, points)``.

    The target is read again for its second end, which a move on the first may have changed.
    """
    for index in state.live():
        for at_end in (False, True):
            start, points = state.target(index)
            yield index, at_end, start, points


def grow_move(state: CemState) -> bool:
    """Extend each end by the best of 1 .. 50 frames along its last velocity, if that helps."""
    fired = False
    for index, forward, start, points in _target_ends(state):
        room = state.n_frames - start - len(points) if forward else start
        steps = min(state.params.max_extension, room)
        if len(points) < 2 or steps <= 0:
            continue
        extra = np.arange(steps + 1)
        ahead = np.arange(1, steps + 1)[:, None]
        if forward:
            grown = np.vstack([points, points[-1] + ahead * (points[-1] - points[-2])])
            cuts = (np.zeros_like(extra), len(points) - 1 + extra)
            fired |= _best_cut(state, index, start, grown, cuts)
        else:
            before = (points[0] + ahead * (points[0] - points[1]))[::-1]
            grown = np.vstack([before, points])
            cuts = (steps - extra, np.full_like(extra, len(grown) - 1))
            fired |= _best_cut(state, index, start - steps, grown, cuts)
    return fired


def shrink_move(state: CemState) -> bool:
    """Cut the best of 1 .. 50 frames from each end (keeping 3), if that helps."""
    fired = False
    for index, from_end, start, points in _target_ends(state):
        steps = min(state.params.max_extension, len(points) - MIN_LENGTH)
        if steps <= 0:
            continue
        cut = np.arange(steps + 1)
        whole = np.full_like(cut, len(points) - 1)
        cuts = (np.zeros_like(cut), whole - cut) if from_end else (cut, whole)
        fired |= _best_cut(state, index, start, points, cuts)
    return fired


def split_move(state: CemState) -> bool:
    """Cut each long target in two at its best frame (pieces of 3 or more), if that helps."""
    fired = False
    for index in state.live():
        start, points = state.target(index)
        length = len(points)
        if length < max(state.params.split_min_length, 2 * MIN_LENGTH):
            continue
        terms = state.terms(start, points, [index])
        at = np.arange(MIN_LENGTH, length - MIN_LENGTH + 1)
        last = np.full_like(at, length - 1)
        whole = state.cut_energies(terms, np.zeros(1, dtype=np.int64), last[:1])[0]
        delta = (
            state.cut_energies(terms, np.zeros_like(at), at - 1)
            + state.cut_energies(terms, at, last)
            - whole
        )
        best = int(np.argmin(delta))
        if delta[best] < -_TOLERANCE:
            cut = int(at[best])
            state.replace(index, start, points[:cut])
            state.add(start + cut, points[cut:])
            fired = True
    return fired


def remove_move(state: CemState) -> bool:
    """Delete every target whose share of the energy is positive."""
    fired = False
    for index in state.live():
        start, points = state.target(index)
        if state.share(start, points, [index]) > _TOLERANCE:
            state.replace(index, 0, None)
            fired = True
    state.compact()
    return fired


def add_move(state: CemState) -> bool:
    """Seed 3-frame targets on free detections, the best first, up to ``add_per_call``."""
    frames, points = _free_detections(state)
    added = 0
    while added < state.params.add_per_call and len(frames):
        seeds = _seeds(state, frames, points)
        energies = _seed_energies(state, frames - 1, seeds)
        best = int(np.argmin(energies))
        if energies[best] >= -_TOLERANCE:
            break
        state.add(int(frames[best]) - 1, seeds[best])
        added += 1
        # Detections now close to the new target are no longer free.
        offset = frames - frames[best] + 1
        near = (offset >= 0) & (offset <= 2)
        distance = np.linalg.norm(points - seeds[best][np.clip(offset, 0, 2)], axis=1)
        taken = near & (distance < state.params.add_free_distance * state.scene.target_size)
        taken[best] = True
        frames, points = frames[~taken], points[~taken]
    return added > 0


def _free_detections(state: CemState) -> tuple[IntArray, FloatArray]:
    """Detections (frame, point) on frames 1 .. F-2 with no live target within the free distance."""
    scene = state.scene
    frames, slots = np.nonzero(scene.scores[1:-1] > 0)
    frames = frames + 1
    points = scene.detections[frames, slots]
    positions, alive = state.dense()
    apart = np.linalg.norm(points[:, None, :] - positions[frames], axis=2)
    limit = state.params.add_free_distance * scene.target_size
    free = ~np.any(alive[frames] & (apart < limit), axis=1)
    return frames[free], points[free]


def _nearest(state: CemState, frames: IntArray, points: FloatArray) -> FloatArray:
    """``(P, 2)`` offset from each point to the nearest detection of ``frames`` (NaN: none)."""
    difference = state.scene.detections[frames] - points[:, None, :]
    squared = np.where(
        state.scene.scores[frames] > 0, np.einsum("pgk,pgk->pg", difference, difference), np.inf
    )
    nearest = np.argmin(squared, axis=1)
    offset = difference[np.arange(len(points)), nearest]
    close = squared[np.arange(len(points)), nearest] < (2.0 * state.scene.target_size) ** 2
    return np.where(close[:, None], offset, np.nan)


def _seeds(state: CemState, frames: IntArray, points: FloatArray) -> FloatArray:
    """``(P, 3, 2)`` seeds ``d - v, d, d + v``; v from the neighbours on frames t - 1 and t + 1."""
    steps = np.stack([-_nearest(state, frames - 1, points), _nearest(state, frames + 1, points)])
    known = np.isfinite(steps[..., 0])
    count = known.sum(axis=0)[:, None]
    velocity = np.where(count > 0, np.nansum(steps, axis=0) / np.maximum(count, 1), 0.0)
    return points[:, None, :] + np.array([-1.0, 0.0, 1.0])[None, :, None] * velocity[:, None, :]


def _seed_energies(state: CemState, starts: IntArray, seeds: FloatArray) -> FloatArray:
    """``(P,)`` shares of 3-frame straight seeds (no dynamics cost) starting on ``starts``."""
    scene = state.scene
    frames = starts[:, None] + np.arange(3)[None, :]
    positions, alive = state.dense()
    local = frame_costs(
        seeds,
        (scene.detections[frames], scene.scores[frames]),
        (positions[frames], alive[frames]),
        scene,
        state.params,
    ).sum(axis=1)
    inside = (starts > 0, starts + 2 < state.n_frames - 1)
    lengths = np.full(len(seeds), 3)
    ends = (seeds[:, 0], seeds[:, 2])
    return local + end_costs(ends, inside, lengths, scene, state.params)


#: The moves in the reference's order.
JUMP_MOVES: tuple[Callable[[CemState], bool], ...] = (
    merge_move,
    grow_move,
    shrink_move,
    split_move,
    add_move,
    remove_move,
)

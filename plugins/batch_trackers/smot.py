"""SMOT: tracklets stitched by Hankel-rank dynamics similarity (Dicle, Camps & Sznaier, ICCV 2013).

"The way they move: tracking multiple targets with similar appearance", the SMOT row of Table 1
of Yu et al. 2018. Written fresh from the method's description in
``docs/algorithms/batch-trackers.md#smot``:

1. *Tracklets*: detection ``i`` at ``t`` links to its nearest detection at ``t + 1`` when the
   second-nearest is more than ``ratio`` times farther (with one detection at ``t + 1`` the last
   known second-nearest distance stands in; unknown means no link); a detection claimed twice
   takes no link. Chained links are tracklets (length 1 allowed).
2. *Grow*: a length-1 tracklet adjacent in time to a longer one joins it when the longer one's
   constant-velocity prediction is within ``sqrt(eta_max)`` px (the code compares a *squared*
   distance with ``eta_max``; we keep that quirk).
3. *Three windowed passes* of ``horizon`` frames (offsets 0 and ``horizon // 2``, then windows of
   ``2 * horizon``). Before each window, tracklets of length <= 2 (<= 4 in the third pass) are
   deleted for good. Inside a window the tracklets (cropped to it) are stitched by a generalised
   linear assignment on the similarity until their number stops falling.
4. *Similarity* of ``i -> j`` (``i`` ends before ``j`` starts): with gap ``g``, it needs
   ``0 <= g < max_gap`` (half the mean tracklet length) and a jump speed below twice the largest
   per-frame step inside any tracklet; then ``S = (r_i + r_j) / r_ij - 1`` where ``r`` is the
   rank of the block-Hankel matrix of a trajectory and ``r_ij`` that of ``[x_i, gap, x_j]`` with
   the gap unobserved. ``S < 1e-5`` means no link.
5. *Rank*: the smallest order ``R`` whose structured total least norm fit (HSTLN: corrections
   ``eta`` such that ``u + eta`` obeys one order-``R`` linear recursion, missing samples free)
   has ``||eta * Omega||_F / sum(Omega) < eta_max`` (the code's normalisation, a quirk: not a
   per-sample RMS).
6. Stitched gaps are filled linearly and reported with ``observed = False``.

Boxes and scores are not used: only the detection centres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.stages import StageParams
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections
from trackfw_plugins.maths.assignment import distance_matrix, linear_sum_assignment

_NO_LINK_COST = 1.0e15
_SIMILARITY_FLOOR = 1.0e-5


class SmotParams(StageParams):
    """SMOT settings; defaults of the DETRAC wrapper of the reference code."""

    horizon: int = Field(30, ge=2, description="hor: window length in frames")
    eta_max: float = Field(2.0, gt=0.0, description="inlier noise of the rank test (see quirk)")
    min_similarity: float = Field(
        0.01, gt=0.0, description="min_s: the assignment's slack; weaker links are not made"
    )
    ratio: float = Field(3.0, gt=1.0, description="nearest/second-nearest ratio of a first link")
    hstln_max_iter: int = Field(100, ge=1, description="Gauss-Newton iterations of HSTLN")
    hstln_tol: float = Field(1e-4, gt=0.0, description="HSTLN stops when the step is this small")
    hstln_weight: float = Field(1e8, gt=0.0, description="penalty weight of the Hankel constraint")


@dataclass
class Tracklet:
    """A trajectory piece: ``points`` ``(L, 2)`` from frame ``start``, ``omega`` ``(L,)`` observed."""

    start: int
    points: FloatArray
    omega: BoolArray

    @property
    def end(self) -> int:
        """Last frame."""
        return self.start + len(self.points) - 1

    def crop(self, first: int, last: int) -> Tracklet | None:
        """The part inside frames ``[first, last]``, or None."""
        low, high = max(first, self.start), min(last, self.end)
        if low > high:
            return None
        rows = slice(low - self.start, high - self.start + 1)
        return Tracklet(low, self.points[rows], self.omega[rows])


def join(first: Tracklet, second: Tracklet) -> Tracklet:
    """``first`` then a linear fill over the gap (unobserved) then ``second``."""
    gap = second.start - first.end - 1
    steps = np.arange(1, gap + 1)[:, None] / (gap + 1)
    fill = first.points[-1] + steps * (second.points[0] - first.points[-1])
    return Tracklet(
        first.start,
        np.vstack([first.points, fill, second.points]),
        np.concatenate([first.omega, np.zeros(gap, dtype=bool), second.omega]),
    )


# --- rank by structured total least norm -----------------------------------------------------


def hstln(
    u: FloatArray, omega: BoolArray, order: int, params: SmotParams
) -> tuple[FloatArray, FloatArray]:
    """Smallest masked correction making ``u`` ``(D, N)`` obey one order-``R`` recursion.

    Solves ``min ||Omega * eta||²`` subject to ``H(u + eta)[:, :R] x = H(u + eta)[:, R]`` (the
    block-Hankel matrix of ``R + 1`` columns), as a penalty of weight ``hstln_weight`` by
    Gauss-Newton.

    Returns:
        ``eta`` ``(D, N)`` and the recursion coefficients ``x`` ``(R,)``.
    """
    dims, count = u.shape
    rows = count - order
    weight = params.hstln_weight
    # Flattened index of sample (d, t) is d * N + t; constraint row (t, d) is t * D + d.
    t_index = np.repeat(np.arange(rows), dims)
    d_index = np.tile(np.arange(dims), rows)
    columns = d_index[:, None] * count + t_index[:, None] + np.arange(order + 1)[None, :]
    mask = np.repeat(omega.astype(np.float64)[None, :], dims, axis=0).reshape(-1)
    flat = u.reshape(-1).astype(np.float64)
    eta = np.zeros(dims * count)
    hankel = flat[columns]
    x = np.linalg.lstsq(hankel[:, :order], hankel[:, order], rcond=None)[0]
    row_index = np.arange(rows * dims)
    # Imported here: scipy.linalg would otherwise load with every CLI command (about 0.4 s).
    from scipy.linalg import lstsq

    jacobian = np.zeros((rows * dims + dims * count, dims * count + order))
    jacobian[rows * dims :, : dims * count] = np.diag(mask)
    for _ in range(params.hstln_max_iter):
        hankel = (flat + eta)[columns]
        residual = hankel[:, :order] @ x - hankel[:, order]
        block = jacobian[: rows * dims]
        block[:] = 0.0
        coefficients = np.append(x, -1.0)
        for k in range(order + 1):
            block[row_index, columns[:, k]] = weight * coefficients[k]
        block[:, dims * count :] = weight * hankel[:, :order]
        target = -np.concatenate([weight * residual, mask * eta])
        # QR with column pivoting: several times faster than the SVD driver at these sizes.
        step = lstsq(jacobian, target, lapack_driver="gelsy", check_finite=False)[0]
        eta += step[: dims * count]
        x += step[dims * count :]
        if np.linalg.norm(step) < params.hstln_tol:
            break
    return eta.reshape(dims, count), x


def trajectory_rank(u: FloatArray, omega: BoolArray, params: SmotParams) -> int:
    """Smallest order whose HSTLN fit passes the ``eta_max`` test; ``u`` is ``(D, N)``.

    Orders run from 1 to ``min(ceil(N / (D + 1)) * D, N - ceil(N / (D + 1)) + 1)``; the last
    one is returned when none passes.
    """
    top = _largest_order(u.shape[0], u.shape[1])
    found = first_passing_order(u, omega, params, 1, top)
    return top if found is None else found


def _largest_order(dims: int, count: int) -> int:
    block = math.ceil(count / (dims + 1))
    return max(1, min(block * dims, count - block + 1))


def first_passing_order(
    u: FloatArray, omega: BoolArray, params: SmotParams, low: int, high: int
) -> int | None:
    """The first order in ``[low, high]`` (capped by the block-Hankel size) that passes, or None."""
    observed = max(int(omega.sum()), 1)
    high = min(high, _largest_order(u.shape[0], u.shape[1]))
    for order in range(max(1, low), high + 1):
        if order >= u.shape[1]:
            return order
        eta, _ = hstln(u, omega, order, params)
        if np.linalg.norm(eta * omega[None, :]) / observed < params.eta_max:
            return order
    return None


# --- tracklets --------------------------------------------------------------------------------


def initial_tracklets(detections: VideoDetections, ratio: float) -> list[Tracklet]:
    """Chain unambiguous nearest-neighbour links between consecutive frames (step 1)."""
    bounds = detections.frame_bounds()
    points = detections.points
    successor = np.full(len(detections), -1, dtype=np.int64)
    last_second = math.nan
    for frame in range(detections.n_frames - 1):
        here = np.arange(bounds[frame], bounds[frame + 1])
        there = np.arange(bounds[frame + 1], bounds[frame + 2])
        if len(here) == 0 or len(there) == 0:
            continue
        distances = distance_matrix(points[here], points[there])
        nearest = np.argmin(distances, axis=1)
        first = distances[np.arange(len(here)), nearest]
        if len(there) > 1:
            second = np.partition(distances, 1, axis=1)[:, 1]
            last_second = float(second.min())
        elif math.isnan(last_second):
            continue
        else:
            second = np.full(len(here), last_second)
        with np.errstate(divide="ignore"):
            sure = second > ratio * first
        claimed = np.bincount(nearest[sure], minlength=len(there))
        sure &= claimed[nearest] == 1
        successor[here[sure]] = there[nearest[sure]]
    has_parent = np.zeros(len(detections), dtype=bool)
    has_parent[successor[successor >= 0]] = True
    tracklets = []
    for head in np.flatnonzero(~has_parent).tolist():
        chain = [head]
        while successor[chain[-1]] >= 0:
            chain.append(int(successor[chain[-1]]))
        rows = np.array(chain)
        tracklets.append(
            Tracklet(int(detections.frames[head]), points[rows].copy(), np.ones(len(rows), bool))
        )
    return tracklets


def grow_tracklets(tracklets: list[Tracklet], eta_max: float) -> list[Tracklet]:
    """Attach single detections to adjacent tracklets that predict them (step 2)."""
    changed = True
    while changed:
        changed = False
        singles = [index for index, piece in enumerate(tracklets) if len(piece.points) == 1]
        used: set[int] = set()
        for index, piece in enumerate(tracklets):
            if len(piece.points) < 2 or index in used:
                continue
            for forward in (True, False):
                frame = piece.end + 1 if forward else piece.start - 1
                guess = (
                    2 * piece.points[-1] - piece.points[-2]
                    if forward
                    else 2 * piece.points[0] - piece.points[1]
                )
                candidates = [
                    single
                    for single in singles
                    if single not in used and tracklets[single].start == frame
                ]
                if not candidates:
                    continue
                squared = [float(np.sum((tracklets[c].points[0] - guess) ** 2)) for c in candidates]
                best = int(np.argmin(squared))
                if squared[best] < eta_max:
                    single = tracklets[candidates[best]]
                    piece = join(piece, single) if forward else join(single, piece)
                    tracklets[index] = piece
                    used.add(candidates[best])
                    changed = True
        tracklets = [piece for index, piece in enumerate(tracklets) if index not in used]
    return tracklets


# --- window association -----------------------------------------------------------------------


class _RankCache:
    """Ranks of cropped tracklets, keyed by their content (tracklets change when stitched)."""

    def __init__(self, params: SmotParams) -> None:
        self.params = params
        self.ranks: dict[tuple[int, int, bytes], int] = {}

    def rank(self, piece: Tracklet) -> int:
        key = (piece.start, len(piece.points), piece.points.tobytes())
        if key not in self.ranks:
            self.ranks[key] = trajectory_rank(piece.points.T, piece.omega, self.params)
        return self.ranks[key]


def similarity_matrix(pieces: list[Tracklet], cache: _RankCache) -> FloatArray:
    """``(N, N)`` similarity ``S[i, j]`` of ``i`` followed by ``j``; ``-inf`` = no link."""
    count = len(pieces)
    similarity = np.full((count, count), -np.inf)
    lengths = [len(piece.points) for piece in pieces if len(piece.points) > 1]
    if count < 2 or not lengths:
        return similarity
    max_gap = float(np.mean(lengths)) / 2.0
    max_slope = max(
        (
            float(np.linalg.norm(np.diff(p.points, axis=0), axis=1).max())
            for p in pieces
            if len(p.points) > 1
        ),
        default=0.0,
    )
    for i, first in enumerate(pieces):
        for j, second in enumerate(pieces):
            gap = second.start - first.end - 1
            if gap < 0 or gap >= max_gap:
                continue
            if len(first.points) <= 2 and len(second.points) <= 2:
                continue
            jump = float(np.linalg.norm(second.points[0] - first.points[-1])) / (gap + 1)
            if jump >= 2.0 * max_slope:
                continue
            rank_i, rank_j = cache.rank(first), cache.rank(second)
            joined = join(first, second)
            # A joint order of r_i + r_j or more gives S <= 0 (no link): it is never fitted.
            joint = first_passing_order(
                joined.points.T,
                joined.omega,
                cache.params,
                min(rank_i, rank_j),
                rank_i + rank_j - 1,
            )
            if joint is None:
                continue
            value = (rank_i + rank_j) / joint - 1.0
            if value >= _SIMILARITY_FLOOR:
                similarity[i, j] = value
    return similarity


def generalised_assignment(similarity: FloatArray, min_similarity: float) -> IntArray:
    """Successor of each tracklet (-1 = none) by linear assignment with slack ``-min_s``."""
    count = len(similarity)
    slack = -min_similarity
    cost = np.full((2 * count, 2 * count), slack)
    cost[:count, :count] = np.where(np.isfinite(similarity), -similarity, _NO_LINK_COST)
    rows, columns = linear_sum_assignment(cost)
    successor = np.full(count, -1, dtype=np.int64)
    for row, column in zip(rows.tolist(), columns.tolist(), strict=True):
        if row < count and column < count and np.isfinite(similarity[row, column]):
            successor[row] = column
    return successor


def associate_window(
    tracklets: list[Tracklet], first: int, last: int, cache: _RankCache
) -> list[Tracklet]:
    """Stitch the tracklets inside frames ``[first, last]`` until their number stops falling."""
    while True:
        inside = []
        for index, piece in enumerate(tracklets):
            cropped = piece.crop(first, last)
            if cropped is not None and len(cropped.points) > 2:
                inside.append((index, cropped))
        if len(inside) < 2:
            return tracklets
        similarity = similarity_matrix([cropped for _, cropped in inside], cache)
        successor = generalised_assignment(similarity, cache.params.min_similarity)
        if (successor < 0).all():
            return tracklets
        has_parent = np.zeros(len(inside), dtype=bool)
        has_parent[successor[successor >= 0]] = True
        merged: dict[int, Tracklet] = {}
        consumed: set[int] = set()
        for head in np.flatnonzero(~has_parent).tolist():
            link = int(successor[head])
            if link < 0:
                continue
            chain = tracklets[inside[head][0]]
            while link >= 0:
                chain = join(chain, tracklets[inside[link][0]])
                consumed.add(inside[link][0])
                link = int(successor[link])
            merged[inside[head][0]] = chain
        tracklets = [
            merged.get(index, piece)
            for index, piece in enumerate(tracklets)
            if index not in consumed
        ]


def track_smot(detections: VideoDetections, params: SmotParams | None = None) -> Tracks:
    """Run SMOT over a video.

    Args:
        detections: all detections (only the centres are used).
        params: settings; defaults when None.

    Returns:
        Tracks numbered by first frame; stitched gaps have ``observed = False``.
    """
    params = params or SmotParams()
    tracklets = grow_tracklets(initial_tracklets(detections, params.ratio), params.eta_max)
    cache = _RankCache(params)
    frames = detections.n_frames
    width = params.horizon
    passes = [(0, width, 2), (width // 2, width, 2), (0, 2 * width, 4)]
    for offset, size, shortest in passes:
        for first in range(offset, max(frames, 1), size):
            tracklets = [piece for piece in tracklets if len(piece.points) > shortest]
            tracklets = associate_window(tracklets, first, first + size - 1, cache)
    if not tracklets:
        return Tracks.empty()
    return Tracks(
        np.concatenate([np.full(len(p.points), k) for k, p in enumerate(tracklets)]),
        np.concatenate([np.arange(p.start, p.end + 1) for p in tracklets]),
        np.concatenate([p.points for p in tracklets]),
        np.concatenate([p.omega for p in tracklets]),
    ).renumbered()

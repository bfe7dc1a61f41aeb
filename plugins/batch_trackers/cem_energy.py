"""The continuous energy of CEM (Milan, Roth & Schindler, TPAMI 2014), 2-D, with its gradients.

Written from the equations (the reference code's licence forbids derivative works). The state is
``N`` trajectories on a dense ``(F, N, 2)`` position array with an ``(F, N)`` mask of the frames
each target lives on (one contiguous run per target). ``c`` is the target size (the length scale
of every term). With ``p_i(t)`` the position of target ``i`` on frame ``t`` and ``d_g(t)``,
``s_g`` the detections of frame ``t`` and their scores:

* ``E_det = sum_i sum_t [lambda - sum_g s_g c² / (|p_i(t) - d_g(t)|² + c²)]``;
* ``E_dyn = (1/c) sum_i sum_t |p_i(t-1) - 2 p_i(t) + p_i(t+1)|²`` over the inner frames;
* ``E_exc = sum_t sum_{i != j} c² / |p_i(t) - p_j(t)|²`` (ordered pairs);
* ``E_per = sum_i [s_i > first] sigma(b(p_i(s_i))) + [e_i < last] sigma(b(p_i(e_i)))`` with
  ``sigma(b) = 1 / (1 + exp(1 - b / c))`` and ``b`` the distance to the nearest image border;
* ``E_reg = N + sum_i 1 / length_i`` (no gradient: it only matters to the jump moves).

``E = w_det E_det + w_dyn E_dyn + w_exc E_exc + w_per E_per + w_reg E_reg``, weights 1, 2, 1, 1,
0.5 and ``lambda = 0.1`` by default. See ``docs/algorithms/batch-trackers.md#cem``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw_plugins.batch_trackers.cem_params import CemParams

#: Squared distance below which two targets count as on top of each other (keeps E_exc finite).
_EXCLUSION_FLOOR = 1e-6


@dataclass(frozen=True)
class Scene:
    """What the energy is measured against.

    Attributes:
        detections: ``(F, G, 2)`` detections per frame, padded.
        scores: ``(F, G)`` their scores, 0 on padding.
        width, height: the image (the tracking area is ``[0, width] x [0, height]``).
        target_size: ``c`` in px.
    """

    detections: FloatArray
    scores: FloatArray
    width: float
    height: float
    target_size: float


def detection_energy(
    positions: FloatArray, alive: BoolArray, scene: Scene, existence: float
) -> tuple[float, FloatArray]:
    """``E_det`` and its ``(F, N, 2)`` gradient."""
    c2 = scene.target_size**2
    # x and y apart: (F, N, G) planes are several times faster than (F, N, G, 2) reductions.
    dx = positions[:, :, 0, None] - scene.detections[:, None, :, 0]
    dy = positions[:, :, 1, None] - scene.detections[:, None, :, 1]
    denominator = dx * dx + dy * dy + c2
    attraction = scene.scores[:, None, :] * c2 / denominator
    mask = alive.astype(np.float64)
    energy = float(np.sum(mask * (existence - attraction.sum(axis=2))))
    weight = 2.0 * attraction / denominator
    gradient = np.stack([np.sum(weight * dx, axis=2), np.sum(weight * dy, axis=2)], axis=2)
    return energy, gradient * mask[:, :, None]


def dynamics_energy(
    positions: FloatArray, alive: BoolArray, target_size: float
) -> tuple[float, FloatArray]:
    """``E_dyn`` and its gradient (inner frames of each lifespan only)."""
    gradient = np.zeros_like(positions)
    if len(positions) < 3:
        return 0.0, gradient
    inner = (alive[:-2] & alive[1:-1] & alive[2:])[:, :, None]
    acceleration = (positions[:-2] - 2.0 * positions[1:-1] + positions[2:]) * inner
    energy = float(np.sum(acceleration**2)) / target_size
    scaled = 2.0 * acceleration / target_size
    gradient[:-2] += scaled
    gradient[1:-1] -= 2.0 * scaled
    gradient[2:] += scaled
    return energy, gradient


def exclusion_energy(
    positions: FloatArray, alive: BoolArray, target_size: float
) -> tuple[float, FloatArray]:
    """``E_exc`` over ordered pairs of targets alive on the same frame, and its gradient."""
    c2 = target_size**2
    dx = positions[:, :, 0, None] - positions[:, None, :, 0]  # (F, N, N)
    dy = positions[:, :, 1, None] - positions[:, None, :, 1]
    squared = np.maximum(dx * dx + dy * dy, _EXCLUSION_FLOOR)
    pair = alive[:, :, None] & alive[:, None, :]
    count = positions.shape[1]
    pair &= ~np.eye(count, dtype=bool)[None]
    inverse = np.where(pair, c2 / squared, 0.0)
    energy = float(np.sum(inverse))
    # Each unordered pair is counted twice, so p_i's gradient is twice one term's derivative.
    weight = -4.0 * inverse / squared
    gradient = np.stack([np.sum(weight * dx, axis=2), np.sum(weight * dy, axis=2)], axis=2)
    return energy, gradient


def border_distance(
    points: FloatArray, width: float, height: float
) -> tuple[FloatArray, FloatArray]:
    """Distance ``(P,)`` of ``(P, 2)`` points to the nearest image border, and its gradient."""
    candidates = np.stack(
        [points[:, 0], width - points[:, 0], points[:, 1], height - points[:, 1]], axis=1
    )
    nearest = np.argmin(candidates, axis=1)
    directions = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    return candidates[np.arange(len(points)), nearest], directions[nearest]


@dataclass(frozen=True)
class Lifespans:
    """Which target lives where on an ``(F, K, 2)`` position array.

    Several targets may share a column (a packed array) when at least one dead frame separates
    them, so no dynamics triple spans two of them.

    Attributes:
        columns: ``(N,)`` column of each target.
        starts: ``(N,)`` first frame.
        ends: ``(N,)`` last frame.
        open_ends: ``(N,)`` whether the start, and ``(N,)`` whether the end, is inside the video
            (and so pays persistence); by default a start after the array's first frame and an
            end before its last. A window of a video says so explicitly.
    """

    columns: IntArray
    starts: IntArray
    ends: IntArray
    open_ends: tuple[BoolArray, BoolArray] | None = None

    @classmethod
    def of_columns(cls, alive: BoolArray) -> Lifespans:
        """One target per column that lives on some frame (its first to last alive frame)."""
        columns = np.flatnonzero(alive.any(axis=0))
        frames = len(alive)
        starts = np.argmax(alive[:, columns], axis=0)
        ends = frames - 1 - np.argmax(alive[::-1, columns], axis=0)
        return cls(columns, starts, ends)


def persistence_energy(
    positions: FloatArray, alive: BoolArray, scene: Scene, spans: Lifespans | None = None
) -> tuple[float, FloatArray]:
    """``E_per``: starting or ending away from the border costs up to 1, and its gradient."""
    spans = spans or Lifespans.of_columns(alive)
    gradient = np.zeros_like(positions)
    first, last = spans.open_ends or (spans.starts > 0, spans.ends < len(alive) - 1)
    frames = np.concatenate([spans.starts[first], spans.ends[last]])
    columns = np.concatenate([spans.columns[first], spans.columns[last]])
    if len(frames) == 0:
        return 0.0, gradient
    distance, direction = border_distance(positions[frames, columns], scene.width, scene.height)
    sigma = 1.0 / (1.0 + np.exp(1.0 - distance / scene.target_size))
    slope = (sigma * (1.0 - sigma) / scene.target_size)[:, None] * direction
    np.add.at(gradient, (frames, columns), slope)
    return float(np.sum(sigma)), gradient


def cross_exclusion_energy(
    positions: FloatArray, alive: BoolArray, fixed: tuple[FloatArray, BoolArray], target_size: float
) -> tuple[float, FloatArray]:
    """``E_exc``'s pairs between moving targets and fixed ones (both orders), and its gradient.

    Args:
        positions: ``(F, N, 2)`` the moving targets; ``alive``: ``(F, N)``.
        fixed: ``(F, M, 2)`` positions and ``(F, M)`` alive flags of targets held still.
        target_size: ``c``.

    Returns:
        The energy and its ``(F, N, 2)`` gradient with respect to the moving targets.
    """
    c2 = target_size**2
    others, others_alive = fixed
    dx = positions[:, :, 0, None] - others[:, None, :, 0]  # (F, N, M)
    dy = positions[:, :, 1, None] - others[:, None, :, 1]
    squared = np.maximum(dx * dx + dy * dy, _EXCLUSION_FLOOR)
    inverse = np.where(alive[:, :, None] & others_alive[:, None, :], 2.0 * c2 / squared, 0.0)
    weight = -2.0 * inverse / squared
    gradient = np.stack([np.sum(weight * dx, axis=2), np.sum(weight * dy, axis=2)], axis=2)
    return float(np.sum(inverse)), gradient


def regulariser_energy(alive: BoolArray, spans: Lifespans | None = None) -> float:
    """``E_reg = N + sum_i 1 / length_i`` over the targets alive on some frame."""
    spans = spans or Lifespans.of_columns(alive)
    lengths = (spans.ends - spans.starts + 1).astype(np.float64)
    return float(len(lengths) + np.sum(1.0 / lengths))


def total_energy(
    positions: FloatArray,
    alive: BoolArray,
    scene: Scene,
    params: CemParams,
    spans: Lifespans | None = None,
) -> tuple[float, FloatArray]:
    """``E`` and its ``(F, K, 2)`` gradient (zero where no target is alive).

    ``spans`` says which target lives where when columns are shared; by default each column is
    one target.
    """
    spans = spans or Lifespans.of_columns(alive)
    det, det_gradient = detection_energy(positions, alive, scene, params.existence)
    dyn, dyn_gradient = dynamics_energy(positions, alive, scene.target_size)
    exc, exc_gradient = exclusion_energy(positions, alive, scene.target_size)
    per, per_gradient = persistence_energy(positions, alive, scene, spans)
    energy = (
        params.detection_weight * det
        + params.dynamics_weight * dyn
        + params.exclusion_weight * exc
        + params.persistence_weight * per
        + params.regulariser_weight * regulariser_energy(alive, spans)
    )
    gradient = (
        params.detection_weight * det_gradient
        + params.dynamics_weight * dyn_gradient
        + params.exclusion_weight * exc_gradient
        + params.persistence_weight * per_gradient
    )
    return energy, gradient * alive[:, :, None]


@dataclass(frozen=True)
class FrameTerms:
    """One target's share of ``E`` split by frame, so that any cut of it costs a few sums.

    The share is everything a change of this target alone changes: its own detection, dynamics,
    persistence and regulariser terms and *both* ordered exclusion pairs with every other target.

    Attributes:
        start: the target's first frame.
        points: ``(L, 2)`` its positions.
        local: ``(L,)`` weighted detection plus exclusion cost of each frame.
        bend: ``(L,)`` weighted dynamics cost of each frame as the middle of three (0 at the ends).
    """

    start: int
    points: FloatArray
    local: FloatArray
    bend: FloatArray


def target_terms(
    start: int,
    points: FloatArray,
    others: tuple[FloatArray, BoolArray],
    scene: Scene,
    params: CemParams,
) -> FrameTerms:
    """The frame terms of a trajectory on frames ``start .. start + L - 1``.

    Args:
        start: first frame.
        points: ``(L, 2)`` positions.
        others: ``(L, M, 2)`` positions and ``(L, M)`` alive flags of the other targets on the
            same frames.
        scene: detections and image.
        params: the term weights and the existence cost.
    """
    count = len(points)
    frames = slice(start, start + count)
    local = frame_costs(
        points, (scene.detections[frames], scene.scores[frames]), others, scene, params
    )
    bend = np.zeros(count)
    if count >= 3:
        acceleration = points[:-2] - 2.0 * points[1:-1] + points[2:]
        bend[1:-1] = params.dynamics_weight * np.sum(acceleration**2, axis=1) / scene.target_size
    return FrameTerms(start, points, local, bend)


def frame_costs(
    points: FloatArray,
    detections: tuple[FloatArray, FloatArray],
    others: tuple[FloatArray, BoolArray],
    scene: Scene,
    params: CemParams,
) -> FloatArray:
    """Weighted detection plus exclusion cost of positions, each on its own frame.

    Args:
        points: ``(..., 2)`` positions.
        detections: ``(..., G, 2)`` the detections of each position's frame and ``(..., G)``
            their scores.
        others: ``(..., M, 2)`` the other targets on each position's frame and ``(..., M)`` their
            alive flags.
        scene: the target size.
        params: the term weights and the existence cost.

    Returns:
        ``(...)`` costs: ``w_det (lambda - attraction) + w_exc 2 sum_j c² / d_j²``.
    """
    c2 = scene.target_size**2
    near, scores = detections
    difference = points[..., None, :] - near
    squared = np.einsum("...gk,...gk->...g", difference, difference)
    detection = params.existence - np.sum(scores * c2 / (squared + c2), axis=-1)
    positions, alive = others
    apart = points[..., None, :] - positions
    distance = np.maximum(np.einsum("...mk,...mk->...m", apart, apart), _EXCLUSION_FLOOR)
    exclusion = 2.0 * np.sum(np.where(alive, c2 / distance, 0.0), axis=-1)
    return params.detection_weight * detection + params.exclusion_weight * exclusion


def range_energies(
    terms: FrameTerms,
    lows: IntArray,
    highs: IntArray,
    scene: Scene,
    params: CemParams,
    n_frames: int,
) -> FloatArray:
    """``(R,)`` share of ``E`` of the target cut to points ``lows[r] .. highs[r]`` (inclusive).

    The cut's ends become its lifespan ends: their dynamics terms drop out, and the persistence
    term is taken there (unless the cut starts on the video's first frame or ends on its last).
    """
    lows = np.asarray(lows, dtype=np.int64)
    highs = np.asarray(highs, dtype=np.int64)
    local = np.concatenate([[0.0], np.cumsum(terms.local)])
    bend = np.concatenate([[0.0], np.cumsum(terms.bend)])
    energy = local[highs + 1] - local[lows]
    energy += np.where(highs - lows >= 2, bend[np.maximum(highs, lows + 1)] - bend[lows + 1], 0.0)
    first, last = terms.points[lows], terms.points[highs]
    inside = (terms.start + lows > 0, terms.start + highs < n_frames - 1)
    return energy + end_costs((first, last), inside, highs - lows + 1, scene, params)


def end_costs(
    ends: tuple[FloatArray, FloatArray],
    inside: tuple[BoolArray, BoolArray],
    lengths: IntArray,
    scene: Scene,
    params: CemParams,
) -> FloatArray:
    """``(R,)`` weighted persistence and regulariser shares of ``R`` trajectories.

    Args:
        ends: ``(R, 2)`` first and ``(R, 2)`` last positions.
        inside: ``(R,)`` whether each starts after the first frame, and ends before the last.
        lengths: ``(R,)`` numbers of frames.
        scene: image and target size.
        params: the term weights and the existence cost.
    """
    energy = params.regulariser_weight * (1.0 + 1.0 / np.asarray(lengths, dtype=np.float64))
    for points, counts in zip(ends, inside, strict=True):
        distance, _ = border_distance(points, scene.width, scene.height)
        sigma = 1.0 / (1.0 + np.exp(1.0 - distance / scene.target_size))
        energy = energy + params.persistence_weight * np.where(counts, sigma, 0.0)
    return energy

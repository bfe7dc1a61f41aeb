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

from trackfw.arrays import BoolArray, FloatArray

#: Squared distance below which two targets count as on top of each other (keeps E_exc finite).
_EXCLUSION_FLOOR = 1e-6


@dataclass(frozen=True)
class EnergyWeights:
    """Weights of the five terms and the per-frame existence cost ``lambda``."""

    detection: float = 1.0
    dynamics: float = 2.0
    exclusion: float = 1.0
    persistence: float = 1.0
    regulariser: float = 0.5
    existence: float = 0.1


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
    difference = positions[:, :, None, :] - scene.detections[:, None, :, :]  # (F, N, G, 2)
    denominator = np.einsum("fngk,fngk->fng", difference, difference) + c2
    attraction = scene.scores[:, None, :] * c2 / denominator
    mask = alive.astype(np.float64)
    energy = float(np.sum(mask * (existence - attraction.sum(axis=2))))
    weight = 2.0 * scene.scores[:, None, :] * c2 / denominator**2
    gradient = np.einsum("fng,fngk->fnk", weight, difference) * mask[:, :, None]
    return energy, gradient


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
    difference = positions[:, :, None, :] - positions[:, None, :, :]  # (F, N, N, 2)
    squared = np.maximum(np.einsum("fijk,fijk->fij", difference, difference), _EXCLUSION_FLOOR)
    pair = alive[:, :, None] & alive[:, None, :]
    count = positions.shape[1]
    pair &= ~np.eye(count, dtype=bool)[None]
    energy = float(np.sum(np.where(pair, c2 / squared, 0.0)))
    # Each unordered pair is counted twice, so p_i's gradient is twice one term's derivative.
    weight = np.where(pair, -4.0 * c2 / squared**2, 0.0)
    gradient = np.einsum("fij,fijk->fik", weight, difference)
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


def persistence_energy(
    positions: FloatArray, alive: BoolArray, scene: Scene
) -> tuple[float, FloatArray]:
    """``E_per``: starting or ending away from the border costs up to 1, and its gradient."""
    gradient = np.zeros_like(positions)
    frames, _ = alive.shape
    energy = 0.0
    for target in np.flatnonzero(alive.any(axis=0)).tolist():
        lives = np.flatnonzero(alive[:, target])
        for frame, counts in (
            (int(lives[0]), lives[0] > 0),
            (int(lives[-1]), lives[-1] < frames - 1),
        ):
            if not counts:
                continue
            distance, direction = border_distance(
                positions[frame, target][None], scene.width, scene.height
            )
            sigma = 1.0 / (1.0 + np.exp(1.0 - distance[0] / scene.target_size))
            energy += float(sigma)
            gradient[frame, target] += sigma * (1.0 - sigma) / scene.target_size * direction[0]
    return energy, gradient


def regulariser_energy(alive: BoolArray) -> float:
    """``E_reg = N + sum_i 1 / length_i`` over the targets alive on some frame."""
    lengths = alive.sum(axis=0)
    lengths = lengths[lengths > 0]
    return float(len(lengths) + np.sum(1.0 / lengths))


def total_energy(
    positions: FloatArray, alive: BoolArray, scene: Scene, weights: EnergyWeights
) -> tuple[float, FloatArray]:
    """``E`` and its ``(F, N, 2)`` gradient (zero where a target is not alive)."""
    det, det_gradient = detection_energy(positions, alive, scene, weights.existence)
    dyn, dyn_gradient = dynamics_energy(positions, alive, scene.target_size)
    exc, exc_gradient = exclusion_energy(positions, alive, scene.target_size)
    per, per_gradient = persistence_energy(positions, alive, scene)
    energy = (
        weights.detection * det
        + weights.dynamics * dyn
        + weights.exclusion * exc
        + weights.persistence * per
        + weights.regulariser * regulariser_energy(alive)
    )
    gradient = (
        weights.detection * det_gradient
        + weights.dynamics * dyn_gradient
        + weights.exclusion * exc_gradient
        + weights.persistence * per_gradient
    )
    return energy, gradient * alive[:, :, None]

"""Gated association of a *positioned* candidate: one whose place on frame b is known.

See docs/algorithms/gap-matchers.md#positioned-candidates.

The AR candidates keep the image geometry of frame a, so window TPS-RPM has to find their
pattern anywhere on b. A candidate carried through a scene registration, or the Kalman
prediction when the camera barely moved, is already in frame-b pixels up to an error of a known
size (its gate). Its detections are found by a gated Hungarian assignment on distance (repeated
once after removing the common offset of the matched pairs), and it is scored with the window
cost ψ = φ + λ1 (|U| − d) + λ2 E_a, so that all candidates compete in one cost.
"""

from __future__ import annotations

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw_plugins.maths.assignment import distance_matrix, hungarian
from trackfw_plugins.maths.thin_plate import homogeneous
from trackfw_plugins.maths.tps_rpm_template import (
    TpsRpmTemplate,
    normalise_points,
    paper_temperatures,
)
from trackfw_plugins.maths.window_association import (
    WindowAssociationParams,
    WindowAssociationResult,
    WindowDiagnostics,
)


def tolerance(predicted: FloatArray, gate: float) -> float:
    """Residual tolerance r: half the median nearest-neighbour spacing of U, at most the gate.

    A pair further than r from its shifted prediction would be closer to a neighbour's place.
    """
    if predicted.shape[0] < 2:
        return gate
    spacing = distance_matrix(predicted, predicted)
    np.fill_diagonal(spacing, np.inf)
    return float(min(gate, 0.5 * np.median(spacing.min(axis=1))))


def common_offset(predicted: FloatArray, detections: FloatArray, gate: float) -> FloatArray:
    """``(2,)`` shift of U, at most ``gate`` long, that brings the most targets within r of a
    detection (shorter shifts win ties), refined by the median offset of those pairs.

    Every offset v_j − u_i within the gate is tried (K·N of them), so a group whose motion over
    the interval the prediction got wrong by a common amount is found all the same.
    """
    radius = tolerance(predicted, gate)
    offsets = (detections[None, :, :] - predicted[:, None, :]).reshape(-1, 2)
    offsets = offsets[np.linalg.norm(offsets, axis=1) <= gate]
    if offsets.size == 0:
        return np.zeros(2)
    # (O, K, N) distances of each shifted prediction to each detection.
    shifted = predicted[None, :, None, :] + offsets[:, None, None, :]
    near = np.linalg.norm(shifted - detections[None, None, :, :], axis=3) <= radius
    support = near.any(axis=2).sum(axis=1)
    order = np.lexsort((np.linalg.norm(offsets, axis=1), -support))
    best = offsets[order[0]]
    rows, columns = np.nonzero(near[order[0]])
    return np.median(detections[columns] - predicted[rows], axis=0) if rows.size else best


def gated_matches(predicted: FloatArray, detections: FloatArray, gate: float) -> IntArray:
    """``(K,)`` detection row per target (``-1`` when none), after removing the common offset.

    Hungarian on the distances to U moved by :func:`common_offset`, pairs beyond the residual
    tolerance r (:func:`tolerance`) forbidden.
    """
    shift = common_offset(predicted, detections, gate)
    return hungarian(distance_matrix(predicted + shift, detections), tolerance(predicted, gate))


def bending_of_pairs(
    predicted: FloatArray, targets: FloatArray, params: WindowAssociationParams
) -> float:
    """φ of the regularised TPS from U onto ``targets``, as TPS-RPM reports it.

    Both sets are normalised separately and the regulariser is TPS-RPM's at its final
    temperature, so φ is on the same scale as the window candidates' bending energy.
    """
    if predicted.shape[0] <= 3:
        return 0.0
    template = TpsRpmTemplate(predicted, params.rpm)
    data, _, _ = normalise_points(targets, params.rpm.rms_radius)
    final = paper_temperatures(template.normalised, data, params.rpm.anneal_rate)[-1]
    factor = predicted.shape[0] * final
    bending, _, _ = template.basis.linear_operators(
        np.array([params.rpm.lamda1_init * factor]), np.array([params.rpm.lamda2_init * factor])
    )
    warp = (bending[0] @ homogeneous(data))[:, 1:3]
    return float(max(np.einsum("ki,kj,ji->", warp, template.basis.kernel, warp), 0.0))


def associate_gated(
    predicted: FloatArray,
    detections: FloatArray,
    gate: float,
    appearance: FloatArray | None,
    params: WindowAssociationParams,
    lambda3: float = 0.0,
) -> tuple[WindowAssociationResult, float]:
    """Associate a positioned candidate U ``(K, 2)`` with V ``(N, 2)`` inside ``gate`` pixels.

    Matched targets go to their detection; unmatched ones to their prediction moved by the
    matched pairs' median offset. Fewer than ``min_matches`` pairs (capped at K) make the cost
    infinite: the candidate cannot win.

    Returns:
        The result, whose cost is ψ + ``lambda3`` · E_p, and E_p: the mean over the matched
        pairs of min(distance to the prediction / gate, 1) (1 without pairs). A free candidate
        has no position evidence and counts E_p = 1.
    """
    predicted = np.asarray(predicted, dtype=np.float64).reshape(-1, 2)
    detections = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
    count = predicted.shape[0]
    matched = gated_matches(predicted, detections, gate)
    pairs = matched >= 0
    shift = np.median(detections[matched[pairs]] - predicted[pairs], axis=0) if pairs.any() else 0.0
    positions = predicted + shift
    positions[pairs] = detections[matched[pairs]]
    found = int(pairs.sum())
    energy = (
        float(appearance[pairs, matched[pairs]].mean()) if appearance is not None and found else 0.0
    )
    bending = bending_of_pairs(predicted, positions, params) if found else 0.0
    distances = np.linalg.norm(positions[pairs] - predicted[pairs], axis=1)
    evidence = float(np.minimum(distances / gate, 1.0).mean()) if found else 1.0
    cost = bending + params.lambda1 * (count - found) + params.lambda2 * energy + lambda3 * evidence
    if found < min(params.min_matches, count) or count == 0:
        cost = float("inf")
    result = WindowAssociationResult(
        positions=positions,
        matched_detection=matched,
        cost=float(cost),
        bending=bending,
        unmatched=count - found,
        appearance=energy,
        window=np.sort(matched[pairs]),
        diagnostics=WindowDiagnostics(window_rule="gated"),
    )
    return result, evidence


__all__ = ["associate_gated", "bending_of_pairs", "gated_matches"]

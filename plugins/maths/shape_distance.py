"""Shape distance Δ ∈ [0, 1] between the convex hulls of two point sets.

See docs/algorithms/gap-matchers.md#hull-shape-distance.

Default ``"shape_context"`` (Belongie, Malik & Puzicha 2002): both hull boundaries are resampled
to 32 points by arc length, every sample gets a 5 × 12 log-polar histogram of the others, the χ²
cost between histograms is matched one-to-one (Hungarian) and Δ is the mean matched cost.
Options: ``"hu"`` (Hu moments through ``cv2.matchShapes``, mapped by d / (1 + d)) and
``"procrustes"`` (least standardised Procrustes dissimilarity over cyclic shifts and both
orientations).

The window association calls this on ~1000 hulls per gap against one template hull, so
:class:`HullShapeMatcher` computes the template descriptor once and the descriptors of many
hulls in one vectorised pass.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import cv2
import numpy as np
from pydantic import ConfigDict, Field

from trackfw.arrays import FloatArray
from trackfw.stages import FiniteModel
from trackfw_plugins.maths.assignment import linear_sum_assignment

_AREA_EPSILON = 1e-9
_CHUNK = 64


class ShapeDistanceSettings(FiniteModel):
    """Parameters of Δ (``shape`` of the window association)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: Literal["shape_context", "hu", "procrustes"] = Field(
        "shape_context", description="Shape distance between two convex hulls."
    )
    n_samples: int = Field(32, ge=3, description="Points resampled along each hull boundary.")
    r_bins: int = Field(5, ge=1, description="Log-radial bins of the shape context.")
    theta_bins: int = Field(12, ge=1, description="Angular bins of the shape context.")
    r_inner: float = Field(0.125, gt=0, description="Inner radial edge / mean pair distance.")
    r_outer: float = Field(2.0, gt=0, description="Outer radial edge / mean pair distance.")
    rotation_invariant: bool = Field(
        False, description="Measure angles relative to the local hull tangent."
    )


def hull_polygon(points: FloatArray) -> FloatArray:
    """Convex hull of a small point set as a closed polygon (vertices in order, not repeated).

    Degenerate sets (fewer than 3 points, or collinear) give the points ordered along their
    main direction: resampling then walks the segment out and back.

    Args:
        points: (P, 2) points.

    Returns:
        (H, 2) polygon vertices, H >= 1 (H = 0 only for an empty input).

    >>> hull_polygon(np.array([[0.0, 0], [2, 0], [1, 1], [1, 0.5]])).shape
    (3, 2)
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] >= 3:
        scale = float(np.ptp(points, axis=0).max())
        if scale > 0:
            indices = cv2.convexHull(
                ((points - points.min(axis=0)) / scale).astype(np.float32), returnPoints=False
            ).ravel()
            polygon = points[indices]
            if polygon.shape[0] >= 3 and _polygon_area(polygon) > _AREA_EPSILON * scale * scale:
                return polygon
    if points.shape[0] <= 1:
        return points.copy()
    centred = points - points.mean(axis=0)
    _, _, direction = np.linalg.svd(centred, full_matrices=False)
    axis = direction[0]
    # SVD's sign is arbitrary; fix it so the order is reproducible.
    if axis[0] < 0 or (axis[0] == 0 and axis[1] < 0):
        axis = -axis
    order = np.argsort(centred @ axis, kind="stable")
    return points[order]


def _polygon_area(polygon: FloatArray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def resample_closed(polygon: FloatArray, n_samples: int = 32) -> FloatArray:
    """Points evenly spaced by arc length along a closed polygon, starting at its first vertex.

    Args:
        polygon: (H, 2) vertices (the closing edge back to the first vertex is implied).
        n_samples: number of samples S.

    Returns:
        (S, 2) samples; a single point (or zero-length polygon) repeats that point.

    >>> resample_closed(np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]), 4).tolist()
    [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    """
    polygon = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    closed = np.vstack([polygon, polygon[:1]])
    lengths = np.sqrt(np.sum(np.diff(closed, axis=0) ** 2, axis=1))
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    total = cumulative[-1]
    if total <= 0:
        return np.repeat(polygon[:1], n_samples, axis=0)
    positions = np.arange(n_samples) * (total / n_samples)
    return np.stack(
        [
            np.interp(positions, cumulative, closed[:, 0]),
            np.interp(positions, cumulative, closed[:, 1]),
        ],
        axis=1,
    )


def shape_context_descriptors(samples: FloatArray, settings: ShapeDistanceSettings) -> FloatArray:
    """Log-polar shape-context histograms of many sampled contours at once.

    Args:
        samples: (M, S, 2) contour samples (in boundary order).
        settings: bins and radii.

    Returns:
        (M, S, r_bins * theta_bins) histograms, each summing to 1 (or all 0 when no other sample
        falls inside the radial range).
    """
    samples = np.asarray(samples, dtype=np.float64)
    sets, count, _ = samples.shape
    bins = settings.r_bins * settings.theta_bins
    histograms = np.zeros((sets, count, bins))
    # Chunks keep the (m, S, S) temporaries in cache; squared radii are binned against squared
    # log-spaced edges, which avoids a log per pair.
    edges = settings.r_inner * (settings.r_outer / settings.r_inner) ** (
        np.arange(settings.r_bins + 1) / settings.r_bins
    )
    squared_edges = edges**2
    off_diagonal = ~np.eye(count, dtype=bool)
    angle_scale = settings.theta_bins / (2 * np.pi)
    for start in range(0, sets, _CHUNK):
        chunk = samples[start : start + _CHUNK]
        size = chunk.shape[0]
        delta_x = chunk[:, None, :, 0] - chunk[:, :, None, 0]  # (m, S, S): from i to j
        delta_y = chunk[:, None, :, 1] - chunk[:, :, None, 1]
        squared = delta_x * delta_x + delta_y * delta_y
        mean_distance = np.sqrt(squared).sum(axis=(1, 2)) / max(count * (count - 1), 1)
        safe_mean = np.where(mean_distance > 0, mean_distance, 1.0)
        relative = squared / (safe_mean * safe_mean)[:, None, None]
        radial = np.searchsorted(squared_edges, relative, side="right") - 1
        angle = np.arctan2(delta_y, delta_x)
        if settings.rotation_invariant:
            tangent = np.roll(chunk, -1, axis=1) - np.roll(chunk, 1, axis=1)
            angle = angle - np.arctan2(tangent[..., 1], tangent[..., 0])[:, :, None]
        angular = np.minimum(
            np.floor(np.mod(angle, 2 * np.pi) * angle_scale), settings.theta_bins - 1
        ).astype(np.int64)
        valid = (
            (radial >= 0)
            & (radial < settings.r_bins)
            & off_diagonal[None]
            & (mean_distance > 0)[:, None, None]
        )
        row = np.arange(size * count).reshape(size, count, 1)
        flat = (row * bins + radial * settings.theta_bins + angular)[valid]
        counts = np.bincount(flat, minlength=size * count * bins).reshape(size, count, bins)
        histograms[start : start + size] = counts
    totals = histograms.sum(axis=2, keepdims=True)
    return np.divide(histograms, totals, out=np.zeros_like(histograms), where=totals > 0)


def chi_square_costs(reference: FloatArray, others: FloatArray) -> FloatArray:
    """χ² costs ½ Σ_k (g−h)²/(g+h) between one set of histograms and many.

    Uses (g−h)²/(g+h) = (g+h) − 4gh/(g+h), and only the reference's non-zero bins can make the
    second term non-zero, so the work is proportional to those bins.

    Args:
        reference: (S, B) histograms h_j.
        others: (M, S', B) histograms g_i.

    Returns:
        (M, S', S) costs C_ij in [0, 1].
    """
    sets = others.shape[0]
    rows, columns = np.nonzero(reference > 0)
    values = reference[rows, columns]
    starts = np.searchsorted(rows, np.arange(reference.shape[0]))
    present = np.bincount(rows, minlength=reference.shape[0]) > 0
    reference_sum = reference.sum(axis=1)
    others_sum = others.sum(axis=2)
    costs = 0.5 * (others_sum[:, :, None] + reference_sum[None, None, :])
    if values.size == 0:
        return costs
    for start in range(0, sets, _CHUNK):
        chunk = others[start : start + _CHUNK][:, :, columns]  # (m, S', L)
        harmonic = chunk * values / (chunk + values)
        sums = np.add.reduceat(harmonic, starts[present], axis=2)
        costs[start : start + _CHUNK][:, :, present] -= 2.0 * sums
    return np.clip(costs, 0.0, 1.0)


def _assignment_means(costs: FloatArray) -> FloatArray:
    result = np.empty(costs.shape[0])
    for index, matrix in enumerate(costs):
        row, column = linear_sum_assignment(matrix)
        result[index] = matrix[row, column].mean()
    return result


def _procrustes_distances(reference: FloatArray, others: FloatArray) -> FloatArray:
    """Least standardised Procrustes dissimilarity over cyclic shifts and both orientations."""

    def standardise(points: FloatArray) -> FloatArray:
        centred = points - points.mean(axis=-2, keepdims=True)
        norm = np.sqrt(np.sum(centred**2, axis=(-2, -1), keepdims=True))
        return np.divide(centred, norm, out=np.zeros_like(centred), where=norm > 0)

    reference = standardise(reference)
    count = reference.shape[0]
    variants = []
    for flipped in (reference, reference[::-1]):
        for shift in range(count):
            variants.append(np.roll(flipped, shift, axis=0))
    candidates = np.stack(variants)  # (2S, S, 2)
    others = standardise(others)
    # Orthogonal Procrustes (reflections allowed, as scipy.spatial.procrustes): the best fit
    # leaves 1 − (Σ singular values of Aᵀ B)² for unit-norm centred A and B.
    cross = np.einsum("vsi,msj->mvij", candidates, others)
    singular = np.linalg.svd(cross, compute_uv=False).sum(axis=-1)
    return np.clip(1.0 - singular.max(axis=1) ** 2, 0.0, 1.0)


def _hu_distance(polygon_a: FloatArray, polygon_b: FloatArray) -> float:
    value = cv2.matchShapes(
        polygon_a.astype(np.float32).reshape(-1, 1, 2),
        polygon_b.astype(np.float32).reshape(-1, 1, 2),
        cv2.CONTOURS_MATCH_I1,
        0,
    )
    if not np.isfinite(value):
        return 1.0
    return float(value / (1.0 + value))


class HullShapeMatcher:
    """Δ between one fixed point set's hull and the hulls of many others.

    Args:
        template_points: (K, 2) points whose hull is the reference shape.
        settings: Δ settings.
    """

    def __init__(
        self, template_points: FloatArray, settings: ShapeDistanceSettings | None = None
    ) -> None:
        self.settings = settings if settings is not None else ShapeDistanceSettings()
        self.polygon = hull_polygon(template_points)
        self.samples = resample_closed(self.polygon, self.settings.n_samples)
        self.descriptor = (
            shape_context_descriptors(self.samples[None], self.settings)[0]
            if self.settings.method == "shape_context"
            else np.zeros((0, 0))
        )

    def distances(self, point_sets: Sequence[FloatArray]) -> FloatArray:
        """Δ to each point set's hull.

        Args:
            point_sets: M arrays of shape (P_i, 2).

        Returns:
            (M,) distances in [0, 1].
        """
        polygons = [hull_polygon(points) for points in point_sets]
        return self.distances_to_polygons(polygons)

    def distances_to_polygons(self, polygons: Sequence[FloatArray]) -> FloatArray:
        """Δ to each hull polygon (as returned by :func:`hull_polygon`); returns (M,)."""
        if len(polygons) == 0:
            return np.zeros(0)
        if self.settings.method == "hu":
            return np.array([_hu_distance(self.polygon, polygon) for polygon in polygons])
        samples = np.stack(
            [resample_closed(polygon, self.settings.n_samples) for polygon in polygons]
        )
        if self.settings.method == "procrustes":
            return _procrustes_distances(self.samples, samples)
        descriptors = shape_context_descriptors(samples, self.settings)
        return _assignment_means(chi_square_costs(self.descriptor, descriptors))


def shape_distance(
    points_a: FloatArray, points_b: FloatArray, settings: ShapeDistanceSettings | None = None
) -> float:
    """Δ(C_A, C_B) between the convex hulls of two point sets, in [0, 1].

    >>> square = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> round(shape_distance(square, 3 * square + 5), 12)
    0.0
    """
    return float(HullShapeMatcher(points_a, settings).distances([points_b])[0])

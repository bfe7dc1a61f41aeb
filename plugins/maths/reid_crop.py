"""Crops and distances for the LOMO / GOG re-ID baselines.

See docs/algorithms/gap-matchers.md#re-identification.

Re-ID descriptors expect a full-body box, but the tracker only knows a head point. The body crop
[x − 0.75s, y − 0.5s, 1.5s × 4s] with s = 80·H/1080 is resized to 128×48 (height × width); the
``"head80"`` option uses the s×s head patch resized to 80×80 instead. Without training data the
distance is Euclidean after mean subtraction (pooled over the interval) and L2 normalisation;
XQDA self-trained on the pre-interval segment is an option.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from trackfw.arrays import FloatArray
from trackfw_plugins.maths.appearance import crop_replicate

CropMode = Literal["body", "head80"]

#: Head size at 1080p (paper's 80-px head box) and the body crop size the descriptors expect.
HEAD_SIZE_AT_1080 = 80.0
BODY_CROP_SHAPE = (128, 48)
HEAD_CROP_SHAPE = (80, 80)


def head_size(frame_height: int) -> float:
    """Head size s in pixels for a frame of the given height.

    >>> head_size(1080), head_size(720)
    (80.0, 53.333333333333336)
    """
    return HEAD_SIZE_AT_1080 * frame_height / 1080.0


def crop_box(
    image: NDArray[np.uint8],
    left: float,
    top: float,
    width: float,
    height: float,
    output_shape: tuple[int, int],
    angle: float = 0.0,
) -> NDArray[np.uint8]:
    """Crop a box with replicated borders and resize it to ``output_shape`` (rows, columns).

    With ``angle`` (degrees, counter-clockwise, OpenCV's sign) the box is cut from the image
    turned about the box's centre, in one bilinear warp: a person leaning with a rolled camera
    is cut upright.
    """
    if angle != 0.0:
        return _turned_crop(
            image, (left, top, max(1.0, width), max(1.0, height)), output_shape, angle
        )
    left_pixel, top_pixel = round(left), round(top)
    width_pixels, height_pixels = max(1, round(width)), max(1, round(height))
    crop = np.ascontiguousarray(
        crop_replicate(image, left_pixel, top_pixel, width_pixels, height_pixels), dtype=np.uint8
    )
    rows, columns = output_shape
    if (height_pixels, width_pixels) == (rows, columns):
        return crop
    shrinking = height_pixels * width_pixels > rows * columns
    interpolation = cv2.INTER_AREA if shrinking else cv2.INTER_LINEAR
    return np.ascontiguousarray(
        cv2.resize(crop, (columns, rows), interpolation=interpolation), dtype=np.uint8
    )


def turned_box_transform(
    box: tuple[float, float, float, float], output_shape: tuple[int, int], angle: float
) -> FloatArray:
    """``(2, 3)`` affine map from image pixels to the crop of ``box`` (left, top, width, height)
    cut from the image turned by ``angle`` degrees (counter-clockwise, OpenCV's sign) about the
    box's centre.

    >>> m = turned_box_transform((10.0, 20.0, 4.0, 8.0), (8, 4), 90.0)
    >>> (m @ [12.0, 24.0, 1.0]).round(6).tolist()  # the centre stays the crop's centre
    [2.0, 4.0]
    """
    left, top, width, height = box
    rows, columns = output_shape
    centre = (left + width / 2.0, top + height / 2.0)
    turn = np.vstack([cv2.getRotationMatrix2D(centre, angle, 1.0), [0.0, 0.0, 1.0]])
    to_crop = np.array(
        [
            [columns / width, 0.0, -left * columns / width],
            [0.0, rows / height, -top * rows / height],
        ]
    )
    return np.asarray(to_crop @ turn, dtype=np.float64)


def _turned_crop(
    image: NDArray[np.uint8],
    box: tuple[float, float, float, float],
    output_shape: tuple[int, int],
    angle: float,
) -> NDArray[np.uint8]:
    """:func:`crop_box` of ``box`` (left, top, width, height) turned by ``angle`` degrees."""
    rows, columns = output_shape
    crop = cv2.warpAffine(
        image,
        turned_box_transform(box, output_shape, angle),
        (columns, rows),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.ascontiguousarray(crop, dtype=np.uint8)


def reid_crop(
    image: NDArray[np.uint8], head_point: ArrayLike, mode: CropMode = "body"
) -> NDArray[np.uint8]:
    """Re-ID input crop around a head point.

    Args:
        image: ``(H, W, 3)`` uint8 BGR frame.
        head_point: ``(2,)`` head centre (x, y).
        mode: ``"body"`` (128×48 body box below the head) or ``"head80"`` (80×80 head patch).

    Returns:
        ``(128, 48, 3)`` or ``(80, 80, 3)`` uint8 BGR crop.

    >>> frame = np.zeros((1080, 1920, 3), dtype=np.uint8)
    >>> reid_crop(frame, (5.0, 1070.0)).shape, reid_crop(frame, (5.0, 5.0), "head80").shape
    ((128, 48, 3), (80, 80, 3))
    """
    x, y = np.asarray(head_point, dtype=np.float64).reshape(2)
    size = head_size(image.shape[0])
    if mode == "body":
        return crop_box(
            image, x - 0.75 * size, y - 0.5 * size, 1.5 * size, 4.0 * size, BODY_CROP_SHAPE
        )
    if mode == "head80":
        return crop_box(image, x - 0.5 * size, y - 0.5 * size, size, size, HEAD_CROP_SHAPE)
    raise ValueError(f"unknown re-ID crop mode {mode!r}; expected 'body' or 'head80'")


def reid_crops(
    image: NDArray[np.uint8], head_points: ArrayLike, mode: CropMode = "body"
) -> NDArray[np.uint8]:
    """Crops for ``(P, 2)`` head points -> ``(P, h, w, 3)`` uint8."""
    points = np.asarray(head_points, dtype=np.float64).reshape(-1, 2)
    shape = BODY_CROP_SHAPE if mode == "body" else HEAD_CROP_SHAPE
    if len(points) == 0:
        return np.zeros((0, *shape, 3), dtype=np.uint8)
    return np.stack([reid_crop(image, point, mode) for point in points])


def normalise_pooled(
    query: ArrayLike, gallery: ArrayLike, block_sizes: Sequence[int] | None = None
) -> tuple[FloatArray, FloatArray]:
    """Subtract the mean of the pooled query + gallery descriptors, then L2 per block.

    Args:
        query: ``(K, D)`` descriptors (targets at a).
        gallery: ``(N, D)`` descriptors (detections at b).
        block_sizes: lengths of blocks normalised separately (GOG: one per colour space);
            None normalises the whole vector (LOMO).

    Returns:
        The normalised ``(K, D)`` and ``(N, D)`` descriptors.
    """
    first = np.asarray(query, dtype=np.float64)
    second = np.asarray(gallery, dtype=np.float64)
    first = first.reshape(len(first), -1)
    second = second.reshape(len(second), -1)
    pooled = np.vstack([first, second])
    if pooled.shape[0] == 0:
        return first, second
    sizes = tuple(block_sizes) if block_sizes is not None else (pooled.shape[1],)
    if sum(sizes) != pooled.shape[1]:
        raise ValueError(f"descriptor length {pooled.shape[1]} does not match blocks {sizes}")
    centred = normalise_blocks(pooled - pooled.mean(axis=0), sizes)
    return centred[: len(first)], centred[len(first) :]


def normalise_blocks(values: FloatArray, sizes: Sequence[int]) -> FloatArray:
    """Each row's consecutive blocks of ``sizes`` columns scaled to unit L2 length.

    Args:
        values: ``(P, D)`` descriptors, ``D = sum(sizes)``.
        sizes: the block lengths.

    Returns:
        ``(P, D)`` normalised copy; a block that is all zero stays zero.

    >>> normalise_blocks(np.array([[3.0, 4.0, 0.0, 2.0]]), (2, 1, 1)).tolist()
    [[0.6, 0.8, 0.0, 1.0]]
    """
    output = np.empty_like(values)
    start = 0
    for size in sizes:
        block = values[:, start : start + size]
        norms = np.linalg.norm(block, axis=1, keepdims=True)
        output[:, start : start + size] = block / np.where(norms > 0, norms, 1.0)
        start += size
    return output


def euclidean_distances(first: FloatArray, second: FloatArray) -> FloatArray:
    """``(K, N)`` Euclidean distances between ``(K, D)`` and ``(N, D)`` rows."""
    squared = (first * first).sum(1)[:, None] + (second * second).sum(1)[None, :]
    squared -= 2.0 * first @ second.T
    return np.sqrt(np.maximum(squared, 0.0))


def reid_distance_matrix(
    query: ArrayLike, gallery: ArrayLike, block_sizes: Sequence[int] | None = None
) -> FloatArray:
    """Training-free re-ID distances: pooled mean subtraction, L2 (per block), Euclidean.

    >>> reid_distance_matrix([[1.0, 0.0], [0.0, 1.0]], [[2.0, 0.1]]).round(3).tolist()
    [[1.218], [1.977]]
    """
    first, second = normalise_pooled(query, gallery, block_sizes)
    return euclidean_distances(first, second)


@dataclass(frozen=True)
class XqdaModel:
    """XQDA metric learned on labelled descriptors (docs/algorithms/gap-matchers.md#xqda).

    Attributes:
        mean: ``(D,)`` centring used before the PCA.
        basis: ``(D, r)`` PCA basis times the XQDA projection W, so z = (x − mean) @ basis.
        metric: ``(q, q)`` M = (WᵀΣ_I W)⁻¹ − (WᵀΣ_E W)⁻¹.
    """

    mean: FloatArray
    basis: FloatArray
    metric: FloatArray

    def distances(self, query: ArrayLike, gallery: ArrayLike) -> FloatArray:
        """``(K, N)`` distances d(x, z) = (x−z)ᵀ W M Wᵀ (x−z)."""
        first = (np.asarray(query, dtype=np.float64) - self.mean) @ self.basis
        second = (np.asarray(gallery, dtype=np.float64) - self.mean) @ self.basis
        quadratic_first = np.einsum("ki,ij,kj->k", first, self.metric, first)
        quadratic_second = np.einsum("ni,ij,nj->n", second, self.metric, second)
        cross = first @ self.metric @ second.T
        return quadratic_first[:, None] + quadratic_second[None, :] - 2.0 * cross


def fit_xqda(
    features: ArrayLike, labels: ArrayLike, max_pca: int = 100, regulariser: float = 0.001
) -> XqdaModel | None:
    """Self-trained XQDA: positives share a label, negatives do not.

    Args:
        features: ``(n, D)`` descriptors (for example each track at several frames).
        labels: ``(n,)`` track identities.
        max_pca: PCA dimension cap; the dimension is min(max_pca, n − 1).
        regulariser: added to the diagonal of the intra-class covariance.

    Returns:
        The model, or None when there are no positive pairs, no negative pairs, or no
        eigenvalue above 1.
    """
    values = np.asarray(features, dtype=np.float64)
    values = values.reshape(len(values), -1)
    identities = np.asarray(labels).reshape(-1)
    count = len(values)
    if count < 3 or len(identities) != count:
        return None
    mean = values.mean(axis=0)
    centred = values - mean
    _, singular, right = np.linalg.svd(centred, full_matrices=False)
    rank = int(np.sum(singular > 1e-10 * max(singular[0], 1e-300)))
    dimension = min(max_pca, count - 1, rank)
    if dimension < 1:
        return None
    pca = right[:dimension].T
    projected = centred @ pca
    same = identities[:, None] == identities[None, :]
    upper = np.triu(np.ones((count, count), dtype=bool), k=1)
    positives, negatives = np.nonzero(same & upper), np.nonzero(~same & upper)
    if len(positives[0]) == 0 or len(negatives[0]) == 0:
        return None
    positive_differences = projected[positives[0]] - projected[positives[1]]
    negative_differences = projected[negatives[0]] - projected[negatives[1]]
    intra = positive_differences.T @ positive_differences / len(positive_differences)
    extra = negative_differences.T @ negative_differences / len(negative_differences)
    intra += regulariser * np.eye(dimension)
    eigenvalues, eigenvectors = np.linalg.eig(np.linalg.solve(intra, extra))
    eigenvalues, eigenvectors = eigenvalues.real, eigenvectors.real
    keep = eigenvalues > 1.0
    if not np.any(keep):
        return None
    order = np.argsort(eigenvalues[keep])[::-1]
    projection = eigenvectors[:, keep][:, order]
    metric = np.linalg.inv(projection.T @ intra @ projection) - np.linalg.inv(
        projection.T @ extra @ projection
    )
    return XqdaModel(mean=mean, basis=pca @ projection, metric=metric)

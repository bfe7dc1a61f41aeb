"""GOG re-identification descriptor (Matsukawa et al., CVPR 2016).

See docs/algorithms/gap-matchers.md#gog.

Gaussian of Gaussian: every k×k patch (k = 5, every p = 2 pixels) is summarised by the Gaussian of
its pixel features, embedded as an SPD matrix, mapped to a vector by the matrix log and
half-vectorisation; each of G = 7 overlapping horizontal strips is then summarised by the weighted
Gaussian of its patch vectors, embedded the same way. On 128×48 this gives 7·1081 = 7567 values
per colour space with 8-d pixel features (RGB, Lab, HSV) and 7·703 = 4921 with 7-d features
(nRnG); the fusion of the four has 27622 values.

The descriptor is returned raw. At distance time, each colour space is mean-centred over the
pooled descriptors of the interval and L2-normalised (:func:`normalise_gog`).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import AbstractContextManager
from functools import lru_cache
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from threadpoolctl import ThreadpoolController

from trackfw.arrays import FloatArray
from trackfw_plugins.detectors.head_scorer import resolve_threads
from trackfw_plugins.maths.lomo import rgb_to_hsv
from trackfw_plugins.maths.reid_crop import normalise_blocks

#: Defaults of the authors' GOG.m.
PATCH_SIZE = 5
PATCH_STEP = 2
EPSILON = 0.001
NUM_REGIONS = 7
ORIENTATION_BINS = 4
COLOUR_SPACES = ("rgb", "lab", "hsv", "nrng")


def half_vectorise(matrices: FloatArray) -> FloatArray:
    """Upper triangle row by row, off-diagonal entries times √2 (so the norm is kept).

    Args:
        matrices: ``(..., n, n)`` symmetric matrices.

    Returns:
        ``(..., n(n+1)/2)`` vectors.

    >>> half_vectorise(np.array([[1.0, 2.0], [2.0, 3.0]])).round(4).tolist()
    [1.0, 2.8284, 3.0]
    """
    size = matrices.shape[-1]
    rows, columns = np.triu_indices(size)
    weights = np.where(rows == columns, 1.0, np.sqrt(2.0))
    return matrices[..., rows, columns] * weights


def gaussian_embedding_log(means: FloatArray, covariances: FloatArray) -> FloatArray:
    """log of the SPD embedding |Σ|^{−1/(d+1)}·[[Σ + μμᵀ, μ], [μᵀ, 1]], half-vectorised.

    The embedded matrix has determinant 1, so its log is log(P₀) − (log|Σ|/(d+1))·I.

    Args:
        means: ``(N, d)`` means.
        covariances: ``(N, d, d)`` regularised (positive definite) covariances.

    Returns:
        ``(N, (d+1)(d+2)/2)`` vectors.

    >>> vector = gaussian_embedding_log(np.zeros((1, 1)), np.ones((1, 1, 1)))
    >>> vector.round(6).tolist()
    [[0.0, 0.0, 0.0]]
    """
    count, dimension = means.shape
    embedded = np.empty((count, dimension + 1, dimension + 1))
    embedded[:, :dimension, :dimension] = covariances + means[:, :, None] * means[:, None, :]
    embedded[:, :dimension, dimension] = means
    embedded[:, dimension, :dimension] = means
    embedded[:, dimension, dimension] = 1.0
    _, log_determinant = np.linalg.slogdet(covariances)
    eigenvalues, eigenvectors = np.linalg.eigh(embedded)
    eigenvalues = np.maximum(eigenvalues, np.finfo(np.float64).tiny)
    logarithm = (eigenvectors * np.log(eigenvalues)[:, None, :]) @ eigenvectors.transpose(0, 2, 1)
    logarithm -= (log_determinant / (dimension + 1))[:, None, None] * np.eye(dimension + 1)
    return half_vectorise(logarithm)


def pixel_features(image_rgb: NDArray[np.uint8], colour_space: str = "rgb") -> FloatArray:
    """Per-pixel features f = [y/H, M₀°, M₉₀°, M₁₈₀°, M₂₇₀°, colour] (step 1).

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.
        colour_space: ``"rgb"``, ``"lab"``, ``"hsv"`` (3 channels) or ``"nrng"`` (2 channels).

    Returns:
        ``(H, W, d)`` features, d = 8 (or 7 for nRnG).
    """
    image = np.asarray(image_rgb)
    height, width = image.shape[:2]
    values = image.astype(np.float64)
    red, green, blue = values[..., 0], values[..., 1], values[..., 2]
    # MATLAB rgb2ycbcr luminance for 8-bit input, in [16, 235]; mapping (Y − 16) / 235.
    luminance = 16.0 + (65.481 * red + 128.553 * green + 24.966 * blue) / 255.0
    luminance = (luminance - 16.0) / 235.0
    padded = np.pad(luminance, 1, mode="edge")
    gradient_x = padded[1:-1, 2:] - padded[1:-1, :-2]
    gradient_y = padded[2:, 1:-1] - padded[:-2, 1:-1]
    magnitude = np.hypot(gradient_x, gradient_y)
    orientation = np.mod(np.degrees(np.arctan2(gradient_y, gradient_x)), 360.0)
    position = orientation / (360.0 / ORIENTATION_BINS)
    lower_bin = np.floor(position).astype(np.int64) % ORIENTATION_BINS
    upper_weight = position - np.floor(position)
    orientation_channels = np.zeros((height, width, ORIENTATION_BINS))
    rows, columns = np.indices((height, width))
    orientation_channels[rows, columns, lower_bin] += magnitude * (1.0 - upper_weight)
    orientation_channels[rows, columns, (lower_bin + 1) % ORIENTATION_BINS] += (
        magnitude * upper_weight
    )

    if colour_space == "rgb":
        colour = values / 255.0
    elif colour_space == "lab":
        lab = cv2.cvtColor((values / 255.0).astype(np.float32), cv2.COLOR_RGB2Lab).astype(
            np.float64
        )
        colour = np.stack(
            [lab[..., 0] / 100.0, (lab[..., 1] + 50.0) / 100.0, (lab[..., 2] + 50.0) / 100.0],
            axis=-1,
        )
    elif colour_space == "hsv":
        colour = rgb_to_hsv(values / 255.0)
    elif colour_space == "nrng":
        total = np.maximum(values.sum(axis=-1, keepdims=True), 1.0)
        colour = values[..., :2] / total
    else:
        raise ValueError(f"unknown GOG colour space {colour_space!r}; expected {COLOUR_SPACES}")
    row_feature = np.broadcast_to(
        (np.arange(1, height + 1, dtype=np.float64) / height)[:, None, None], (height, width, 1)
    )
    return np.concatenate([row_feature, orientation_channels, colour], axis=-1)


def patch_gaussians(
    features: FloatArray,
    patch_size: int = PATCH_SIZE,
    step: int = PATCH_STEP,
    epsilon: float = EPSILON,
) -> FloatArray:
    """Patch-level Gaussians, embedded and half-vectorised (step 2).

    Window sums of f and of the upper triangle of ffᵀ come from separable running sums (an
    integral image evaluated only at the patch rows), so the cost does not grow with k.

    Args:
        features: ``(H, W, d)`` pixel features.

    Returns:
        ``(H₀, W₀, m)`` patch vectors on the ⌈H/p⌉ × ⌈W/p⌉ grid, m = (d²+3d)/2 + 1.
    """
    height, width, dimension = features.shape
    upper_rows, upper_columns = np.triu_indices(dimension)
    stacked = np.concatenate(
        [
            np.ones((height, width, 1)),
            features,
            features[..., upper_rows] * features[..., upper_columns],
        ],
        axis=-1,
    )
    half = patch_size // 2
    centre_rows = np.arange(0, height, step)
    centre_columns = np.arange(0, width, step)
    top = np.clip(centre_rows - half, 0, height)
    bottom = np.clip(centre_rows + half + 1, 0, height)
    left = np.clip(centre_columns - half, 0, width)
    right = np.clip(centre_columns + half + 1, 0, width)
    running = np.zeros((height + 1, width, stacked.shape[-1]))
    np.cumsum(stacked, axis=0, out=running[1:])
    row_sums = running[bottom] - running[top]
    running = np.zeros((len(centre_rows), width + 1, stacked.shape[-1]))
    np.cumsum(row_sums, axis=1, out=running[:, 1:])
    sums = (running[:, right] - running[:, left]).reshape(-1, stacked.shape[-1])
    grid_shape = (len(centre_rows), len(centre_columns))

    counts = sums[:, 0]
    means = sums[:, 1 : 1 + dimension] / counts[:, None]
    second = np.zeros((len(sums), dimension, dimension))
    second[:, upper_rows, upper_columns] = sums[:, 1 + dimension :]
    second[:, upper_columns, upper_rows] = sums[:, 1 + dimension :]
    covariances = (second - counts[:, None, None] * means[:, :, None] * means[:, None, :]) / (
        np.maximum(counts - 1.0, 1.0)[:, None, None]
    )
    trace = np.trace(covariances, axis1=1, axis2=2)
    covariances += (epsilon * np.maximum(trace, 0.01))[:, None, None] * np.eye(dimension)
    vectors = gaussian_embedding_log(means, covariances)
    return vectors.reshape(*grid_shape, -1)


def region_gaussians(
    patch_vectors: FloatArray,
    num_regions: int = NUM_REGIONS,
    epsilon: float = EPSILON,
    weighted: bool = True,
) -> FloatArray:
    """Region-level Gaussians over overlapping horizontal strips (step 3).

    Strips are 2·H₀/(G+1) patch rows tall with half-strip steps (16 rows with step 8 on the
    64×24 grid). Patch columns are weighted by N(x; W₀/2, W₀/4), x = 1..W₀.

    Args:
        patch_vectors: ``(H₀, W₀, m)`` patch vectors.

    Returns:
        ``(G·((m²+3m)/2 + 1),)`` descriptor.
    """
    grid_height, grid_width, dimension = patch_vectors.shape
    strip = max(1, (2 * grid_height) // (num_regions + 1))
    stride = max(1, strip // 2)
    columns = np.arange(1, grid_width + 1, dtype=np.float64)
    if weighted:
        sigma = grid_width / 4.0
        column_weights = np.exp(-((columns - grid_width / 2.0) ** 2) / (2.0 * sigma**2))
    else:
        column_weights = np.ones(grid_width)
    means, covariances = [], []
    for region in range(num_regions):
        top = min(region * stride, max(grid_height - strip, 0))
        block = patch_vectors[top : top + strip].reshape(-1, dimension)
        weights = np.tile(column_weights, min(strip, grid_height - top))
        weights = weights / weights.sum()
        mean = weights @ block
        centred = block - mean
        covariance = (centred * weights[:, None]).T @ centred
        covariance = 0.5 * (covariance + covariance.T)
        covariance += epsilon * np.trace(covariance) * np.eye(dimension)
        if np.trace(covariance) <= 0.0:
            # A constant region (flat crop): keep the embedding defined.
            covariance += epsilon * np.eye(dimension)
        means.append(mean)
        covariances.append(covariance)
    return gaussian_embedding_log(np.array(means), np.array(covariances)).reshape(-1)


@lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    return ThreadpoolController()


def single_threaded_blas() -> AbstractContextManager[Any]:
    """Limit BLAS/LAPACK to one thread: GOG works on thousands of tiny matrices, for which a
    multi-threaded BLAS mostly waits on its own threads (20-100× slower on a busy machine)."""
    return cast(AbstractContextManager[Any], _blas_controller().limit(limits=1, user_api="blas"))


def gog_colour_descriptor(image_rgb: NDArray[np.uint8], colour_space: str) -> FloatArray:
    """Raw GOG descriptor for one colour space: 7567 values (4921 for nRnG) on 128×48."""
    with single_threaded_blas():
        return _colour_descriptor(image_rgb, colour_space)


def _colour_descriptor(image_rgb: NDArray[np.uint8], colour_space: str) -> FloatArray:
    """:func:`gog_colour_descriptor` under the caller's BLAS limit."""
    return region_gaussians(patch_gaussians(pixel_features(image_rgb, colour_space)))


def gog_block_sizes() -> tuple[int, ...]:
    """Lengths of the per-colour-space blocks, in fusion order (any crop size with G = 7).

    >>> gog_block_sizes()
    (7567, 7567, 7567, 4921)
    """
    sizes = []
    for colour_space in COLOUR_SPACES:
        dimension = 7 if colour_space == "nrng" else 8
        patch_dimension = (dimension * dimension + 3 * dimension) // 2 + 1
        sizes.append(NUM_REGIONS * ((patch_dimension**2 + 3 * patch_dimension) // 2 + 1))
    return tuple(sizes)


def gog_descriptor(
    image_bgr: NDArray[np.uint8], colour_spaces: Sequence[str] = COLOUR_SPACES
) -> FloatArray:
    """Raw fused GOG descriptor of one crop.

    Args:
        image_bgr: ``(H, W, 3)`` uint8 BGR crop, normally 128×48.
        colour_spaces: which colour variants to concatenate, in order.

    Returns:
        ``(27622,)`` for 128×48 and all four colour spaces; normalise with :func:`normalise_gog`
        before computing distances.
    """
    image_rgb = _rgb_crop(image_bgr)
    with single_threaded_blas():
        return np.concatenate([_colour_descriptor(image_rgb, space) for space in colour_spaces])


def _rgb_crop(image_bgr: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The ``(H, W, 3)`` uint8 BGR crop as contiguous RGB (checked)."""
    image = np.asarray(image_bgr)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 BGR crop, got {image.shape} {image.dtype}")
    return np.ascontiguousarray(image[..., ::-1])


def gog_descriptors(images_bgr: ArrayLike, workers: int = 0) -> FloatArray:
    """Raw GOG descriptors of ``(P, H, W, 3)`` uint8 BGR crops -> ``(P, 27622)``.

    Each (crop, colour space) is one task, run on ``workers`` threads (0: as many as
    :func:`~trackfw_plugins.detectors.head_scorer.resolve_threads` allows): a gap's few dozen
    crops take seconds on one core, and NumPy's batched eigendecompositions and running sums
    release the GIL. Every task computes what it would alone, so the result does not depend on
    ``workers``.
    """
    images = np.asarray(images_bgr)
    if images.ndim != 4:
        raise ValueError(f"expected (P, H, W, 3) crops, got shape {images.shape}")
    if len(images) == 0:
        return np.zeros((0, sum(gog_block_sizes())))
    crops = [_rgb_crop(image) for image in images]
    tasks = [(crop, space) for crop in crops for space in COLOUR_SPACES]
    threads = min(resolve_threads(workers), len(tasks))
    # One BLAS limit around the pool: threadpoolctl's limit is process-wide, and workers
    # entering and leaving their own would restore each other's settings out of order.
    with single_threaded_blas():
        if threads == 1:
            parts = [_colour_descriptor(crop, space) for crop, space in tasks]
        else:
            with ThreadPoolExecutor(threads, thread_name_prefix="trackfw-gog") as pool:
                parts = list(pool.map(lambda task: _colour_descriptor(*task), tasks))
    per_crop = len(COLOUR_SPACES)
    return np.stack(
        [np.concatenate(parts[k : k + per_crop]) for k in range(0, len(parts), per_crop)]
    )


def normalise_gog(
    descriptors: ArrayLike,
    mean: ArrayLike | None = None,
    block_sizes: Sequence[int] | None = None,
) -> FloatArray:
    """Per colour space: subtract the mean, then L2-normalise (step 4).

    Args:
        descriptors: ``(P, D)`` raw fused descriptors.
        mean: ``(D,)`` mean to subtract; by default the mean of ``descriptors`` (the pooled
            descriptors of the interval).
        block_sizes: block lengths; by default those of a 128×48 crop.

    Returns:
        ``(P, D)`` normalised descriptors, each block of unit length (or zero).
    """
    values = np.asarray(descriptors, dtype=np.float64)
    sizes = tuple(block_sizes) if block_sizes is not None else gog_block_sizes()
    if values.shape[-1] != sum(sizes):
        raise ValueError(f"descriptor length {values.shape[-1]} does not match blocks {sizes}")
    centre = values.mean(axis=0) if mean is None else np.asarray(mean, dtype=np.float64)
    return normalise_blocks(values - centre, sizes)

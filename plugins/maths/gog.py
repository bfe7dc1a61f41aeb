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
from numpy.lib.stride_tricks import sliding_window_view
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

    One batched ``eigh`` of P₀ = [[Σ + μμᵀ, μ], [μᵀ, 1]] gives everything: |P₀| = |Σ| (the
    Schur complement of its corner 1 is Σ), so the scaled matrix has determinant 1 and its log
    is V·diag(log λ − mean(log λ))·Vᵀ, with no separate determinant.

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
    eigenvalues, eigenvectors = np.linalg.eigh(embedded)
    logarithms = np.log(np.maximum(eigenvalues, np.finfo(np.float64).tiny))
    logarithms -= logarithms.mean(axis=1, keepdims=True)
    logarithm = (eigenvectors * logarithms[:, None, :]) @ eigenvectors.transpose(0, 2, 1)
    return half_vectorise(logarithm)


def shape_features(image_rgb: NDArray[np.uint8]) -> FloatArray:
    """The colour-independent features [y/H, M₀°, M₉₀°, M₁₈₀°, M₂₇₀°] (step 1), shared by the
    four colour spaces.

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.

    Returns:
        ``(H, W, 5)`` row position and soft-binned gradient magnitudes.
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
    # Each pixel's magnitude goes to its two neighbouring bins (never the same one): a select
    # per bin instead of scattered adds, with the same values.
    bins = np.arange(ORIENTATION_BINS)
    lower_share = (magnitude * (1.0 - upper_weight))[..., None]
    upper_share = (magnitude * upper_weight)[..., None]
    orientation_channels = np.where(lower_bin[..., None] == bins, lower_share, 0.0) + np.where(
        ((lower_bin + 1) % ORIENTATION_BINS)[..., None] == bins, upper_share, 0.0
    )
    row_feature = np.broadcast_to(
        (np.arange(1, height + 1, dtype=np.float64) / height)[:, None, None], (height, width, 1)
    )
    return np.concatenate([row_feature, orientation_channels], axis=-1)


def colour_features(image_rgb: NDArray[np.uint8], colour_space: str) -> FloatArray:
    """The colour part of the pixel features (step 1).

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.
        colour_space: ``"rgb"``, ``"lab"``, ``"hsv"`` (3 channels) or ``"nrng"`` (2 channels).

    Returns:
        ``(H, W, 3)``, or ``(H, W, 2)`` for nRnG, in [0, 1].
    """
    values = np.asarray(image_rgb).astype(np.float64)
    if colour_space == "rgb":
        return values / 255.0
    if colour_space == "lab":
        lab = cv2.cvtColor((values / 255.0).astype(np.float32), cv2.COLOR_RGB2Lab).astype(
            np.float64
        )
        return np.stack(
            [lab[..., 0] / 100.0, (lab[..., 1] + 50.0) / 100.0, (lab[..., 2] + 50.0) / 100.0],
            axis=-1,
        )
    if colour_space == "hsv":
        return rgb_to_hsv(values / 255.0)
    if colour_space == "nrng":
        total = np.maximum(values.sum(axis=-1, keepdims=True), 1.0)
        return values[..., :2] / total
    raise ValueError(f"unknown GOG colour space {colour_space!r}; expected {COLOUR_SPACES}")


def pixel_features(image_rgb: NDArray[np.uint8], colour_space: str = "rgb") -> FloatArray:
    """Per-pixel features f = [y/H, M₀°, M₉₀°, M₁₈₀°, M₂₇₀°, colour] (step 1).

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.
        colour_space: ``"rgb"``, ``"lab"``, ``"hsv"`` (3 channels) or ``"nrng"`` (2 channels).

    Returns:
        ``(H, W, d)`` features, d = 8 (or 7 for nRnG).
    """
    colour = colour_features(image_rgb, colour_space)
    return np.concatenate([shape_features(image_rgb), colour], axis=-1)


def patch_moments(
    features: FloatArray, patch_size: int = PATCH_SIZE, step: int = PATCH_STEP
) -> FloatArray:
    """Zeroth, first and second moments of every k×k patch, as one Gram matrix per patch.

    The features get a leading channel of ones and a zero border of k//2 pixels (so a patch
    clipped by the image edge sums only its pixels inside); the Gram matrix of a patch's
    k² samples is then [[n, Σfᵀ], [Σf, Σffᵀ]]. One batched matrix product does it: cheaper
    than running sums over the d(d+1)/2 product channels, and with no cancellation.

    Args:
        features: ``(H, W, d)`` pixel features.
        patch_size: k (an even k counts as k + 1, as the authors' windows are centred).
        step: p, the distance between patch centres.

    Returns:
        ``(H₀, W₀, d+1, d+1)`` Gram matrices on the ⌈H/p⌉ × ⌈W/p⌉ grid of patch centres.
    """
    height, width, dimension = features.shape
    half = patch_size // 2
    window = 2 * half + 1
    augmented = np.zeros((height + 2 * half, width + 2 * half, dimension + 1))
    augmented[half : half + height, half : half + width, 0] = 1.0
    augmented[half : half + height, half : half + width, 1:] = features
    windows = sliding_window_view(augmented, (window, window), axis=(0, 1))[::step, ::step]
    grid_height, grid_width = windows.shape[:2]
    # (patch, k² samples, d+1), channels innermost: the copy moves whole pixels at a time.
    samples = windows.transpose(0, 1, 3, 4, 2).reshape(grid_height * grid_width, -1, dimension + 1)
    gram = samples.transpose(0, 2, 1) @ samples
    return gram.reshape(grid_height, grid_width, dimension + 1, dimension + 1)


def patch_gaussians(
    features: FloatArray,
    patch_size: int = PATCH_SIZE,
    step: int = PATCH_STEP,
    epsilon: float = EPSILON,
) -> FloatArray:
    """Patch-level Gaussians, embedded and half-vectorised (step 2).

    Args:
        features: ``(H, W, d)`` pixel features.
        patch_size: k, the patch side.
        step: p, the distance between patch centres.
        epsilon: covariance regularisation, times the trace (at least 0.01).

    Returns:
        ``(H₀, W₀, m)`` patch vectors on the ⌈H/p⌉ × ⌈W/p⌉ grid, m = (d²+3d)/2 + 1.
    """
    return gaussians_from_moments(patch_moments(features, patch_size, step), epsilon)


def gaussians_from_moments(gram: FloatArray, epsilon: float = EPSILON) -> FloatArray:
    """Embedded, half-vectorised Gaussians of patches given by their :func:`patch_moments`.

    Args:
        gram: ``(H₀, W₀, d+1, d+1)`` Gram matrices [[n, Σfᵀ], [Σf, Σffᵀ]].
        epsilon: covariance regularisation, times the trace (at least 0.01).

    Returns:
        ``(H₀, W₀, m)`` patch vectors, m = (d²+3d)/2 + 1.
    """
    grid_shape = gram.shape[:2]
    dimension = gram.shape[-1] - 1
    gram = gram.reshape(-1, dimension + 1, dimension + 1)
    counts = gram[:, 0, 0]
    means = gram[:, 0, 1:] / counts[:, None]
    outer = counts[:, None, None] * means[:, :, None] * means[:, None, :]
    covariances = (gram[:, 1:, 1:] - outer) / np.maximum(counts - 1.0, 1.0)[:, None, None]
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
        num_regions: G, the number of strips.
        epsilon: covariance regularisation, times the trace.
        weighted: whether to weight the patch columns (else uniform weights).

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
    # strip ≤ H₀ for any G ≥ 1, so every strip has its full height and all G go through one
    # batch of matrix products and one eigh.
    tops = [min(region * stride, max(grid_height - strip, 0)) for region in range(num_regions)]
    blocks = np.stack([patch_vectors[top : top + strip].reshape(-1, dimension) for top in tops])
    weights = np.tile(column_weights, strip)
    weights = weights / weights.sum()
    means = weights @ blocks
    centred = blocks - means[:, None, :]
    covariances = (centred * weights[:, None]).transpose(0, 2, 1) @ centred
    covariances = 0.5 * (covariances + covariances.transpose(0, 2, 1))
    identity = np.eye(dimension)
    covariances += epsilon * np.trace(covariances, axis1=1, axis2=2)[:, None, None] * identity
    # A constant region (flat crop): keep the embedding defined.
    flat = np.trace(covariances, axis1=1, axis2=2) <= 0.0
    covariances[flat] += epsilon * identity
    return gaussian_embedding_log(means, covariances).reshape(-1)


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
        return _crop_descriptor(image_rgb, (colour_space,))


def _crop_descriptor(image_rgb: NDArray[np.uint8], colour_spaces: Sequence[str]) -> FloatArray:
    """Raw GOG descriptors of one ``(H, W, 3)`` RGB crop, concatenated in ``colour_spaces``
    order, under the caller's BLAS limit.

    The colour spaces share the shape features, so their patch moments come from one Gram
    matrix per patch over all channels; each space takes its rows and columns of it (entry
    by entry the same products as a Gram matrix of its own features).
    """
    shape = shape_features(image_rgb)
    colours = [colour_features(image_rgb, space) for space in colour_spaces]
    gram = patch_moments(np.concatenate([shape, *colours], axis=-1))
    shared = 1 + shape.shape[-1]  # the patch's ones channel, then the shape features
    parts, start = [], shared
    for colour in colours:
        keep = np.r_[0:shared, start : start + colour.shape[-1]]
        start += colour.shape[-1]
        parts.append(region_gaussians(gaussians_from_moments(gram[..., keep[:, None], keep])))
    return np.concatenate(parts)


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
        return _crop_descriptor(image_rgb, colour_spaces)


def _rgb_crop(image_bgr: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The ``(H, W, 3)`` uint8 BGR crop as contiguous RGB (checked)."""
    image = np.asarray(image_bgr)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 BGR crop, got {image.shape} {image.dtype}")
    return np.ascontiguousarray(image[..., ::-1])


def gog_descriptors(images_bgr: ArrayLike, workers: int = 0) -> FloatArray:
    """Raw GOG descriptors of ``(P, H, W, 3)`` uint8 BGR crops -> ``(P, 27622)``.

    Each crop is one task (its four colour spaces share the shape features and the patch
    moments), run on ``workers`` threads (0: as many as
    :func:`~trackfw_plugins.detectors.head_scorer.resolve_threads` allows): a gap's few dozen
    crops take seconds on one core, and NumPy's batched eigendecompositions and matrix products
    release the GIL. Every task computes what it would alone, so the result does not depend on
    ``workers``.
    """
    images = np.asarray(images_bgr)
    if images.ndim != 4:
        raise ValueError(f"expected (P, H, W, 3) crops, got shape {images.shape}")
    if len(images) == 0:
        return np.zeros((0, sum(gog_block_sizes())))
    crops = [_rgb_crop(image) for image in images]
    threads = min(resolve_threads(workers), len(crops))
    # One BLAS limit around the pool: threadpoolctl's limit is process-wide, and workers
    # entering and leaving their own would restore each other's settings out of order.
    with single_threaded_blas():
        if threads == 1:
            return np.stack([_crop_descriptor(crop, COLOUR_SPACES) for crop in crops])
        with ThreadPoolExecutor(threads, thread_name_prefix="trackfw-gog") as pool:
            return np.stack(
                list(pool.map(lambda crop: _crop_descriptor(crop, COLOUR_SPACES), crops))
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

"""LOMO re-identification descriptor (Liao et al., CVPR 2015; docs/algorithms/gap-matchers.md#lomo).

Local Maximal Occurrence: joint HSV (8×8×8) and SILTP (τ = 0.3, R ∈ {3, 5}, 4 neighbours)
histograms of 10×10 windows with step 5; for every row of windows the bin-wise maximum over the
row is kept, over a 3-level pyramid of 2×2 average pooling; then log(x+1) and L2 normalisation
of the HSV block and of each SILTP block. A 128×48 input gives 24 + 11 + 5 = 40 row histograms
per code map: 40·512 + 2·40·81 = 26960 values.

The Retinex step of the authors is only available as a binary, so :func:`retinex` is the
stand-in (multi-scale Retinex with colour restoration and a 1% simplest colour balance).
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from trackfw.arrays import FloatArray, IntArray

#: Defaults of the authors' LOMO.m.
NUM_SCALES = 3
BLOCK_SIZE = 10
BLOCK_STEP = 5
HSV_BINS = 8
SILTP_TAU = 0.3
SILTP_RADII = (3, 5)
SILTP_BINS = 3**4
RETINEX_SIGMAS = (5.0, 20.0)
#: Jobson et al. (1997) colour-restoration constants.
RESTORATION_ALPHA = 125.0
RESTORATION_BETA = 46.0
#: Fraction clipped at each end by the simplest colour balance.
BALANCE_CLIP = 0.01


def rgb_to_hsv(rgb: ArrayLike) -> FloatArray:
    """MATLAB ``rgb2hsv`` for values in [0, 1]: H, S, V all in [0, 1].

    Args:
        rgb: ``(..., 3)`` RGB values in [0, 1].

    Returns:
        ``(..., 3)`` HSV; H = 0 and S = 0 for greys, S = 0 for black.

    >>> rgb_to_hsv([[1.0, 0.0, 0.0], [0.0, 0.5, 0.5], [0.2, 0.2, 0.2]]).round(4).tolist()
    [[0.0, 1.0, 1.0], [0.5, 1.0, 0.5], [0.0, 0.0, 0.2]]
    """
    values = np.asarray(rgb, dtype=np.float64)
    red, green, blue = values[..., 0], values[..., 1], values[..., 2]
    value = values.max(axis=-1)
    delta = value - values.min(axis=-1)
    safe_delta = np.where(delta > 0, delta, 1.0)
    saturation = np.where(value > 0, delta / np.where(value > 0, value, 1.0), 0.0)
    hue = np.where(
        value == red,
        (green - blue) / safe_delta,
        np.where(value == green, 2.0 + (blue - red) / safe_delta, 4.0 + (red - green) / safe_delta),
    )
    hue = np.where(delta > 0, np.mod(hue / 6.0, 1.0), 0.0)
    return np.stack([hue, saturation, value], axis=-1)


def retinex(image_rgb: NDArray[np.uint8]) -> FloatArray:
    """Multi-scale Retinex with colour restoration, our stand-in for the authors' MEX.

    R_c = mean_σ(log(I_c+1) − log(G_σ∗I_c + 1)), σ ∈ {5, 20}; then
    R_c ← R_c·β·(log(α(I_c+1)) − log Σ_c(I_c+1)); then each channel is stretched to [0, 255]
    clipping 1% at each end.

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.

    Returns:
        ``(H, W, 3)`` float RGB in [0, 255].
    """
    image = np.asarray(image_rgb, dtype=np.float64)
    log_image = np.log(image + 1.0)
    response = np.zeros_like(image)
    for sigma in RETINEX_SIGMAS:
        blurred = cv2.GaussianBlur(image, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        response += log_image - np.log(blurred + 1.0)
    response /= len(RETINEX_SIGMAS)
    restoration = RESTORATION_BETA * (
        np.log(RESTORATION_ALPHA * (image + 1.0)) - np.log((image + 1.0).sum(axis=2, keepdims=True))
    )
    response *= restoration
    output = np.zeros_like(response)
    flat = response.reshape(-1, 3)
    low = np.quantile(flat, BALANCE_CLIP, axis=0)
    high = np.quantile(flat, 1.0 - BALANCE_CLIP, axis=0)
    span = high - low
    stretched = (response - low) / np.where(span > 0, span, 1.0)
    output = np.where(span > 0, np.clip(stretched, 0.0, 1.0) * 255.0, 0.0)
    return output


def siltp_codes(gray: FloatArray, radius: int, tau: float = SILTP_TAU) -> IntArray:
    """Scale-invariant local ternary pattern codes, 4 neighbours at distance ``radius``.

    Neighbour k (right, up, left, down) gives 1 when I_k > (1+τ)I_c, 2 when I_k < (1−τ)I_c and
    0 otherwise; the code is Σ t_k·3^k in [0, 81). Borders are replicated.

    Args:
        gray: ``(H, W)`` grey image in [0, 1].

    Returns:
        ``(H, W)`` codes.

    >>> siltp_codes(np.array([[0.5, 1.0], [0.1, 0.5]]), radius=1).tolist()
    [[55, 72], [4, 21]]
    """
    height, width = gray.shape
    padded = np.pad(gray, radius, mode="edge")
    centre = gray
    neighbours = (
        padded[radius : radius + height, 2 * radius :],  # right
        padded[:height, radius : radius + width],  # up
        padded[radius : radius + height, :width],  # left
        padded[2 * radius :, radius : radius + width],  # down
    )
    upper = (1.0 + tau) * centre
    lower = (1.0 - tau) * centre
    codes = np.zeros((height, width), dtype=np.int64)
    for k, neighbour in enumerate(neighbours):
        digit = (neighbour > upper).astype(np.int64) + 2 * (neighbour < lower).astype(np.int64)
        codes += digit * 3**k
    return codes


@lru_cache(maxsize=32)
def _window_layout(height: int, width: int, block: int, step: int) -> tuple[IntArray, int, int]:
    """Flat pixel indices ``(windows, block²)`` of every window, rows of windows first."""
    starts_row = np.arange(0, height - block + 1, step)
    starts_column = np.arange(0, width - block + 1, step)
    offsets = (np.arange(block)[:, None] * width + np.arange(block)[None, :]).ravel()
    corners = (starts_row[:, None] * width + starts_column[None, :]).ravel()
    return corners[:, None] + offsets[None, :], len(starts_row), len(starts_column)


def max_row_histograms(
    codes: IntArray, bins: int, block: int = BLOCK_SIZE, step: int = BLOCK_STEP
) -> FloatArray:
    """Histograms of the sliding windows, maximised over each row of windows.

    Args:
        codes: ``(H, W)`` integer codes in [0, bins).

    Returns:
        ``(rows, bins)`` counts, one histogram per row of windows (zero rows when H < block).

    >>> max_row_histograms(np.array([[0, 1, 1], [0, 1, 1]]), bins=2, block=2, step=1).tolist()
    [[2.0, 4.0]]
    """
    height, width = codes.shape
    if height < block or width < block:
        return np.zeros((0, bins))
    indices, rows, columns = _window_layout(height, width, block, step)
    window_codes = codes.ravel()[indices]
    keys = window_codes + bins * np.arange(len(indices))[:, None]
    counts = np.bincount(keys.ravel(), minlength=len(indices) * bins)
    return counts.reshape(rows, columns, bins).max(axis=1).astype(np.float64)


def _pool_average(image: FloatArray) -> FloatArray:
    """2×2 average pooling, dropping an odd last row or column (LOMO.m ``Pooling``)."""
    height, width = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2
    trimmed = image[:height, :width]
    return trimmed.reshape(height // 2, 2, width // 2, 2, *image.shape[2:]).mean(axis=(1, 3))


def _unit(vector: FloatArray) -> FloatArray:
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 0.0 else vector


def lomo_hsv_block(image_rgb: NDArray[np.uint8], num_scales: int = NUM_SCALES) -> FloatArray:
    """Raw (unnormalised) joint-HSV max-occurrence histograms over the pyramid."""
    hsv = rgb_to_hsv(retinex(image_rgb) / 255.0)
    quantised = np.minimum(np.floor(hsv * HSV_BINS), HSV_BINS - 1)
    blocks = []
    for scale in range(num_scales):
        hue, saturation, value = quantised[..., 0], quantised[..., 1], quantised[..., 2]
        codes = ((value * HSV_BINS + saturation) * HSV_BINS + hue).astype(np.int64)
        histograms = max_row_histograms(codes, HSV_BINS**3)
        if len(histograms) == 0:
            break
        blocks.append(histograms.ravel())
        if scale < num_scales - 1:
            # The authors pool the quantised channels and floor the mean (ColorPooling).
            quantised = np.floor(_pool_average(quantised))
    return np.concatenate(blocks) if blocks else np.zeros(0)


def lomo_siltp_block(
    gray: FloatArray, radius: int, num_scales: int = NUM_SCALES, tau: float = SILTP_TAU
) -> FloatArray:
    """Raw SILTP max-occurrence histograms over the pyramid for one radius."""
    blocks = []
    image = gray
    for scale in range(num_scales):
        if image.shape[1] >= 2 * radius + 1 and image.shape[0] >= 2 * radius + 1:
            histograms = max_row_histograms(siltp_codes(image, radius, tau), SILTP_BINS)
            if len(histograms) == 0:
                break
            blocks.append(histograms.ravel())
        if scale < num_scales - 1:
            image = _pool_average(image)
    return np.concatenate(blocks) if blocks else np.zeros(0)


def lomo_descriptor(image_bgr: NDArray[np.uint8]) -> FloatArray:
    """LOMO descriptor of one crop.

    Args:
        image_bgr: ``(H, W, 3)`` uint8 BGR crop, normally 128×48.

    Returns:
        ``(D,)`` descriptor, D = 26960 for 128×48: [HSV (20480), SILTP R=3 (3240), R=5 (3240)],
        each block log(x+1)-compressed and L2-normalised.
    """
    image = np.asarray(image_bgr)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 BGR crop, got {image.shape} {image.dtype}")
    image_rgb = np.ascontiguousarray(image[..., ::-1])
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.float64) / 255.0
    parts = [_unit(np.log(lomo_hsv_block(image_rgb) + 1.0))]
    for radius in SILTP_RADII:
        parts.append(_unit(np.log(lomo_siltp_block(gray, radius) + 1.0)))
    return np.concatenate(parts)


def lomo_descriptors(images_bgr: ArrayLike) -> FloatArray:
    """LOMO descriptors of ``(P, H, W, 3)`` uint8 BGR crops -> ``(P, D)``."""
    images = np.asarray(images_bgr)
    if images.ndim != 4:
        raise ValueError(f"expected (P, H, W, 3) crops, got shape {images.shape}")
    if len(images) == 0:
        return np.zeros((0, 0))
    return np.stack([lomo_descriptor(image) for image in images])

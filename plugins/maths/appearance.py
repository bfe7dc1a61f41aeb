"""Appearance descriptors for the E_a term of the window cost.

See docs/algorithms/gap-matchers.md#appearance-term.

An 80×80 patch around each point is described by four groups: mean RGB (3), mean HSV (3), the
uniform LBP histogram (59) and HOG (2916). Each group is L2-normalised, the groups are concatenated
and the result multiplied by ½, so a descriptor has unit norm and two descriptors lie at most √2
apart.

>>> import numpy as np
>>> image = np.zeros((120, 160, 3), dtype=np.uint8)
>>> descriptors = appearance_descriptors(image, np.array([[10.0, 10.0], [150.0, 100.0]]))
>>> descriptors.shape, bool(appearance_distance_matrix(descriptors, descriptors).max() < 1e-6)
((2, 2981), True)
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from trackfw.arrays import FloatArray, UInt8Array

#: Paper patch size: 80×80 pixels.
PATCH_SIZE = 80
LBP_NEIGHBOURS = 8
LBP_RADIUS = 1.0
LBP_BINS = 59
HOG_SIZE = 2916
#: Sizes of the four feature groups, in descriptor order.
GROUP_SIZES = (3, 3, LBP_BINS, HOG_SIZE)
DESCRIPTOR_SIZE = sum(GROUP_SIZES)


def crop_replicate(
    image: NDArray[np.generic], left: int, top: int, width: int, height: int
) -> NDArray[np.generic]:
    """Crop a ``(height, width, ...)`` box, replicating border pixels where it leaves the image.

    >>> import numpy as np
    >>> crop_replicate(np.arange(9).reshape(3, 3), -1, -1, 3, 2).tolist()
    [[0, 0, 1], [0, 0, 1]]
    """
    rows = np.clip(np.arange(top, top + height), 0, image.shape[0] - 1)
    columns = np.clip(np.arange(left, left + width), 0, image.shape[1] - 1)
    return image[rows[:, None], columns[None, :]]


def extract_patch(
    image: UInt8Array, point: ArrayLike, patch_size: int = PATCH_SIZE, scale: float = 1.0
) -> UInt8Array:
    """Square patch centred on ``point``, with replicated borders.

    Args:
        image: ``(H, W, C)`` or ``(H, W)`` pixels.
        point: ``(2,)`` centre (x, y).
        patch_size: output side length.
        scale: the patch covers ``round(patch_size·scale)`` source pixels and is resized to
            ``patch_size`` (for example height/1080 to keep the paper's 80 px at 1080p).

    Returns:
        ``(patch_size, patch_size, C)`` (or 2-D) uint8 patch.
    """
    x, y = np.asarray(point, dtype=np.float64).reshape(2)
    side = max(1, round(patch_size * scale))
    left = round(x) - side // 2
    top = round(y) - side // 2
    patch = np.ascontiguousarray(crop_replicate(image, left, top, side, side), dtype=np.uint8)
    if side != patch_size:
        interpolation = cv2.INTER_AREA if side > patch_size else cv2.INTER_LINEAR
        patch = np.ascontiguousarray(
            cv2.resize(patch, (patch_size, patch_size), interpolation=interpolation),
            dtype=np.uint8,
        )
    return patch


@lru_cache(maxsize=4)
def uniform_lbp_table(neighbours: int = LBP_NEIGHBOURS) -> NDArray[np.int64]:
    """Lookup table code -> bin of the "u2" uniform mapping (Ojala et al. 2002).

    Codes with at most two circular 0/1 transitions get their own bin, in increasing code order;
    every other code shares the last bin. For 8 neighbours there are 58 uniform codes + 1.

    >>> table = uniform_lbp_table()
    >>> len(table), int(table.max()) + 1, int(table[0]), int(table[255]), int(table[0b101])
    (256, 59, 0, 57, 58)
    """
    codes = np.arange(2**neighbours)
    rotated = ((codes << 1) | (codes >> (neighbours - 1))) & (2**neighbours - 1)
    transitions = np.array([bin(int(value)).count("1") for value in codes ^ rotated])
    uniform = transitions <= 2
    table = np.full(len(codes), int(uniform.sum()), dtype=np.int64)
    table[uniform] = np.arange(int(uniform.sum()))
    return table


def lbp_codes(
    gray: ArrayLike, radius: float = LBP_RADIUS, neighbours: int = LBP_NEIGHBOURS
) -> NDArray[np.int64]:
    """Circular LBP codes with bilinear interpolation (Ojala et al. 2002), vectorised.

    Neighbour k sits at (dy, dx) = (−r·sin(2πk/P), r·cos(2πk/P)); bit k is set when the
    neighbour is ≥ the centre. Only pixels whose whole neighbourhood lies inside are coded.

    Args:
        gray: ``(H, W)`` grey image.

    Returns:
        ``(H − 2⌈r⌉, W − 2⌈r⌉)`` integer codes in [0, 2^P).

    >>> lbp_codes(np.array([[9, 9, 9], [9, 5, 1], [1, 1, 1]])).tolist()
    [[30]]
    """
    image = np.asarray(gray, dtype=np.float64)
    margin = int(np.ceil(radius))
    height, width = image.shape[0] - 2 * margin, image.shape[1] - 2 * margin
    if height <= 0 or width <= 0:
        raise ValueError(f"image {image.shape} is too small for LBP radius {radius}")
    centre = image[margin : margin + height, margin : margin + width]
    codes = np.zeros((height, width), dtype=np.int64)
    # A tolerance keeps flat regions from flipping bits through interpolation round-off.
    tolerance = 1e-9 * max(1.0, float(np.abs(image).max(initial=0.0)))
    for k in range(neighbours):
        angle = 2.0 * np.pi * k / neighbours
        dy, dx = -radius * np.sin(angle), radius * np.cos(angle)
        y0, x0 = int(np.floor(dy + 1e-9)), int(np.floor(dx + 1e-9))
        fy, fx = dy - y0, dx - x0
        fy, fx = (0.0 if abs(fy) < 1e-6 else fy), (0.0 if abs(fx) < 1e-6 else fx)

        def shifted(row_offset: int, column_offset: int) -> FloatArray:
            top, left = margin + row_offset, margin + column_offset
            return image[top : top + height, left : left + width]

        neighbour = (1.0 - fy) * (1.0 - fx) * shifted(y0, x0)
        if fx:
            neighbour = neighbour + (1.0 - fy) * fx * shifted(y0, x0 + 1)
        if fy:
            neighbour = neighbour + fy * (1.0 - fx) * shifted(y0 + 1, x0)
        if fx and fy:
            neighbour = neighbour + fy * fx * shifted(y0 + 1, x0 + 1)
        codes |= (neighbour >= centre - tolerance).astype(np.int64) << k
    return codes


def uniform_lbp_histogram(gray: ArrayLike) -> FloatArray:
    """59-bin uniform LBP(8, 1) histogram of a grey patch, normalised to sum 1.

    >>> uniform_lbp_histogram(np.zeros((5, 5))).tolist()[57]  # flat: every code is 255
    1.0
    """
    codes = lbp_codes(gray)
    counts = np.bincount(uniform_lbp_table()[codes].ravel(), minlength=LBP_BINS).astype(np.float64)
    return counts / max(counts.sum(), 1.0)


@lru_cache(maxsize=4)
def _hog(patch_size: int) -> cv2.HOGDescriptor:
    return cv2.HOGDescriptor((patch_size, patch_size), (16, 16), (8, 8), (8, 8), 9)


def _unit(vector: FloatArray) -> FloatArray:
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 0.0 else vector


def patch_descriptor(patch: UInt8Array) -> FloatArray:
    """Descriptor of one BGR patch: ½·[mean RGB, mean HSV, LBP, HOG], each group unit length.

    Args:
        patch: ``(S, S, 3)`` uint8 BGR patch (S = 80 gives 2916 HOG values).

    Returns:
        ``(D,)`` descriptor with unit norm (D = 2981 for S = 80). A group that is all zero (HOG
        of a flat patch) stays zero, so the norm is then below 1.
    """
    if patch.ndim != 3 or patch.shape[2] != 3 or patch.dtype != np.uint8:
        raise ValueError(f"expected an (S, S, 3) uint8 BGR patch, got {patch.shape} {patch.dtype}")
    mean_rgb = patch.reshape(-1, 3).mean(axis=0)[::-1] / 255.0
    hsv = cv2.cvtColor(patch, cv2.COLOR_BGR2HSV).reshape(-1, 3).mean(axis=0)
    mean_hsv = hsv / np.array([180.0, 255.0, 255.0])
    gray = cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)
    lbp = uniform_lbp_histogram(gray)
    hog = np.asarray(_hog(patch.shape[0]).compute(gray), dtype=np.float64).reshape(-1)
    groups = [mean_rgb, mean_hsv, lbp, hog]
    return 0.5 * np.concatenate([_unit(np.asarray(group, dtype=np.float64)) for group in groups])


def appearance_descriptors(
    image: UInt8Array, points: ArrayLike, patch_size: int = PATCH_SIZE, scale: float = 1.0
) -> FloatArray:
    """Descriptors of the patches centred on ``points``.

    Args:
        image: ``(H, W, 3)`` uint8 BGR frame.
        points: ``(P, 2)`` patch centres (x, y) in pixels.
        patch_size: patch side (80 in the paper).
        scale: source patch side = patch_size·scale (see :func:`extract_patch`).

    Returns:
        ``(P, D)`` descriptors, D = 2981 for 80×80 patches.
    """
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) BGR image, got shape {image.shape}")
    centres = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    size = 6 + LBP_BINS + _hog(patch_size).getDescriptorSize()
    descriptors = np.zeros((len(centres), size))
    for row, centre in enumerate(centres):
        descriptors[row] = patch_descriptor(extract_patch(image, centre, patch_size, scale))
    return descriptors


def appearance_distance_matrix(first: ArrayLike, second: ArrayLike) -> FloatArray:
    """Euclidean distances between ``(K, D)`` and ``(N, D)`` descriptors -> ``(K, N)``.

    >>> appearance_distance_matrix([[0.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]]).round(6).tolist()
    [[0.0, 1.414214]]
    """
    a = np.asarray(first, dtype=np.float64)
    b = np.asarray(second, dtype=np.float64)
    a = a.reshape(len(a), -1)
    b = b.reshape(len(b), -1)
    squared = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.sqrt(np.maximum(squared, 0.0))

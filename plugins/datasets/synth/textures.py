"""Procedural textures (ground, facades, walkway) and loading a real background image.

Every function takes a ``numpy.random.Generator`` so a texture is fully determined by the seed.
Textures are BGR ``uint8`` images; their metric size comes from the caller's pixels-per-metre.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from trackfw.arrays import FloatArray, ImageArray
from trackfw.errors import UserError

#: Ground patterns a site may use.
GROUND_STYLES = ("paving", "tiles", "asphalt", "brick", "gravel", "checker")


def smooth_noise(rng: np.random.Generator, height: int, width: int, cell: int) -> FloatArray:
    """Low-frequency noise in [-1, 1], ``(height, width)``: random values on a coarse grid of
    ``cell`` pixels, interpolated bicubically."""
    coarse = rng.uniform(-1.0, 1.0, size=(height // cell + 2, width // cell + 2)).astype(np.float32)
    full = cv2.resize(
        coarse,
        ((width // cell + 2) * cell, (height // cell + 2) * cell),
        interpolation=cv2.INTER_CUBIC,
    )
    return np.clip(full[:height, :width], -1.0, 1.0)


def _colour_jitter(
    rng: np.random.Generator, base: ImageArray, count: int, amount: float
) -> ImageArray:
    jitter = rng.uniform(1 - amount, 1 + amount, size=(count, 1))
    return np.clip(base[None, :] * jitter, 0, 255).astype(np.float32)


def _finish(
    rng: np.random.Generator,
    image: np.ndarray,
    stains: np.ndarray,
    stain_amount: float,
    grain_sigma: float,
) -> ImageArray:
    """Multiply by (1 + stain_amount * stains), add grey grain, clip to uint8 (float32 maths)."""
    height, width = image.shape[:2]
    factor = (1.0 + stain_amount * stains)[..., None].astype(np.float32)
    grain = rng.standard_normal(size=(height, width, 1), dtype=np.float32) * np.float32(grain_sigma)
    return np.clip(image.astype(np.float32) * factor + grain, 0, 255).astype(np.uint8)


def ground_texture(
    rng: np.random.Generator,
    style: str,
    base_colour: tuple[int, int, int],
    size: tuple[int, int],
    pixels_per_metre: float,
) -> ImageArray:
    """A ground texture ``(height, width, 3)``.

    Args:
        rng: random generator.
        style: one of :data:`GROUND_STYLES`.
        base_colour: BGR base colour.
        size: ``(width, height)`` in pixels.
        pixels_per_metre: resolution, used for the size of tiles and joints.
    """
    width, height = size
    base = np.asarray(base_colour, dtype=np.float32)
    rows = np.arange(height)[:, None]
    columns = np.arange(width)[None, :]
    image: ImageArray = np.broadcast_to(base, (height, width, 3)).copy()
    if style in ("paving", "tiles", "brick", "checker"):
        tile_w = {"paving": 0.6, "tiles": 1.2, "brick": 0.4, "checker": 2.0}[
            style
        ] * pixels_per_metre
        tile_h = {"paving": 0.6, "tiles": 1.2, "brick": 0.2, "checker": 2.0}[
            style
        ] * pixels_per_metre
        tile_row = rows // max(int(tile_h), 1)
        offset = (tile_row % 2) * (tile_w / 2.0) if style == "brick" else 0.0
        tile_col = ((columns + offset) // max(int(tile_w), 1)).astype(np.int64)
        tile_id = (tile_row * 7919 + tile_col * 104729) % 4096
        if style == "checker":
            palette = np.stack([base, base * 0.72]).astype(np.float32)
            image = palette[(tile_row + tile_col) % 2]
        else:
            palette = _colour_jitter(rng, base, 4096, 0.12)
            image = palette[tile_id]
        joint = max(1, round(0.02 * pixels_per_metre))
        in_joint = ((rows % max(int(tile_h), 1)) < joint) | (
            ((columns + offset).astype(np.int64) % max(int(tile_w), 1)) < joint
        )
        image[in_joint] *= 0.6
    elif style == "asphalt":
        lines = (
            np.abs((columns % int(8 * pixels_per_metre)) - 4 * pixels_per_metre)
            < 0.06 * pixels_per_metre
        ) & ((rows // int(3 * pixels_per_metre)) % 2 == 0)
        image[lines] = (215.0, 220.0, 225.0)
    elif style == "gravel":
        path = np.abs(smooth_noise(rng, height, width, int(6 * pixels_per_metre))) < 0.25
        image[~path] *= np.array([0.55, 0.95, 0.6], dtype=np.float32)
    stains = smooth_noise(rng, height, width, max(int(2.5 * pixels_per_metre), 2))
    return _finish(rng, image, stains, 0.12, 9.0)


def facade_texture(
    rng: np.random.Generator,
    wall_colour: tuple[int, int, int],
    size: tuple[int, int],
    pixels_per_metre: float,
    storey_metres: float = 3.2,
) -> ImageArray:
    """A building facade with rows of windows, ``(height, width, 3)``; row 0 is the roof line."""
    width, height = size
    wall = np.asarray(wall_colour, dtype=np.float64)
    image = np.broadcast_to(wall, (height, width, 3)).copy()
    storey = storey_metres * pixels_per_metre
    bay = rng.uniform(2.5, 4.0) * pixels_per_metre
    window_w, window_h = 0.45 * bay, 0.5 * storey
    rows = np.arange(height)[:, None]
    columns = np.arange(width)[None, :]
    # Storeys are counted from the ground (the last row), so windows sit at a sensible height.
    from_ground = height - 1 - rows
    in_window = (
        ((columns % bay) > (bay - window_w) / 2)
        & ((columns % bay) < (bay + window_w) / 2)
        & ((from_ground % storey) > 0.35 * storey)
        & ((from_ground % storey) < 0.35 * storey + window_h)
    )
    glass = np.array([95.0, 80.0, 70.0]) * rng.uniform(0.7, 1.3)
    image = np.where(in_window[..., None], glass, image)
    return _finish(
        rng, image, smooth_noise(rng, height, width, int(4 * pixels_per_metre)), 0.1, 6.0
    )


def plain_texture(
    rng: np.random.Generator,
    colour: tuple[int, int, int],
    size: tuple[int, int],
    pixels_per_metre: float,
    stripe_metres: float = 0.0,
) -> ImageArray:
    """A plain material (concrete, planks) with grain and optional stripes across the columns."""
    width, height = size
    image = np.broadcast_to(np.asarray(colour, dtype=np.float64), (height, width, 3)).copy()
    if stripe_metres > 0:
        columns = np.arange(width)[None, :]
        joint = (columns % max(int(stripe_metres * pixels_per_metre), 2)) < max(
            1, int(0.02 * pixels_per_metre)
        )
        image = np.where(joint[..., None], image * 0.65, image)
    return _finish(rng, image, smooth_noise(rng, height, width, int(pixels_per_metre)), 0.1, 7.0)


def load_background(path: Path, size: tuple[int, int], pixels_per_metre: float) -> ImageArray:
    """A real image used as the ground texture, ``(height, width, 3)`` for ``size = (w, h)``.

    When an ``H.txt`` lies beside the image (ETH/UCY OpenTraj layout: ``H @ [row, col, 1]`` gives
    world metres), the image is first rectified to a top view at ``pixels_per_metre``; otherwise
    it is taken to be a top view already. The result is then tiled (mirrored) to ``size``.
    """
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise UserError(f"{path}: cannot read this background image; expected a PNG or JPEG file.")
    homography_file = path.parent / "H.txt"
    if homography_file.is_file():
        image = _rectify(image, homography_file, pixels_per_metre)
    else:
        # Without a scale, assume the image spans 30 m across.
        factor = 30.0 * pixels_per_metre / image.shape[1]
        image = cv2.resize(image, None, fx=factor, fy=factor, interpolation=cv2.INTER_LINEAR)
    width, height = size
    reps_x = width // image.shape[1] + 1
    reps_y = height // image.shape[0] + 1
    tile = np.concatenate([image, image[:, ::-1]], axis=1)
    tile = np.concatenate([tile, tile[::-1]], axis=0)
    tiled = np.tile(tile, (reps_y // 2 + 1, reps_x // 2 + 1, 1))
    return np.ascontiguousarray(tiled[:height, :width])


def _rectify(image: ImageArray, homography_file: Path, pixels_per_metre: float) -> ImageArray:
    try:
        homography = np.loadtxt(homography_file, dtype=np.float64).reshape(3, 3)
    except ValueError:
        raise UserError(
            f"{homography_file}: expected a 3x3 matrix of numbers (image row,col -> world metres)."
        ) from None
    height, width = image.shape[:2]
    corners = np.array([[0, 0, 1], [height, 0, 1], [height, width, 1], [0, width, 1]], dtype=float)
    world = corners @ homography.T
    world = world[:, :2] / world[:, 2:3]
    low, high = world.min(axis=0), world.max(axis=0)
    out_w = int(min((high[0] - low[0]) * pixels_per_metre, 4000))
    out_h = int(min((high[1] - low[1]) * pixels_per_metre, 4000))
    if out_w < 8 or out_h < 8:
        raise UserError(f"{homography_file}: the homography maps the image to a tiny area.")
    # top-view pixel -> world -> image (row, col) -> image (x, y)
    to_world = np.array(
        [[1 / pixels_per_metre, 0, low[0]], [0, 1 / pixels_per_metre, low[1]], [0, 0, 1.0]]
    )
    swap = np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, 1]])
    matrix = swap @ np.linalg.inv(homography) @ to_world
    return cv2.warpPerspective(
        image,
        matrix,
        (out_w, out_h),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REFLECT_101,
    )

"""Drawing people and composing frames.

People are pre-rendered once per video as premultiplied BGRA sprites (a body per gait phase, a
head, a soft shadow) at a few resolutions; each frame then places them with one small
``cv2.warpAffine`` each, far to near (painter's algorithm). Heads are drawn as a skin ellipse
under a hair (or hat) cap, the way a head looks from a first to fourth floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from trackfw.arrays import FloatArray, ImageArray

#: Sprite size at full resolution: body (width, height) from neck (top) to feet (bottom).
BODY_SPRITE = (64, 176)
HEAD_SPRITE = 48
GAIT_PHASES = 4
#: Shoulder width, head diameter and the neck height below the top of the head (metres).
BODY_WIDTH_M = 0.50
HEAD_DIAMETER_M = 0.22

SKIN_TONES = ((170, 195, 235), (140, 170, 215), (105, 140, 190), (75, 105, 150), (50, 70, 105))
HAIR_COLOURS = ((20, 20, 25), (30, 40, 60), (45, 70, 110), (110, 150, 190), (150, 150, 150),
                (20, 25, 35))


@dataclass(frozen=True)
class PersonLook:
    """How one person is dressed (BGR colours)."""

    shirt: tuple[int, int, int]
    shirt_second: tuple[int, int, int]
    pattern: str
    trousers: tuple[int, int, int]
    skin: tuple[int, int, int]
    hair: tuple[int, int, int]
    hat: tuple[int, int, int] | None
    bag: tuple[int, int, int] | None
    width_factor: float


def _colour(rng: np.random.Generator, saturated: bool) -> tuple[int, int, int]:
    hue = int(rng.integers(0, 180))
    saturation = int(rng.integers(120, 255)) if saturated else int(rng.integers(0, 90))
    value = int(rng.integers(50, 240))
    pixel = np.array([[[hue, saturation, value]]], dtype=np.uint8)
    bgr = cv2.cvtColor(pixel, cv2.COLOR_HSV2BGR)[0, 0]
    return int(bgr[0]), int(bgr[1]), int(bgr[2])


def random_look(rng: np.random.Generator) -> PersonLook:
    """Draw clothing, skin, hair, hat and bag at random."""
    hat = _colour(rng, bool(rng.random() < 0.5)) if rng.random() < 0.15 else None
    bag = _colour(rng, False) if rng.random() < 0.25 else None
    return PersonLook(
        shirt=_colour(rng, bool(rng.random() < 0.55)),
        shirt_second=_colour(rng, bool(rng.random() < 0.5)),
        pattern=str(rng.choice(["plain", "plain", "stripes", "checks", "two_tone"])),
        trousers=_colour(rng, bool(rng.random() < 0.2)),
        skin=SKIN_TONES[int(rng.integers(len(SKIN_TONES)))],
        hair=HAIR_COLOURS[int(rng.integers(len(HAIR_COLOURS)))],
        hat=hat,
        bag=bag,
        width_factor=float(rng.uniform(0.85, 1.15)),
    )


def _premultiply(bgra: ImageArray) -> ImageArray:
    image = bgra.astype(np.float32)
    image[..., :3] *= image[..., 3:4] / 255.0
    return image


def _pyramid(premultiplied: ImageArray, levels: int = 4) -> list[ImageArray]:
    result = [premultiplied]
    for _level in range(1, levels):
        previous = result[-1]
        height, width = previous.shape[:2]
        if min(height, width) < 8:
            break
        result.append(cv2.resize(previous, (max(width // 2, 1), max(height // 2, 1)),
                                 interpolation=cv2.INTER_AREA))
    return result


def body_sprite(look: PersonLook, phase: int, rng: np.random.Generator) -> ImageArray:
    """One body (neck at the top row, feet at the bottom), BGRA ``(176, 64, 4)``."""
    width, height = BODY_SPRITE
    canvas = np.zeros((height, width, 4), dtype=np.uint8)
    centre = width // 2
    hip = int(height * 0.45)
    swing = math.sin(2 * math.pi * phase / GAIT_PHASES)
    trousers = (*look.trousers, 255)
    # Legs: two slightly tapering quads; the stride opens and closes with the gait phase.
    for side in (-1, 1):
        foot_x = centre + side * 7 + round(side * swing * 6)
        leg = np.array([[centre + side * 2, hip], [centre + side * 14, hip],
                        [foot_x + side * 5, height - 10], [foot_x - side * 4, height - 10]], np.int32)
        cv2.fillConvexPoly(canvas, leg, trousers, lineType=cv2.LINE_AA)
        cv2.ellipse(canvas, (foot_x, height - 8), (7, 6), 0, 0, 360, (25, 25, 30, 255), -1,
                    lineType=cv2.LINE_AA)
    # Torso: shoulders rounded at the top (seen from above), narrowing to the hips.
    torso_mask = np.zeros((height, width), dtype=np.uint8)
    torso = np.array([[6, 14], [width - 6, 14], [width - 12, hip + 6], [12, hip + 6]], np.int32)
    cv2.fillConvexPoly(torso_mask, torso, 255, lineType=cv2.LINE_AA)
    cv2.ellipse(torso_mask, (centre, 16), (centre - 6, 14), 0, 180, 360, 255, -1, lineType=cv2.LINE_AA)
    cloth = np.zeros((height, width, 3), dtype=np.uint8)
    cloth[:] = look.shirt
    if look.pattern == "stripes":
        for row in range(0, hip + 8, 8):
            cv2.rectangle(cloth, (0, row), (width, row + 3), look.shirt_second, -1)
    elif look.pattern == "checks":
        for row in range(0, hip + 8, 10):
            for column in range(0, width, 10):
                if (row // 10 + column // 10) % 2:
                    cv2.rectangle(cloth, (column, row), (column + 9, row + 9), look.shirt_second, -1)
    elif look.pattern == "two_tone":
        cloth[: hip // 2] = look.shirt_second
    # Fabric shading: lighter on one side, darker on the other (light from the upper left).
    shading = np.linspace(1.15, 0.75, width, dtype=np.float32)[None, :, None]
    cloth = np.clip(cloth.astype(np.float32) * shading + rng.normal(0, 5, cloth.shape), 0, 255)
    alpha = torso_mask.astype(np.float32)[..., None] / 255.0
    canvas[..., :3] = (canvas[..., :3] * (1 - alpha) + cloth * alpha).astype(np.uint8)
    canvas[..., 3] = np.maximum(canvas[..., 3], torso_mask)
    # Arms swing opposite to the legs.
    for side in (-1, 1):
        hand_y = hip + 10 + round(-side * swing * 6)
        shoulder = (centre + side * (centre - 8), 20)
        hand = (centre + side * (centre - 4), hand_y)
        cv2.line(canvas, shoulder, hand, (*look.shirt, 255), 9, lineType=cv2.LINE_AA)
        cv2.circle(canvas, hand, 4, (*look.skin, 255), -1, lineType=cv2.LINE_AA)
    if look.bag is not None:
        cv2.rectangle(canvas, (centre - 14, 18), (centre + 14, hip - 10), (*look.bag, 255), -1,
                      lineType=cv2.LINE_AA)
    return canvas


def head_sprite(look: PersonLook) -> ImageArray:
    """A head seen from above and in front: skin ellipse, hair or hat cap, BGRA ``(48, 48, 4)``."""
    size = HEAD_SPRITE
    canvas = np.zeros((size, size, 4), dtype=np.uint8)
    centre = (size // 2, size // 2)
    axes = (int(size * 0.40), int(size * 0.46))
    cv2.ellipse(canvas, centre, axes, 0, 0, 360, (*look.skin, 255), -1, lineType=cv2.LINE_AA)
    head_mask = canvas[..., 3].copy()
    cap = np.zeros((size, size), dtype=np.uint8)
    cap_colour = look.hat if look.hat is not None else look.hair
    cap_axes = (int(size * 0.44), int(size * 0.40))
    cv2.ellipse(cap, (size // 2, int(size * 0.36)), cap_axes, 0, 0, 360, 255, -1, lineType=cv2.LINE_AA)
    if look.hat is None:
        cap = np.minimum(cap, head_mask)
    weight = cap.astype(np.float32)[..., None] / 255.0
    canvas[..., :3] = (canvas[..., :3] * (1 - weight) + np.array(cap_colour) * weight).astype(np.uint8)
    canvas[..., 3] = np.maximum(head_mask, cap)
    # Round shading, so the head reads as a ball rather than a disc.
    grid_y, grid_x = np.mgrid[0:size, 0:size].astype(np.float32)
    distance = np.hypot(grid_x - size * 0.4, grid_y - size * 0.35) / (size * 0.6)
    shade = np.clip(1.15 - 0.45 * distance, 0.55, 1.15)[..., None]
    canvas[..., :3] = np.clip(canvas[..., :3] * shade, 0, 255).astype(np.uint8)
    if look.hat is None:  # eyes and a darker mouth line on the face part
        for side in (-1, 1):
            cv2.circle(canvas, (size // 2 + side * 7, int(size * 0.70)), 2, (30, 30, 40, 255), -1,
                       lineType=cv2.LINE_AA)
    return canvas


def shadow_sprite() -> ImageArray:
    """A soft dark ellipse (premultiplied BGRA float) laid on the ground under a person."""
    size = 64
    alpha = np.zeros((size, size), dtype=np.float32)
    cv2.ellipse(alpha, (size // 2, size // 2), (26, 26), 0, 0, 360, 1.0, -1, lineType=cv2.LINE_AA)
    alpha = cv2.GaussianBlur(alpha, (0, 0), 5) * 110.0
    sprite = np.zeros((size, size, 4), dtype=np.float32)
    sprite[..., 3] = alpha
    return sprite


@dataclass
class PersonSprites:
    """Pre-rendered pyramids of one person: body per gait phase and head."""

    bodies: list[list[ImageArray]]
    head: list[ImageArray]

    @classmethod
    def build(cls, look: PersonLook, rng: np.random.Generator) -> PersonSprites:
        bodies = [_pyramid(_premultiply(body_sprite(look, phase, rng))) for phase in range(GAIT_PHASES)]
        return cls(bodies=bodies, head=_pyramid(_premultiply(head_sprite(look))))


def paste(frame: ImageArray, pyramid: list[ImageArray], destination: FloatArray) -> None:
    """Warp a premultiplied sprite onto ``frame`` (in place) and blend it.

    Args:
        frame: ``(H, W, 3)`` uint8 image.
        pyramid: sprite levels, full resolution first, each ``(h, w, 4)`` premultiplied float32.
        destination: ``(3, 2)`` image positions of the sprite's top-centre, bottom-centre and
            top-left corner.
    """
    # Plain float maths: this runs for every person on every frame, numpy calls cost more here.
    (top_x, top_y), (bottom_x, bottom_y), (corner_x, corner_y) = destination.tolist()
    side_x, side_y = top_x - corner_x, top_y - corner_y
    full_height, full_width = pyramid[0].shape[:2]
    # Choose the level that is at most 2x larger than needed: sharper than a big downsample.
    wanted = max(2.0 * math.hypot(side_x, side_y) / full_width,
                 math.hypot(bottom_x - top_x, bottom_y - top_y) / full_height)
    level = 0
    while level + 1 < len(pyramid) and wanted < 0.5 ** (level + 1):
        level += 1
    sprite = pyramid[level]
    height, width = sprite.shape[:2]
    xs = (corner_x, top_x + side_x, bottom_x - side_x, bottom_x + side_x)
    ys = (corner_y, top_y + side_y, bottom_y - side_y, bottom_y + side_y)
    left = max(math.floor(min(xs)) - 1, 0)
    upper = max(math.floor(min(ys)) - 1, 0)
    right = min(math.ceil(max(xs)) + 2, frame.shape[1])
    lower = min(math.ceil(max(ys)) + 2, frame.shape[0])
    if right <= left or lower <= upper:
        return
    source = np.array([[width / 2.0, 0.0], [width / 2.0, float(height)], [0.0, 0.0]], dtype=np.float32)
    target = np.array([[top_x - left, top_y - upper], [bottom_x - left, bottom_y - upper],
                       [corner_x - left, corner_y - upper]], dtype=np.float32)
    matrix = cv2.getAffineTransform(source, target)
    warped = cv2.warpAffine(sprite, matrix, (right - left, lower - upper), flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    region = frame[upper:lower, left:right]
    keep = 1.0 - warped[..., 3:4] * np.float32(1.0 / 255.0)
    # Premultiplied colours never exceed 255, so the unsafe cast cannot wrap around.
    np.copyto(region, region * keep + warped[..., :3], casting="unsafe")


def motion_blur(frame: ImageArray, vector: FloatArray) -> ImageArray:
    """Blur along ``vector`` (pixels moved during the exposure, ``(2,)``)."""
    length = float(np.hypot(vector[0], vector[1]))
    if length < 1.5:
        return frame
    # Long kernels are costly: blur a half-size image instead when the streak is long.
    factor = 2 if length > 24 else 1
    length_scaled = min(length / factor, 60.0)
    size = math.ceil(length_scaled) | 1
    kernel = np.zeros((size, size), dtype=np.float32)
    direction = np.asarray(vector, dtype=np.float64) / length * (length_scaled / 2.0)
    middle = size // 2
    cv2.line(kernel, (round(middle - direction[0]), round(middle - direction[1])),
             (round(middle + direction[0]), round(middle + direction[1])), 1.0, 1,
             lineType=cv2.LINE_AA)
    kernel /= max(float(kernel.sum()), 1e-6)
    if factor == 1:
        return cv2.filter2D(frame, -1, kernel, borderType=cv2.BORDER_REFLECT)
    height, width = frame.shape[:2]
    small = cv2.resize(frame, (width // 2, height // 2), interpolation=cv2.INTER_AREA)
    small = cv2.filter2D(small, -1, kernel, borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (width, height), interpolation=cv2.INTER_LINEAR)


class SensorNoise:
    """A bank of pre-drawn Gaussian noise images, so per-frame noise costs two saturating adds."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, int], sigma: float,
                 bank: int = 3) -> None:
        noise = rng.standard_normal(size=(bank, shape[0], shape[1], 3), dtype=np.float32)
        # Mostly luminance noise (shared by the channels), a little colour noise.
        noise = (noise.mean(axis=3, keepdims=True) * 1.5 + noise * 0.35) * np.float32(sigma)
        self.positive = np.clip(noise, 0, 255).astype(np.uint8)
        self.negative = np.clip(-noise, 0, 255).astype(np.uint8)

    def apply(self, frame: ImageArray, index: int) -> ImageArray:
        """Add the noise image ``index`` (modulo the bank size)."""
        slot = index % len(self.positive)
        return cv2.subtract(cv2.add(frame, self.positive[slot]), self.negative[slot])

"""Shared test images for the re-identification descriptors."""

from __future__ import annotations

import cv2
import numpy as np


def person_image(
    rng: np.random.Generator, shape: tuple[int, int] = (128, 48), head: bool = True
) -> np.ndarray:
    """A crude 128×48 "person": textured background, shirt and trousers with stripes, and a
    skin-coloured head patch unless ``head`` is False."""
    height, width = shape
    background = cv2.resize(
        rng.integers(60, 200, size=(8, 4, 3), dtype=np.uint8),
        (width, height),
        interpolation=cv2.INTER_LINEAR,
    )
    image = background.copy()
    shirt, trousers = rng.integers(0, 256, size=(2, 3))
    image[20:70, 8:40] = shirt
    image[70:125, 12:36] = trousers
    period = int(rng.integers(3, 9))
    image[20:70:period, 8:40] = (shirt // 2).astype(np.uint8)
    if head:
        image[4:20, 16:32] = (150, 170, 210)
    return image

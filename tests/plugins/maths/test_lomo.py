"""Tests of the LOMO descriptor (docs/algorithms/gap-matchers.md#lomo)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from trackfw_plugins.maths.lomo import (
    lomo_descriptor,
    lomo_descriptors,
    lomo_hsv_block,
    lomo_siltp_block,
    max_row_histograms,
    retinex,
    rgb_to_hsv,
    siltp_codes,
)
from trackfw_plugins.maths.reid_crop import reid_distance_matrix

from .conftest import person_image


def _noisy_shift(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    shifted = np.roll(image, shift=(2, 1), axis=(0, 1))
    noise = rng.normal(0.0, 6.0, size=image.shape)
    return np.clip(shifted.astype(np.float64) + noise, 0, 255).astype(np.uint8)


def test_dimensions_and_block_norms() -> None:
    image = person_image(np.random.default_rng(0))
    descriptor = lomo_descriptor(image)
    assert descriptor.shape == (26960,)
    assert np.linalg.norm(descriptor[:20480]) == pytest.approx(1.0)
    assert np.linalg.norm(descriptor[20480:23720]) == pytest.approx(1.0)
    assert np.linalg.norm(descriptor[23720:]) == pytest.approx(1.0)
    assert np.all(descriptor >= 0)
    assert lomo_descriptors(np.stack([image, image])).shape == (2, 26960)


def test_pyramid_gives_40_rows_per_code_map() -> None:
    image = person_image(np.random.default_rng(1))
    hsv_block = lomo_hsv_block(image[..., ::-1].copy())
    assert hsv_block.shape == (40 * 512,)
    rows = hsv_block.reshape(40, 512)
    # Each row is a bin-wise max of 100-pixel window histograms.
    assert np.all(rows.sum(axis=1) >= 100)
    assert rows.max() <= 100
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) / 255.0
    for radius in (3, 5):
        assert lomo_siltp_block(gray, radius).shape == (40 * 81,)


def test_max_row_histograms_takes_the_maximum_over_each_row() -> None:
    codes = np.zeros((20, 20), dtype=np.int64)
    codes[:10, 10:] = 1  # only the right-hand windows of the first row see code 1
    histograms = max_row_histograms(codes, bins=2)
    assert histograms.shape == (3, 2)
    np.testing.assert_array_equal(histograms[0], [100, 100])
    np.testing.assert_array_equal(histograms[2], [100, 0])


def test_siltp_is_scale_invariant() -> None:
    gray = np.random.default_rng(4).uniform(0.1, 0.5, size=(30, 20))
    np.testing.assert_array_equal(siltp_codes(gray, 3), siltp_codes(gray * 1.9, 3))
    assert siltp_codes(gray, 3).max() < 81


def test_rgb_to_hsv_agrees_with_opencv() -> None:
    rgb = np.random.default_rng(6).uniform(0, 1, size=(50, 3)).astype(np.float32)
    ours = rgb_to_hsv(rgb)
    theirs = cv2.cvtColor(rgb[None], cv2.COLOR_RGB2HSV)[0].astype(np.float64)
    theirs[:, 0] /= 360.0
    np.testing.assert_allclose(ours, theirs, atol=1e-4)


def test_retinex_output_range() -> None:
    output = retinex(person_image(np.random.default_rng(2))[..., ::-1].copy())
    assert output.shape == (128, 48, 3)
    assert output.min() >= 0.0 and output.max() <= 255.0
    assert output.max() > 200.0  # the balance stretches each channel


def test_same_person_ranks_first() -> None:
    rng = np.random.default_rng(7)
    people = [person_image(rng) for _ in range(6)]
    query = np.stack([lomo_descriptor(person) for person in people[:3]])
    gallery_images = [_noisy_shift(person, rng) for person in people]
    gallery = np.stack([lomo_descriptor(image) for image in gallery_images])
    distances = reid_distance_matrix(query, gallery)
    assert distances.shape == (3, 6)
    np.testing.assert_array_equal(distances.argmin(axis=1), [0, 1, 2])

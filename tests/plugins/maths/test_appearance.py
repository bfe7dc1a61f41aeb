"""Tests of the E_a appearance descriptor (docs/algorithms/gap-matchers.md#appearance-term)."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

from trackfw_plugins.maths.appearance import (
    DESCRIPTOR_SIZE,
    HOG_SIZE,
    LBP_BINS,
    appearance_descriptors,
    appearance_distance_matrix,
    extract_patch,
    lbp_codes,
    patch_descriptor,
    uniform_lbp_histogram,
    uniform_lbp_table,
)


@pytest.fixture(scope="module")
def textured_image() -> np.ndarray:
    rng = np.random.default_rng(1)
    small = rng.integers(0, 256, size=(30, 40, 3), dtype=np.uint8)
    image = cv2.resize(small, (320, 240), interpolation=cv2.INTER_CUBIC)
    noise = rng.integers(0, 40, size=image.shape)
    return np.clip(image.astype(np.int64) + noise, 0, 255).astype(np.uint8)


def _reference_lbp(gray: np.ndarray) -> np.ndarray:
    """Per-pixel circular LBP(8, 1) with bilinear interpolation, written the slow way."""
    image = gray.astype(np.float64)
    height, width = image.shape
    codes = np.zeros((height - 2, width - 2), dtype=np.int64)
    for row in range(1, height - 1):
        for column in range(1, width - 1):
            code = 0
            for k in range(8):
                y = row - np.sin(2 * np.pi * k / 8)
                x = column + np.cos(2 * np.pi * k / 8)
                y0, x0 = int(np.floor(y + 1e-9)), int(np.floor(x + 1e-9))
                fy, fx = y - y0, x - x0
                if abs(fy) < 1e-6:
                    fy = 0.0
                if abs(fx) < 1e-6:
                    fx = 0.0
                value = (1 - fy) * (1 - fx) * image[y0, x0]
                if fx:
                    value += (1 - fy) * fx * image[y0, x0 + 1]
                if fy:
                    value += fy * (1 - fx) * image[y0 + 1, x0]
                if fx and fy:
                    value += fy * fx * image[y0 + 1, x0 + 1]
                code |= int(value >= image[row, column] - 1e-9 * 255) << k
            codes[row - 1, column - 1] = code
    return codes


def test_uniform_mapping_has_58_plus_1_bins() -> None:
    table = uniform_lbp_table()
    assert len(table) == 256
    assert len(np.unique(table)) == LBP_BINS == 59
    uniform_codes = [code for code in range(256) if table[code] < 58]
    assert len(uniform_codes) == 58
    # Every uniform code has at most two circular transitions, every other code more.
    for code in range(256):
        bits = [(code >> k) & 1 for k in range(8)]
        transitions = sum(bits[k] != bits[(k + 1) % 8] for k in range(8))
        assert (transitions <= 2) == (table[code] < 58)


def test_vectorised_lbp_matches_the_per_pixel_definition() -> None:
    gray = np.random.default_rng(3).integers(0, 256, size=(12, 15)).astype(np.uint8)
    gray[4:8, 4:8] = 100  # a flat area exercises the equality case
    np.testing.assert_array_equal(lbp_codes(gray), _reference_lbp(gray))


def test_lbp_histogram_sums_to_one() -> None:
    gray = np.random.default_rng(2).integers(0, 256, size=(80, 80))
    histogram = uniform_lbp_histogram(gray)
    assert histogram.shape == (59,)
    assert histogram.sum() == pytest.approx(1.0)
    assert histogram[58] > 0  # random texture has non-uniform codes


def test_dimensions_and_unit_norm(textured_image: np.ndarray) -> None:
    points = np.array([[100.0, 100.0], [200.0, 150.0], [0.0, 0.0]])
    descriptors = appearance_descriptors(textured_image, points)
    assert descriptors.shape == (3, DESCRIPTOR_SIZE)
    assert DESCRIPTOR_SIZE == 3 + 3 + 59 + HOG_SIZE
    assert HOG_SIZE == 2916
    np.testing.assert_allclose(np.linalg.norm(descriptors, axis=1), 1.0, rtol=1e-9)
    assert np.all(descriptors >= 0.0)
    # Each of the four groups has norm 1/2.
    bounds = np.cumsum([0, 3, 3, 59, 2916])
    for start, end in itertools.pairwise(bounds):
        np.testing.assert_allclose(np.linalg.norm(descriptors[:, start:end], axis=1), 0.5)


def test_patch_uses_replicated_border(textured_image: np.ndarray) -> None:
    patch = extract_patch(textured_image, (5.0, 7.0))
    padded = np.pad(textured_image, ((40, 40), (40, 40), (0, 0)), mode="edge")
    np.testing.assert_array_equal(patch, padded[7 : 7 + 80, 5 : 5 + 80])
    assert extract_patch(textured_image, (50.0, 60.0), scale=1.5).shape == (80, 80, 3)


def test_same_patch_is_at_zero_and_changes_are_farther(textured_image: np.ndarray) -> None:
    centre = np.array([[160.0, 120.0]])
    reference = appearance_descriptors(textured_image, centre)
    same = appearance_descriptors(textured_image.copy(), centre)
    shifted = appearance_descriptors(textured_image, centre + np.array([20.0, 0.0]))
    noise = np.random.default_rng(5).integers(0, 6, textured_image.shape)
    noisy_image = np.clip(textured_image.astype(np.int64) + noise, 0, 255).astype(np.uint8)
    noisy = appearance_descriptors(noisy_image, centre)
    recoloured_image = textured_image.copy()
    recoloured_image[..., 0] = 255 - recoloured_image[..., 0]
    recoloured = appearance_descriptors(recoloured_image, centre)
    distances = appearance_distance_matrix(reference, np.vstack([same, noisy, shifted, recoloured]))
    assert distances.shape == (1, 4)
    assert distances[0, 0] == pytest.approx(0.0, abs=1e-7)
    assert 0.0 < distances[0, 1] < distances[0, 2]
    assert distances[0, 1] < distances[0, 3]
    assert np.all(distances <= np.sqrt(2.0) + 1e-9)


def test_distance_matrix_is_euclidean() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(4, 7)), rng.normal(size=(3, 7))
    expected = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    np.testing.assert_allclose(appearance_distance_matrix(a, b), expected, atol=1e-9)


def test_rejects_non_bgr_patch() -> None:
    with pytest.raises(ValueError, match="uint8"):
        patch_descriptor(np.zeros((80, 80), dtype=np.uint8))

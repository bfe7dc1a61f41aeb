"""Tests of the GOG descriptor (docs/algorithms/gap-matchers.md#gog)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from trackfw_plugins.maths.gog import (
    COLOUR_SPACES,
    gaussian_embedding_log,
    gog_block_sizes,
    gog_colour_descriptor,
    gog_descriptor,
    gog_descriptors,
    half_vectorise,
    normalise_gog,
    patch_gaussians,
    pixel_features,
)
from trackfw_plugins.maths.reid_crop import reid_distance_matrix

from .conftest import person_image


def _reference_embedding_log(means: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """The embedding's log written plainly: |Σ|^(−1/(d+1))·[[Σ + μμᵀ, μ], [μᵀ, 1]], then eigh,
    log of the eigenvalues, recomposed. ``(N, d)``, ``(N, d, d)`` -> ``(N, (d+1)(d+2)/2)``."""
    count, dimension = means.shape
    embedded = np.zeros((count, dimension + 1, dimension + 1))
    embedded[:, :dimension, :dimension] = covariances + np.einsum("ni,nj->nij", means, means)
    embedded[:, :dimension, dimension] = embedded[:, dimension, :dimension] = means
    embedded[:, dimension, dimension] = 1.0
    _, log_determinants = np.linalg.slogdet(covariances)
    embedded *= np.exp(-log_determinants / (dimension + 1))[:, None, None]
    values, vectors = np.linalg.eigh(embedded)
    return half_vectorise(np.einsum("nik,nk,njk->nij", vectors, np.log(values), vectors))


def _reference_colour_descriptor(image_rgb: np.ndarray, colour_space: str) -> np.ndarray:
    """One colour space's GOG from the pixel features: centred covariances patch by patch (the
    window clipped at the border), then strip by strip."""
    features = pixel_features(image_rgb, colour_space)
    means, covariances = [], []
    for row in range(0, 128, 2):
        for column in range(0, 48, 2):
            window = features[max(row - 2, 0) : row + 3, max(column - 2, 0) : column + 3]
            samples = window.reshape(-1, features.shape[-1])
            centred = samples - samples.mean(axis=0)
            covariance = centred.T @ centred / (len(samples) - 1)
            covariance += 0.001 * max(np.trace(covariance), 0.01) * np.eye(len(covariance))
            means.append(samples.mean(axis=0))
            covariances.append(covariance)
    patches = _reference_embedding_log(np.array(means), np.array(covariances)).reshape(64, 24, -1)
    size = patches.shape[-1]
    column_weights = np.exp(-((np.arange(1, 25) - 12) ** 2) / (2 * 6**2))
    weights = np.tile(column_weights, 16) / (16 * column_weights.sum())
    means, covariances = [], []
    for top in range(0, 7 * 8, 8):  # 16-row strips every 8 rows on the 64×24 grid
        samples = patches[top : top + 16].reshape(-1, size)
        mean = weights @ samples
        covariance = (samples - mean).T @ ((samples - mean) * weights[:, None])
        covariances.append(covariance + 0.001 * np.trace(covariance) * np.eye(size))
        means.append(mean)
    return _reference_embedding_log(np.array(means), np.array(covariances)).reshape(-1)


def test_dimensions() -> None:
    image = person_image(np.random.default_rng(0), head=False)[..., ::-1].copy()
    assert gog_colour_descriptor(image, "rgb").shape == (7567,)
    assert gog_colour_descriptor(image, "nrng").shape == (4921,)
    assert sum(gog_block_sizes()) == 27622
    flat = gog_descriptor(np.full((128, 48, 3), 90, dtype=np.uint8))
    assert flat.shape == (27622,)
    assert np.all(np.isfinite(flat))  # a constant crop must not break the SPD embedding


def test_descriptors_on_threads_are_those_of_one_crop_at_a_time() -> None:
    rng = np.random.default_rng(3)
    crops = np.stack([person_image(rng, head=False) for _ in range(3)])
    one_by_one = np.stack([gog_descriptor(crop) for crop in crops])
    np.testing.assert_array_equal(gog_descriptors(crops, workers=1), one_by_one)
    np.testing.assert_array_equal(gog_descriptors(crops, workers=3), one_by_one)
    assert gog_descriptors(crops[:0], workers=2).shape == (0, 27622)


def test_descriptor_matches_a_plain_reference() -> None:
    """The batched path (one Gram matrix per patch for all colour spaces, eigenvalues giving the
    determinant) against a patch-by-patch computation: equal up to round-off, so a faster
    path that changes the values fails here."""
    rng = np.random.default_rng(11)
    smooth = cv2.resize(rng.integers(0, 256, size=(16, 6, 3), dtype=np.uint8), (48, 128))
    noise = rng.integers(0, 256, size=(128, 48, 3), dtype=np.uint8)
    for image_bgr in (person_image(rng), smooth, noise):
        image_rgb = image_bgr[..., ::-1].copy()
        expected = np.concatenate(
            [_reference_colour_descriptor(image_rgb, space) for space in COLOUR_SPACES]
        )
        actual = gog_descriptor(image_bgr)
        np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-8 * np.abs(expected).max())


def test_pixel_features() -> None:
    image = np.zeros((6, 4, 3), dtype=np.uint8)
    image[:, 2:] = 255  # a vertical edge: gradient along +x only
    features = pixel_features(image, "rgb")
    assert features.shape == (6, 4, 8)
    np.testing.assert_allclose(features[:, 0, 0], np.arange(1, 7) / 6)
    # Magnitude at the edge goes fully into the 0° bin.
    assert features[2, 1, 1] > 0 and features[2, 1, 2:5].sum() == 0
    np.testing.assert_allclose(features[0, 3, 5:], 1.0)
    assert pixel_features(image, "nrng").shape == (6, 4, 7)
    lab = pixel_features(image, "lab")
    np.testing.assert_allclose(lab[0, 3, 5:], [1.0, 0.5, 0.5], atol=0.01)
    with pytest.raises(ValueError, match="colour space"):
        pixel_features(image, "xyz")


def test_half_vectorisation_keeps_the_frobenius_norm() -> None:
    matrix = np.random.default_rng(1).normal(size=(5, 5))
    symmetric = matrix + matrix.T
    vector = half_vectorise(symmetric)
    assert vector.shape == (15,)
    assert np.linalg.norm(vector) == pytest.approx(np.linalg.norm(symmetric))


def test_embedding_log_of_standard_gaussian_is_zero_and_matches_scipy() -> None:
    from scipy.linalg import logm

    assert np.allclose(gaussian_embedding_log(np.zeros((1, 3)), np.eye(3)[None]), 0.0)
    rng = np.random.default_rng(2)
    factor = rng.normal(size=(3, 3))
    covariance = factor @ factor.T + 0.1 * np.eye(3)
    mean = rng.normal(size=3)
    embedded = np.block([[covariance + np.outer(mean, mean), mean[:, None]], [mean[None], 1.0]])
    embedded /= np.linalg.det(covariance) ** (1 / 4)
    expected = half_vectorise(np.real(logm(embedded)))
    np.testing.assert_allclose(
        gaussian_embedding_log(mean[None], covariance[None])[0], expected, atol=1e-8
    )


def test_patch_gaussians_match_direct_statistics() -> None:
    rng = np.random.default_rng(3)
    features = rng.uniform(size=(12, 10, 2))
    vectors = patch_gaussians(features)
    assert vectors.shape == (6, 5, 6)
    for grid_row, grid_column in [(0, 0), (3, 2), (5, 4)]:
        row, column = 2 * grid_row, 2 * grid_column
        window = features[max(row - 2, 0) : row + 3, max(column - 2, 0) : column + 3]
        samples = window.reshape(-1, 2)
        covariance = np.cov(samples, rowvar=False)
        covariance += 0.001 * max(np.trace(covariance), 0.01) * np.eye(2)
        expected = gaussian_embedding_log(samples.mean(axis=0)[None], covariance[None])[0]
        np.testing.assert_allclose(vectors[grid_row, grid_column], expected, atol=1e-9)


@pytest.fixture(scope="module")
def query_and_gallery() -> tuple[np.ndarray, np.ndarray]:
    """Raw GOG of 4 people and of a shifted, noised copy of each (computed once)."""
    rng = np.random.default_rng(9)
    people = [person_image(rng, head=False) for _ in range(4)]
    query = np.stack([gog_descriptor(person) for person in people])
    gallery = []
    for person in people:
        shifted = np.roll(person, shift=(2, 1), axis=(0, 1)).astype(np.float64)
        noisy = np.clip(shifted + rng.normal(0, 6, size=person.shape), 0, 255).astype(np.uint8)
        gallery.append(gog_descriptor(noisy))
    return query, np.stack(gallery)


def test_normalised_blocks_have_unit_norm(
    query_and_gallery: tuple[np.ndarray, np.ndarray],
) -> None:
    raw = np.vstack(query_and_gallery)
    assert raw.shape == (8, 27622)
    normalised = normalise_gog(raw)
    start = 0
    for size in gog_block_sizes():
        np.testing.assert_allclose(np.linalg.norm(normalised[:, start : start + size], axis=1), 1)
        start += size
    # Centred on the pooled mean: the normalised descriptors are not all in one orthant.
    assert normalised.min() < 0 < normalised.max()


def test_same_person_ranks_first(query_and_gallery: tuple[np.ndarray, np.ndarray]) -> None:
    query, gallery = query_and_gallery
    # Two targets against all four candidates (two of them distractors).
    distances = reid_distance_matrix(query[:2], gallery, gog_block_sizes())
    assert distances.shape == (2, 4)
    np.testing.assert_array_equal(distances.argmin(axis=1), [0, 1])
    everyone = reid_distance_matrix(query, gallery, gog_block_sizes())
    np.testing.assert_array_equal(everyone.argmin(axis=1), np.arange(4))

"""Tests of the re-ID crops, training-free distances and XQDA.

See docs/algorithms/gap-matchers.md#re-identification.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from trackfw_plugins.maths.lomo import lomo_descriptors
from trackfw_plugins.maths.reid_crop import (
    fit_xqda,
    head_size,
    normalise_pooled,
    reid_crop,
    reid_crops,
    reid_distance_matrix,
)


def _gradient_frame(height: int = 1080, width: int = 1920) -> np.ndarray:
    rows, columns = np.indices((height, width))
    return np.stack([columns % 256, rows % 256, (rows + columns) % 256], axis=-1).astype(np.uint8)


def test_body_crop_geometry() -> None:
    frame = _gradient_frame()
    x, y = 900.0, 300.0
    crop = reid_crop(frame, (x, y))
    assert crop.shape == (128, 48, 3) and crop.dtype == np.uint8
    # s = 80 at 1080p: box [x − 60, y − 40, 120 × 320].
    expected = cv2.resize(frame[260:580, 840:960], (48, 128), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(crop, expected)


def test_crop_scales_with_frame_height() -> None:
    assert head_size(540) == pytest.approx(40.0)
    frame = _gradient_frame(540, 960)
    crop = reid_crop(frame, (400.0, 100.0))
    expected = cv2.resize(frame[80:240, 370:430], (48, 128), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(crop, expected)


def test_crop_outside_the_frame_replicates_the_border() -> None:
    frame = _gradient_frame(200, 300)
    frame[0, 0] = (1, 2, 3)
    crop = reid_crop(frame, (-100.0, -100.0), mode="head80")
    assert crop.shape == (80, 80, 3)
    assert np.all(crop == np.array([1, 2, 3], dtype=np.uint8))
    with pytest.raises(ValueError, match="crop mode"):
        reid_crop(frame, (10.0, 10.0), mode="legs")
    assert reid_crops(frame, np.zeros((0, 2))).shape == (0, 128, 48, 3)


def test_pooled_normalisation() -> None:
    rng = np.random.default_rng(0)
    query, gallery = rng.normal(5.0, 1.0, (3, 6)), rng.normal(5.0, 1.0, (4, 6))
    first, second = normalise_pooled(query, gallery, block_sizes=(2, 4))
    pooled = np.vstack([first, second])
    np.testing.assert_allclose(np.linalg.norm(pooled[:, :2], axis=1), 1.0)
    np.testing.assert_allclose(np.linalg.norm(pooled[:, 2:], axis=1), 1.0)
    distances = reid_distance_matrix(query, query)
    np.testing.assert_allclose(np.diag(distances), 0.0, atol=1e-7)
    with pytest.raises(ValueError, match="blocks"):
        normalise_pooled(query, gallery, block_sizes=(2, 2))


def _draw_person(
    frame: np.ndarray, head: np.ndarray, shirt: tuple, trousers: tuple, period: int
) -> None:
    x, y = int(head[0]), int(head[1])
    size = int(head_size(frame.shape[0]))
    cv2.circle(frame, (x, y), size // 2, (120, 160, 200), -1)
    cv2.rectangle(frame, (x - size // 2, y + size // 2), (x + size // 2, y + 2 * size), shirt, -1)
    for stripe in range(y + size // 2, y + 2 * size, period):
        cv2.line(frame, (x - size // 2, stripe), (x + size // 2, stripe), (20, 20, 20), 1)
    cv2.rectangle(
        frame, (x - size // 3, y + 2 * size), (x + size // 3, y + int(3.4 * size)), trousers, -1
    )


def test_same_people_are_ranked_first_across_frames() -> None:
    rng = np.random.default_rng(3)
    height, width = 540, 960
    count = 5
    looks = [
        (
            tuple(int(v) for v in rng.integers(0, 256, 3)),
            tuple(int(v) for v in rng.integers(0, 256, 3)),
            int(rng.integers(4, 12)),
        )
        for _ in range(count)
    ]
    backdrop = cv2.resize(rng.integers(40, 120, (9, 16, 3), dtype=np.uint8), (width, height))
    frame_a, frame_b = backdrop.copy(), backdrop.copy()
    heads_a = np.array([[100 + 170 * i, 120] for i in range(count)])
    # Frame b: another viewpoint, people shuffled and moved, plus sensor noise.
    order = rng.permutation(count)
    heads_b = np.array([[130 + 160 * slot, 150 + 10 * slot] for slot in range(count)])
    for person, (shirt, trousers, period) in enumerate(looks):
        _draw_person(frame_a, heads_a[person], shirt, trousers, period)
        _draw_person(frame_b, heads_b[order[person]], shirt, trousers, period)
    frame_b = np.clip(frame_b + rng.normal(0, 5, frame_b.shape), 0, 255).astype(np.uint8)
    query = lomo_descriptors(reid_crops(frame_a, heads_a))
    gallery = lomo_descriptors(reid_crops(frame_b, heads_b))
    distances = reid_distance_matrix(query, gallery)
    np.testing.assert_array_equal(distances.argmin(axis=1), order)


def test_xqda_learns_a_metric_that_separates_identities() -> None:
    rng = np.random.default_rng(5)
    identities, per_identity, dimension = 6, 5, 40
    centres = rng.normal(0.0, 1.0, (identities, dimension))
    # Large nuisance variance on a few directions shared by everyone, small identity signal.
    nuisance = np.zeros(dimension)
    nuisance[:5] = 6.0

    def sample(count: int) -> tuple[np.ndarray, np.ndarray]:
        labels = np.repeat(np.arange(identities), count)
        noise = rng.normal(size=(len(labels), dimension)) * (0.3 + nuisance)
        return centres[labels] + noise, labels

    train, train_labels = sample(per_identity)
    model = fit_xqda(train, train_labels)
    assert model is not None
    test, test_labels = sample(1)
    gallery, gallery_labels = sample(1)
    learned = model.distances(test, gallery)
    plain = reid_distance_matrix(test, gallery)
    learned_hits = np.mean(gallery_labels[learned.argmin(axis=1)] == test_labels)
    plain_hits = np.mean(gallery_labels[plain.argmin(axis=1)] == test_labels)
    assert learned_hits == 1.0
    assert learned_hits > plain_hits
    assert fit_xqda(train, np.zeros(len(train))) is None  # no negative pairs

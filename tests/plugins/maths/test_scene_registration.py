"""Tests of the scene registration between two frames."""

from __future__ import annotations

import cv2
import numpy as np

from trackfw_plugins.maths.scene_registration import (
    RegistrationSettings,
    people_mask,
    plausible,
    register_scene,
    transform_points,
)


def _scene(seed: int, size: tuple[int, int] = (480, 640)) -> np.ndarray:
    """A textured frame: blurred noise with rectangles, rich in corners."""
    rng = np.random.default_rng(seed)
    image = cv2.GaussianBlur(rng.integers(0, 255, (*size, 3), dtype=np.uint8), (5, 5), 0)
    for _ in range(60):
        x, y = rng.integers(0, size[1] - 40), rng.integers(0, size[0] - 40)
        colour = tuple(int(c) for c in rng.integers(0, 255, 3))
        cv2.rectangle(image, (int(x), int(y)), (int(x + 30), int(y + 25)), colour, -1)
    return image


def _similarity(angle_deg: float, scale: float, shift: tuple[float, float]) -> np.ndarray:
    matrix = cv2.getRotationMatrix2D((320.0, 240.0), angle_deg, scale)
    matrix[:, 2] += shift
    return np.vstack([matrix, [0.0, 0.0, 1.0]])


def test_recovers_a_known_camera_motion() -> None:
    image_a = _scene(0)
    truth = _similarity(6.0, 1.1, (25.0, -15.0))
    image_b = cv2.warpPerspective(image_a, truth, (640, 480))
    registration = register_scene(image_a, image_b)
    assert registration.ok
    assert registration.inliers >= 15
    points = np.array([[200.0, 200.0], [400.0, 300.0], [320.0, 100.0]])
    error = np.linalg.norm(registration.apply(points) - transform_points(truth, points), axis=1)
    assert error.max() < 3.0


def test_unrelated_frames_fail_with_identity() -> None:
    registration = register_scene(_scene(1), _scene(2))
    assert not registration.ok
    assert registration.reason
    np.testing.assert_array_equal(registration.matrix, np.eye(3))


def test_people_are_masked_out() -> None:
    mask = people_mask((200, 200), np.array([[90.0, 20.0, 20.0, 20.0]]), scale=1.0)
    assert mask[25, 100] == 0  # the head
    assert mask[150, 100] == 0  # the body below it
    assert mask[25, 10] == 255  # the scene beside it


def test_homography_model_and_akaze_run() -> None:
    image_a = _scene(3)
    truth = _similarity(-4.0, 0.95, (10.0, 5.0))
    image_b = cv2.warpPerspective(image_a, truth, (640, 480))
    for settings in (
        RegistrationSettings(model="homography"),
        RegistrationSettings(features="akaze"),
    ):
        registration = register_scene(image_a, image_b, settings=settings)
        assert registration.ok
        point = np.array([[300.0, 250.0]])
        assert np.linalg.norm(registration.apply(point) - transform_points(truth, point)) < 3.0


def test_collapsed_or_flipped_maps_are_implausible() -> None:
    assert plausible(np.eye(3), (480, 640), 4.0)
    assert plausible(np.diag([1.5, 1.5, 1.0]), (480, 640), 4.0)
    assert not plausible(np.diag([0.2, 0.2, 1.0]), (480, 640), 4.0)  # area / 25
    assert not plausible(np.diag([-1.0, 1.0, 1.0]), (480, 640), 4.0)  # mirrored

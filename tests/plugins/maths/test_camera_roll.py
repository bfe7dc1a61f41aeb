"""The camera's roll from the frame's near-vertical lines, and upright crops.

See docs/algorithms/segment-tracker.md#upright-crops.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw_plugins.maths.camera_roll import upright_angle
from trackfw_plugins.maths.person_reid import PersonReidEmbedder, cosine_distance_matrix
from trackfw_plugins.maths.reid_crop import crop_box


def _facade(height: int = 480, width: int = 640) -> np.ndarray:
    """A grey street front: dark vertical window edges and a few horizontal ledges."""
    rng = np.random.default_rng(3)
    image = np.full((height, width, 3), 170, dtype=np.uint8)
    for x in range(40, width - 40, 70):
        image[60 : height - 60, x : x + 6] = 40
    for y in (120, 300):
        image[y : y + 4, :] = 90
    noise = rng.integers(-10, 10, size=image.shape)
    return np.clip(image.astype(np.int64) + noise, 0, 255).astype(np.uint8)


def _turned(image: np.ndarray, angle: float) -> np.ndarray:
    height, width = image.shape[:2]
    matrix = cv2.getRotationMatrix2D((width / 2, height / 2), angle, 1.0)
    return cv2.warpAffine(image, matrix, (width, height), borderMode=cv2.BORDER_REPLICATE)


@pytest.mark.parametrize("roll", [-9.0, -4.0, 0.0, 6.0, 12.0])
def test_the_upright_angle_undoes_the_roll(roll: float) -> None:
    # A camera rolled by `roll` shows the scene turned by -roll; turning it back by the
    # estimate must stand the edges upright again.
    rolled = _turned(_facade(), -roll)
    angle = upright_angle(rolled)
    assert angle == pytest.approx(roll, abs=1.0)


def test_a_frame_without_vertical_lines_has_no_roll() -> None:
    sky = np.full((480, 640, 3), 200, dtype=np.uint8)
    assert upright_angle(sky) is None
    ledges = np.full((480, 640, 3), 200, dtype=np.uint8)
    ledges[100:104, :] = 30
    ledges[300:304, :] = 30
    assert upright_angle(ledges) is None


def test_large_frames_are_read_at_the_same_angle() -> None:
    rolled = _turned(_facade(960, 1280), -7.0)
    assert upright_angle(rolled) == pytest.approx(7.0, abs=1.0)


def test_a_turned_crop_of_a_turned_person_is_the_upright_crop() -> None:
    upright = _facade()
    left, top, width, height = 250.0, 150.0, 90.0, 180.0
    reference = crop_box(upright, left, top, width, height, (256, 128)).astype(np.int64)
    # Turned about the box centre, the person stays at the box; cut turned back, it is upright.
    centre = (left + width / 2, top + height / 2)
    matrix = cv2.getRotationMatrix2D(centre, -10.0, 1.0)
    rolled = cv2.warpAffine(upright, matrix, (640, 480), borderMode=cv2.BORDER_REPLICATE)
    plain = crop_box(rolled, left, top, width, height, (256, 128)).astype(np.int64)
    turned = crop_box(rolled, left, top, width, height, (256, 128), 10.0).astype(np.int64)
    inner = (slice(20, -20), slice(10, -10))  # the corners come from outside the box
    assert np.abs(turned - reference)[inner].mean() < 0.3 * np.abs(plain - reference)[inner].mean()


def test_no_turn_is_the_plain_crop() -> None:
    image = _facade()
    np.testing.assert_array_equal(
        crop_box(image, 10.5, 20.2, 60.0, 120.0, (256, 128), 0.0),
        crop_box(image, 10.5, 20.2, 60.0, 120.0, (256, 128)),
    )


def test_upright_crops_bring_a_rolled_person_back_to_its_look(shared_data: Path) -> None:
    # TUD-Stadtmitte's people, seen through a camera rolled by 10 degrees: cut upright with
    # the estimated angle, each lies nearer its upright embedding than cut as it stands.
    sequence = shared_data / "TUD-Stadtmitte"
    gt = np.loadtxt(sequence / "gt" / "gt.txt", delimiter=",")
    image = cv2.imread(str(sequence / "img1" / "000040.jpg"))
    rows = gt[(gt[:, 0] == 40) & (gt[:, 5] > 150)]
    boxes = rows[:, 2:6].copy()
    boxes[:, 0] += boxes[:, 2] / 2 - boxes[:, 3] / 4
    boxes[:, 2] = boxes[:, 3] / 2
    embedder = PersonReidEmbedder("0287", threads=1)
    upright = embedder.describe(image, boxes)
    height, width = image.shape[:2]
    matrix = cv2.getRotationMatrix2D((width / 2, height / 2), -10.0, 1.0)
    rolled = cv2.warpAffine(image, matrix, (width, height), borderMode=cv2.BORDER_REPLICATE)
    centres = boxes[:, :2] + boxes[:, 2:] / 2
    moved = boxes.copy()
    moved[:, :2] = centres @ matrix[:, :2].T + matrix[:, 2] - boxes[:, 2:] / 2
    angle = upright_angle(rolled)
    assert angle == pytest.approx(10.0, abs=2.0)
    as_it_stands = np.diagonal(cosine_distance_matrix(upright, embedder.describe(rolled, moved)))
    cut_upright = np.diagonal(
        cosine_distance_matrix(upright, embedder.describe(rolled, moved, angle))
    )
    assert len(rows) >= 3
    assert np.median(cut_upright) < 0.6 * np.median(as_it_stands)

"""Procedural textures and real backgrounds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.datasets.synth.textures import (
    GROUND_STYLES,
    facade_texture,
    ground_texture,
    load_background,
)


@pytest.mark.parametrize("style", GROUND_STYLES)
def test_ground_textures_have_the_size_and_some_structure(style: str) -> None:
    rng = np.random.default_rng(0)
    texture = ground_texture(rng, style, (140, 150, 160), (300, 200), 10.0)
    assert texture.shape == (200, 300, 3) and texture.dtype == np.uint8
    assert texture.std() > 5.0
    again = ground_texture(np.random.default_rng(0), style, (140, 150, 160), (300, 200), 10.0)
    assert np.array_equal(texture, again)


def test_facade_has_windows_darker_than_the_wall() -> None:
    texture = facade_texture(np.random.default_rng(1), (200, 210, 220), (400, 160), 10.0)
    brightness = texture.mean(axis=2)
    assert np.percentile(brightness, 10) < np.percentile(brightness, 90) - 40


def test_background_image_is_rectified_with_its_homography(shared_data: Path) -> None:
    reference = shared_data / "eth_ucy" / "opentraj" / "ETH" / "seq_hotel" / "reference.png"
    texture = load_background(reference, (900, 700), 20.0)
    assert texture.shape == (700, 900, 3)
    assert texture.std() > 10.0


def test_unreadable_background_is_a_user_error(tmp_path: Path) -> None:
    path = tmp_path / "ground.png"
    path.write_bytes(b"not an image")
    with pytest.raises(UserError, match=r"ground\.png"):
        load_background(path, (100, 100), 10.0)

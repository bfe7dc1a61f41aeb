"""The appearance veto of re-acquisition: looks decide, except on patches cut by the border."""

from __future__ import annotations

import numpy as np

from trackfw.records import Detections
from trackfw_plugins.trackers.appearance_memory import AppearanceMemory, AppearanceSettings


def _image() -> np.ndarray:
    # Left half red, right half noisy green: a red-patch target and green-patch bystanders.
    rng = np.random.default_rng(0)
    image = np.zeros((360, 640, 3), dtype=np.uint8)
    image[:, :320, 2] = 200
    image[:, 320:, 1] = rng.integers(100, 255, size=(360, 320))
    return image


def test_patch_veto_refuses_a_different_look_inside_but_not_at_the_border() -> None:
    image = _image()
    memory = AppearanceMemory(AppearanceSettings(descriptor="patch"), 1, 360, 25.0)
    seen = Detections.from_points(np.array([[150.0, 180.0]]))
    memory.remember(0, image, np.array([0]), seen, np.array([0]))
    # A bystander in the green half well inside the image, and one at the right edge whose
    # patch is half replicated border.
    candidates = Detections.from_points(np.array([[480.0, 180.0], [635.0, 180.0], [160.0, 170.0]]))
    veto = memory.veto(image, np.array([0]), candidates, np.arange(3), np.ones((1, 3), dtype=bool))
    assert veto.tolist() == [[True, False, False]]


def test_entering_pairs_need_a_descriptor_and_the_stricter_distance() -> None:
    image = _image()
    settings = AppearanceSettings(descriptor="patch", max_distance=1.2, reentry_max_distance=0.05)
    memory = AppearanceMemory(settings, 2, 360, 25.0)
    seen = Detections.from_points(np.array([[150.0, 180.0]]))
    memory.remember(0, image, np.array([0]), seen, np.array([0]))  # target 1 never described
    candidates = Detections.from_points(np.array([[480.0, 180.0], [635.0, 180.0]]))
    entering = np.array([[True, True], [True, False]])
    veto = memory.veto(
        image, np.array([0, 1]), candidates, np.arange(2), np.ones((2, 2), dtype=bool), entering
    )
    # Inside: farther than 0.05 though within 1.2; at the border the patch says nothing, so an
    # entering pair there is refused; target 1 has no descriptor: its entering pair is refused.
    assert veto.tolist() == [[True, True], [True, False]]

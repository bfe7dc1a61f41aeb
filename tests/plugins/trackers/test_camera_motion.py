"""Camera-motion compensation between consecutive frames: the map from one frame to the next."""

from __future__ import annotations

import cv2
import numpy as np

from trackfw_plugins.trackers.camera_motion import FrameMotion, consecutive_frames_registration


def _scene(shift_px: float) -> np.ndarray:
    """A textured 640x360 scene seen by a camera panned ``shift_px`` to the left."""
    random = np.random.default_rng(5)
    scene = cv2.GaussianBlur(random.integers(0, 255, (360, 640, 3), dtype=np.uint8), (5, 5), 0)
    for _ in range(80):
        x, y = random.integers(0, 600), random.integers(0, 330)
        colour = tuple(int(c) for c in random.integers(0, 255, 3))
        cv2.rectangle(scene, (int(x), int(y)), (int(x + 30), int(y + 25)), colour, -1)
    return cv2.warpAffine(scene, np.array([[1.0, 0, -shift_px], [0, 1.0, 0]]), (640, 360))


def test_the_motion_of_a_pan_from_one_frame_to_the_next() -> None:
    motion = FrameMotion(consecutive_frames_registration())
    assert motion.motion(_scene(0.0), None) is None  # no previous frame yet
    matrix = motion.motion(_scene(12.0), None)
    assert matrix is not None
    assert np.allclose(matrix[:2, 2], [-12.0, 0.0], atol=1.0)
    assert np.allclose(matrix[:2, :2], np.eye(2), atol=0.01)
    # A frame without pixels breaks the chain: the next frame has nothing to register to.
    assert motion.motion(None, None) is None
    assert motion.motion(_scene(24.0), None) is None

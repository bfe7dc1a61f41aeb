"""Camera-motion compensation between consecutive frames (the Kalman tracker's ``cmc``).

As BoT-SORT's global motion compensation: the scene features of each frame (outside the heads)
are registered to the previous frame's, and the filters are warped by that map before they
predict. See docs/algorithms/segment-tracker.md#parameters.
"""

from __future__ import annotations

from trackfw.arrays import FloatArray, UInt8Array
from trackfw_plugins.maths.scene_registration import (
    RegistrationSettings,
    SceneFeatures,
    register_features,
    scene_features,
)


def consecutive_frames_registration() -> RegistrationSettings:
    """The registration of consecutive frames that ``cmc`` uses by default."""
    # BoT-SORT's GMC fits a partial affine map (a similarity) to sparse features between
    # consecutive frames. A full affine fit sheared by walkers' features, and a similarity that
    # zooms by more than a few percent in 1/30 s, moved predictions 15-40 px off the heads (synth
    # seed 9): between consecutive frames the camera barely changes scale.
    return RegistrationSettings(model="similarity", max_features=500, max_area_change=1.05)


class FrameMotion:
    """The previous frame's scene features, and the camera's motion from it to each new frame.

    Each frame's features are found once: the frame is registered as the newer one, then kept
    as the older one for the next frame.
    """

    def __init__(self, settings: RegistrationSettings) -> None:
        self.settings = settings
        self.previous: SceneFeatures | None = None

    def remember(self, image: UInt8Array | None, boxes: FloatArray | None) -> None:
        """Keep this frame's scene features (outside the head ``boxes``) for the next frame."""
        self.previous = None if image is None else scene_features(image, boxes, self.settings)

    def motion(self, image: UInt8Array | None, boxes: FloatArray | None) -> FloatArray | None:
        """Remember this frame; return the ``(3, 3)`` map from the previous frame to it, or
        None when either frame has no features or the two do not register."""
        previous = self.previous
        self.remember(image, boxes)
        if previous is None or self.previous is None:
            return None
        registration = register_features(previous, self.previous, self.settings)
        return registration.matrix if registration.ok else None


__all__ = ["FrameMotion", "consecutive_frames_registration"]

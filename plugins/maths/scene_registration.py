"""Scene registration: how the camera moved between two frames, from the static background.

See docs/algorithms/predictors.md#scene-registration.

The paper treats the camera poses at a and b as unrelated. A wearer usually looks back at the
same scene, so the background of frames a and b tells how the image moved: binary features
(ORB or AKAZE) are detected outside the people (each head box grown into a body box), matched
with a ratio test, and a similarity, affine or homography is fitted with RANSAC. The inlier count
and ratio say how far to trust it; a failed registration is reported, never guessed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray
from trackfw.stages import FiniteModel

#: Body box around a head box of side s: from ``BODY_SIDE`` s left/right of its centre and from
#: half a head above it to ``BODY_BELOW`` s below (a standing person is ~7 heads tall).
BODY_SIDE = 1.2
BODY_BELOW = 7.5


class RegistrationSettings(FiniteModel):
    """Settings of :func:`register_scene` (docs/algorithms/predictors.md#scene-registration)."""

    features: Literal["orb", "akaze", "sift"] = Field(
        "orb", description="feature detector/descriptor"
    )
    max_features: int = Field(1500, ge=10, le=100000, description="ORB: most keypoints per frame")
    max_side: int = Field(
        640, ge=64, le=100000, description="frames are downscaled to this longer side first"
    )
    ratio: float = Field(0.8, gt=0, le=1, description="Lowe ratio test on the two nearest")
    model: Literal["similarity", "affine", "homography"] = Field(
        "similarity", description="motion model fitted with RANSAC"
    )
    ransac_px: float = Field(
        3.0, gt=0, description="RANSAC inlier threshold in pixels of the downscaled frame"
    )
    min_inliers: int = Field(15, ge=4, le=100000, description="fewer inliers: registration failed")
    min_inlier_ratio: float = Field(
        0.25, ge=0, le=1, description="smaller inliers/matches: registration failed"
    )
    mask_people: bool = Field(True, description="ignore features on the detected people")
    max_area_change: float = Field(
        4.0,
        gt=1,
        description="the frame's outline mapped to b must keep its area within this factor"
        " (wrong fits on a patch of sky or a repeated texture collapse it)",
    )


@dataclass(frozen=True)
class SceneRegistration:
    """The image motion from frame a to frame b.

    Attributes:
        matrix: ``(3, 3)`` homogeneous map of frame-a pixels to frame-b pixels (identity when
            the registration failed).
        ok: whether enough inliers support it.
        matches: feature matches that passed the ratio test.
        inliers: RANSAC inliers among them.
        residual_px: median inlier reprojection error in full-resolution pixels.
        reason: why it failed ("" when ok).
    """

    matrix: FloatArray
    ok: bool
    matches: int
    inliers: int
    residual_px: float
    reason: str = ""

    @property
    def inlier_ratio(self) -> float:
        """Inliers over matches (0 without matches)."""
        return self.inliers / self.matches if self.matches else 0.0

    def apply(self, points: FloatArray) -> FloatArray:
        """Map ``(P, 2)`` frame-a pixels to frame b."""
        return transform_points(self.matrix, points)

    def walks(self, at_a: FloatArray, at_b: FloatArray, frames: int) -> FloatArray:
        """``(P, 2)`` pixels per frame each point moved against the scene from ``(P, 2)``
        ``at_a`` on frame a to ``at_b`` on frame b, ``frames`` frames later: its motion with the
        camera's registered out (a walker's own walk, not the wearer's sway).

        >>> shift = np.array([[1.0, 0.0, -10.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        >>> camera = SceneRegistration(shift, True, 50, 40, 0.5)  # the view slid 10 px left
        >>> camera.walks(np.array([[100.0, 50.0]]), np.array([[110.0, 50.0]]), 10).tolist()
        [[2.0, 0.0]]
        """
        return (np.asarray(at_b, dtype=np.float64) - self.apply(at_a)) / frames

    def summary(self) -> dict[str, object]:
        """JSON-ready record for gaps.json."""
        return {
            "ok": self.ok,
            "matrix": [[round(float(v), 6) for v in row] for row in self.matrix],
            "matches": self.matches,
            "inliers": self.inliers,
            "residual_px": round(self.residual_px, 3),
            "reason": self.reason,
        }


def transform_points(matrix: FloatArray, points: FloatArray) -> FloatArray:
    """Apply a ``(3, 3)`` homogeneous map to ``(P, 2)`` points."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    mapped = np.hstack([points, np.ones((len(points), 1))]) @ np.asarray(matrix).T
    return mapped[:, :2] / mapped[:, 2:3]


def people_mask(shape: tuple[int, int], boxes: FloatArray | None, scale: float) -> np.ndarray:
    """``(H, W)`` uint8 mask, 255 on the static scene and 0 on the people's bodies.

    Args:
        shape: (H, W) of the (downscaled) frame.
        boxes: ``(N, 4)`` head boxes (left, top, width, height) in full-resolution pixels.
        scale: downscale factor applied to the frame.
    """
    mask = np.full(shape, 255, dtype=np.uint8)
    if boxes is None:
        return mask
    for left, top, width, height in np.asarray(boxes, dtype=np.float64).reshape(-1, 4) * scale:
        side = max(width, height)
        centre = left + width / 2
        x0, x1 = int(centre - BODY_SIDE * side), int(np.ceil(centre + BODY_SIDE * side))
        y0, y1 = int(top - side / 2), int(np.ceil(top + BODY_BELOW * side))
        mask[max(y0, 0) : max(y1, 0), max(x0, 0) : max(x1, 0)] = 0
    return mask


def _features(
    image: np.ndarray, mask: np.ndarray, settings: RegistrationSettings
) -> tuple[FloatArray, np.ndarray | None]:
    """Keypoint positions ``(P, 2)`` and binary descriptors of a grey frame."""
    # OpenCV 5 keeps AKAZE in the contrib module xfeatures2d (opencv-contrib-python); the
    # factories are looked up by name because the stubs of 4.x and 5.x disagree on them.
    if settings.features == "orb":
        detector = getattr(cv2, "ORB_create")(nfeatures=settings.max_features)  # noqa: B009
    elif settings.features == "sift":
        detector = getattr(cv2, "SIFT_create")(nfeatures=settings.max_features)  # noqa: B009
    else:
        factory = getattr(cv2, "AKAZE_create", None) or getattr(cv2.xfeatures2d, "AKAZE_create")  # noqa: B009
        detector = factory()
    keypoints, descriptors = detector.detectAndCompute(image, mask)
    points = np.array([kp.pt for kp in keypoints], dtype=np.float64).reshape(-1, 2)
    return points, descriptors


def _grey(image: np.ndarray, scale: float) -> np.ndarray:
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    if scale < 1.0:
        grey = cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    return grey


def _failed(matches: int, inliers: int, reason: str) -> SceneRegistration:
    return SceneRegistration(np.eye(3), False, matches, inliers, float("nan"), reason)


def _fit(
    source: np.ndarray, target: np.ndarray, settings: RegistrationSettings
) -> tuple[FloatArray | None, np.ndarray | None]:
    """RANSAC fit of the motion model; ``(3, 3)`` matrix and inlier flags, or Nones."""
    if settings.model == "homography":
        matrix, flags = cv2.findHomography(source, target, cv2.RANSAC, settings.ransac_px)
        if matrix is None:
            return None, None
        return np.asarray(matrix, dtype=np.float64), np.asarray(flags)
    fit = cv2.estimateAffinePartial2D if settings.model == "similarity" else cv2.estimateAffine2D
    affine, flags = fit(source, target, method=cv2.RANSAC, ransacReprojThreshold=settings.ransac_px)
    if affine is None:
        return None, None
    return np.vstack([affine, [0.0, 0.0, 1.0]]), np.asarray(flags)


@dataclass(frozen=True)
class SceneFeatures:
    """Features of one frame's static scene, ready to register against another frame's.

    Attributes:
        points: ``(P, 2)`` keypoint positions in the downscaled frame.
        descriptors: their descriptors (None when the detector found none).
        scale: the downscale factor of the frame (``max_side`` over its longer side, at most 1).
        shape: ``(H, W)`` of the downscaled frame.
    """

    points: FloatArray
    descriptors: np.ndarray | None
    scale: float
    shape: tuple[int, int]


def scene_features(
    image: np.ndarray, boxes: FloatArray | None, settings: RegistrationSettings
) -> SceneFeatures:
    """Detect the features of ``image`` outside the bodies of the ``(N, 4)`` head ``boxes``.

    A frame registered against several others (each frame of a segment against the next, for
    camera-motion compensation) needs its features found only once.
    """
    scale = min(1.0, settings.max_side / max(image.shape[:2]))
    grey = _grey(image, scale)
    mask = people_mask(grey.shape[:2], boxes if settings.mask_people else None, scale)
    points, descriptors = _features(grey, mask, settings)
    return SceneFeatures(points, descriptors, scale, (grey.shape[0], grey.shape[1]))


def register_scene(
    image_a: np.ndarray,
    image_b: np.ndarray,
    boxes_a: FloatArray | None = None,
    boxes_b: FloatArray | None = None,
    settings: RegistrationSettings | None = None,
) -> SceneRegistration:
    """Estimate the image motion from frame a to frame b from their static scene.

    Args:
        image_a: ``(H, W, 3)`` uint8 BGR frame a (or ``(H, W)`` grey).
        image_b: frame b, the same size.
        boxes_a: ``(N, 4)`` head boxes on a whose bodies are masked out, or None.
        boxes_b: ``(M, 4)`` head boxes on b.
        settings: the settings.

    Returns:
        The registration; ``ok`` is False (with an identity matrix) when too few features,
        matches or inliers support it.
    """
    settings = settings if settings is not None else RegistrationSettings()
    return register_features(
        scene_features(image_a, boxes_a, settings),
        scene_features(image_b, boxes_b, settings),
        settings,
    )


def register_features(
    features_a: SceneFeatures, features_b: SceneFeatures, settings: RegistrationSettings
) -> SceneRegistration:
    """:func:`register_scene` on features already found (frames of the same size)."""
    points_a, descriptors_a = features_a.points, features_a.descriptors
    points_b, descriptors_b = features_b.points, features_b.descriptors
    scale = features_a.scale
    if descriptors_a is None or descriptors_b is None or len(points_a) < 2 or len(points_b) < 2:
        return _failed(0, 0, "too few features")
    norm = cv2.NORM_L2 if settings.features == "sift" else cv2.NORM_HAMMING
    pairs = cv2.BFMatcher(norm).knnMatch(descriptors_a, descriptors_b, k=2)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < settings.ratio * p[1].distance]
    if len(good) < settings.min_inliers:
        return _failed(len(good), 0, "too few matches")
    source = points_a[[m.queryIdx for m in good]].astype(np.float32)
    target = points_b[[m.trainIdx for m in good]].astype(np.float32)
    matrix, flags = _fit(source, target, settings)
    if matrix is None or flags is None:
        return _failed(len(good), 0, "RANSAC found no model")
    inlier = flags.reshape(-1).astype(bool)
    count = int(inlier.sum())
    # Back to full-resolution pixels: x_b = S^-1 M S x_a with S the downscale.
    rescale = np.diag([scale, scale, 1.0])
    full = np.linalg.inv(rescale) @ matrix @ rescale
    errors = np.linalg.norm(transform_points(matrix, source[inlier]) - target[inlier], axis=1)
    residual = float(np.median(errors)) / scale if count else float("nan")
    if count < settings.min_inliers or count < settings.min_inlier_ratio * len(good):
        return SceneRegistration(np.eye(3), False, len(good), count, residual, "too few inliers")
    if not plausible(matrix, features_a.shape, settings.max_area_change):
        return SceneRegistration(np.eye(3), False, len(good), count, residual, "implausible map")
    return SceneRegistration(full / full[2, 2], True, len(good), count, residual)


def plausible(matrix: FloatArray, shape: tuple[int, int], max_area_change: float) -> bool:
    """Whether the map keeps the frame's outline a convex, unflipped quadrilateral whose area
    changes by at most ``max_area_change`` (a camera turn or zoom does; a collapsed fit does not).
    """
    height, width = shape
    corners = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
    mapped = transform_points(matrix, corners)
    edges = np.roll(mapped, -1, axis=0) - mapped
    following = np.roll(edges, -1, axis=0)
    turns = edges[:, 0] * following[:, 1] - edges[:, 1] * following[:, 0]
    x, y = mapped[:, 0], mapped[:, 1]
    # Shoelace area; positive for the image's (clockwise in y-down) corner order.
    ratio = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) / (width * height)
    return bool((turns > 0).all()) and 1.0 / max_area_change <= ratio <= max_area_change


__all__ = [
    "RegistrationSettings",
    "SceneFeatures",
    "SceneRegistration",
    "people_mask",
    "plausible",
    "register_features",
    "register_scene",
    "scene_features",
    "transform_points",
]

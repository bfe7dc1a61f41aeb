"""Camera geometry of the virtual wearer: a rotation homography of a real frame.

``H = K_out R K_src^-1`` with ``K_src`` the focal length of a ``horizontal_fov`` camera and
``K_out`` the same camera zoomed by ``scale``; see :mod:`trackfw_plugins.datasets.wear` for the
pose conventions. The output is filled where the source does not reach with a blurred, mirrored
continuation of the frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Width of the blend between the real frame and its blurred continuation (fraction of width).
FEATHER = 0.025


@dataclass(frozen=True)
class CameraPose:
    """Warp parameters of one frame (see the module docstring for the conventions)."""

    pan: float = 0.0
    tilt: float = 0.0
    roll: float = 0.0
    scale: float = 1.0
    tx: float = 0.0
    ty: float = 0.0


def pose_homography(
    pose: CameraPose,
    source_size: tuple[int, int],
    output_size: tuple[int, int],
    horizontal_fov: float,
) -> np.ndarray:
    """The ``(3, 3)`` homography from source pixels to output pixels for ``pose``.

    >>> H = pose_homography(CameraPose(), (640, 480), (640, 480), 80.0)
    >>> np.allclose(H, np.eye(3))
    True
    """
    width, height = source_size
    out_width, out_height = output_size
    focal = (width / 2) / math.tan(math.radians(horizontal_fov) / 2)
    cover = max(out_width / width, out_height / height)
    source_camera = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1.0]])
    out_focal = focal * cover * pose.scale
    output_camera = np.array(
        [
            [out_focal, 0, out_width / 2 + pose.tx],
            [0, out_focal, out_height / 2 + pose.ty],
            [0, 0, 1.0],
        ]
    )
    pan, tilt, roll = (math.radians(angle) for angle in (pose.pan, pose.tilt, pose.roll))
    about_y = np.array(
        [[math.cos(pan), 0, math.sin(pan)], [0, 1, 0], [-math.sin(pan), 0, math.cos(pan)]]
    )
    about_x = np.array(
        [[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)], [0, math.sin(tilt), math.cos(tilt)]]
    )
    about_z = np.array(
        [[math.cos(roll), -math.sin(roll), 0], [math.sin(roll), math.cos(roll), 0], [0, 0, 1]]
    )
    homography = output_camera @ about_z @ about_x @ about_y @ np.linalg.inv(source_camera)
    return homography / homography[2, 2]


def transform_points(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a ``(3, 3)`` homography to ``(N, 2)`` points; returns ``(N, 2)``.

    >>> transform_points(np.diag([2.0, 2.0, 1.0]), np.array([[1.0, 3.0]])).tolist()
    [[2.0, 6.0]]
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    homogeneous = np.hstack([points, np.ones((len(points), 1))]) @ homography.T
    return homogeneous[:, :2] / homogeneous[:, 2:3]


def local_scale(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Linear magnification ``sqrt(|det J|)`` of a homography at ``(N, 2)`` points; ``(N,)``.

    For ``H`` normalised so that ``w = h31 x + h32 y + h33``, ``det J = det H / w**3``.

    >>> np.round(local_scale(np.diag([3.0, 3.0, 1.0]), np.zeros((1, 2))), 9).tolist()
    [3.0]
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    w = points @ homography[2, :2] + homography[2, 2]
    return np.sqrt(np.abs(np.linalg.det(homography) / w**3))


def warp_frame(
    image: np.ndarray, homography: np.ndarray, output_size: tuple[int, int]
) -> np.ndarray:
    """Warp a ``(H, W, 3)`` uint8 frame with a ``(3, 3)`` homography to ``output_size``.

    Output pixels the frame does not cover show its mirrored continuation, sharp right at the
    frame's edge (so there is no seam) and fading within ``FEATHER`` of the output size into a
    strong blur (so that no mirrored head is recognisable).
    """
    import cv2

    out_width, out_height = output_size
    sharp = cv2.warpPerspective(
        image, homography, output_size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
    )
    corners = np.array(
        [[0, 0], [image.shape[1], 0], [image.shape[1], image.shape[0]], [0, image.shape[0]]],
        dtype=np.float64,
    )
    projected = transform_points(homography, corners)
    if _inside_polygon(projected, output_size):
        return sharp
    # Feathering at 1/4 and the periphery at 1/8 resolution: both are smooth anyway.
    quarter = np.diag([0.25, 0.25, 1.0])
    quarter_size = (max(out_width // 4, 1), max(out_height // 4, 1))
    outside = 1 - _polygon_mask(transform_points(quarter, projected), quarter_size).round()
    distance = cv2.distanceTransform(outside.astype(np.uint8), cv2.DIST_L2, 3)
    ramp = np.clip(1.0 - distance / (FEATHER * max(quarter_size)), 0.0, 1.0)
    alpha = cv2.resize(ramp * ramp * (3 - 2 * ramp), output_size, interpolation=cv2.INTER_LINEAR)
    small_size = (max(out_width // 8, 1), max(out_height // 8, 1))
    shrink = np.diag([small_size[0] / out_width, small_size[1] / out_height, 1.0])
    periphery = cv2.warpPerspective(
        image,
        shrink @ homography,
        small_size,
        flags=cv2.INTER_AREA,
        borderMode=cv2.BORDER_REFLECT_101,
    )
    periphery = cv2.GaussianBlur(periphery, (0, 0), 3.0)
    periphery = cv2.resize(periphery, output_size, interpolation=cv2.INTER_LINEAR)
    # Inside the frame the sharp warp wins whatever the feathering says.
    alpha = np.maximum(alpha, _polygon_mask(projected, output_size))[:, :, None]
    blended = alpha * sharp.astype(np.float32) + (1.0 - alpha) * periphery.astype(np.float32)
    return np.clip(blended + 0.5, 0, 255).astype(np.uint8)


def _inside_polygon(polygon: np.ndarray, output_size: tuple[int, int]) -> bool:
    """True when the convex ``(4, 2)`` polygon contains the whole output rectangle."""
    import cv2

    contour = polygon.astype(np.float32).reshape(-1, 1, 2)
    width, height = output_size
    return all(
        cv2.pointPolygonTest(contour, (float(x), float(y)), False) >= 0
        for x, y in ((0, 0), (width - 1, 0), (width - 1, height - 1), (0, height - 1))
    )


def _polygon_mask(polygon: np.ndarray, output_size: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` float32 mask, 1 inside the convex ``(4, 2)`` polygon (anti-aliased edge)."""
    import cv2

    mask = np.zeros((output_size[1], output_size[0]), np.float32)
    cv2.fillConvexPoly(mask, np.round(polygon * 16).astype(np.int32), 1.0, cv2.LINE_AA, shift=4)
    return mask


# ------------------------------------------------------------------------------------ planning

"""World geometry and the pinhole camera of the synthetic wearable-camera generator.

World frame (metres): X runs along the wearer's building, Y points away from it into the square
(the square is ``Y > 0``), Z is up, the square's ground is ``Z = 0``. The wearer stands on a
walkway (a balcony or an upper-floor corridor, ``-2.5 < Y < 0``) behind a parapet at ``Y = 0``.

Camera pose: ``pan`` is the heading in degrees (0 looks along +Y, positive turns towards +X),
``tilt`` the elevation in degrees (negative looks down), ``roll`` the rotation about the optical
axis in degrees, ``scale`` a focal-length factor (1 = the nominal field of view; it stands for
the wearer moving closer or farther, which mostly scales the image of a distant group), and
``(tx, ty, tz)`` the camera centre in metres. The image follows OpenCV: x right, y down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from trackfw.arrays import FloatArray, ImageArray

#: Columns of poses.csv (angles in degrees, positions in metres).
POSE_COLUMNS = ("pan", "tilt", "roll", "scale", "tx", "ty", "tz")


@dataclass(frozen=True)
class CameraModel:
    """Pinhole intrinsics of the head-worn camera (no lens distortion).

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        hfov_deg: horizontal field of view at ``scale = 1`` in degrees (GoPro "linear" modes
            are 75-90 degrees).
    """

    width: int = 1280
    height: int = 720
    hfov_deg: float = 75.0

    @property
    def focal(self) -> float:
        """Focal length in pixels at ``scale = 1``."""
        return (self.width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    def intrinsics(self, scale: float = 1.0) -> FloatArray:
        """``(3, 3)`` camera matrix for a focal factor ``scale``."""
        focal = self.focal * scale
        return np.array(
            [[focal, 0.0, self.width / 2.0], [0.0, focal, self.height / 2.0], [0.0, 0.0, 1.0]]
        )


def rotation(pan: float, tilt: float, roll: float) -> FloatArray:
    """World-to-camera rotation ``(3, 3)``; rows are the camera's right, down and forward axes.

    >>> np.round(rotation(0.0, 0.0, 0.0), 6).tolist()
    [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]
    """
    yaw, pitch, twist = math.radians(pan), math.radians(tilt), math.radians(roll)
    forward = np.array(
        [math.sin(yaw) * math.cos(pitch), math.cos(yaw) * math.cos(pitch), math.sin(pitch)]
    )
    right = np.array([math.cos(yaw), -math.sin(yaw), 0.0])
    down = np.cross(forward, right)
    rolled_right = math.cos(twist) * right + math.sin(twist) * down
    rolled_down = -math.sin(twist) * right + math.cos(twist) * down
    return np.stack([rolled_right, rolled_down, forward])


@dataclass(frozen=True)
class Pose:
    """One camera pose (see the module docstring for the meaning of each field)."""

    pan: float
    tilt: float
    roll: float
    scale: float
    tx: float
    ty: float
    tz: float

    @property
    def centre(self) -> FloatArray:
        """Camera centre ``(3,)`` in metres."""
        return np.array([self.tx, self.ty, self.tz])

    @cached_property
    def rotation_matrix(self) -> FloatArray:
        """World-to-camera rotation ``(3, 3)`` (see :func:`rotation`)."""
        return rotation(self.pan, self.tilt, self.roll)

    @classmethod
    def from_row(cls, row: FloatArray) -> Pose:
        """Build a pose from a ``(7,)`` row ordered as :data:`POSE_COLUMNS`."""
        return cls(*(float(value) for value in row))


def project(points: FloatArray, pose: Pose, camera: CameraModel) -> tuple[FloatArray, FloatArray]:
    """Project world points into the image.

    Args:
        points: ``(N, 3)`` world points in metres.
        pose: camera pose.
        camera: intrinsics.

    Returns:
        ``(N, 2)`` pixel positions and ``(N,)`` depths along the optical axis (metres; points
        with depth <= 0 are behind the camera and their pixels are meaningless).
    """
    rotation_matrix = pose.rotation_matrix
    in_camera = (
        np.asarray(points, dtype=np.float64).reshape(-1, 3) - pose.centre
    ) @ rotation_matrix.T
    depth = in_camera[:, 2]
    safe = np.where(depth > 1e-6, depth, 1e-6)
    focal = camera.focal * pose.scale
    pixels = np.stack(
        [
            focal * in_camera[:, 0] / safe + camera.width / 2.0,
            focal * in_camera[:, 1] / safe + camera.height / 2.0,
        ],
        axis=1,
    )
    return pixels, depth


def look_at(centre: FloatArray, target: FloatArray) -> tuple[float, float]:
    """Pan and tilt (degrees) that put ``target`` on the optical axis of a camera at ``centre``.

    >>> [round(value, 3) for value in look_at(np.array([0.0, 0, 10]), np.array([0.0, 10, 0]))]
    [0.0, -45.0]
    """
    delta = np.asarray(target, dtype=np.float64) - np.asarray(centre, dtype=np.float64)
    pan = math.degrees(math.atan2(delta[0], delta[1]))
    tilt = math.degrees(math.atan2(delta[2], math.hypot(delta[0], delta[1])))
    return pan, tilt


@dataclass
class TexturedPlane:
    """A textured planar rectangle of the world (ground, facade, walkway, parapet, wall).

    The plane point for texture pixel ``(u, v)`` is ``origin + u / pixels_per_metre * axis_u +
    v / pixels_per_metre * axis_v``.

    Attributes:
        name: for debugging.
        origin: ``(3,)`` world position of texture pixel (0, 0).
        axis_u: ``(3,)`` unit vector along the texture's columns.
        axis_v: ``(3,)`` unit vector along the texture's rows.
        texture: ``(Ht, Wt, 3)`` BGR texture.
        pixels_per_metre: texture resolution.
    """

    name: str
    origin: FloatArray
    axis_u: FloatArray
    axis_v: FloatArray
    texture: ImageArray
    pixels_per_metre: float
    extent: tuple[float, float, float, float] | None = None

    def corners(self) -> FloatArray:
        """``(4, 3)`` world corners of the rectangle, in polygon order.

        ``extent = (u0, v0, u1, v1)`` (texture pixels) makes the plane larger than its texture;
        the texture is then mirrored beyond its edges.
        """
        height, width = self.texture.shape[:2]
        u0, v0, u1, v1 = self.extent if self.extent is not None else (0.0, 0.0, width, height)
        scale = 1.0 / self.pixels_per_metre
        return np.stack(
            [
                self.origin + scale * (u * self.axis_u + v * self.axis_v)
                for u, v in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))
            ]
        )

    def homography(self, pose: Pose, camera: CameraModel) -> FloatArray:
        """``(3, 3)`` map from texture pixels to image pixels for this pose."""
        rotation_matrix = pose.rotation_matrix
        columns = np.stack(
            [
                rotation_matrix @ self.axis_u / self.pixels_per_metre,
                rotation_matrix @ self.axis_v / self.pixels_per_metre,
                rotation_matrix @ (self.origin - pose.centre),
            ],
            axis=1,
        )
        return camera.intrinsics(pose.scale) @ columns


def clip_polygon(points_camera: FloatArray, normal: FloatArray, offset: float) -> FloatArray:
    """Clip a polygon ``(N, 3)`` to the half-space ``normal . p >= offset``.

    One Sutherland-Hodgman pass; returns ``(M, 3)`` (M may be 0).

    >>> square = np.array([[-1.0, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]])
    >>> clip_polygon(square, np.array([0.0, 0, 1]), 0.0).shape
    (4, 3)
    """
    output: list[FloatArray] = []
    count = len(points_camera)
    values = points_camera @ normal - offset
    for index in range(count):
        following_index = (index + 1) % count
        current, following = points_camera[index], points_camera[following_index]
        current_in = values[index] >= 0
        if current_in:
            output.append(current)
        if current_in != (values[following_index] >= 0):
            fraction = values[index] / (values[index] - values[following_index])
            output.append(current + fraction * (following - current))
    return np.asarray(output).reshape(-1, 3)


def clip_to_view(
    points_camera: FloatArray, camera: CameraModel, scale: float, near: float = 0.05
) -> FloatArray:
    """Clip a polygon in camera coordinates to the viewing frustum (a little wider than the
    image), so that its projection stays bounded; ``(M, 3)``."""
    focal = camera.focal * scale
    slope_x = (camera.width / 2.0 + 8.0) / focal
    slope_y = (camera.height / 2.0 + 8.0) / focal
    polygon = clip_polygon(points_camera, np.array([0.0, 0.0, 1.0]), near)
    for normal in (
        (-1.0, 0.0, slope_x),
        (1.0, 0.0, slope_x),
        (0.0, -1.0, slope_y),
        (0.0, 1.0, slope_y),
    ):
        if len(polygon) < 3:
            break
        polygon = clip_polygon(polygon, np.array(normal), 0.0)
    return polygon


def draw_plane(frame: ImageArray, plane: TexturedPlane, pose: Pose, camera: CameraModel) -> None:
    """Paint ``plane`` over ``frame`` (in place) where it is in front of the camera."""
    rotation_matrix = pose.rotation_matrix
    corners_camera = (plane.corners() - pose.centre) @ rotation_matrix.T
    clipped = clip_to_view(corners_camera, camera, pose.scale)
    if len(clipped) < 3:
        return
    intrinsics = camera.intrinsics(pose.scale)
    projected = clipped @ intrinsics.T
    polygon = projected[:, :2] / projected[:, 2:3]
    left = max(math.floor(polygon[:, 0].min()), 0)
    top = max(math.floor(polygon[:, 1].min()), 0)
    right = min(math.ceil(polygon[:, 0].max()) + 1, camera.width)
    bottom = min(math.ceil(polygon[:, 1].max()) + 1, camera.height)
    if right <= left or bottom <= top:
        return
    shift = np.array([[1.0, 0.0, -left], [0.0, 1.0, -top], [0.0, 0.0, 1.0]])
    matrix = shift @ plane.homography(pose, camera)
    size = (right - left, bottom - top)
    warped = cv2.warpPerspective(
        plane.texture, matrix, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
    )
    mask = np.zeros((size[1], size[0]), dtype=np.uint8)
    cv2.fillPoly(
        mask,
        [np.round((polygon - [left, top]) * 16).astype(np.int32)],
        255,
        lineType=cv2.LINE_8,
        shift=4,
    )
    region = frame[top:bottom, left:right]
    cv2.copyTo(warped, mask, region)


def corner_elevations(pose: Pose, camera: CameraModel) -> FloatArray:
    """``(4,)`` sine of the elevation of the rays through the image corners."""
    corners = np.array(
        [
            [0.0, 0.0, 1.0],
            [camera.width, 0.0, 1.0],
            [camera.width, camera.height, 1.0],
            [0.0, camera.height, 1.0],
        ]
    )
    rays = corners @ np.linalg.inv(camera.intrinsics(pose.scale)).T @ pose.rotation_matrix
    return rays[:, 2] / np.linalg.norm(rays, axis=1)


def sky_image(
    pose: Pose, camera: CameraModel, zenith: tuple[int, int, int], horizon: tuple[int, int, int]
) -> ImageArray:
    """A sky gradient by elevation angle, ``(H, W, 3)`` BGR; cheap (computed on a coarse grid)."""
    step = 16
    columns = np.arange(0, camera.width + step, step, dtype=np.float64)
    rows = np.arange(0, camera.height + step, step, dtype=np.float64)
    grid_x, grid_y = np.meshgrid(columns, rows)
    rays = np.stack([grid_x, grid_y, np.ones_like(grid_x)], axis=-1)
    rays = rays @ np.linalg.inv(camera.intrinsics(pose.scale)).T
    world = rays @ pose.rotation_matrix
    elevation = world[..., 2] / np.linalg.norm(world, axis=-1)
    weight = np.clip(elevation, 0.0, 1.0) ** 0.6
    colour = (1.0 - weight[..., None]) * np.array(horizon) + weight[..., None] * np.array(zenith)
    coarse = colour.astype(np.float32)
    full = cv2.resize(
        coarse, (len(columns) * step, len(rows) * step), interpolation=cv2.INTER_LINEAR
    )
    return np.clip(full[: camera.height, : camera.width], 0, 255).astype(np.uint8)

"""From a plan to everything but pixels: motion, camera poses, ground truth, blur and lighting.

Tests and statistics use :func:`simulate` alone, which is fast; :mod:`.generate` renders it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.records import Interval

from .excursions import add_excursions
from .people import Crowd, builtin_crowd, trajectory_crowd
from .presets import VideoPlan
from .render import BODY_WIDTH_M, HEAD_DIAMETER_M
from .scene import CameraModel, Pose, project
from .wearer import WATCH_Y, WearerMotion, head_points, plan_wearer

#: Parapet height above the walkway floor (metres).
PARAPET_HEIGHT = 0.9
#: Fraction of a frame time the shutter is open (sets the motion-blur length).
SHUTTER = 0.6


@dataclass
class Simulation:
    """One video without pixels.

    Attributes:
        plan: the plan it came from.
        camera: intrinsics.
        crowd: everyone, people of interest first (ids ``1..n_targets``), then the others.
        motion: wearer poses and interval variants.
        intervals: the info-less intervals as records (``a``, ``b`` 0-based).
        targets: ``{0-based frame: {id: (x, y)}}`` of the people of interest (gt.csv).
        heads: ``(frame, id, x, y, head_size)`` of every visible head (heads.csv).
        blur: ``(T, 2)`` motion-blur streak per frame, pixels.
        gain: ``(T,)`` brightness factor per frame.
    """

    plan: VideoPlan
    camera: CameraModel
    crowd: Crowd
    motion: WearerMotion
    intervals: list[Interval]
    targets: dict[int, dict[int, tuple[float, float]]]
    heads: list[tuple[int, int, float, float, float]]
    blur: FloatArray
    gain: FloatArray

    def pose(self, frame: int) -> Pose:
        """Camera pose of a 0-based frame."""
        return Pose.from_row(self.motion.poses[frame])

    def infoless(self) -> np.ndarray:
        """``(T,)`` True on info-less frames."""
        mask = np.zeros(self.plan.n_frames, dtype=bool)
        for interval in self.plan.intervals:
            mask[interval.start : interval.start + interval.length] = True
        return mask


def simulate(plan: VideoPlan) -> Simulation:
    """Simulate the people, the wearer and the ground truth of one planned video."""
    rng = np.random.default_rng(plan.seed)
    camera = CameraModel(plan.width, plan.height, plan.hfov_deg)
    site = plan.site
    distance = rng.uniform(*site.group_distance)
    bearing = math.radians(rng.uniform(-20, 20))
    start = np.array([distance * math.sin(bearing), max(distance * math.cos(bearing), 6.0)])
    if plan.trajectories:
        crowd = trajectory_crowd(
            rng, Path(plan.trajectories), plan.n_frames, plan.fps, plan.n_targets, start
        )
    else:
        crowd = builtin_crowd(
            rng,
            plan.n_frames,
            plan.fps,
            plan.n_targets,
            start,
            site.background_people,
            math.degrees(bearing),
        )
    motion = plan_wearer(rng, crowd, plan.intervals, camera, site.eye_height, plan.fps, plan.wearer)
    if motion.extra_people is not None:
        crowd = crowd.append(motion.extra_people)
    if plan.leave:
        crowd, excursions = add_excursions(
            plan.seed, crowd, motion.poses, camera, plan.intervals, plan.leave, plan.fps
        )
        crowd.notes["excursions"] = [excursion.as_notes() for excursion in excursions]
    simulation = Simulation(
        plan=plan,
        camera=camera,
        crowd=crowd,
        motion=motion,
        intervals=[
            Interval(a=i.start - 1, b=i.start + i.length, kind=i.kind) for i in plan.intervals
        ],
        targets={},
        heads=[],
        blur=np.zeros((plan.n_frames, 2)),
        gain=np.ones(plan.n_frames),
    )
    _ground_truth(simulation)
    simulation.blur = _blur(simulation)
    simulation.gain = _gain(rng, simulation)
    return simulation


def visible_heads(
    simulation: Simulation, frame: int
) -> tuple[FloatArray, FloatArray, np.ndarray, np.ndarray]:
    """Image geometry of every head on one frame.

    Returns:
        ``(P, 2)`` head pixels, ``(P,)`` head diameters in pixels, ``(P,)`` True where the head
        is inside the image and not hidden (behind the camera, the parapet or a nearer person),
        and ``(P,)`` True where it is inside the image and in front of the parapet.
    """
    crowd, camera = simulation.crowd, simulation.camera
    pose = simulation.pose(frame)
    heads_world = head_points(crowd, frame)
    pixels, depth = project(heads_world, pose, camera)
    focal = camera.focal * pose.scale
    safe_depth = np.maximum(depth, 1e-3)
    size = focal * HEAD_DIAMETER_M / safe_depth
    inside = (
        (depth > 0.3)
        & (pixels[:, 0] >= 0)
        & (pixels[:, 0] <= camera.width - 1)
        & (pixels[:, 1] >= 0)
        & (pixels[:, 1] <= camera.height - 1)
        & (heads_world[:, 1] > 0.3)
    )
    # The parapet (and the building under it) hides what the ray meets below its top edge.
    crossing = (0.0 - pose.ty) / np.maximum(heads_world[:, 1] - pose.ty, 1e-6)
    height_at_edge = pose.tz + crossing * (heads_world[:, 2] - pose.tz)
    parapet_top = simulation.plan.site.walkway_height + PARAPET_HEIGHT
    unblocked = inside & ((pose.ty >= 0) | (height_at_edge > parapet_top))
    # A nearer person's head or body covering this head's centre hides it.
    feet, _ = project(
        np.column_stack([crowd.positions[:, frame], np.zeros(crowd.count)]), pose, camera
    )
    body_width = focal * BODY_WIDTH_M / safe_depth
    nearer = depth[None, :] < depth[:, None] - 0.2  # [i, j]: j is nearer than i
    head_gap = np.linalg.norm(pixels[:, None, :] - pixels[None, :, :], axis=2)
    covered_by_head = head_gap < 0.45 * size[None, :]
    segment = pixels[None, :, :] - feet[None, :, :]  # j's body: foot -> head
    offset = pixels[:, None, :] - feet[None, :, :]
    along = np.clip(
        np.sum(offset * segment, axis=2) / np.maximum(np.sum(segment**2, axis=2), 1e-6), 0.0, 0.85
    )
    distance = np.linalg.norm(offset - along[..., None] * segment, axis=2)
    covered_by_body = distance < 0.4 * body_width[None, :]
    hidden = np.any(nearer & (covered_by_head | covered_by_body) & unblocked[None, :], axis=1)
    return pixels, size, unblocked & ~hidden, unblocked


def _ground_truth(simulation: Simulation) -> None:
    crowd = simulation.crowd
    infoless = simulation.infoless()
    targets: dict[int, dict[int, tuple[float, float]]] = {}
    heads: list[tuple[int, int, float, float, float]] = []
    target_indices = np.flatnonzero(crowd.is_target)
    for frame in range(simulation.plan.n_frames):
        pixels, size, visible, in_view = visible_heads(simulation, frame)
        for person in np.flatnonzero(visible):
            heads.append(
                (
                    frame,
                    int(person) + 1,
                    float(pixels[person, 0]),
                    float(pixels[person, 1]),
                    float(size[person]),
                )
            )
        if infoless[frame]:
            continue
        frame_targets = {
            int(person) + 1: (float(pixels[person, 0]), float(pixels[person, 1]))
            for person in target_indices
            if in_view[person]
        }
        if frame_targets:
            targets[frame] = frame_targets
    simulation.targets = targets
    simulation.heads = heads


def _blur(simulation: Simulation) -> FloatArray:
    """Streak of the image centre during the exposure: where the point seen at the centre on
    the previous frame moved to, times the shutter fraction."""
    poses = simulation.motion.poses
    camera = simulation.camera
    blur = np.zeros((len(poses), 2))
    centre = np.array([camera.width / 2.0, camera.height / 2.0])
    first_after = {interval.b for interval in simulation.intervals}
    for frame in range(1, len(poses)):
        # The first frame after an interval is where the head has come to rest: its exposure
        # sees the motion that follows it, not the end of the swing.
        earlier, later = (
            (frame, frame + 1)
            if frame in first_after and frame + 1 < len(poses)
            else (frame - 1, frame)
        )
        previous = Pose.from_row(poses[earlier])
        forward = previous.rotation_matrix[2]
        point = previous.centre + 20.0 * forward
        pixel, depth = project(point[None], Pose.from_row(poses[later]), camera)
        if depth[0] > 0:
            blur[frame] = SHUTTER * (pixel[0] - centre)
        else:
            blur[frame] = SHUTTER * np.array([camera.width, 0.0])
    return blur


def _gain(rng: np.random.Generator, simulation: Simulation) -> FloatArray:
    """Brightness per frame: slow lighting drift (clouds, auto exposure), darker while the
    camera faces the bright sky and recovering after it."""
    count = simulation.plan.n_frames
    fps = simulation.plan.fps
    walk = np.cumsum(rng.normal(0, 0.004, size=count))
    walk -= np.linspace(0, 1, count) * walk[-1]
    gain = 1.0 + np.clip(walk, -0.12, 0.12) + rng.uniform(-0.06, 0.06)
    for plan, variant in zip(simulation.plan.intervals, simulation.motion.variants, strict=True):
        if variant != "sky":
            continue
        frames = np.arange(plan.start, min(plan.start + plan.length + int(fps), count))
        progress = np.clip((frames - plan.start) / max(plan.length, 1), 0, 1)
        recovery = np.clip((frames - plan.start - plan.length) / fps, 0, 1)
        gain[frames] *= 1.0 - 0.3 * np.sin(np.pi * np.minimum(progress, 0.5)) * (1 - recovery)
    return gain


__all__ = ["WATCH_Y", "Simulation", "simulate", "visible_heads"]

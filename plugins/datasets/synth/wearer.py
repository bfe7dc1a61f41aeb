"""The wearer's head: smooth small motion inside segments, fast swings for info-less intervals.

Inside a segment the camera follows the people of interest (the wearer watches them): the aim is
their smoothed centre, plus a per-segment offset (pan, tilt, roll, scale), a slow drift and a
walking jitter. An interval swings away fast (motion blur comes from the pose change), looks at
the sky or a building (kind ``sky``), at another group (``group``) or down at the walkway while
walking along it (``path``, which moves the viewpoint), then swings back to a *different* pose:
new offsets within the configured limits, checked so that the group stays mostly in view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from trackfw.arrays import FloatArray

from .people import Crowd, standing_group
from .presets import IntervalPlan, WearerConfig
from .scene import CameraModel, Pose, look_at, project

#: Camera distance behind the parapet while watching, and while walking the walkway (metres).
WATCH_Y = -0.2
WALK_Y = -1.2
#: Height of the aim point above the ground (roughly the group's chests).
AIM_HEIGHT = 1.2
HEAD_CENTRE_BELOW_TOP = 0.11


@dataclass
class WearerMotion:
    """The camera pose of every frame and what each interval looks at.

    Attributes:
        poses: ``(T, 7)`` rows ordered as ``scene.POSE_COLUMNS``.
        variants: per interval, what it shows (``sky``, ``building``, ``group``, ``path``).
        extra_people: people added for the intervals (the 'another group' ones).
        segment_offsets: per segment, the (pan, tilt, roll, scale) offsets.
    """

    poses: FloatArray
    variants: list[str]
    extra_people: Crowd | None
    segment_offsets: list[tuple[float, float, float, float]] = field(default_factory=list)


def head_points(crowd: Crowd, frame: int, people: np.ndarray | None = None) -> FloatArray:
    """``(N, 3)`` head centres (metres) of ``people`` (all when None) at ``frame``."""
    selected = np.arange(crowd.count) if people is None else np.asarray(people)
    ground = crowd.positions[selected, frame]
    return np.column_stack([ground, crowd.heights[selected] - HEAD_CENTRE_BELOW_TOP])


def _ou(rng: np.random.Generator, count: int, sigma: float, tau_frames: float) -> FloatArray:
    """Ornstein-Uhlenbeck series with stationary deviation ``sigma``, ``(count,)``."""
    decay = math.exp(-1.0 / tau_frames)
    noise = rng.normal(0.0, sigma * math.sqrt(1 - decay * decay), size=count)
    values = np.empty(count)
    current = rng.normal(0.0, sigma)
    for index in range(count):
        current = decay * current + noise[index]
        values[index] = current
    return values


def _smoothstep(u: FloatArray) -> FloatArray:
    return u * u * (3.0 - 2.0 * u)


def _wrap(angle: float) -> float:
    return (angle + 180.0) % 360.0 - 180.0


class _Planner:
    def __init__(
        self,
        rng: np.random.Generator,
        crowd: Crowd,
        camera: CameraModel,
        eye_height: float,
        fps: float,
        config: WearerConfig,
    ) -> None:
        self.rng = rng
        self.crowd = crowd
        self.camera = camera
        self.eye_height = eye_height
        self.fps = fps
        self.config = config
        self.n_frames = crowd.positions.shape[1]
        self.targets = np.flatnonzero(crowd.is_target)
        centres = crowd.positions[self.targets].mean(axis=0)
        window = max(int(fps), 1)
        padded = np.pad(centres, ((window // 2, window - 1 - window // 2), (0, 0)), mode="edge")
        kernel = np.ones(window) / window
        self.attention = np.stack(
            [np.convolve(padded[:, k], kernel, mode="valid") for k in range(2)], axis=1
        )
        frames = self.n_frames
        self.drift = np.stack(
            [_ou(rng, frames, sigma, 2.0 * fps) for sigma in config.drift_deg], axis=1
        )
        time = np.arange(frames) / fps
        bob = 2 * math.pi * rng.uniform(1.6, 2.0) * time + rng.uniform(0, 2 * math.pi)
        self.jitter = np.stack(
            [
                amplitude * np.sin(bob + shift) + rng.normal(0, amplitude * 0.4, frames)
                for amplitude, shift in zip(config.jitter_deg, (0.0, 1.3, 2.1), strict=True)
            ],
            axis=1,
        )

    def segment_pose(
        self, frame: int, offsets: tuple[float, float, float, float], centre: FloatArray
    ) -> FloatArray:
        aim = np.array([*self.attention[frame], AIM_HEIGHT])
        pan, tilt = look_at(centre, aim)
        pan_offset, tilt_offset, roll, scale = offsets
        drift, jitter = self.drift[frame], self.jitter[frame]
        return np.array(
            [
                pan + pan_offset + drift[0] + jitter[0],
                tilt + tilt_offset + drift[1] + jitter[1],
                roll + drift[2] + jitter[2],
                scale,
                *centre,
            ]
        )

    def in_view_fraction(
        self,
        frames: range,
        offsets: tuple[float, float, float, float],
        centre: FloatArray,
        margin: float = 12.0,
    ) -> tuple[float, float]:
        """Mean fraction of targets inside the image over ``frames`` and at the first one."""
        fractions = []
        for frame in frames:
            pose = Pose.from_row(self.segment_pose(frame, offsets, centre))
            pixels, depth = project(head_points(self.crowd, frame, self.targets), pose, self.camera)
            inside = (
                (depth > 0.5)
                & (pixels[:, 0] > margin)
                & (pixels[:, 0] < self.camera.width - margin)
                & (pixels[:, 1] > margin)
                & (pixels[:, 1] < self.camera.height - margin)
            )
            fractions.append(float(inside.mean()))
        return float(np.mean(fractions)), fractions[0]

    def first_offsets(self, centre: FloatArray, frames: range) -> tuple[float, float, float, float]:
        rng = self.rng
        offsets = (
            rng.uniform(-6, 6),
            rng.uniform(-4, 3),
            rng.uniform(-4, 4),
            rng.uniform(0.9, 1.15),
        )
        for _attempt in range(12):
            mean, first = self.in_view_fraction(frames, offsets, centre)
            if first >= 1.0 and mean >= self.config.min_in_view:
                return offsets
            offsets = (
                offsets[0] * 0.6,
                offsets[1] * 0.6,
                offsets[2] * 0.6,
                max(0.6, offsets[3] * 0.9),
            )
        return offsets

    def next_offsets(
        self, previous: tuple[float, float, float, float], centre: FloatArray, frames: range
    ) -> tuple[float, float, float, float]:
        rng, config = self.rng, self.config
        pan_change = rng.uniform(config.min_pan_change, config.max_pan_change) * rng.choice(
            [-1.0, 1.0]
        )
        roll_change = rng.uniform(0.3, 1.0) * config.max_roll_change * rng.choice([-1.0, 1.0])
        tilt_change = rng.uniform(-config.max_tilt_change, config.max_tilt_change)
        log_scale = rng.uniform(math.log(config.scale_range[0]), math.log(config.scale_range[1]))
        candidate = previous
        for _attempt in range(12):
            candidate = (
                float(np.clip(previous[0] + pan_change, -35, 35)),
                float(np.clip(previous[1] + tilt_change, -12, 10)),
                float(np.clip(previous[2] + roll_change, -12, 12)),
                float(np.clip(previous[3] * math.exp(log_scale), 0.6, 1.6)),
            )
            mean, first = self.in_view_fraction(frames, candidate, centre)
            if mean >= config.min_in_view and first >= 0.8:
                return candidate
            # Shrink the change (keep its direction) until the group fits in the image.
            pan_change *= 0.75
            roll_change *= 0.8
            tilt_change *= 0.7
            log_scale *= 0.7
            if mean < 0.5 and pan_change * previous[0] > 0:
                pan_change = -pan_change
        return candidate


def plan_wearer(
    rng: np.random.Generator,
    crowd: Crowd,
    intervals: tuple[IntervalPlan, ...],
    camera: CameraModel,
    eye_height: float,
    fps: float,
    config: WearerConfig | None = None,
) -> WearerMotion:
    """Camera poses for every frame of a video.

    Args:
        rng: random generator.
        crowd: everyone's motion; the people of interest are ``crowd.is_target``.
        intervals: planned info-less intervals (0-based start, length, kind).
        camera: intrinsics.
        eye_height: camera height above the square (metres).
        fps: frame rate.
        config: motion limits.

    Returns:
        the poses (``(T, 7)``), interval variants and any people added for 'group' intervals.
    """
    config = config or WearerConfig()
    planner = _Planner(rng, crowd, camera, eye_height, fps, config)
    n_frames = planner.n_frames
    poses = np.zeros((n_frames, 7))
    centre = np.array([0.0, WATCH_Y, eye_height])
    boundaries = [0] + [plan.start + plan.length for plan in intervals]
    ends = [plan.start for plan in intervals] + [n_frames]
    check = range(0, min(ends[0], 60))
    offsets = planner.first_offsets(centre, check)
    segment_offsets = [offsets]
    for frame in range(boundaries[0], ends[0]):
        poses[frame] = planner.segment_pose(frame, offsets, centre)
    variants: list[str] = []
    extra: Crowd | None = None
    for index, plan in enumerate(intervals):
        after = boundaries[index + 1]
        next_centre = centre.copy()
        walk_direction = float(rng.choice([-1.0, 1.0]))
        if plan.kind == "path":
            distance = float(np.clip(1.3 * plan.length / fps, *config.path_move))
            next_centre = centre + np.array([walk_direction * distance, 0.0, 0.0])
        if after < n_frames:
            check = range(after, min(ends[index + 1], after + 60))
            offsets = planner.next_offsets(offsets, next_centre, check)
            segment_offsets.append(offsets)
            for frame in range(after, ends[index + 1]):
                poses[frame] = planner.segment_pose(frame, offsets, next_centre)
        variant, hold, added = _interval_hold(
            planner, plan, poses[plan.start - 1], centre, next_centre, walk_direction
        )
        variants.append(variant)
        if added is not None:
            extra = added if extra is None else extra.append(added)
        end_pose = poses[after] if after < n_frames else hold[-1]
        poses[plan.start : after] = _swing(poses[plan.start - 1], hold, end_pose)
        centre = next_centre
    return WearerMotion(
        poses=poses, variants=variants, extra_people=extra, segment_offsets=segment_offsets
    )


def _interval_hold(
    planner: _Planner,
    plan: IntervalPlan,
    before: FloatArray,
    centre: FloatArray,
    next_centre: FloatArray,
    walk_direction: float,
) -> tuple[str, FloatArray, Crowd | None]:
    """Poses ``(length, 7)`` the wearer would hold while looking away (swings added later)."""
    rng, fps = planner.rng, planner.fps
    frames = np.arange(plan.start, plan.start + plan.length)
    drift = planner.drift[frames] * 1.5
    jitter = planner.jitter[frames]
    hold = np.zeros((plan.length, 7))
    hold[:, 3] = before[3]
    hold[:, 4:7] = centre
    added: Crowd | None = None
    if plan.kind == "sky":
        variant = "building" if rng.random() < 0.4 else "sky"
        if variant == "sky":
            pan = before[0] + rng.uniform(-35, 35)
            tilt = rng.uniform(22, 45)
        else:
            pan = before[0] + rng.choice([-1.0, 1.0]) * rng.uniform(110, 160)
            tilt = rng.uniform(-10, 12)
        hold[:, 0] = pan + drift[:, 0] + jitter[:, 0]
        hold[:, 1] = tilt + drift[:, 1] + jitter[:, 1]
        hold[:, 2] = before[2] + rng.uniform(-8, 8) + drift[:, 2]
    elif plan.kind == "group":
        variant = "group"
        side = float(rng.choice([-1.0, 1.0]))
        bearing = before[0] + side * rng.uniform(60, 100)
        if abs(bearing) > 80:
            bearing = before[0] - side * rng.uniform(60, 100)
        bearing = float(np.clip(bearing, -80, 80))
        distance = rng.uniform(7.0, 16.0)
        ground = centre[:2] + distance * np.array(
            [math.sin(math.radians(bearing)), math.cos(math.radians(bearing))]
        )
        ground[1] = max(ground[1], 6.0)
        added = standing_group(rng, int(rng.integers(3, 8)), ground, planner.n_frames, fps)
        middle = added.positions[:, frames].mean(axis=0)
        for row, frame in enumerate(frames):
            pan, tilt = look_at(centre, np.array([*middle[row], AIM_HEIGHT]))
            hold[row, 0] = pan + drift[row, 0] * 0.5 + jitter[row, 0]
            hold[row, 1] = tilt + drift[row, 1] * 0.5 + jitter[row, 1]
            del frame
        hold[:, 2] = before[2] + rng.uniform(-5, 5) + drift[:, 2]
    else:
        variant = "path"
        pan = walk_direction * 90.0 + rng.uniform(-15, 15)
        tilt = rng.uniform(-70, -50)
        time = np.arange(plan.length) / fps
        bob = np.sin(2 * math.pi * 1.9 * time)
        hold[:, 0] = pan + drift[:, 0] + 1.0 * bob
        hold[:, 1] = tilt + drift[:, 1] + 1.2 * np.abs(bob)
        hold[:, 2] = before[2] * 0.3 + 0.8 * bob + drift[:, 2]
        progress = (np.arange(plan.length) + 1.0) / (plan.length + 1.0)
        hold[:, 4:7] = centre + progress[:, None] * (next_centre - centre)
        hold[:, 5] = WATCH_Y + (WALK_Y - WATCH_Y) * np.sin(np.pi * progress)
        hold[:, 6] = centre[2] + 0.03 * bob
    hold[:, 0] = np.array([_wrap(value) for value in hold[:, 0]])
    return variant, hold, added


def _swing(before: FloatArray, hold: FloatArray, after: FloatArray) -> FloatArray:
    """Interval poses: a fast eased swing from ``before`` into ``hold``, and from ``hold`` back
    to ``after`` (each takes about a fifth of the interval, 3 to 9 frames)."""
    length = len(hold)
    out_frames = int(np.clip(round(0.18 * length), 3, 9))
    back_frames = int(np.clip(round(0.18 * length), 3, 9))
    result = hold.copy()
    for count, start_pose, end_index, reverse in (
        (out_frames, before, out_frames, False),
        (back_frames, after, length - back_frames - 1, True),
    ):
        for step in range(count):
            if reverse:
                row = length - count + step
                weight = float(_smoothstep(np.array((step + 1.0) / (count + 1.0))))
                source, target = hold[end_index], start_pose
            else:
                row = step
                weight = float(_smoothstep(np.array((step + 1.0) / (count + 1.0))))
                source, target = start_pose, hold[end_index]
            delta = target - source
            delta[0] = _wrap(float(delta[0]))
            result[row] = source + weight * delta
            if not reverse and row < len(hold):
                result[row, 4:7] = hold[row, 4:7]
            if reverse:
                result[row, 4:7] = hold[row, 4:7]
    return result

"""The plan of a virtual-wearer video: everything random about it, drawn before any frame is rendered.

The info-less intervals and their views, the head sway and walking bob, one camera pose per
segment (each clearly different from the one before and keeping most people of interest in view)
and the people of interest themselves. The conventions are those of
:mod:`trackfw_plugins.datasets.wear`; :mod:`trackfw_plugins.datasets.wear_render` renders a plan.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

import numpy as np

from trackfw.errors import UserError
from trackfw.formats import body_head_points
from trackfw_plugins.datasets.mot import MotSequence
from trackfw_plugins.datasets.wear_camera import CameraPose, pose_homography, transform_points

if TYPE_CHECKING:
    from trackfw_plugins.datasets.wear_intervals import InfolessView

#: Per-channel amplitude of the smooth head sway: pan, tilt, roll (degrees), log-scale [OURS].
SWAY_AMPLITUDE = (1.2, 0.8, 0.8, 0.015)
#: Walking bob (fraction of the output height) and step frequency in Hz [OURS].
BOB_AMPLITUDE = 0.004
STEP_FREQUENCY = 1.8


class FrameFormat(StrEnum):
    """How the frames are stored."""

    mp4 = "mp4"
    jpg = "jpg"


@dataclass
class WearSettings:
    """Parameters of the virtual wearer; every value is [OURS] unless the brief fixed it."""

    n_intervals: int | None = None  # None: one per 80 frames, 1 to 6
    min_interval: int = 15
    max_interval: int = 60
    min_segment: int = 12
    max_pan: float = 30.0
    max_tilt: float = 8.0
    max_roll: float = 10.0
    min_scale: float = 0.7
    max_scale: float = 1.4
    horizontal_fov: float = 80.0
    #: A new pose differs from the previous one by at least one of these.
    min_pan_change: float = 10.0
    min_roll_change: float = 5.0
    min_scale_ratio: float = 1.2
    min_targets: int = 5
    max_targets: int = 10
    #: Exactly this many people of interest (at most the people in view on frame 1) instead of
    #: a draw in min..max_targets; the others stay bystanders (heads.csv, not gt.csv).
    n_targets: int | None = None
    output_size: tuple[int, int] | None = None
    frame_format: FrameFormat = FrameFormat.mp4
    jpeg_quality: int = 95


@dataclass
class VideoPlan:
    """Everything random about one output video, drawn before any frame is rendered."""

    name: str
    seed: int
    index: int
    output_size: tuple[int, int]
    views: list[InfolessView]
    segment_poses: list[CameraPose]
    sway: np.ndarray  # (T, 6) per-frame offsets: pan, tilt, roll, log-scale, tx, ty
    targets: list[int]
    group_id_offset: int
    frame_view: list[int] = field(default_factory=list)  # per frame: interval index or -1

    def segment_of(self, frame: int) -> int:
        """Index of the pose segment ``frame`` belongs to (intervals that ended before it)."""
        return sum(1 for view in self.views if view.last < frame)

    def pose(self, frame: int, segment: int) -> CameraPose:
        """The pose of ``frame`` seen with the base pose of ``segment``."""
        base = self.segment_poses[segment]
        pan, tilt, roll, log_scale, tx, ty = self.sway[frame]
        return CameraPose(
            base.pan + pan,
            base.tilt + tilt,
            base.roll + roll,
            base.scale * math.exp(log_scale),
            base.tx + tx,
            base.ty + ty,
        )


def _sway(n_frames: int, fps: float, out_height: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth per-frame pose offsets: two sinusoids per channel plus the walking bob."""
    time = np.arange(n_frames) / fps
    sway = np.zeros((n_frames, 6))
    for channel, amplitude in enumerate(SWAY_AMPLITUDE):
        slow, fast = rng.uniform(0.15, 0.4), rng.uniform(0.6, 1.2)
        phases = rng.uniform(0, 2 * math.pi, size=2)
        sway[:, channel] = amplitude * (
            0.7 * np.sin(2 * math.pi * slow * time + phases[0])
            + 0.3 * np.sin(2 * math.pi * fast * time + phases[1])
        )
    step = STEP_FREQUENCY * rng.uniform(0.9, 1.1)
    sway[:, 5] = (
        BOB_AMPLITUDE * out_height * np.sin(2 * math.pi * step * time + rng.uniform(0, 6.3))
    )
    return sway


def inside(points: np.ndarray, size: tuple[int, int], margin: float = 0.0) -> np.ndarray:
    """``(N,)`` True where an ``(N, 2)`` point lies at least ``margin`` inside a ``size`` image."""
    return (
        (points[:, 0] >= margin)
        & (points[:, 0] < size[0] - margin)
        & (points[:, 1] >= margin)
        & (points[:, 1] < size[1] - margin)
    )


def _choose_pose(
    rng: np.random.Generator,
    settings: WearSettings,
    previous: CameraPose | None,
    heads: np.ndarray,
    required: int,
    project: Callable[[CameraPose], np.ndarray],
    output_size: tuple[int, int],
) -> CameraPose:
    """A random pose, different from ``previous``, that keeps ``required`` of ``heads`` in view."""
    margin = 0.04 * min(output_size)
    best, best_count = CameraPose(), -1
    for _ in range(200):
        pose = CameraPose(
            pan=float(rng.uniform(-settings.max_pan, settings.max_pan)),
            tilt=float(rng.uniform(-settings.max_tilt, settings.max_tilt)),
            roll=float(rng.uniform(-settings.max_roll, settings.max_roll)),
            scale=float(
                math.exp(rng.uniform(math.log(settings.min_scale), math.log(settings.max_scale)))
            ),
        )
        if previous is not None and not (
            abs(pose.pan - previous.pan) >= settings.min_pan_change
            or abs(pose.roll - previous.roll) >= settings.min_roll_change
            or abs(math.log(pose.scale / previous.scale)) >= math.log(settings.min_scale_ratio)
        ):
            continue
        count = int(inside(project(pose), output_size, margin).sum()) if len(heads) else 0
        if count >= required:
            return pose
        if count > best_count:
            best, best_count = pose, count
    return best


def plan_video(sequence: MotSequence, settings: WearSettings, seed: int, index: int) -> VideoPlan:
    """Draw the intervals, views, poses and targets of video ``index`` for ``seed``."""
    # The draws come in one fixed order (intervals, kinds, views, sway, first pose, targets,
    # then a pose per segment): the same seed gives the same video.
    rng = np.random.default_rng([seed, index, zlib.crc32(sequence.name.encode("utf-8"))])
    output_size = settings.output_size or (sequence.width, sequence.height)
    views = _draw_views(sequence, settings, output_size, rng)
    sway = _sway(sequence.n_frames, sequence.fps, output_size[1], rng)
    projector = _projector(sway, (sequence.width, sequence.height), output_size, settings)
    first_pose, targets = _first_pose_and_targets(sequence, settings, projector, output_size, rng)
    poses = [first_pose]
    for view in views:
        after = view.last + 1
        boxes = sequence.boxes_at(after)
        present = boxes[np.isin(boxes[:, 0].astype(int), targets)]
        heads = body_head_points(present[:, 1:])
        required = math.ceil(0.6 * len(heads))
        poses.append(
            _choose_pose(
                rng, settings, poses[-1], heads, required, projector(after, heads), output_size
            )
        )
    max_id = max((int(b[:, 0].max()) for b in sequence.boxes.values() if len(b)), default=0)
    plan = VideoPlan(
        name=f"{sequence.name}-s{seed}-v{index:02d}",
        seed=seed,
        index=index,
        output_size=output_size,
        views=views,
        segment_poses=poses,
        sway=sway,
        targets=targets,
        group_id_offset=max(100000, 10 ** len(str(max_id))),
    )
    plan.frame_view = [-1] * sequence.n_frames
    for number, view in enumerate(views):
        for frame in range(view.first, view.last + 1):
            plan.frame_view[frame] = number
    return plan


def _draw_views(
    sequence: MotSequence,
    settings: WearSettings,
    output_size: tuple[int, int],
    rng: np.random.Generator,
) -> list[InfolessView]:
    """The info-less intervals of the video, each with its kind and view."""
    from trackfw_plugins.datasets.wear_intervals import WEAR_KINDS, make_view, place_intervals

    n_frames = sequence.n_frames
    n_intervals = settings.n_intervals or max(1, min(6, n_frames // 80))
    try:
        spans = place_intervals(
            n_frames,
            n_intervals,
            settings.min_interval,
            settings.max_interval,
            settings.min_segment,
            rng,
        )
    except UserError as error:
        raise UserError(f"{sequence.path}: {error}") from None
    kinds = [WEAR_KINDS[k % 3] for k in rng.permutation(max(3, n_intervals))][:n_intervals]
    return [
        make_view(kind, a, b, sequence, output_size, rng)
        for kind, (a, b) in zip(kinds, spans, strict=True)
    ]


Projector = Callable[[int, np.ndarray], Callable[[CameraPose], np.ndarray]]


def _projector(
    sway: np.ndarray,
    source_size: tuple[int, int],
    output_size: tuple[int, int],
    settings: WearSettings,
) -> Projector:
    """``projector(frame, points)(pose)``: the source points seen by the camera at ``pose`` plus
    the frame's sway, in output pixels."""

    def projector(frame: int, points: np.ndarray) -> Callable[[CameraPose], np.ndarray]:
        def project(base: CameraPose) -> np.ndarray:
            pan, tilt, roll, log_scale, tx, ty = sway[frame]
            pose = CameraPose(
                base.pan + pan,
                base.tilt + tilt,
                base.roll + roll,
                base.scale * math.exp(log_scale),
                tx,
                ty,
            )
            homography = pose_homography(pose, source_size, output_size, settings.horizontal_fov)
            return transform_points(homography, points)

        return project

    return projector


def _first_pose_and_targets(
    sequence: MotSequence,
    settings: WearSettings,
    projector: Projector,
    output_size: tuple[int, int],
    rng: np.random.Generator,
) -> tuple[CameraPose, list[int]]:
    """The camera pose of frame 1 and the target ids: the people in view nearest a random one."""
    first_boxes = sequence.boxes_at(0)
    first_heads = body_head_points(first_boxes[:, 1:])
    in_source = inside(first_heads, (sequence.width, sequence.height))
    if not in_source.any():
        raise UserError(
            f"{sequence.path}: frame 1 has no ground-truth person inside the image; expected"
            " the people of interest there."
        )
    required = min(settings.min_targets, int(in_source.sum()))
    pose = _choose_pose(
        rng, settings, None, first_heads, required, projector(0, first_heads), output_size
    )
    projected = projector(0, first_heads)(pose)
    visible = np.flatnonzero(inside(projected, output_size))
    if len(visible) == 0:
        raise UserError(
            f"{sequence.path}: no camera pose keeps a person of frame 1 in view; expected"
            " people well inside the first frame."
        )
    wanted = int(rng.integers(settings.min_targets, settings.max_targets + 1))
    if settings.n_targets is not None:
        # Drawn all the same, so that the rest of the video is what it is without --targets.
        wanted = settings.n_targets
    anchor = projected[rng.choice(visible)]
    nearest = visible[
        np.argsort(np.linalg.norm(projected[visible] - anchor, axis=1), kind="stable")
    ]
    return pose, sorted(int(first_boxes[i, 0]) for i in nearest[: min(wanted, len(nearest))])

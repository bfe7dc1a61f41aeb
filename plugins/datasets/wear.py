"""A virtual wearer over a real MOTChallenge sequence (the command is in :mod:`.wear_cli`).

Every frame of the sequence is seen through a head-worn camera whose pose changes smoothly
(head sway, walking bob) within a segment and jumps to a clearly different pose after each
info-less interval. The pose is a rotation homography ``H = K_out R K_src^-1`` of the real frame:

* ``pan`` (degrees, rotation about the vertical axis; positive moves the content right),
* ``tilt`` (degrees, about the horizontal axis; positive moves the content up),
* ``roll`` (degrees, about the optical axis),
* ``scale`` (zoom of the output focal length), ``tx``/``ty`` (output pixels, the walking bob).

``K_src`` has the focal length of a ``horizontal_fov`` camera (80 degrees [OURS]); ``K_out`` is
the same camera zoomed by ``scale`` and by the factor that makes the source cover ``--size``. The
parts of the output the real frame does not cover are filled with a strongly blurred, mirrored
continuation of it (no black border, no recognisable head).

Ground truth: every MOT body box gives a head proxy ``(left + width/2, top + 0.08 height)`` with
size ``0.13 height`` (:func:`trackfw.formats.body_heads`, the head-point rule), moved by the frame's
homography (the size by the homography's local scale). The people of interest are a spatial group
of 5-10 people visible on frame 1 (a random person and its nearest neighbours); gt.csv holds them on
every informative frame where they are inside the image, heads.csv every visible person (and the
other group's heads during ``group`` intervals, with ids offset by ``group_id_offset``).
"""

from __future__ import annotations

import csv
import io
import math
import os
import shutil
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from trackfw.atomic import atomic_open, write_text
from trackfw.dataset import IMAGE_FOLDER, META_FILE, POSES_FILE, VIDEO_FILE, write_meta
from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, HEAD_SIZE_FRACTION, body_head_points, body_heads
from trackfw.formats.annotations import write_annotations
from trackfw.records import Interval
from trackfw.video_io import check_written_video
from trackfw_plugins.datasets.mot import MotSequence, load_mot_sequence, read_frame
from trackfw_plugins.datasets.wear_camera import (
    CameraPose,
    local_scale,
    pose_homography,
    transform_points,
    warp_frame,
)

if TYPE_CHECKING:
    from trackfw_plugins.datasets.wear_intervals import InfolessView

POSE_COLUMNS = ("frame", "pan", "tilt", "roll", "scale", "tx", "ty", "view")
PREVIEW_FOLDER = "preview"
#: Per-channel amplitude of the smooth head sway: pan, tilt, roll (degrees), log-scale [OURS].
SWAY_AMPLITUDE = (1.2, 0.8, 0.8, 0.015)
#: Walking bob (fraction of the output height) and step frequency in Hz [OURS].
BOB_AMPLITUDE = 0.004
STEP_FREQUENCY = 1.8
#: Width (fraction of the output size) over which the mirrored border fades into blur [OURS].
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


def _inside(points: np.ndarray, size: tuple[int, int], margin: float = 0.0) -> np.ndarray:
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
        count = int(_inside(project(pose), output_size, margin).sum()) if len(heads) else 0
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
    in_source = _inside(first_heads, (sequence.width, sequence.height))
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
    visible = np.flatnonzero(_inside(projected, output_size))
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


# ------------------------------------------------------------------------------------ rendering


def _look_pose(view: InfolessView, base: CameraPose) -> CameraPose:
    """Nominal camera pose while looking away (written to poses.csv, not used for warping)."""
    if view.kind == "sky":
        return replace(base, tilt=-45.0)
    if view.kind == "path":
        return replace(base, tilt=50.0)
    return replace(base, pan=base.pan + (-60.0 if view.enter_from == "right" else 60.0))


def _blend_poses(first: CameraPose, second: CameraPose, weight: float) -> CameraPose:
    values = [
        (1 - weight) * a + weight * b
        for a, b in zip(asdict(first).values(), asdict(second).values(), strict=True)
    ]
    return CameraPose(*values)


@dataclass
class RenderedFrame:
    """One output frame and its annotation."""

    image: np.ndarray  # (H, W, 3) uint8 BGR
    pose: CameraPose
    label: str  # real, swing, sky, group or path
    heads: np.ndarray  # (M, 4): id, x, y, head_size of the visible heads
    targets: dict[int, tuple[float, float]]


def render_frame(
    sequence: MotSequence, plan: VideoPlan, settings: WearSettings, frame: int
) -> RenderedFrame:
    """Render 0-based ``frame`` of ``plan``."""
    from trackfw_plugins.datasets.wear_intervals import compose_swing, render_view, swing_progress

    source_size = (sequence.width, sequence.height)
    number = plan.frame_view[frame]

    def real_view(segment: int) -> tuple[np.ndarray, CameraPose, np.ndarray]:
        pose = plan.pose(frame, segment)
        homography = pose_homography(pose, source_size, plan.output_size, settings.horizontal_fov)
        return (
            warp_frame(read_frame(sequence, frame), homography, plan.output_size),
            pose,
            homography,
        )

    if number < 0:
        image, pose, homography = real_view(plan.segment_of(frame))
        boxes = sequence.boxes_at(frame)
        proxies = body_heads(boxes[:, 1:])
        points = transform_points(homography, proxies[:, :2])
        sizes = proxies[:, 2] * local_scale(homography, proxies[:, :2])
        heads = np.column_stack([boxes[:, 0], points, sizes])[_inside(points, plan.output_size)]
        targets = {
            int(identity): (float(x), float(y))
            for identity, x, y, _ in heads
            if int(identity) in plan.targets
        }
        return RenderedFrame(image, pose, "real", heads, targets)
    view = plan.views[number]
    other, other_heads = render_view(view, frame, sequence, plan.output_size)
    swing = swing_progress(view, frame)
    away_base = plan.segment_poses[number]
    if swing is None:
        other_heads = other_heads.copy()
        other_heads[:, 0] += plan.group_id_offset
        return RenderedFrame(other, _look_pose(view, away_base), view.kind, other_heads, {})
    progress, step = swing
    # Swinging away from the old pose, or back to the new one.
    segment = number if frame - view.first < view.swing_in else number + 1
    real, pose, _ = real_view(segment)
    image = compose_swing(real, other, progress, step, view.enter_from)
    look = _look_pose(view, plan.segment_poses[segment])
    return RenderedFrame(image, _blend_poses(pose, look, progress), "swing", np.zeros((0, 4)), {})


def _draw_annotation(image: np.ndarray, rendered: RenderedFrame) -> np.ndarray:
    import cv2

    canvas = image.copy()
    for identity, x, y, size in rendered.heads:
        is_target = int(identity) in rendered.targets
        colour = (0, 255, 0) if is_target else (0, 200, 255)
        centre = (round(x), round(y))
        cv2.circle(canvas, centre, max(2, round(size / 2)), colour, 2, cv2.LINE_AA)
        if is_target:
            cv2.putText(
                canvas,
                str(int(identity)),
                (centre[0] + 4, centre[1] - 4),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.5,
                colour,
                1,
                cv2.LINE_AA,
            )
    return canvas


def _write_png(path: Path, image: np.ndarray) -> None:
    import cv2

    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise UserError(f"{path}: cannot encode the preview image.")
    with atomic_open(path, "wb") as stream:
        stream.write(encoded.tobytes())


def _preview_frames(plan: VideoPlan) -> dict[int, list[str]]:
    """0-based frame -> preview labels: frame a, a swing frame, the other view, frame b."""
    labels: dict[int, list[str]] = {}
    for number, view in enumerate(plan.views, start=1):
        hold = view.length - view.swing_in - view.swing_out
        wanted = {
            "a": view.first - 1,
            "swing": view.first + view.swing_in // 2,
            view.kind: view.first + view.swing_in + hold // 2,
            "b": view.last + 1,
        }
        for label, frame in wanted.items():
            labels.setdefault(frame, []).append(f"interval{number}_{label}")
    return labels


def _poses_text(rows: list[tuple[int, CameraPose, str]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(POSE_COLUMNS)
    for frame, pose, label in rows:
        writer.writerow([frame + 1, *(f"{value:.4f}" for value in asdict(pose).values()), label])
    return buffer.getvalue()


def render_video(
    sequence: MotSequence,
    plan: VideoPlan,
    settings: WearSettings,
    folder: Path,
    preview_folder: Path | None = None,
    progress: Callable[[int], None] | None = None,
) -> None:
    """Render ``plan`` into the video folder ``folder`` (which must not exist yet).

    Args:
        sequence: the real sequence.
        plan: the plan from :func:`plan_video`.
        settings: the wearer settings (frame format, field of view).
        folder: the video folder to create.
        preview_folder: where to save the preview PNGs, if anywhere.
        progress: called with the number of frames done after each frame.
    """
    import cv2

    folder.mkdir(parents=True)
    width, height = plan.output_size
    writer: Any = None
    if settings.frame_format is FrameFormat.mp4:
        writer = cv2.VideoWriter(
            str(folder / VIDEO_FILE), cv2.VideoWriter.fourcc(*"mp4v"), sequence.fps, (width, height)
        )
        if not writer.isOpened():
            raise UserError(f"{folder / VIDEO_FILE}: OpenCV cannot write an mp4v video here.")
    else:
        (folder / IMAGE_FOLDER).mkdir()
    preview_labels = _preview_frames(plan) if preview_folder is not None else {}
    targets: dict[int, dict[int, tuple[float, float]]] = {}
    heads: list[tuple[int, int, float, float, float]] = []
    pose_rows: list[tuple[int, CameraPose, str]] = []
    try:
        for frame in range(sequence.n_frames):
            rendered = render_frame(sequence, plan, settings, frame)
            if writer is not None:
                writer.write(rendered.image)
            else:
                path = folder / IMAGE_FOLDER / f"{frame + 1:06d}.jpg"
                if not cv2.imwrite(
                    str(path), rendered.image, [cv2.IMWRITE_JPEG_QUALITY, settings.jpeg_quality]
                ):
                    raise UserError(f"{path}: cannot write the frame.")
            if rendered.targets:
                targets[frame] = rendered.targets
            heads.extend(
                (frame, int(identity), float(x), float(y), float(size))
                for identity, x, y, size in rendered.heads
            )
            pose_rows.append((frame, rendered.pose, rendered.label))
            for label in preview_labels.get(frame, []):
                assert preview_folder is not None
                image = rendered.image
                if rendered.label == "real":
                    image = _draw_annotation(image, rendered)
                _write_png(preview_folder / f"{plan.name}_{label}.png", image)
            if progress is not None:
                progress(frame + 1)
    finally:
        if writer is not None:
            writer.release()
    if writer is not None:
        check_written_video(folder / VIDEO_FILE, sequence.n_frames)
    write_annotations(
        folder,
        targets,
        heads,
        [Interval(a=view.first - 1, b=view.last + 1, kind=view.kind) for view in plan.views],
    )
    write_text(folder / POSES_FILE, _poses_text(pose_rows))
    write_meta(folder / META_FILE, _meta(sequence, plan, settings))


def _meta(sequence: MotSequence, plan: VideoPlan, settings: WearSettings) -> dict[str, Any]:
    return {
        "fps": sequence.fps,
        "width": plan.output_size[0],
        "height": plan.output_size[1],
        "n_frames": sequence.n_frames,
        "source": f"wear:{sequence.name}",
        "source_path": str(sequence.path),
        "seed": plan.seed,
        "video_index": plan.index,
        "generator": "trackfw dataset wear",
        "format": settings.frame_format.value,
        "targets": plan.targets,
        "intervals": [
            {
                "start": view.first + 1,
                "end": view.last + 1,
                "kind": view.kind,
                "swing_in": view.swing_in,
                "swing_out": view.swing_out,
            }
            for view in plan.views
        ],
        "segment_poses": [asdict(pose) for pose in plan.segment_poses],
        "horizontal_fov": settings.horizontal_fov,
        "head_proxy": f"x = left + width/2, y = top + {HEAD_FRACTION:g} height,"
        f" head_size = {HEAD_SIZE_FRACTION:g} height",
        "group_id_offset": plan.group_id_offset,
    }


# ------------------------------------------------------------------------------------ dataset


def generate_dataset(
    mot_folder: Path,
    out_folder: Path,
    seed: int = 0,
    n_videos: int = 1,
    settings: WearSettings | None = None,
    force: bool = False,
    progress: Callable[[str, int, int], None] | None = None,
) -> list[Path]:
    """Write ``n_videos`` virtual-wearer videos of one MOT sequence into ``out_folder``.

    Each video is rendered into a hidden temporary folder and renamed when complete, so an
    interrupted run never leaves a video that looks finished. With ``force``, video folders of
    the same names are replaced and anything else in ``out_folder`` is left alone (so that
    several sequences can share one dataset folder).

    Args:
        mot_folder: the MOTChallenge sequence folder.
        out_folder: the dataset folder to write.
        seed: random seed; the same seed gives the same videos.
        n_videos: how many videos (different intervals and poses) to make.
        settings: wearer settings (defaults when omitted).
        force: allow a non-empty ``out_folder``.
        progress: called with (video name, frames done, frames in the video).

    Returns:
        The video folders written.
    """
    settings = settings or WearSettings()
    if seed < 0:
        raise UserError(f"--seed is {seed}; expected a non-negative integer.")
    if n_videos < 1:
        raise UserError(f"--videos is {n_videos}; expected at least 1.")
    if out_folder.exists() and not out_folder.is_dir():
        raise UserError(f"{out_folder}: exists and is not a folder; expected a dataset folder.")
    if out_folder.is_dir() and any(out_folder.iterdir()) and not force:
        raise UserError(
            f"{out_folder}: folder is not empty; expected a new or empty folder, or --force to"
            " replace its videos of the same names."
        )
    sequence = load_mot_sequence(mot_folder)
    preview_folder = out_folder / PREVIEW_FOLDER
    preview_folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for index in range(n_videos):
        plan = plan_video(sequence, settings, seed, index)
        final = out_folder / plan.name
        partial = out_folder / f".{plan.name}.partial-{os.getpid()}"
        if partial.exists():
            shutil.rmtree(partial)

        def report(done: int, name: str = plan.name) -> None:
            if progress is not None:
                progress(name, done, sequence.n_frames)

        try:
            render_video(sequence, plan, settings, partial, preview_folder, report)
            if final.exists():
                shutil.rmtree(final)
            os.replace(partial, final)
        except BaseException:
            shutil.rmtree(partial, ignore_errors=True)
            raise
        written.append(final)
    return written

"""Rendering a planned virtual-wearer video into a video folder.

Each frame of the real sequence is warped by its pose (:mod:`.wear_camera`), or replaced by the
interval's other view while the wearer looks away (:mod:`.wear_intervals`); the frames go to
video.mp4 or img1/, the heads and people of interest to gt.csv and heads.csv, the poses to
poses.csv, the plan to meta.json, and a few annotated frames to preview PNGs.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from trackfw.atomic import atomic_open, write_text
from trackfw.dataset import IMAGE_FOLDER, META_FILE, POSES_FILE, VIDEO_FILE, write_meta
from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, HEAD_SIZE_FRACTION, body_heads
from trackfw.formats.annotations import write_annotations
from trackfw.records import Interval
from trackfw.video_io import check_written_video
from trackfw_plugins.datasets.mot import MotSequence, read_frame
from trackfw_plugins.datasets.wear_camera import (
    CameraPose,
    local_scale,
    pose_homography,
    transform_points,
    warp_frame,
)
from trackfw_plugins.datasets.wear_plan import FrameFormat, VideoPlan, WearSettings, inside

if TYPE_CHECKING:
    from trackfw_plugins.datasets.wear_intervals import InfolessView

POSE_COLUMNS = ("frame", "pan", "tilt", "roll", "scale", "tx", "ty", "view")
#: meta.json's ``generator`` of the videos this module writes.
GENERATOR = "trackfw dataset wear"


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
        heads = np.column_stack([boxes[:, 0], points, sizes])[inside(points, plan.output_size)]
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
        "generator": GENERATOR,
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
        # With the poses and the field of view, where the real frame shows in each image.
        "source_size": [sequence.width, sequence.height],
        "horizontal_fov": settings.horizontal_fov,
        "head_proxy": f"x = left + width/2, y = top + {HEAD_FRACTION:g} height,"
        f" head_size = {HEAD_SIZE_FRACTION:g} height",
        "group_id_offset": plan.group_id_offset,
    }

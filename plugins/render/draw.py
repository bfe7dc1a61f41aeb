"""Read a run folder and draw its tracks: points, boxes, identity colours, trails, intervals.

Everything here works on one video's run folder (tracks.txt, frames.csv, gaps.json,
summary.json; docs/algorithms/index.md#run-outputs). Frames on disk are 1-based; in memory 0-based.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import FloatArray
from trackfw.formats.run import check_complete_run, read_run

Image = NDArray[np.uint8]
Point = tuple[float, float]

TEXT_FONT = cv2.FONT_HERSHEY_SIMPLEX
INFOLESS_COLOUR = (40, 40, 220)  # BGR red
CANVAS_GREY = 48


@dataclass
class Gap:
    """One resolved interval crossing: last normal frame ``a``, first normal frame ``b`` (0-based).

    Attributes:
        a, b: frame indices.
        positions_b: target id -> ``(x, y)`` where the gap matcher placed it on frame ``b``.
        chosen: the gap matcher's chosen candidate (e.g. ``ar2``), or None.
    """

    a: int
    b: int
    positions_b: dict[int, Point]
    chosen: str | None = None


@dataclass
class RunData:
    """What the renderer needs from one video's run folder.

    Attributes:
        run_dir: the folder.
        video_name: the video's name.
        video_path: the dataset video it ran on (summary.json), or None.
        pipeline: the pipeline's name.
        n_frames: frames in the video.
        box_size: the pipeline's ``engine.box_size``: the side of tracks.txt's squares, a head at
            1080p. A point with no detection size is drawn with this side scaled to the frame.
        tracks: 0-based frame -> ``{target id: (x, y)}``.
        detections: 0-based frame -> ``((K, 2) points, (K, 2) box (width, height))``; the sizes
            are NaN where the detector gave no boxes.
        infoless: 0-based frames the run judged info-less.
        unread: 0-based frames that could not be read.
        gaps: resolved interval crossings, in order.
    """

    run_dir: Path
    video_name: str
    video_path: str | None
    pipeline: str
    n_frames: int
    box_size: float
    tracks: dict[int, dict[int, Point]] = field(default_factory=dict)
    detections: dict[int, tuple[FloatArray, FloatArray]] = field(default_factory=dict)
    infoless: set[int] = field(default_factory=set)
    unread: set[int] = field(default_factory=set)
    gaps: list[Gap] = field(default_factory=list)


def load_run_data(run_dir: Path) -> RunData:
    """Read one video's run folder.

    Raises:
        UserError: a missing or malformed file, named with the problem.
    """
    run_dir = Path(run_dir)
    summary = check_complete_run(run_dir)
    config = summary.get("config") or {}
    box_size = float((config.get("engine") or {}).get("box_size", 80.0))
    data = RunData(
        run_dir=run_dir,
        video_name=str(summary.get("video", run_dir.name)),
        video_path=summary.get("video_path"),
        pipeline=str(summary.get("pipeline", "")),
        n_frames=int(summary.get("n_frames", 0)),
        box_size=box_size,
    )
    run = read_run(run_dir)
    data.tracks = {
        frame: {target: (position[0], position[1]) for target, position in targets.items()}
        for frame, targets in run.tracks.items()
    }
    for frame, points, sizes in zip(
        run.frames.frames.tolist(), run.frames.detections, run.frames.detection_sizes, strict=True
    ):
        if len(points):
            data.detections[frame] = (points, sizes)
    for frame, status, infoless in zip(
        run.frames.frames.tolist(), run.frames.status, run.frames.infoless.tolist(), strict=True
    ):
        if status != "ok":
            data.unread.add(frame)
        elif infoless:
            data.infoless.add(frame)
    gaps = run.gaps if run.gaps is not None else []
    for entry in gaps if isinstance(gaps, list) else []:
        if not isinstance(entry, dict) or not entry.get("resolved") or entry.get("b") is None:
            continue
        positions = {
            int(target): (float(point[0]), float(point[1]))
            for target, point in (entry.get("positions") or {}).items()
        }
        data.gaps.append(
            Gap(int(entry["a"]) - 1, int(entry["b"]) - 1, positions, entry.get("chosen"))
        )
    return data


def identity_colour(target_id: int) -> tuple[int, int, int]:
    """A distinct, stable BGR colour per identity (hues spaced by the golden ratio).

    >>> identity_colour(1) == identity_colour(1), identity_colour(1) != identity_colour(2)
    (True, True)
    """
    hue = (target_id * 0.618033988749895) % 1.0
    red, green, blue = colorsys.hsv_to_rgb(hue, 0.85, 1.0)
    return int(blue * 255), int(green * 255), int(red * 255)


def blank_frame(width: int, height: int) -> Image:
    """A grey canvas for videos without frames (point-only videos)."""
    return np.full((height, width, 3), CANVAS_GREY, dtype=np.uint8)


def _label(image: Image, text: str, origin: tuple[int, int], scale: float = 0.6) -> None:
    """White text on a dark outline, readable on any background; drawn in place.

    The text is drawn once, into a mask, and the outline is that mask dilated. Two ``putText``
    passes with different thicknesses do not line up: OpenCV 5 makes a glyph's advance depend on
    the stroke thickness, so a thick outline pass runs ahead of a thin text pass letter by letter.

    Args:
        image: ``(H, W, 3)`` uint8 BGR.
        text: the label.
        origin: ``(x, y)`` of the text's baseline start, as for ``cv2.putText``.
        scale: the font scale.
    """
    (text_width, text_height), baseline = cv2.getTextSize(text, TEXT_FONT, scale, 1)
    radius = max(1, round(1 + 1.5 * scale))
    # A margin for the outline and for glyphs that reach past the nominal text box.
    pad = radius + 2 + round(4 * scale)
    mask = np.zeros((text_height + baseline + 2 * pad, text_width + 2 * pad), dtype=np.uint8)
    cv2.putText(mask, text, (pad, pad + text_height), TEXT_FONT, scale, 255, 1, cv2.LINE_AA)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    outline = cv2.dilate(mask, kernel)
    # Clip the mask's rectangle to the image.
    left, top = origin[0] - pad, origin[1] - text_height - pad
    x0, y0 = max(left, 0), max(top, 0)
    x1 = min(left + mask.shape[1], image.shape[1])
    y1 = min(top + mask.shape[0], image.shape[0])
    if x0 >= x1 or y0 >= y1:
        return
    window = (slice(y0 - top, y1 - top), slice(x0 - left, x1 - left))
    fill_alpha = (mask[window].astype(np.float32) / 255.0)[..., None]
    outline_alpha = (outline[window].astype(np.float32) / 255.0)[..., None]
    region = image[y0:y1, x0:x1].astype(np.float32)
    region *= 1.0 - outline_alpha  # dark outline under the text
    region = region * (1.0 - fill_alpha) + 255.0 * fill_alpha
    image[y0:y1, x0:x1] = np.clip(np.round(region), 0, 255).astype(np.uint8)


def _segment_start(data: RunData, t: int) -> int:
    """The first frame of the segment holding ``t`` (trails never cross an interval)."""
    start = 0
    for gap in data.gaps:
        if gap.b <= t:
            start = max(start, gap.b)
    return start


#: The height tracks.txt's fixed box refers to (the paper's videos are 1080p).
REFERENCE_HEIGHT = 1080


def box_size_at(data: RunData, t: int, point: Point, frame_height: int) -> tuple[float, float]:
    """``(width, height)`` of the box to draw around a tracked point on frame ``t``.

    The size of the detection the point sits on (the nearest one within its own size), else
    ``data.box_size`` (a head at 1080p, the MOT-text convention) scaled by ``frame_height / 1080``.

    >>> data = RunData(Path("."), "v", None, "p", 1, 80.0)
    >>> box_size_at(data, 0, (5.0, 5.0), 540)
    (40.0, 40.0)
    >>> data.detections[0] = (np.array([[6.0, 5.0]]), np.array([[12.0, 14.0]]))
    >>> box_size_at(data, 0, (5.0, 5.0), 540)
    (12.0, 14.0)
    """
    points, sizes = data.detections.get(t, (None, None))
    if points is not None and sizes is not None and len(points):
        known = np.isfinite(sizes).all(axis=1)
        distance = np.hypot(points[:, 0] - point[0], points[:, 1] - point[1])
        # Only a detection within its own size counts as the one the point sits on.
        near = known & (distance <= np.nan_to_num(sizes.max(axis=1)))
        if near.any():
            index = int(np.argmin(np.where(near, distance, np.inf)))
            return float(sizes[index, 0]), float(sizes[index, 1])
    side = data.box_size * frame_height / REFERENCE_HEIGHT
    return side, side


def draw_frame(image: Image, t: int, data: RunData, trail: int = 15) -> Image:
    """Draw frame ``t``: boxes, points, ids, trails; info-less and unread frames are marked.

    Args:
        image: ``(H, W, 3)`` uint8 BGR; drawn on a copy.
        t: 0-based frame index.
        data: the run.
        trail: frames of trail behind each point.
    """
    canvas = image.copy()
    height, width = canvas.shape[:2]
    scale = max(0.5, height / 900)
    if t in data.infoless or t in data.unread:
        canvas = (canvas * 0.45).astype(np.uint8)
        cv2.rectangle(
            canvas, (0, 0), (width - 1, height - 1), INFOLESS_COLOUR, max(6, height // 60)
        )
        text = "INFO-LESS" if t in data.infoless else "UNREADABLE"
        _label(canvas, text, (width // 2 - int(80 * scale), height // 2), 1.2 * scale)
    start = max(_segment_start(data, t), t - trail)
    targets = sorted(data.tracks.get(t, {}).items())
    corners: dict[int, tuple[int, int]] = {}
    for target, (x, y) in targets:
        colour = identity_colour(target)
        history = [
            data.tracks[s][target]
            for s in range(start, t + 1)
            if s in data.tracks and target in data.tracks[s]
        ]
        if len(history) > 1:
            points = np.round(np.asarray(history)).astype(np.int32).reshape(-1, 1, 2)
            cv2.polylines(canvas, [points], False, colour, 2, cv2.LINE_AA)
        box_width, box_height = box_size_at(data, t, (x, y), height)
        top_left = (round(x - box_width / 2), round(y - box_height / 2))
        bottom_right = (round(x + box_width / 2), round(y + box_height / 2))
        cv2.rectangle(canvas, top_left, bottom_right, colour, 2, cv2.LINE_AA)
        corners[target] = top_left
    # Points and ids go on top of every box and trail: in a group, a neighbour's box must not
    # hide where a target is.
    for target, (x, y) in targets:
        cv2.circle(canvas, (round(x), round(y)), 4, identity_colour(target), -1, cv2.LINE_AA)
    for target, _ in targets:
        left, top = corners[target]
        _label(canvas, str(target), (left + 3, top - 6), 0.6 * scale)
    _label(
        canvas,
        f"frame {t + 1}/{data.n_frames}  {data.pipeline}",
        (10, int(28 * scale)),
        0.7 * scale,
    )
    return canvas


def draw_gap_panel(image_a: Image, image_b: Image, gap: Gap, data: RunData) -> Image:
    """Frame ``a`` beside frame ``b`` with a line linking each identity across the interval.

    Returns an image the size of ``image_b``: each frame is scaled to half the width.
    """
    height, width = image_b.shape[:2]
    panel = np.zeros_like(image_b)
    half_width = width // 2
    factor = half_width / width
    scaled_height = round(height * factor)
    top = (height - scaled_height) // 2
    for index, image in enumerate((image_a, image_b)):
        small = cv2.resize(image, (half_width, scaled_height), interpolation=cv2.INTER_AREA)
        panel[top : top + scaled_height, index * half_width : (index + 1) * half_width] = small
    cv2.line(panel, (half_width, 0), (half_width, height - 1), (200, 200, 200), 2)
    positions_a = data.tracks.get(gap.a, {})
    # Targets the run reported on frame b (inside the image); gaps.json also has those outside.
    positions_b = data.tracks.get(gap.b, {})
    for target, (xa, ya) in sorted(positions_a.items()):
        if target not in positions_b:
            continue
        xb, yb = positions_b[target]
        colour = identity_colour(target)
        start = (round(xa * factor), round(top + ya * factor))
        end = (round(half_width + xb * factor), round(top + yb * factor))
        cv2.line(panel, start, end, colour, 2, cv2.LINE_AA)
        for point in (start, end):
            cv2.circle(panel, point, 5, colour, -1, cv2.LINE_AA)
        _label(panel, str(target), (end[0] + 6, end[1] - 6), 0.5)
    scale = max(0.5, height / 900)
    chosen = f", {gap.chosen}" if gap.chosen else ""
    _label(panel, f"frame a = {gap.a + 1}", (10, max(24, top - 12)), 0.7 * scale)
    _label(panel, f"frame b = {gap.b + 1}", (half_width + 10, max(24, top - 12)), 0.7 * scale)
    _label(
        panel,
        f"interval of {gap.b - gap.a - 1} info-less frames{chosen}",
        (10, min(height - 12, top + scaled_height + int(30 * scale))),
        0.7 * scale,
    )
    return panel


__all__ = [
    "Gap",
    "RunData",
    "blank_frame",
    "draw_frame",
    "draw_gap_panel",
    "identity_colour",
    "load_run_data",
]

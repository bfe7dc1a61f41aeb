"""Render one video's run as an MP4 (OpenCV ``mp4v``), optionally with PNG stills.

The output follows the video frame by frame. Before each frame ``b`` that ends an interval, a
panel (frame ``a`` beside frame ``b``, a line per identity) is held for ``panel_frames`` frames.
A point-only video (annotations without pixels) is drawn on a grey canvas.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from trackfw.atomic import check_output_file
from trackfw.dataset import frame_source_path, load_video
from trackfw.errors import UserError
from trackfw.formats.run import SUMMARY_FILE
from trackfw.records import VideoContext
from trackfw.video_io import check_written_video, iter_frames
from trackfw_plugins.render.draw import (
    Image,
    RunData,
    blank_frame,
    draw_frame,
    draw_gap_panel,
    load_run_data,
)


@dataclass
class RenderResult:
    """What was written.

    Attributes:
        video: the MP4 file.
        frames_written: frames in it (video frames plus held panel frames).
        panels: interval panels drawn.
        pngs: PNG stills written.
    """

    video: Path
    frames_written: int
    panels: int
    pngs: list[Path] = field(default_factory=list)


def find_run_dir(run_dir: Path, video: str | None = None) -> Path:
    """The run folder of one video: ``run_dir`` itself or its sub-folder for ``video``.

    Raises:
        UserError: no complete run there, or several videos and no ``video`` chosen.
    """
    run_dir = Path(run_dir)
    if video is None and (run_dir / SUMMARY_FILE).is_file():
        return run_dir
    if not run_dir.is_dir():
        raise UserError(f"{run_dir}: no such folder; expected a run folder (trackfw run --output).")
    if video is not None:
        chosen = run_dir / video
        if (chosen / SUMMARY_FILE).is_file():
            return chosen
        if (run_dir / SUMMARY_FILE).is_file() and run_dir.name == video:
            return run_dir
    names = sorted(child.name for child in run_dir.iterdir() if (child / SUMMARY_FILE).is_file())
    if video is not None:
        raise UserError(
            f"{run_dir}: no complete run for video {video!r}; expected one of"
            f" {', '.join(names) or 'none (no summary.json found)'}."
        )
    if len(names) == 1:
        return run_dir / names[0]
    if not names:
        raise UserError(
            f"{run_dir}: no summary.json here or in a sub-folder; expected a run folder."
        )
    raise UserError(
        f"{run_dir}: runs of several videos ({', '.join(names)}); choose one with --video."
    )


def _video_for(data: RunData, dataset: Path | None) -> VideoContext:
    if dataset is not None:
        candidate = Path(dataset) / data.video_name
        path = candidate if candidate.exists() else Path(dataset)
    elif data.video_path:
        path = Path(data.video_path)
    else:
        raise UserError(
            f"{data.run_dir / SUMMARY_FILE}: video_path: missing; give --dataset with the video."
        )
    if not path.exists():
        raise UserError(
            f"{data.run_dir / SUMMARY_FILE}: video_path {str(path)!r} does not exist;"
            " give --dataset with the folder that holds the video."
        )
    return load_video(path)


def _images(video: VideoContext) -> Iterator[tuple[int, Image]]:
    """Every frame of the video; grey where there are no pixels."""
    try:
        frame_source_path(Path(video.path))
        has_frames = True
    except UserError:
        has_frames = False
    canvas = blank_frame(video.width, video.height)
    if not has_frames:
        for t in range(video.n_frames):
            yield t, canvas
        return
    for t, image, _ in iter_frames(video, decode=True):
        yield t, canvas if image is None else image


def render_run(
    run_dir: Path,
    out: Path | None = None,
    dataset: Path | None = None,
    video: str | None = None,
    panel_frames: int | None = None,
    png_frames: Sequence[int] = (),
    png_panels: bool = False,
    trail: int = 15,
) -> RenderResult:
    """Render a run to an MP4 (written atomically).

    Args:
        run_dir: a video's run folder, or a runs folder (then ``video`` picks one).
        out: the MP4 file; default ``<video run folder>/render.mp4``.
        dataset: the dataset folder holding the video; default summary.json's ``video_path``.
        video: the video's name inside a runs folder.
        panel_frames: frames each interval panel is held; default one second.
        png_frames: 1-based frame numbers also saved as PNG next to the MP4.
        png_panels: also save every interval panel as PNG.
        trail: frames of trail behind each point.
    """
    folder = find_run_dir(run_dir, video)
    data = load_run_data(folder)
    source = _video_for(data, dataset)
    out = Path(out) if out is not None else folder / "render.mp4"
    if out.suffix.lower() != ".mp4":
        raise UserError(f"--out {out}: expected a file name ending in .mp4.")
    check_output_file(out, "--out")
    # Checked before anything is written: a still that cannot exist is a mistyped number, and
    # silently rendering without it would hide that.
    outside = sorted(frame for frame in png_frames if not 1 <= frame <= source.n_frames)
    if outside:
        raise UserError(
            f"--png-frames: {'frames' if len(outside) > 1 else 'frame'}"
            f" {', '.join(map(str, outside))} {'are' if len(outside) > 1 else 'is'} out of range;"
            f" {data.video_name} has frames 1 to {source.n_frames}."
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    hold = max(0, round(source.fps) if panel_frames is None else panel_frames)
    wanted = {frame - 1 for frame in png_frames}
    gap_at = {gap.b: gap for gap in data.gaps}
    frames_a = {gap.a for gap in data.gaps}
    temporary = out.with_name(f".{out.stem}.tmp{os.getpid()}.mp4")
    writer = cv2.VideoWriter(
        str(temporary),
        cv2.VideoWriter.fourcc(*"mp4v"),
        float(source.fps or 30.0),
        (source.width, source.height),
    )
    if not writer.isOpened():
        raise UserError(f"--out {out}: OpenCV cannot write an mp4v video there.")
    result = RenderResult(out, 0, 0)
    kept: dict[int, Image] = {}
    try:
        for t, image in _images(source):
            if image.shape[:2] != (source.height, source.width):
                image = np.asarray(cv2.resize(image, (source.width, source.height)), dtype=np.uint8)
            if t in frames_a:
                kept[t] = image
            gap = gap_at.get(t)
            if gap is not None and gap.a in kept:
                panel = draw_gap_panel(kept.pop(gap.a), image, gap, data)
                for _ in range(hold):
                    writer.write(panel)
                result.frames_written += hold
                result.panels += 1
                if png_panels:
                    result.pngs.append(_png(out, f"gap{gap.a + 1:06d}-{gap.b + 1:06d}", panel))
            drawn = draw_frame(image, t, data, trail)
            writer.write(drawn)
            result.frames_written += 1
            if t in wanted:
                result.pngs.append(_png(out, f"frame{t + 1:06d}", drawn))
        writer.release()
        check_written_video(temporary, result.frames_written, shown=out)
        os.replace(temporary, out)
    except BaseException:
        writer.release()
        temporary.unlink(missing_ok=True)
        raise
    return result


def _png(out: Path, suffix: str, image: Image) -> Path:
    path = out.with_name(f"{out.stem}-{suffix}.png")
    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise UserError(f"{path}: OpenCV could not encode the PNG.")
    from trackfw.atomic import atomic_open

    with atomic_open(path, "wb") as stream:
        stream.write(np.asarray(encoded).tobytes())
    return path


__all__ = ["RenderResult", "find_run_dir", "render_run"]

"""Frame readers for video files and MOT-style image folders.

A frame that fails to decode is reported with status ``"unreadable"`` and no pixels, never an
exception: the engine records it in frames.csv and carries on. When a video container stops
early (a truncated or corrupt tail), the remaining frames are reported as ``"unread"``.
"""

from __future__ import annotations

import os
import struct
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, cast

import numpy as np
from numpy.typing import NDArray

from trackfw.dataset import IMAGE_SUFFIXES, VIDEO_SUFFIXES, frame_source_path
from trackfw.errors import UserError
from trackfw.records import VideoContext

FrameItem = tuple[int, NDArray[np.uint8] | None, str]
"""``(t, image or None, status)`` with status ``ok``, ``unreadable`` or ``unread``."""


def iter_frames(video: VideoContext, decode: bool = True) -> Iterator[FrameItem]:
    """Yield every frame index of ``video`` in order, with pixels when ``decode`` is true.

    Args:
        video: the video, as returned by :func:`trackfw.dataset.load_video`.
        decode: read pixels; when false, yields ``(t, None, "ok")`` for every frame without
            touching the file (pipelines whose stages need no pixels).

    Yields:
        ``(t, image, status)``: ``image`` is ``(H, W, 3)`` uint8 BGR or None.
    """
    if not decode:
        for t in range(video.n_frames):
            yield t, None, "ok"
        return
    source = frame_source_path(Path(video.path))
    if source.is_dir():
        yield from _iter_image_folder(source, video.n_frames)
    else:
        yield from _iter_container(source, video.n_frames)


def _iter_image_folder(folder: Path, n_frames: int) -> Iterator[FrameItem]:
    import cv2

    files = sorted(child for child in folder.iterdir() if child.suffix.lower() in IMAGE_SUFFIXES)
    for t in range(n_frames):
        image = cast(
            NDArray[np.uint8] | None, cv2.imread(str(files[t])) if t < len(files) else None
        )
        yield t, image, "ok" if image is not None else "unreadable"


def _iter_container(path: Path, n_frames: int) -> Iterator[FrameItem]:
    import cv2

    capture = cv2.VideoCapture(str(path))
    try:
        t = 0
        while t < n_frames and capture.isOpened():
            ok, image = capture.read()
            if not ok or image is None:
                break
            yield t, cast(NDArray[np.uint8], image), "ok"
            t += 1
        # Decoders stop at the first broken packet; what follows cannot be trusted.
        for rest in range(t, n_frames):
            yield rest, None, "unread"
    finally:
        capture.release()


# ------------------------------------------------------------------------------------- probing


@dataclass(frozen=True)
class ContainerInfo:
    """What a video file's header says: frame size, frame rate and frame count."""

    width: int
    height: int
    fps: float
    n_frames: int


@contextmanager
def native_stderr_silenced() -> Iterator[None]:
    """Send file descriptor 2 to /dev/null for the duration.

    FFmpeg and OpenCV print from C straight to the descriptor (``moov atom not found``), past
    ``sys.stderr``; their environment switches are read once per process, so they cannot be
    turned on just for a probe. Only for short calls: anything the process prints meanwhile is
    lost.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def probe_container(path: Path) -> ContainerInfo:
    """Open a video file, read its header and close it, without the decoder's own messages.

    Raises:
        UserError: one sentence naming the file and what was expected, when the file is empty,
            is not a container FFmpeg can read, or has no video stream with a frame size.
    """
    import cv2

    expected = f"expected a video file ({', '.join(s[1:].upper() for s in VIDEO_SUFFIXES)})"
    if path.stat().st_size == 0:
        raise UserError(f"{path}: empty file (0 bytes); {expected}.")
    with native_stderr_silenced():
        capture = cv2.VideoCapture(str(path))
        try:
            opened = capture.isOpened()
            width = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)) if opened else 0
            height = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)) if opened else 0
            fps = float(capture.get(cv2.CAP_PROP_FPS)) if opened else 0.0
            n_frames = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) if opened else 0
        finally:
            capture.release()
    if not opened:
        raise UserError(
            f"{path}: not a video FFmpeg can open (unknown or damaged container); {expected}."
        )
    if width <= 0 or height <= 0:
        raise UserError(f"{path}: no video stream with a frame size; {expected} with pictures.")
    return ContainerInfo(width, height, fps if fps > 0 else 30.0, max(n_frames, 0))


def check_written_video(path: Path, n_frames: int, shown: Path | None = None) -> None:
    """Reopen a video just written and count its frames; a UserError when some are missing.

    OpenCV's writer reports no error: on a full disk (or past ``ulimit -f``) it drops frames and
    the index, and the file cannot be opened. Writers call this before renaming the file into
    place.

    Args:
        path: the file written.
        n_frames: frames handed to the writer.
        shown: the name to report (the final name when ``path`` is a temporary one).
    """
    import cv2

    with native_stderr_silenced():
        capture = cv2.VideoCapture(str(path))
        try:
            count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) if capture.isOpened() else 0
        finally:
            capture.release()
    if count != n_frames:
        written = "it cannot be opened" if count <= 0 else f"it holds {count}"
        raise UserError(
            f"{shown or path}: the video writer was given {n_frames} frames but {written} (is the"
            f" disk full?); expected a complete video of {n_frames} frames."
        )


def check_frame_sizes(
    files: Sequence[Path], width: int | None = None, height: int | None = None
) -> None:
    """Every image of a frame folder must have one size: ``width`` x ``height`` or the first's.

    Trackers, gap matchers and the run outputs work in one pixel frame per video; a resized
    frame would silently move every point on it. Only the image headers are read (a few bytes
    each), so a folder of thousands of frames is checked in well under a second. An image whose
    header cannot be read is left to the decoder, which reports it as an unreadable frame.

    Args:
        files: the frame images in frame order.
        width, height: the expected size; None takes it from the first image with a header.

    Raises:
        UserError: naming the first image of another size, its size and the expected one.
    """
    reference: Path | None = None
    for path in files:
        size = image_size(path)
        if size is None:
            continue
        if width is None or height is None:
            (width, height), reference = size, path
        elif size != (width, height):
            like = "" if reference is None else f" like {reference.name}"
            raise UserError(
                f"{path}: frame is {size[0]}x{size[1]}; expected {width}x{height}{like}"
                " (every frame of a video must have the same size)."
            )


def image_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG, JPEG or BMP header, or None when it cannot be read."""
    try:
        with path.open("rb") as stream:
            head = stream.read(32)
            if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR":
                width, height = struct.unpack(">II", head[16:24])
                return int(width), int(height)
            if head.startswith(b"BM") and len(head) >= 26:
                width, height = struct.unpack("<ii", head[18:26])
                return int(width), abs(int(height))  # negative height: rows stored top-down
            if head.startswith(b"\xff\xd8"):
                stream.seek(2)
                return _jpeg_size(stream)
    except (OSError, struct.error):
        return None
    return None


def _jpeg_size(stream: BinaryIO) -> tuple[int, int] | None:
    read = stream.read
    while True:
        marker = read(2)
        if len(marker) < 2 or marker[0] != 0xFF:
            return None
        kind = marker[1]
        if kind == 0xFF:  # fill byte before a marker
            stream.seek(-1, 1)
            continue
        if kind in (0xD8, 0x01) or 0xD0 <= kind <= 0xD7:  # markers without a length
            continue
        length = struct.unpack(">H", read(2))[0]
        # Start of frame (baseline, progressive, lossless...), not DHT/JPG/DAC which share the range.
        if 0xC0 <= kind <= 0xCF and kind not in (0xC4, 0xC8, 0xCC):
            height, width = struct.unpack(">xHH", read(5))
            return int(width), int(height)
        stream.seek(length - 2, 1)

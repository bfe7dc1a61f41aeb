"""Frame readers for video files and MOT-style image folders.

A frame that fails to decode is reported with status ``"unreadable"`` and no pixels, never an
exception: the engine records it in frames.csv and carries on. When a video container stops
early (a truncated or corrupt tail), the remaining frames are reported as ``"unread"``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from trackfw.dataset import IMAGE_SUFFIXES, frame_source_path
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

"""Video and frame-folder probing: header sizes and the container probe."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.video_io import check_frame_sizes, image_size, probe_container


@pytest.mark.parametrize("suffix", [".jpg", ".png", ".bmp"])
@pytest.mark.parametrize(("width", "height"), [(1, 1), (37, 23), (1920, 1080)])
def test_image_size_reads_the_header_like_the_decoder(
    suffix: str, width: int, height: int, tmp_path: Path
) -> None:
    path = tmp_path / f"frame{suffix}"
    pixels = np.random.default_rng(width).integers(0, 256, (height, width, 3), dtype=np.uint8)
    assert cv2.imwrite(str(path), pixels)
    decoded = cv2.imread(str(path))
    assert image_size(path) == (decoded.shape[1], decoded.shape[0]) == (width, height)


def test_image_size_of_a_progressive_jpeg(tmp_path: Path) -> None:
    path = tmp_path / "frame.jpg"
    pixels = np.zeros((30, 50, 3), dtype=np.uint8)
    assert cv2.imwrite(str(path), pixels, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    assert image_size(path) == (50, 30)


@pytest.mark.parametrize("content", [b"", b"\xff\xd8", b"\x89PNG\r\n\x1a\n", b"hello world"])
def test_image_size_of_a_broken_header_is_unknown(content: bytes, tmp_path: Path) -> None:
    path = tmp_path / "frame.jpg"
    path.write_bytes(content)
    assert image_size(path) is None


def test_check_frame_sizes_leaves_unreadable_frames_to_the_decoder(tmp_path: Path) -> None:
    good = tmp_path / "000001.png"
    assert cv2.imwrite(str(good), np.zeros((8, 10, 3), np.uint8))
    broken = tmp_path / "000002.png"
    broken.write_bytes(b"broken")
    check_frame_sizes([good, broken], 10, 8)
    with pytest.raises(UserError, match=r"000001.png: frame is 10x8; expected 12x8"):
        check_frame_sizes([good, broken], 12, 8)


def test_probe_container_reads_a_real_video(tmp_path: Path) -> None:
    path = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), 12.0, (64, 48))
    assert writer.isOpened()
    for value in range(5):
        writer.write(np.full((48, 64, 3), value * 40, np.uint8))
    writer.release()
    info = probe_container(path)
    assert (info.width, info.height, info.n_frames) == (64, 48, 5)
    assert info.fps == pytest.approx(12.0)


def test_probe_container_restores_stderr(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "clip.mp4"
    path.write_text("text\n", encoding="utf-8")
    with pytest.raises(UserError, match="not a video FFmpeg can open"):
        probe_container(path)
    import os

    os.write(2, b"still here\n")
    assert capfd.readouterr().err == "still here\n"

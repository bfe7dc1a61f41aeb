"""Run outputs: what a run says and records when some frames of the video could not be read."""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from trackfw.cli import main

#: MP4 boxes that hold other boxes on the way from ``moov`` to the sample tables.
_CONTAINERS = {"moov", "trak", "mdia", "minf", "stbl"}


def _boxes(data: bytes | bytearray, start: int, end: int) -> Iterator[tuple[str, int, int, int]]:
    """``(kind, offset, size, header size)`` of each MP4 box in ``data[start:end]``."""
    position = start
    while position < end:
        size, kind = struct.unpack(">I4s", data[position : position + 8])
        header = 8
        if size == 1:
            size, header = struct.unpack(">Q", data[position + 8 : position + 16])[0], 16
        elif size == 0:
            size = end - position
        yield kind.decode("latin-1"), position, size, header
        position += size


def _walk_tables(moov: bytearray, start: int, end: int, shift: int, sizes: list[int]) -> None:
    """Add ``shift`` to every chunk offset (stco) and collect the sample sizes (stsz)."""
    for kind, position, size, header in _boxes(moov, start, end):
        if kind in _CONTAINERS:
            _walk_tables(moov, position + header, position + size, shift, sizes)
        elif kind == "stco":
            (count,) = struct.unpack(">I", moov[position + 12 : position + 16])
            for index in range(count):
                at = position + 16 + 4 * index
                struct.pack_into(">I", moov, at, struct.unpack(">I", moov[at : at + 4])[0] + shift)
        elif kind == "stsz":
            fixed, count = struct.unpack(">II", moov[position + 12 : position + 20])
            sizes.extend(
                [fixed] * count
                if fixed
                else struct.unpack(f">{count}I", moov[position + 20 : position + 20 + 4 * count])
            )


def truncated_faststart_mp4(path: Path, n_frames: int, keep: int) -> None:
    """An ``mp4v`` MP4 of ``n_frames`` whose index (moov) sits at the front, cut after ``keep``.

    This is what a copy interrupted mid-way leaves of a camera's (or ``-movflags faststart``)
    recording: the index still lists every frame, the data stops early.
    """
    plain = path.with_suffix(".plain.mp4")
    writer = cv2.VideoWriter(str(plain), cv2.VideoWriter.fourcc(*"mp4v"), 25, (64, 48))
    rng = np.random.default_rng(0)
    for _ in range(n_frames):
        writer.write(rng.integers(20, 235, (48, 64, 3), dtype=np.uint8))
    writer.release()
    data = plain.read_bytes()
    plain.unlink()
    boxes = list(_boxes(data, 0, len(data)))
    _, moov_at, moov_size, _ = next(box for box in boxes if box[0] == "moov")
    moov = bytearray(data[moov_at : moov_at + moov_size])
    sizes: list[int] = []
    # moov moves in front of mdat, so every chunk offset grows by its size.
    _walk_tables(moov, 8, len(moov), moov_size, sizes)
    out = bytearray()
    data_start = 0
    for kind, position, size, header in boxes:
        if kind == "moov":
            continue
        if kind == "mdat":
            out += moov
            data_start = len(out) + header
        out += data[position : position + size]
    assert len(sizes) == n_frames
    path.write_bytes(bytes(out[: data_start + sum(sizes[:keep])]))


def _run_clip(
    pipeline: Path, video: Path, out: Path, capsys: pytest.CaptureFixture[str]
) -> tuple[dict[str, Any], str]:
    """``trackfw run`` of ``video`` (it must succeed): its summary.json and its stderr."""
    code = main(["run", str(pipeline), "--input", str(video), "--output", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    return json.loads((out / video.stem / "summary.json").read_text()), err


def test_truncated_mp4_says_how_many_frames_could_not_be_read(
    tmp_path: Path, pixel_pipeline: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    video = tmp_path / "clip.mp4"
    truncated_faststart_mp4(video, n_frames=120, keep=40)
    capture = cv2.VideoCapture(str(video))
    assert capture.get(cv2.CAP_PROP_FRAME_COUNT) == 120  # the index still promises 120 frames
    capture.release()
    summary, err = _run_clip(pixel_pipeline, video, tmp_path / "out", capsys)
    assert summary["frames_ok"] == 40 and summary["frames_unread"] == 80
    assert summary["frames_not_read"] == 80
    warnings = [line for line in err.splitlines() if "could not be read" in line]
    assert warnings == [f"warning: {line}" for line in summary["warnings"]]
    assert str(video) in warnings[0] and "80 of 120 frames could not be read" in warnings[0]
    assert "stop after frame 40" in warnings[0]


def test_complete_video_has_no_warning(
    tmp_path: Path, pixel_pipeline: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    video = tmp_path / "clip.mp4"
    truncated_faststart_mp4(video, n_frames=30, keep=30)
    summary, err = _run_clip(pixel_pipeline, video, tmp_path / "out", capsys)
    assert summary["frames_not_read"] == 0 and summary["warnings"] == []
    assert "could not be read" not in err

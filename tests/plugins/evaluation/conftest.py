"""Fixtures that write small fake datasets and runs in the real on-disk formats."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np
import pytest

from trackfw.dataset import write_meta
from trackfw.formats.annotations import write_heads, write_intervals, write_targets
from trackfw.records import Interval

Points = Mapping[int, Mapping[int, tuple[float, float]]]
FRAMES_HEADER = (
    "frame,status,infoless_probability,infoless,n_detections,detections,"
    "ms_detector,ms_classifier,ms_tracker,ms_gap_matcher"
)


def write_video(
    dataset: Path,
    name: str,
    targets: Points,
    n_frames: int,
    intervals: Iterable[tuple[int, int]] = (),
    heads: Iterable[tuple[int, int, float, float, float]] | None = None,
) -> Path:
    """A video folder: empty img1/, meta.json, gt.csv, intervals.csv (0-based a, b) and heads.csv."""
    video = dataset / name
    (video / "img1").mkdir(parents=True)
    write_meta(
        video / "meta.json", {"n_frames": n_frames, "width": 1920, "height": 1080, "fps": 30}
    )
    write_targets(video / "gt.csv", {frame: dict(points) for frame, points in targets.items()})
    write_intervals(video / "intervals.csv", [Interval(a=a, b=b, kind="sky") for a, b in intervals])
    if heads is not None:
        write_heads(video / "heads.csv", heads)
    return video


def write_run(
    runs: Path,
    name: str,
    tracks: Points,
    n_frames: int,
    infoless_frames: Iterable[int] = (),
    detections: Mapping[int, np.ndarray] | None = None,
    status: Mapping[int, str] | None = None,
    classifier: bool = True,
    initialised_from: str | None = None,
) -> Path:
    """A run folder: tracks.txt (80x80 boxes around the points) and frames.csv (every frame).

    Without a classifier (a batch tracker's run) the probability column is empty and no frame is
    labelled info-less.
    """
    folder = runs / name
    folder.mkdir(parents=True)
    lines = []
    for frame in sorted(tracks):
        for track_id, (x, y) in sorted(tracks[frame].items()):
            lines.append(
                f"{frame + 1},{track_id},{x - 40:.2f},{y - 40:.2f},80.00,80.00,1.00,-1,-1,-1"
            )
    (folder / "tracks.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    infoless = set(infoless_frames)
    rows = [FRAMES_HEADER]
    for frame in range(n_frames):
        points = np.zeros((0, 2)) if detections is None else detections.get(frame, np.zeros((0, 2)))
        text = ";".join(f"{x:.1f} {y:.1f}" for x, y in points)
        label = int(frame in infoless and classifier)
        probability = (0.9 if label else 0.1) if classifier else ""
        frame_status = "ok" if status is None else status.get(frame, "ok")
        rows.append(
            f"{frame + 1},{frame_status},{probability},{label},{len(points)},{text},1,1,1,0"
        )
    (folder / "frames.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    summary = {
        "video": name,
        "n_frames": n_frames,
        "pipeline": "test",
        "pipeline_hash": "0123456789ab",
    }
    if initialised_from is not None:
        summary["initialised_from"] = initialised_from
    (folder / "summary.json").write_text(json.dumps(summary) + "\n", encoding="utf-8")
    (folder / "gaps.json").write_text("[]\n", encoding="utf-8")
    return folder


@pytest.fixture
def make_video() -> Callable[..., Path]:
    """The :func:`write_video` helper."""
    return write_video


@pytest.fixture
def make_run() -> Callable[..., Path]:
    """The :func:`write_run` helper."""
    return write_run

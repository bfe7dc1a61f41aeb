"""Point-only videos: annotations without pixels, for engine tests and benchmarks.

A group of targets walks with constant velocity plus noise; each info-less interval applies a
similarity transform (the camera-pose change) to everything seen after it. With the oracle
detector and classifier such a video exercises the whole online loop without decoding frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from trackfw.dataset import write_heads, write_intervals, write_meta, write_targets
from trackfw.records import Interval


def make_points_video(
    directory: Path,
    n_frames: int = 200,
    n_targets: int = 8,
    n_others: int = 6,
    intervals: Sequence[tuple[int, int]] = ((80, 120),),
    width: int = 1280,
    height: int = 720,
    seed: int = 0,
    rotation_degrees: float = 10.0,
    scale: float = 1.1,
    shift: tuple[float, float] = (60.0, -30.0),
) -> Path:
    """Write a point-only video folder and return it.

    Args:
        directory: folder to create (the video's name is its folder name).
        n_frames: frames in the video.
        n_targets: people of interest (ids 1..n_targets), visible on frame 1.
        n_others: other people (heads.csv only).
        intervals: ``(start, end)`` 1-based inclusive info-less frames.
        width, height: frame size.
        seed: random seed.
        rotation_degrees, scale, shift: camera-pose change applied after each interval.
    """
    random = np.random.default_rng(seed)
    count = n_targets + n_others
    centre = np.array([width / 2, height / 2])
    start = centre + random.normal(0, [width / 8, height / 8], (count, 2))
    velocity = random.normal([1.0, 0.3], 0.2, (count, 2))
    infoless = np.zeros(n_frames, dtype=bool)
    for first, last in intervals:
        infoless[first - 1 : last] = True
    # Camera pose per frame: a similarity that changes once per interval.
    angle, zoom, offset = 0.0, 1.0, np.zeros(2)
    targets: dict[int, dict[int, tuple[float, float]]] = {}
    heads: list[tuple[int, int, float, float, float]] = []
    boundaries = {last for _, last in intervals}
    for t in range(n_frames):
        world = start + velocity * t + random.normal(0, 0.3, (count, 2))
        if t in boundaries:
            angle += np.radians(rotation_degrees)
            zoom *= scale
            offset += np.asarray(shift)
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        image = (world - centre) @ rotation.T * zoom + centre + offset
        if infoless[t]:
            continue
        inside = (
            (image[:, 0] >= 0) & (image[:, 0] < width) & (image[:, 1] >= 0) & (image[:, 1] < height)
        )
        frame_targets = {
            person + 1: (float(image[person, 0]), float(image[person, 1]))
            for person in range(n_targets)
            if inside[person]
        }
        if frame_targets:
            targets[t] = frame_targets
        heads.extend(
            (t, person + 1, float(image[person, 0]), float(image[person, 1]), 40.0 * zoom)
            for person in range(count)
            if inside[person]
        )
    directory.mkdir(parents=True, exist_ok=True)
    write_targets(directory / "gt.csv", targets)
    write_heads(directory / "heads.csv", heads)
    write_intervals(
        directory / "intervals.csv",
        [Interval(a=first - 2, b=last, kind="sky") for first, last in intervals],
    )
    write_meta(
        directory / "meta.json",
        {
            "fps": 30.0,
            "width": width,
            "height": height,
            "n_frames": n_frames,
            "source": "points",
            "seed": seed,
        },
    )
    return directory

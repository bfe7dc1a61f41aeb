"""Point-only videos: annotations without pixels, for engine tests and benchmarks.

A group of targets walks with constant velocity plus noise; each info-less interval applies a
similarity transform (the camera-pose change) to everything seen after it. With the oracle
detector and classifier such a video exercises the whole online loop without decoding frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from trackfw.dataset import write_meta
from trackfw.formats.annotations import write_annotations
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
    write_annotations(
        directory,
        targets,
        heads,
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


def gap_scene(
    detection_count: int,
    seed: int,
    size: int = 8,
    noise: float = 6.0,
    clustered: bool = False,
    candidates: int = 1,
    image: tuple[float, float] = (1920.0, 1080.0),
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """A gap-matching problem: a group pattern seen after a camera-pose change, among clutter.

    The pattern (points at least 60 px apart) is rotated by up to 15 degrees, scaled by 0.8-1.25,
    moved and jittered; clutter lies outside its bounding box, uniform over the image or around
    four centres (``clustered``). Predictions are the unrotated pattern at the observed centroid
    plus noise, one array per candidate (e.g. per AR order).

    Returns:
        ``candidates`` arrays ``(size, 2)`` of predictions U, the detections V ``(N, 2)`` in random
        order, and ``(size,)`` the row of V that belongs to each target.
    """
    rng = np.random.default_rng(seed)
    while True:
        pattern = rng.uniform([0, 0], [500, 300], (size, 2))
        gaps = np.sqrt(np.sum((pattern[:, None] - pattern[None]) ** 2, axis=2))
        np.fill_diagonal(gaps, np.inf)
        if gaps.min() > 60:
            break
    angle, scale = rng.uniform(-0.26, 0.26), rng.uniform(0.8, 1.25)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    observed = (pattern - pattern.mean(axis=0)) @ rotation.T * scale
    observed += rng.uniform([700, 400], [1200, 700]) + rng.normal(0, noise, (size, 2))
    low, high = observed.min(axis=0) - 40, observed.max(axis=0) + 40
    bounds = np.asarray(image, dtype=np.float64)
    centres = rng.uniform([0, 0], bounds, (4, 2)) if clustered else None
    clutter: list[np.ndarray] = []
    while len(clutter) < detection_count - size:
        if centres is not None:
            point = centres[rng.integers(4)] + rng.normal(0, 150, 2)
        else:
            point = rng.uniform([0, 0], bounds)
        inside_group = np.all((point >= low) & (point <= high))
        if not inside_group and np.all((point >= 0) & (point <= bounds)):
            clutter.append(point)
    detections = np.vstack([observed, np.array(clutter).reshape(-1, 2)])
    permutation = rng.permutation(detection_count)
    predicted = pattern - pattern.mean(axis=0) + observed.mean(axis=0)
    predictions = [predicted + rng.normal(0, noise, (size, 2)) for _ in range(candidates)]
    return predictions, detections[permutation], np.argsort(permutation)[:size]

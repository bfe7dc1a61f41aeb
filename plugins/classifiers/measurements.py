"""Per-video measurements for training the info-less SVM: flow, detections, labels (cached as NPZ).

:func:`measure_video` runs a detector and the optical flow over a video once and keeps the raw
per-frame ``M_t``, ``N_t`` and ``S_t`` with the ground-truth labels; decoding and flow dominate
the cost, so :func:`collect_measurements` caches them keyed by the feature settings.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.atomic import atomic_open
from trackfw.errors import UserError
from trackfw.formats.annotations import INTERVALS_FILE
from trackfw.records import FrameData, VideoContext
from trackfw.stages import Detector
from trackfw_plugins.classifiers.infoless_features import (
    DEFAULT_C_MAX,
    DisPreset,
    FlowMethod,
    OpticalFlowMeter,
    assemble_features,
    spread,
)

CACHE_VERSION = 1


@dataclass
class FeatureSettings:
    """How ``M_t`` and ``C_t`` are computed; recorded in the model file."""

    flow: FlowMethod = "dis"
    flow_width: int = 320
    dis_preset: DisPreset = "ultrafast"
    c_max: float = DEFAULT_C_MAX

    def as_dict(self) -> dict[str, Any]:
        """JSON form (the model file's ``features`` field)."""
        return {
            "flow": self.flow,
            "flow_width": self.flow_width,
            "dis_preset": self.dis_preset,
            "c_max": self.c_max,
        }


@dataclass
class VideoMeasurements:
    """Per-frame measurements of one video (readable frames only, in order).

    Attributes:
        name: the video's name.
        frames: ``(T,)`` frame indices.
        motion: ``(T,)`` ``M_t`` in working-resolution pixels.
        counts: ``(T,)`` ``N_t``.
        spreads: ``(T,)`` ``S_t`` in native pixels.
        labels: ``(T,)`` True for ground-truth info-less frames.
    """

    name: str
    frames: IntArray
    motion: FloatArray
    counts: FloatArray
    spreads: FloatArray
    labels: BoolArray

    def training_features(self, c_max: float = DEFAULT_C_MAX) -> FloatArray:
        """``(T, 11)`` features with the ground truth choosing the reference of ``C_t``."""
        return assemble_features(self.motion, self.counts, self.spreads, ~self.labels, c_max)


def ground_truth_labels(video: VideoContext) -> BoolArray:
    """``(n_frames,)`` True inside a ground-truth interval; a UserError when there is none."""
    truth = video.ground_truth
    if truth is None or not (Path(video.path) / INTERVALS_FILE).is_file():
        raise UserError(
            f"{video.path}: no intervals.csv; training the classifier needs the ground-truth"
            " info-less intervals."
        )
    labels = np.zeros(video.n_frames, dtype=bool)
    for interval in truth.intervals:
        labels[interval.a + 1 : min(interval.b, video.n_frames)] = True
    return labels


def measure_video(
    video: VideoContext,
    detector: Detector,
    meter: OpticalFlowMeter,
    frames: Any,
    progress: Callable[[int], None] | None = None,
) -> VideoMeasurements:
    """Run ``detector`` and ``meter`` over a video.

    Args:
        video: the video with its ground truth.
        detector: a built detector stage.
        meter: the optical-flow meter (reset here).
        frames: iterable of ``(t, image, status)`` as from ``trackfw.video_io.iter_frames``.
        progress: called with each frame index.
    """
    labels = ground_truth_labels(video)
    detector.start(video)
    meter.reset()
    rows: list[tuple[int, float, float, float]] = []
    for t, image, status in frames:
        if progress is not None:
            progress(t)
        if status != "ok" or image is None:
            continue  # the engine skips unreadable frames too
        detections = detector.detect(FrameData(t, image, video))
        points = np.asarray(detections.points, dtype=np.float64).reshape(-1, 2)
        rows.append((t, meter.measure(image), float(len(points)), spread(points)))
    table = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    indices = table[:, 0].astype(np.int64)
    return VideoMeasurements(
        name=video.name,
        frames=indices,
        motion=table[:, 1].copy(),
        counts=table[:, 2].copy(),
        spreads=table[:, 3].copy(),
        labels=labels[indices],
    )


# ----------------------------------------------------------------------------------- caching


def save_measurements(path: Path, measurements: VideoMeasurements, key: dict[str, Any]) -> None:
    """Write the measurements and the settings they depend on to an NPZ file, atomically."""
    with atomic_open(path, "wb") as stream:
        np.savez_compressed(
            stream,
            key=np.array(json.dumps(key, sort_keys=True)),
            frames=measurements.frames,
            motion=measurements.motion,
            counts=measurements.counts,
            spreads=measurements.spreads,
            labels=measurements.labels,
        )


def load_measurements(path: Path, name: str, key: dict[str, Any]) -> VideoMeasurements | None:
    """The cached measurements when ``path`` exists and was made with ``key``; else None."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != json.dumps(key, sort_keys=True):
                return None
            arrays = {
                name: np.asarray(data[name])
                for name in ("frames", "motion", "counts", "spreads", "labels")
            }
    except (OSError, ValueError, KeyError):
        return None  # a damaged cache is simply recomputed
    length = len(arrays["frames"])
    if any(array.shape != (length,) for array in arrays.values()):
        return None
    return VideoMeasurements(
        name=name,
        frames=arrays["frames"].astype(np.int64),
        motion=arrays["motion"].astype(np.float64),
        counts=arrays["counts"].astype(np.float64),
        spreads=arrays["spreads"].astype(np.float64),
        labels=arrays["labels"].astype(bool),
    )


# ---------------------------------------------------------------------------------- training


def read_video_list(path: Path) -> list[str]:
    """Video names from a split file: one per line; blank lines and ``#`` comments ignored."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise UserError(
            f"{path}: cannot read the split file ({error}); expected UTF-8 text."
        ) from None
    names = [line.split("#", 1)[0].strip() for line in text.splitlines()]
    names = [name for name in names if name]
    if not names:
        raise UserError(f"{path}: no video name; expected one video folder name per line.")
    return names


def select_videos(dataset: Path, names: Sequence[str] | None) -> list[Path]:
    """The dataset's video folders, restricted to ``names`` (in the dataset's order)."""
    from trackfw.dataset import list_videos

    videos = list_videos(dataset)
    if names is None:
        return videos
    by_name = {video.name: video for video in videos}
    missing = [name for name in names if name not in by_name]
    if missing:
        raise UserError(
            f"{dataset}: no video named {', '.join(repr(n) for n in missing[:5])}; expected names"
            f" of its sub-folders such as {', '.join(sorted(by_name)[:3])}."
        )
    wanted = set(names)
    return [video for video in videos if video.name in wanted]


def collect_measurements(
    video_dirs: Sequence[Path],
    detector_spec: dict[str, Any],
    settings: FeatureSettings,
    cache_dir: Path | None = None,
    log: Callable[[str], None] | None = None,
) -> list[VideoMeasurements]:
    """Measure every video with the registered detector, reusing the NPZ cache when valid.

    Args:
        video_dirs: the video folders.
        detector_spec: ``{"type": name, "params": {...}}`` for the registry.
        settings: flow settings.
        cache_dir: folder of per-video NPZ caches, or None for no cache.
        log: receives one line per video.
    """
    from trackfw.dataset import load_video
    from trackfw.registry import load_registry
    from trackfw.video_io import iter_frames

    say = log or (lambda line: None)
    registry = load_registry()
    try:
        detector = registry.build_stage("detector", detector_spec)
    except UserError as error:
        # The lines name detector.params.KEY, which the command line spells --detector-param KEY.
        raise UserError(*(f"--detector-param: {line}" for line in error.lines)) from None
    if not isinstance(detector, Detector):
        raise UserError(f"{detector_spec['type']!r} is not a detector.")
    meter = OpticalFlowMeter(settings.flow, settings.flow_width, settings.dis_preset)
    measured: list[VideoMeasurements] = []
    for number, video_dir in enumerate(video_dirs, start=1):
        video = load_video(video_dir)
        key = {
            "cache_version": CACHE_VERSION,
            "video": str(Path(video.path).resolve()),
            "n_frames": video.n_frames,
            "detector": detector_spec,
            "flow": settings.flow,
            "flow_width": settings.flow_width,
            "dis_preset": settings.dis_preset,
        }
        # The key's hash in the name lets runs with other settings share the folder.
        digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:12]
        cache = None if cache_dir is None else cache_dir / f"{video.name}.{digest}.npz"
        result = None if cache is None else load_measurements(cache, video.name, key)
        if result is None:
            result = measure_video(video, detector, meter, iter_frames(video, decode=True))
            if cache is not None:
                save_measurements(cache, result, key)
            origin = "measured"
        else:
            origin = "cached"
        say(
            f"[{number}/{len(video_dirs)}] {video.name}: {len(result.frames)} frames,"
            f" {int(result.labels.sum())} info-less ({origin})"
        )
        measured.append(result)
    return measured

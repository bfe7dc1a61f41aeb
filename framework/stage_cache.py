"""A cache of the per-frame outputs of the stages before the gap matcher.

The detector and the info-less classifier are the expensive part of a run and they do not depend
on the tracker or on the gap matcher: the classifier's online features are fed back the engine's
final decisions, and those decisions come from the classifier itself (and from whether a frame is
the first readable one), never from tracking. So an ablation that changes only the tracker or the
gap matcher may replay the recorded detections and classifier decisions instead of computing them
again.

One NPZ file (no pickle, loaded with ``allow_pickle=False``) per video and configuration. The key
hashes:

* the video: its resolved path, and the relative path, size and modification time of every file
  inside its folder (frames and annotations: a re-generated or edited video misses);
* the exact configuration (type and fully defaulted params) of the detector and the classifier,
  the providing package and version, and the content of the module that defines each class;
* the size and modification time of any file a parameter names (model files).

Files are written atomically; an unreadable or inconsistent file is a miss and is rewritten.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import re
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.atomic import atomic_open
from trackfw.records import Detections, VideoContext

if TYPE_CHECKING:
    from trackfw.pipeline import Pipeline, StageConfig
    from trackfw.registry import Registry

#: The stage kinds whose outputs are cached, in the order the engine runs them.
CACHED_KINDS = ("detector", "classifier")
#: Bumped when the NPZ layout or the key recipe changes, so old files are never misread.
CACHE_FORMAT = 1
FRAME_STATUSES = ("ok", "unreadable", "unread")
_ARRAYS = (
    "format",
    "key",
    "status",
    "probability",
    "infoless",
    "ms_detector",
    "ms_classifier",
    "counts",
    "points",
    "scores",
    "has_boxes",
    "boxes",
)


class RecordedFrame(Protocol):
    """What the cache reads from each of the engine's frame records."""

    t: int
    status: str
    probability: float | None
    infoless: bool | None
    detections: Detections | None
    milliseconds: dict[str, float]


def _file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def video_fingerprint(path: str | os.PathLike[str]) -> list[Any]:
    """``[resolved path, [[relative path, size, mtime_ns], ...]]`` of a video folder or file.

    Hidden files (temporary files of atomic writes) are left out.
    """
    root = Path(path).resolve()
    if root.is_file():
        stat = root.stat()
        return [str(root), [[root.name, stat.st_size, stat.st_mtime_ns]]]
    entries: list[list[Any]] = []
    for folder, directories, files in os.walk(root):
        directories[:] = sorted(d for d in directories if not d.startswith("."))
        for name in sorted(files):
            if name.startswith("."):
                continue
            file_path = Path(folder) / name
            stat = file_path.stat()
            entries.append([str(file_path.relative_to(root)), stat.st_size, stat.st_mtime_ns])
    return [str(root), entries]


def _named_files(value: Any) -> list[list[Any]]:
    """``[path, size, mtime_ns]`` of every existing file a parameter value names."""
    found: list[list[Any]] = []
    if isinstance(value, Mapping):
        for item in value.values():
            found.extend(_named_files(item))
    elif isinstance(value, list | tuple):
        for item in value:
            found.extend(_named_files(item))
    elif isinstance(value, str) and value and len(value) < 4096:
        candidate = Path(value).expanduser()
        try:
            if candidate.is_file():
                stat = candidate.stat()
                found.append([str(candidate.resolve()), stat.st_size, stat.st_mtime_ns])
        except OSError:
            pass
    return found


def _stage_code(registry: Registry | None, kind: str, type_name: str) -> list[str]:
    """Package, version and module digest of the class registered as ``kind``/``type_name``."""
    if registry is None or (kind, type_name) not in registry.stages:
        return []
    entry = registry.stages[(kind, type_name)]
    identity = [entry.source.package, entry.source.version, entry.cls.__qualname__]
    try:
        module_file = inspect.getsourcefile(entry.cls)
    except TypeError:
        module_file = None
    if module_file is not None and Path(module_file).is_file():
        identity.append(_file_digest(Path(module_file)))
    return identity


def _resources(registry: Registry | None, spec: StageConfig) -> list[Path]:
    """Files a stage reads besides those its parameters name (see ``Stage.resource_files``)."""
    if registry is None or (spec.kind, spec.name) not in registry.stages:
        return []
    return spec.cls.resource_files(spec.params)


def cache_key(
    pipeline: Pipeline,
    video: VideoContext,
    registry: Registry | None = None,
    kinds: Sequence[str] = CACHED_KINDS,
) -> str:
    """The key of ``video`` run through the detector and classifier of ``pipeline``.

    ``kinds=("detector",)`` gives the key of the detector alone: the key of a batch pipeline
    without a classifier that uses the same detector (see :meth:`StageCache.store_detector`).
    """
    # A batch pipeline may have no classifier: its key covers the detector alone.
    configs = {kind: pipeline.stages[kind] for kind in kinds if kind in pipeline.stages}
    stages = {kind: spec.as_data() for kind, spec in configs.items()}
    recipe = {
        "format": CACHE_FORMAT,
        "video": video_fingerprint(video.path),
        "n_frames": video.n_frames,
        "stages": stages,
        "code": {kind: _stage_code(registry, kind, spec.name) for kind, spec in configs.items()},
        "files": _named_files(stages),
        "resources": _named_files(
            [str(path) for spec in configs.values() for path in _resources(registry, spec)]
        ),
    }
    canonical = json.dumps(recipe, sort_keys=True, default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()[:32]


@dataclass
class StageReplay:
    """Recorded detector and classifier outputs of one video, frame by frame.

    Attributes:
        status: ``(T,)`` index into :data:`FRAME_STATUSES` per frame.
        probability: ``(T,)`` info-less probability (NaN on frames that were not read).
        infoless: ``(T,)`` the engine's decision on each frame.
        ms_detector, ms_classifier: ``(T,)`` recorded milliseconds.
        offsets: ``(T + 1,)`` start of each frame's detections in ``points``.
        points: ``(D, 2)`` head points of every frame, concatenated.
        scores: ``(D,)`` their scores.
        has_boxes: ``(T,)`` whether the detector gave boxes on that frame.
        boxes: ``(D, 4)`` boxes (NaN on frames without).
    """

    status: np.ndarray
    probability: FloatArray
    infoless: np.ndarray
    ms_detector: FloatArray
    ms_classifier: FloatArray
    offsets: np.ndarray
    points: FloatArray
    scores: FloatArray
    has_boxes: np.ndarray
    boxes: FloatArray

    def status_of(self, t: int) -> str:
        """The frame status recorded for frame ``t``."""
        return FRAME_STATUSES[int(self.status[t])]

    def frame(self, t: int) -> tuple[Detections, float, bool, float, float]:
        """``(detections, probability, infoless, ms detector, ms classifier)`` of frame ``t``."""
        start, stop = int(self.offsets[t]), int(self.offsets[t + 1])
        detections = Detections(
            self.points[start:stop],
            self.scores[start:stop],
            self.boxes[start:stop] if self.has_boxes[t] else None,
        )
        return (
            detections,
            float(self.probability[t]),
            bool(self.infoless[t]),
            float(self.ms_detector[t]),
            float(self.ms_classifier[t]),
        )


def _recording_arrays(
    frames: Sequence[RecordedFrame], key: str, classifier: bool = True
) -> dict[str, np.ndarray]:
    count = len(frames)
    status = np.zeros(count, dtype=np.uint8)
    probability = np.full(count, np.nan)
    infoless = np.zeros(count, dtype=bool)
    ms_detector = np.zeros(count)
    ms_classifier = np.zeros(count)
    counts = np.zeros(count, dtype=np.int64)
    has_boxes = np.zeros(count, dtype=bool)
    points: list[FloatArray] = []
    scores: list[FloatArray] = []
    boxes: list[FloatArray] = []
    for position, record in enumerate(frames):
        if record.t != position:
            raise ValueError(f"frame records out of order: record {position} is frame {record.t}")
        status[position] = FRAME_STATUSES.index(record.status)
        if record.status != "ok" or record.detections is None:
            continue
        detections = record.detections
        # Without the classifier a frame reads as a classifier-less run records it.
        probability[position] = float(record.probability or 0.0) if classifier else 0.0
        infoless[position] = bool(record.infoless) and classifier
        ms_detector[position] = record.milliseconds.get("detector", 0.0)
        ms_classifier[position] = record.milliseconds.get("classifier", 0.0) if classifier else 0.0
        counts[position] = len(detections)
        points.append(detections.points)
        scores.append(detections.scores)
        has_boxes[position] = detections.boxes is not None
        boxes.append(
            detections.boxes
            if detections.boxes is not None
            else np.full((len(detections), 4), np.nan)
        )
    return {
        "format": np.array(CACHE_FORMAT, dtype=np.int64),
        "key": np.array(key),
        "status": status,
        "probability": probability,
        "infoless": infoless,
        "ms_detector": ms_detector,
        "ms_classifier": ms_classifier,
        "counts": counts,
        "points": np.concatenate(points) if points else np.zeros((0, 2)),
        "scores": np.concatenate(scores) if scores else np.zeros(0),
        "has_boxes": has_boxes,
        "boxes": np.concatenate(boxes) if boxes else np.zeros((0, 4)),
    }


def _replay_from(arrays: Mapping[str, np.ndarray], key: str, n_frames: int) -> StageReplay | None:
    """A replay when the arrays are complete and consistent; None otherwise."""
    if int(arrays["format"]) != CACHE_FORMAT or str(arrays["key"]) != key:
        return None
    per_frame = ("status", "probability", "infoless", "ms_detector", "ms_classifier", "counts")
    if any(arrays[name].shape != (n_frames,) for name in (*per_frame, "has_boxes")):
        return None
    counts = arrays["counts"].astype(np.int64)
    total = int(counts.sum())
    points, scores, boxes = arrays["points"], arrays["scores"], arrays["boxes"]
    if points.shape != (total, 2) or scores.shape != (total,) or boxes.shape != (total, 4):
        return None
    if (counts < 0).any() or int(arrays["status"].max(initial=0)) >= len(FRAME_STATUSES):
        return None
    return StageReplay(
        status=arrays["status"],
        probability=arrays["probability"].astype(np.float64),
        infoless=arrays["infoless"].astype(bool),
        ms_detector=arrays["ms_detector"].astype(np.float64),
        ms_classifier=arrays["ms_classifier"].astype(np.float64),
        offsets=np.concatenate([[0], np.cumsum(counts)]),
        points=points.astype(np.float64),
        scores=scores.astype(np.float64),
        has_boxes=arrays["has_boxes"].astype(bool),
        boxes=boxes.astype(np.float64),
    )


class StageCache:
    """Detector and classifier outputs per video and configuration, as NPZ files in a folder.

    The counters ``hits``, ``misses`` and ``stores`` count this instance's lookups and writes
    (a benchmark job reports them).
    """

    def __init__(self, directory: str | os.PathLike[str], share_detector: bool = False) -> None:
        self.directory = Path(directory)
        #: A run with a classifier also records its detector alone (:meth:`store_detector`).
        self.share_detector = share_detector
        self.hits = 0
        self.misses = 0
        self.stores = 0

    def key(self, pipeline: Pipeline, video: VideoContext, registry: Registry | None = None) -> str:
        """See :func:`cache_key`."""
        return cache_key(pipeline, video, registry)

    def path(self, key: str, video_name: str = "") -> Path:
        """The NPZ file of ``key`` (the video's name in front, for people browsing the folder)."""
        prefix = re.sub(r"[^A-Za-z0-9._-]+", "_", video_name)[:80]
        return self.directory / (f"{prefix}-{key}.npz" if prefix else f"{key}.npz")

    def load(self, key: str, n_frames: int, video_name: str = "") -> StageReplay | None:
        """The replay stored under ``key``, or None (a miss) when absent or unusable."""
        path = self.path(key, video_name)
        replay: StageReplay | None = None
        if path.is_file():
            try:
                with np.load(path, allow_pickle=False) as archive:
                    arrays = {name: archive[name] for name in _ARRAYS}
                replay = _replay_from(arrays, key, n_frames)
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
                replay = None  # a damaged file is recomputed and overwritten
        if replay is None:
            self.misses += 1
        else:
            self.hits += 1
        return replay

    def store(self, key: str, frames: Sequence[RecordedFrame], video_name: str = "") -> Path:
        """Record the detector and classifier outputs of a finished run (atomically)."""
        return self._write(key, _recording_arrays(frames, key), video_name)

    def store_detector(
        self, key: str, frames: Sequence[RecordedFrame], video_name: str = ""
    ) -> Path | None:
        """Record the detector's outputs alone under its own key, unless already there.

        A run with a classifier writes this beside its own entry, so a batch pipeline without a
        classifier that uses the same detector (Table 1's batch rows) replays the detections
        instead of computing them again. ``key`` comes from :func:`cache_key` with
        ``kinds=("detector",)``.
        """
        if self.contains(key, video_name):
            return None
        return self._write(key, _recording_arrays(frames, key, classifier=False), video_name)

    def _write(self, key: str, arrays: dict[str, np.ndarray], video_name: str) -> Path:
        """Write one entry's arrays atomically; count the store."""
        path = self.path(key, video_name)
        with atomic_open(path, "wb") as stream:
            np.savez(stream, **arrays)  # type: ignore[arg-type]
        self.stores += 1
        return path

    def contains(self, key: str, video_name: str = "") -> bool:
        """True when a file for ``key`` exists (not checked for consistency)."""
        return self.path(key, video_name).is_file()


__all__ = [
    "CACHED_KINDS",
    "CACHE_FORMAT",
    "StageCache",
    "StageReplay",
    "cache_key",
    "video_fingerprint",
]

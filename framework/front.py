"""The frame front of the online loop: one observation per frame, live or replayed.

The front reads the video and turns each frame into an :class:`Observation`: its detections and
its info-less decision, with the milliseconds they took. Live, the detector and the classifier
run; from a stage cache, their recorded outputs are replayed. Either way the first readable frame
(the one the targets are initialised on) is informative, whatever the classifier said.

A classifier with ``hindsight_frames`` may revise its last info-less decisions when it leaves an
interval, and one with ``onset_frames`` its last informative decisions when it enters one
(docs/algorithms/index.md#the-online-loop); the front then holds back those frames that long,
so that the tracking only ever sees final decisions, in frame order.
"""

from __future__ import annotations

import itertools
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from trackfw.arrays import UInt8Array
from trackfw.records import Detections, FrameData, VideoContext
from trackfw.stage_cache import StageReplay
from trackfw.stages import Classifier, Detector
from trackfw.video_io import iter_frames


@dataclass
class FrameRecord:
    """What happened on one frame (one row of frames.csv)."""

    t: int
    status: str
    probability: float | None = None
    infoless: bool | None = None
    detections: Detections | None = None
    milliseconds: dict[str, float] = field(default_factory=dict)
    #: Targets per lifecycle state after the frame (empty before the targets exist or when
    #: the frame was not tracked).
    target_states: dict[str, int] = field(default_factory=dict)


@dataclass
class Observation:
    """One frame as the front saw it.

    Attributes:
        record: its frames.csv row; the tracking stages add their milliseconds to it.
        image: ``(H, W, 3)`` uint8 BGR pixels, or None when the pipeline decodes none.
        first: whether it is the first readable frame (the targets are initialised on it).
        done_at: ``time.perf_counter()`` when the front finished with it (tracking timings
            start there).
    """

    record: FrameRecord
    image: UInt8Array | None = None
    first: bool = False
    done_at: float = 0.0

    @property
    def t(self) -> int:
        """The 0-based frame index."""
        return self.record.t

    @property
    def readable(self) -> bool:
        """Whether the frame could be read (and so was detected and classified)."""
        return self.record.status == "ok"

    @property
    def infoless(self) -> bool:
        """The final decision: info-less (never on the first frame)."""
        return bool(self.record.infoless)

    @property
    def detections(self) -> Detections:
        """The frame's detections (empty on an unreadable frame)."""
        return self.record.detections if self.record.detections is not None else Detections.empty()


def _stable_index(detections: Detections) -> Detections:
    """``detections`` whose index is the position in the detector's own output."""
    if np.array_equal(detections.index, np.arange(len(detections))):
        return detections
    return Detections(detections.points, detections.scores, detections.boxes)


class FrameFront:
    """Yields one :class:`Observation` per frame of a video, live or from a stage replay.

    Args:
        video: the video.
        detector: the live detector (unused when ``replay`` is given).
        classifier: the live classifier (unused when ``replay`` is given), or None for a batch
            pipeline without one: every frame is then informative (probability left empty).
        replay: recorded detector and classifier outputs, or None to run them.
        decode: whether to read pixels (some stage needs them).
        progress: called with each frame index before the frame is processed.
    """

    def __init__(
        self,
        video: VideoContext,
        detector: Detector[Any],
        classifier: Classifier[Any] | None,
        replay: StageReplay | None,
        decode: bool,
        progress: Callable[[int], None] | None = None,
    ) -> None:
        self.video = video
        self.progress = progress
        self.detector = detector
        self.classifier = classifier
        self.replay = replay
        self.decode = decode

    def __iter__(self) -> Iterator[Observation]:
        # A classifier that decides in hindsight may turn the last few info-less frames
        # informative once it leaves an interval, or the last few informative frames info-less
        # once it enters one: those frames wait here, in order, until their decision is final.
        # A replay holds the final decisions already.
        window = onset = 0
        if self.replay is None and self.classifier is not None:
            window = self.classifier.hindsight_frames
            onset = self.classifier.onset_frames
        held: deque[Observation] = deque()
        for observation, revises in _onset_revised(self._observations(), onset):
            if window and observation.readable and observation.infoless:
                held.append(observation)
                if len(held) > window:
                    yield _released(held.popleft())
                continue
            for revised in itertools.islice(reversed(held), revises):
                revised.record.infoless = False
            while held:
                yield _released(held.popleft())
            yield observation
        while held:
            yield _released(held.popleft())

    def _observations(self) -> Iterator[tuple[Observation, int, int]]:
        """Each frame's observation with the classifier's ``revises`` and ``onset``."""
        first = True
        for t, image, status in iter_frames(self.video, decode=self.decode):
            if self.progress is not None:
                self.progress(t)
            if self.replay is not None and status == "ok":
                status = self.replay.status_of(t)
            if status != "ok":
                yield Observation(FrameRecord(t, status), image, done_at=time.perf_counter()), 0, 0
            else:
                yield self._observe(t, image, first)
                first = False

    def _observe(
        self, t: int, image: UInt8Array | None, first: bool
    ) -> tuple[Observation, int, int]:
        record = FrameRecord(t, "ok")
        if self.replay is None:
            frame = FrameData(t, image, self.video, first)
            tick = time.perf_counter()
            detections = _stable_index(self.detector.detect(frame))
            tock = time.perf_counter()
            record.milliseconds["detector"] = (tock - tick) * 1e3
            probability: float | None = None
            said_infoless = False
            revises = onset = 0
            if self.classifier is not None:
                decision = self.classifier.classify(frame, detections)
                record.milliseconds["classifier"] = (time.perf_counter() - tock) * 1e3
                probability, said_infoless = float(decision.probability), bool(decision.infoless)
                revises = 0 if said_infoless else max(0, int(decision.revises))
                onset = max(0, int(decision.onset)) if said_infoless else 0
            done = time.perf_counter()
        else:
            detections, recorded, said_infoless, detector_ms, classifier_ms = self.replay.frame(t)
            revises = onset = 0
            record.milliseconds["detector"] = detector_ms
            probability = recorded
            if self.classifier is not None:
                record.milliseconds["classifier"] = classifier_ms
            else:
                probability, said_infoless = None, False
            done = time.perf_counter()
        record.probability = probability
        # The first frame carries the annotation: it is informative whatever was said.
        record.infoless = said_infoless and not first
        record.detections = detections
        return Observation(record, image, first, done), revises, onset


def _onset_revised(
    observations: Iterator[tuple[Observation, int, int]], frames: int
) -> Iterator[tuple[Observation, int]]:
    """``observations`` with their start-of-interval revisions applied, and their ``revises``.

    Informative frames wait (at most ``frames`` of them) until the next frame says whether
    the start of an interval turns them info-less; the first frame never does.
    """
    held: deque[tuple[Observation, int]] = deque()
    for observation, revises, onset in observations:
        if frames and observation.readable and not observation.infoless:
            held.append((observation, revises))
            if len(held) > frames:
                yield _released_with(held.popleft())
            continue
        for revised, _ in itertools.islice(reversed(held), onset):
            if not revised.first:
                revised.record.infoless = True
        while held:
            yield _released_with(held.popleft())
        yield observation, revises
    while held:
        yield _released_with(held.popleft())


def _released_with(entry: tuple[Observation, int]) -> tuple[Observation, int]:
    """A held ``(observation, revises)`` leaving the onset queue."""
    return _released(entry[0]), entry[1]


def _released(observation: Observation) -> Observation:
    """``observation`` leaving the hindsight queue: the tracking's timings start now."""
    observation.done_at = time.perf_counter()
    return observation


__all__ = ["FrameFront", "FrameRecord", "Observation"]

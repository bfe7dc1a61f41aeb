"""The stage interfaces: detector, classifier, tracker, gap matcher, and the motion predictor.

A stage class declares:

* ``name``: the plugin type used in YAML (``type: kalman``);
* ``Params``: a :class:`StageParams` pydantic model, every field typed, defaulted and described;
* ``uses_pixels``: whether it reads frame pixels (a pipeline whose stages need none is run
  without decoding the video);
* ``needs_ground_truth``: whether it reads the dataset's ground truth (oracle stages).

The engine builds one instance per video run and calls :meth:`Stage.start` before the first
frame. Stages keep their own per-video state; they are never shared between threads.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from pathlib import Path
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from trackfw.arrays import FloatArray, IntArray
from trackfw.records import (
    ClassifierDecision,
    Detections,
    FrameData,
    GapProblem,
    GapSolution,
    Prediction,
    TargetState,
    VideoContext,
)

STAGE_KINDS = ("detector", "classifier", "tracker", "gap_matcher")
"""The four stage kinds of a pipeline, in the order the engine runs them."""

NESTED_KINDS = ("predictor",)
"""Kinds that are not pipeline stages themselves but are configured inside one."""


class StageParams(BaseModel):
    """Base of every stage's parameter model: unknown keys are errors, values are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class Stage(abc.ABC):  # noqa: B024 - abstract by intent; each kind adds its methods
    """Common base of every stage kind."""

    kind: ClassVar[str] = ""
    name: ClassVar[str] = ""
    Params: ClassVar[type[StageParams]] = StageParams
    uses_pixels: ClassVar[bool] = False
    needs_ground_truth: ClassVar[bool] = False
    #: Parameters that hold another configured stage, mapped to its kind
    #: (``{"predictor": "predictor"}`` for gap matchers). The pipeline loader validates and builds
    #: them and passes the instances to ``__init__`` as keyword arguments.
    nested: ClassVar[dict[str, str]] = {}

    def __init__(self, params: StageParams | None = None, **nested: Stage) -> None:
        self.params = params if params is not None else self.Params()
        self.nested_stages = nested

    @property
    def needs_pixels(self) -> bool:
        """Whether this configured instance reads pixels (may depend on its parameters)."""
        return self.uses_pixels or any(stage.needs_pixels for stage in self.nested_stages.values())

    @classmethod
    def resource_files(cls, params: StageParams) -> list[Path]:
        """Files the configured stage reads that its parameters do not name (a shipped model).

        Caches key on them, so that a retrained shipped model invalidates cached outputs.
        """
        return []

    def start(self, video: VideoContext) -> None:  # noqa: B027 - optional hook
        """Reset per-video state before the first frame of ``video``."""

    @classmethod
    def summary(cls) -> str:
        """First line of the class docstring."""
        doc = (cls.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""


class Detector(Stage):
    """Finds head points on a frame."""

    kind = "detector"
    uses_pixels = True

    @abc.abstractmethod
    def detect(self, frame: FrameData) -> Detections:
        """Detect heads on ``frame``.

        Args:
            frame: the frame; ``frame.image`` is ``(H, W, 3)`` uint8 BGR when ``needs_pixels``.

        Returns:
            The detections; their ``index`` is assigned by the engine afterwards.
        """


class Classifier(Stage):
    """Decides online, frame by frame, whether a frame is info-less."""

    kind = "classifier"

    @abc.abstractmethod
    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """Classify ``frame`` given its detections. Called once per frame, in order.

        Frame 0 carries the annotation and is always treated as informative by the engine,
        whatever this returns; it is still called so that features can warm up.
        """

    def feedback(self, t: int, infoless: bool) -> None:
        """The engine's final decision for frame ``t`` (used for recursive features)."""


class Tracker(Stage):
    """Tracks the fixed set of targets inside a segment (between info-less intervals)."""

    kind = "tracker"

    @abc.abstractmethod
    def initialise(self, t: int, target_ids: IntArray, positions: FloatArray) -> None:
        """Start tracking ``(K,)`` targets at ``(K, 2)`` positions on frame ``t``."""

    @abc.abstractmethod
    def step(self, t: int, detections: Detections) -> None:
        """Advance one frame: predict, associate with ``detections``, correct."""

    @abc.abstractmethod
    def reinitialise(self, t: int, positions: FloatArray, matched_detection: IntArray) -> None:
        """Restart every target at frame ``t`` (= b) from ``(K, 2)`` positions after a gap."""

    @abc.abstractmethod
    def states(self) -> list[TargetState]:
        """The current state of every target, in the order of ``initialise``."""

    def positions(self) -> FloatArray:
        """``(K, 2)`` current positions; override when it can be cheaper than :meth:`states`.

        The engine calls this on every frame and :meth:`states` only at a gap.
        """
        return np.array([state.position for state in self.states()], dtype=np.float64).reshape(
            -1, 2
        )


class Predictor(Stage):
    """Predicts where the targets are on frame ``b`` from their history up to ``a``."""

    kind = "predictor"

    @abc.abstractmethod
    def predict(self, problem: GapProblem) -> Sequence[Prediction]:
        """Return one or more candidate predictions U (a gap matcher chooses among them)."""


class GapMatcher(Stage):
    """Re-links the targets to the detections on frame ``b`` after an info-less interval."""

    kind = "gap_matcher"
    nested: ClassVar[dict[str, str]] = {"predictor": "predictor"}
    #: Predictor used when the YAML gives none ("TR", constant velocity).
    default_predictor: ClassVar[str] = "kalman"

    @property
    def predictor(self) -> Predictor:
        """The configured motion predictor."""
        predictor = self.nested_stages.get("predictor")
        if not isinstance(predictor, Predictor):
            raise TypeError(f"gap matcher {self.name!r} was built without a predictor")
        return predictor

    @abc.abstractmethod
    def match(self, problem: GapProblem) -> GapSolution:
        """Solve the gap: the position of every target on frame ``b``."""


STAGE_BASES: dict[str, type[Stage]] = {
    "detector": Detector,
    "classifier": Classifier,
    "tracker": Tracker,
    "gap_matcher": GapMatcher,
    "predictor": Predictor,
}


def no_match(count: int) -> IntArray:
    """An index array meaning "no detection" for ``count`` targets.

    >>> no_match(3).tolist()
    [-1, -1, -1]
    """
    return np.full(count, -1, dtype=np.int64)

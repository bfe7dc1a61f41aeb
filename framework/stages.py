"""The stage interfaces: detector, classifier, tracker, gap matcher, the motion predictor, and
the batch tracker.

A pipeline is either a *segment* pipeline (detector, classifier, tracker, gap matcher: the
paper's method) or a *batch* pipeline (detector and batch tracker, with an optional classifier):
the batch tracker gets every detection of a video at once and returns tracks with its own
identities (the comparison rows of Table 1, ByteTrack).

A stage class declares:

* ``name``: the plugin type used in YAML (``type: kalman``);
* its parameters: a :class:`StageParams` pydantic model, every field typed, defaulted and
  described, given as the type argument of its base (``class Mine(Detector[MineParams])``);
  the class attribute ``Params`` is set from it, and every instance holds its validated
  parameters as ``self.params``, typed as that model;
* ``uses_pixels``: whether it reads frame pixels (a pipeline whose stages need none is run
  without decoding the video);
* ``needs_ground_truth``: whether it reads the dataset's ground truth (oracle stages).

The engine builds one instance per video run and calls :meth:`Stage.start` before the first
frame. Stages keep their own per-video state; they are never shared between threads.
"""

from __future__ import annotations

import abc
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar, cast, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, field_validator

from trackfw.arrays import FloatArray, IntArray, UInt8Array
from trackfw.records import (
    ClassifierDecision,
    Detections,
    FrameData,
    GapProblem,
    GapSolution,
    Prediction,
    TargetState,
    Tracks,
    VideoContext,
)

STAGE_KINDS = ("detector", "classifier", "tracker", "gap_matcher")
"""The four stage kinds of a pipeline, in the order the engine runs them."""

BATCH_KINDS = ("detector", "batch_tracker")
"""The stage kinds a batch pipeline needs (a classifier is optional there)."""

NESTED_KINDS = ("predictor",)
"""Kinds that are not pipeline stages themselves but are configured inside one."""


#: Largest magnitude of an integer parameter: the C int that OpenCV and numpy take underneath.
MAX_INT_PARAMETER = 2**31 - 1


def _integer_out_of_range(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, int):
        return abs(value) > MAX_INT_PARAMETER
    if isinstance(value, list | tuple | set | frozenset):
        return any(_integer_out_of_range(item) for item in value)
    if isinstance(value, dict):
        return any(_integer_out_of_range(item) for item in value.values())
    return False


class FiniteModel(BaseModel):
    """Base of every parameter and settings model: numbers finite, integers within a C int.

    ``inf`` or ``nan`` (``1e400`` in YAML is ``inf``) would run and write ``Infinity`` into the
    outputs; an integer like ``1e23`` would validate and overflow in OpenCV on the first frame.
    Settings models nested in a stage's parameters derive from this too.
    """

    model_config = ConfigDict(allow_inf_nan=False)

    @field_validator("*", mode="after")
    @classmethod
    def _integers_in_range(cls, value: Any) -> Any:
        if _integer_out_of_range(value):
            raise ValueError(
                f"expected integers between {-MAX_INT_PARAMETER} and {MAX_INT_PARAMETER}"
            )
        return value


class StageParams(FiniteModel):
    """Base of every stage's parameter model: unknown keys are errors, values are immutable."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )


P = TypeVar("P", bound=StageParams)
"""The parameter model of a stage class."""


def _params_argument(cls: type) -> type[StageParams] | None:
    """The concrete ``StageParams`` subclass ``cls`` names as its base's type argument, if any."""
    for base in getattr(cls, "__orig_bases__", ()):
        origin = get_origin(base)
        if isinstance(origin, type) and issubclass(origin, Stage):
            for argument in get_args(base):
                if isinstance(argument, type) and issubclass(argument, StageParams):
                    return argument
    return None


class Stage(abc.ABC, Generic[P]):
    """Common base of every stage kind, generic in its parameter model ``P``."""

    kind: ClassVar[str] = ""
    name: ClassVar[str] = ""
    #: The parameter model; set from the type argument (``Detector[MineParams]``) when the class
    #: does not assign it itself.
    Params: ClassVar[type[StageParams]] = StageParams
    uses_pixels: ClassVar[bool] = False
    needs_ground_truth: ClassVar[bool] = False
    #: Parameters that hold another configured stage, mapped to its kind
    #: (``{"predictor": "predictor"}`` for gap matchers). The pipeline resolves them
    #: (``trackfw.pipeline.resolve_stage``) and passes the built instances to ``__init__`` as
    #: keyword arguments.
    nested: ClassVar[dict[str, str]] = {}

    params: P
    """The validated parameters of this instance."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        argument = _params_argument(cls)
        if argument is None:
            return
        if "Params" not in cls.__dict__:
            cls.Params = argument
        elif not issubclass(cls.Params, argument):
            raise TypeError(
                f"{cls.__qualname__}.Params is {cls.Params.__qualname__} but the class is generic"
                f" in {argument.__qualname__}"
            )

    def __init__(self, params: P | None = None, **nested: Stage[Any]) -> None:
        if params is not None and not isinstance(params, self.Params):
            raise TypeError(
                f"{type(self).__qualname__} takes {self.Params.__qualname__},"
                f" got {type(params).__qualname__}"
            )
        self.params = params if params is not None else cast(P, self.Params())
        self.nested_stages = nested

    @property
    def needs_pixels(self) -> bool:
        """Whether this configured instance reads pixels (may depend on its parameters)."""
        return self.uses_pixels or any(stage.needs_pixels for stage in self.nested_stages.values())

    def with_nested(self) -> Iterator[Stage[Any]]:
        """This stage, then every stage configured inside it (a gap matcher's predictor)."""
        yield self
        for stage in self.nested_stages.values():
            yield from stage.with_nested()

    @classmethod
    def resource_files(cls, params: P) -> list[Path]:
        """Files the configured stage reads that its parameters do not name (a shipped model).

        Caches key on them, so that a retrained shipped model invalidates cached outputs.
        """
        return []

    def start(self, video: VideoContext) -> None:
        """Reset per-video state before the first frame of ``video``."""

    @classmethod
    def summary(cls) -> str:
        """First line of the class docstring."""
        doc = (cls.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""


class Detector(Stage[P]):
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


class Classifier(Stage[P]):
    """Decides online, frame by frame, whether a frame is info-less."""

    kind = "classifier"

    @abc.abstractmethod
    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """Classify ``frame`` given its detections. Called once per readable frame, in order.

        The first frame (``frame.first``) carries the annotation and is informative whatever
        this returns; it is still called so that features can warm up, and a classifier whose
        later decisions depend on earlier ones should decide it informative.
        """

    @property
    def hindsight_frames(self) -> int:
        """The most frames a later decision may turn from info-less to informative.

        The front holds back that many info-less frames before the tracking sees them
        (:attr:`ClassifierDecision.revises`); 0, the default, keeps every decision final at once.
        """
        return 0

    @property
    def onset_frames(self) -> int:
        """The most frames a later decision may turn from informative to info-less.

        The front holds back that many informative frames before the tracking sees them
        (:attr:`ClassifierDecision.onset`); 0, the default, keeps every decision final at once.
        """
        return 0


class Tracker(Stage[P]):
    """Tracks the fixed set of targets inside a segment (between info-less intervals)."""

    kind = "tracker"

    @abc.abstractmethod
    def initialise(self, t: int, target_ids: IntArray, positions: FloatArray) -> None:
        """Start tracking ``(K,)`` targets at ``(K, 2)`` positions on frame ``t``."""

    @abc.abstractmethod
    def step(self, t: int, detections: Detections) -> None:
        """Advance one frame: predict, associate with ``detections``, correct."""

    @abc.abstractmethod
    def reinitialise(
        self,
        t: int,
        positions: FloatArray,
        matched_detection: IntArray,
        detections: Detections | None = None,
    ) -> None:
        """Restart the targets at frame ``t`` (= b) from ``(K, 2)`` positions after a gap.

        ``detections`` are frame b's (the ``matched_detection`` indices are their stable
        indices), given so that a tracker may check the gap matcher's matches.

        The engine gives every target a row. Lost and out-of-view targets were left out of the
        gap match: their row holds their current position and ``NO_MATCH``, and a tracker with a
        lifecycle keeps them as they are (they return only through re-acquisition).
        """

    @abc.abstractmethod
    def states(self) -> list[TargetState]:
        """The current state of every target, in the order of ``initialise``."""

    def see_match_ratios(self, ratios: FloatArray) -> None:
        """How clearly each of the gap matcher's matches stood out, before :meth:`reinitialise`.

        Called at b, only when the gap matcher gives them (:attr:`.GapSolution.match_ratios`):
        ``(K,)``, one per target row in the order of ``initialise`` (NaN for a target without a
        match, out of the gap match, or where the matcher could not tell). A tracker that checks
        the matches at b may hold a match that barely beat another detection to a stricter test.
        The default ignores them.
        """

    def see(self, image: UInt8Array | None) -> None:
        """The pixels of the frame the next call (initialise, step, reinitialise) is about.

        Called on every tracked frame; ``image`` is None unless some stage of the pipeline
        needs pixels (a tracker that does says so with ``uses_pixels`` or ``needs_pixels``).
        """

    def statuses(self) -> list[str]:
        """Every target's lifecycle state (:data:`trackfw.records.TARGET_STATES`), in order.

        The engine reports only ``tracked`` targets. A tracker without a lifecycle keeps the
        default, every target tracked.
        """
        return [state.status for state in self.states()]

    def withdrawn(self) -> list[tuple[int, int]]:
        """Reports to take back, found since the last call: ``(target row, first frame)`` pairs.

        A tracker that learns, some frames after b, that a match at b was someone else's may
        withdraw that target's reports from frame b on (or, some frames after the start, that
        the target followed someone else from its start). The engine calls this on every tracked
        frame, after the tracker's call, and unreports the target from that frame up to the
        current one; filling short absences (``engine.fill_missing_s``) never puts them back.
        The default withdraws nothing.
        """
        return []

    def checked_at_b(self) -> dict[int, dict[str, Any]]:
        """What the tracker made of the gap matcher's matches at the last :meth:`reinitialise`.

        Keyed by target row; each value is JSON-ready and recorded in gaps.json under ``at_b``
        (by target id). A tracker that checks the matches at b (by size, by look, ...) says
        there which match it kept, which it refused and why, and which target it found itself,
        so that a user reading gaps.json sees the outcome, not only the proposal. The default,
        for a tracker that takes every match as given, records nothing.
        """
        return {}

    def positions(self) -> FloatArray:
        """``(K, 2)`` current positions; override when it can be cheaper than :meth:`states`.

        The engine calls this on every frame and :meth:`states` only at a gap.
        """
        return np.array([state.position for state in self.states()], dtype=np.float64).reshape(
            -1, 2
        )


class Predictor(Stage[P]):
    """Predicts where the targets are on frame ``b`` from their history up to ``a``."""

    kind = "predictor"

    @abc.abstractmethod
    def predict(self, problem: GapProblem) -> Sequence[Prediction]:
        """Return one or more candidate predictions U (a gap matcher chooses among them)."""


class GapMatcher(Stage[P]):
    """Re-links the targets to the detections on frame ``b`` after an info-less interval."""

    kind = "gap_matcher"
    nested: ClassVar[dict[str, str]] = {"predictor": "predictor"}
    #: Predictor used when the YAML gives none ("TR", constant velocity).
    default_predictor: ClassVar[str] = "kalman"

    @property
    def predictor(self) -> Predictor[Any]:
        """The configured motion predictor."""
        predictor = self.nested_stages.get("predictor")
        if not isinstance(predictor, Predictor):
            raise TypeError(f"gap matcher {self.name!r} was built without a predictor")
        return predictor

    @abc.abstractmethod
    def match(self, problem: GapProblem) -> GapSolution:
        """Solve the gap: the position of every target on frame ``b``."""


class BatchTracker(Stage[P]):
    """Tracks every person through a whole video at once, with its own identities."""

    kind = "batch_tracker"

    @abc.abstractmethod
    def track(self, detections: Sequence[Detections], video: VideoContext) -> Tracks:
        """Track through the video from every frame's detections.

        Args:
            detections: one entry per frame of ``video`` (``video.n_frames``); frames that were
                not read, or were dropped as info-less, have no detections.
            video: the video (size, frame rate, number of frames).

        Returns:
            The tracks: identities of the tracker's own, births and deaths where it likes, and a
            per-point ``observed`` flag (False where a position was filled in).
        """


@dataclass(frozen=True)
class PipelineStages:
    """One built instance of each pipeline stage kind, for one video run."""

    detector: Detector[Any]
    classifier: Classifier[Any]
    tracker: Tracker[Any]
    gap_matcher: GapMatcher[Any]

    def by_kind(self) -> dict[str, Stage[Any]]:
        """Kind -> stage, in :data:`STAGE_KINDS` order."""
        return {kind: getattr(self, kind) for kind in STAGE_KINDS}

    @property
    def needs_pixels(self) -> bool:
        """True when any stage (or a stage nested in one) reads pixels."""
        return any(stage.needs_pixels for stage in self.by_kind().values())


@dataclass(frozen=True)
class BatchStages:
    """One built instance of each stage of a batch pipeline, for one video run."""

    detector: Detector[Any]
    batch_tracker: BatchTracker[Any]
    classifier: Classifier[Any] | None = None

    def by_kind(self) -> dict[str, Stage[Any]]:
        """Kind -> stage: detector, classifier (when configured), batch tracker."""
        stages: dict[str, Stage[Any]] = {"detector": self.detector}
        if self.classifier is not None:
            stages["classifier"] = self.classifier
        stages["batch_tracker"] = self.batch_tracker
        return stages

    @property
    def needs_pixels(self) -> bool:
        """True when any stage (or a stage nested in one) reads pixels."""
        return any(stage.needs_pixels for stage in self.by_kind().values())


STAGE_BASES: dict[str, type[Stage[Any]]] = {
    "detector": Detector,
    "classifier": Classifier,
    "tracker": Tracker,
    "gap_matcher": GapMatcher,
    "predictor": Predictor,
    "batch_tracker": BatchTracker,
}


def no_match(count: int) -> IntArray:
    """An index array meaning "no detection" for ``count`` targets.

    >>> no_match(3).tolist()
    [-1, -1, -1]
    """
    return np.full(count, -1, dtype=np.int64)

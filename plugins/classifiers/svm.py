"""The ``svm`` classifier: the paper's 11-d feature and RBF SVM [PAPER §3.2].

See docs/algorithms/infoless-classifier.md#svm and
docs/algorithms/infoless-classifier.md#online-rules.

Each frame, the classifier measures ``M_t``, ``N_t`` and ``S_t``, builds ``x_t`` and maps the SVM's
decision value through the Platt sigmoid stored in the model to a probability. The online rules
of :mod:`online_rules` [OURS] turn it into a label: with the paper's rules (a model that records
none) the frame is info-less when the probability reaches ``threshold`` (0.5); a model may
record hysteresis, re-anchoring of ``C_t``'s reference and a turn latch, which the stage then
applies by default (each can be overridden by a parameter). It only labels frames: turning labels
into intervals is the engine's job. The reference frame ``a`` of ``C_t`` follows the
decisions, which are the engine's: the first frame (``frame.first``) is informative, whatever the
SVM says, as the engine has it.

The shipped model (``models/infoless_svm.json``) was trained with ``trackfw train classifier
--reference replay`` and the online rules chosen by cross-validation (``--select-rules``) on the
synthetic ``paper`` preset generated with seed 1 (30 videos, 1280x720) with oracle detections,
DIS ultrafast flow at 320 pixels; its ``training`` field records the details. Retrain it for
another detector or real footage: ``N_t`` depends on the detector.

``model: yolox`` selects ``models/infoless_svm_yolox.json``, trained the same way on the ``yolox``
detector's outputs (defaults) over a synthetic set the evaluations do not use::

    trackfw dataset synth --preset paper --seed 7 --videos 12 --out synth7
    trackfw train classifier --dataset synth7 --out infoless_svm_yolox.json
        --detector yolox --reference replay --select-rules
"""

from __future__ import annotations

import logging
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import Field, field_validator

from trackfw.arrays import FloatArray
from trackfw.errors import UserError
from trackfw.records import ClassifierDecision, Detections, FrameData, VideoContext
from trackfw.stages import Classifier, StageParams
from trackfw_plugins.classifiers.hindsight import EndHindsight, OnsetHindsight
from trackfw_plugins.classifiers.infoless_features import (
    DEFAULT_C_MAX,
    FEATURE_LAYOUT,
    HISTORY,
    DisPreset,
    FlowMethod,
    InfolessFeatureExtractor,
    latest_count,
    latest_motion,
)
from trackfw_plugins.classifiers.online_rules import OnlineDecider, OnlineRules, model_rules
from trackfw_plugins.classifiers.svm_model import SvmModel, load_model

logger = logging.getLogger(__name__)

#: File name of the model shipped inside the package (``trackfw_plugins/classifiers/models``).
SHIPPED_MODEL = "infoless_svm.json"
#: Other shipped models, by the name a pipeline gives as ``model``: each was trained on one
#: detector's outputs, because N_t and S_t depend on the detector.
NAMED_MODELS = {"yolox": "infoless_svm_yolox.json"}

#: Feature settings used when a model file does not record them.
_FEATURE_DEFAULTS: dict[str, Any] = {
    "flow": "dis",
    "flow_width": 320,
    "dis_preset": "ultrafast",
    "c_max": DEFAULT_C_MAX,
}


def shipped_model_path(file_name: str = SHIPPED_MODEL) -> Path:
    """Path of a shipped model (a real file in both wheel and editable installs)."""
    resource = resources.files("trackfw_plugins.classifiers").joinpath("models", file_name)
    with resources.as_file(resource) as path:
        return Path(path)


def load_shipped_model() -> SvmModel:
    """The model shipped with trackfw, read through :mod:`importlib.resources`."""
    resource = resources.files("trackfw_plugins.classifiers").joinpath("models", SHIPPED_MODEL)
    with resources.as_file(resource) as path:
        return load_model(path)


def load_classifier_model(path: str | None) -> SvmModel:
    """Load ``path`` (a file, a :data:`NAMED_MODELS` name, or None for the shipped model) and
    check it holds the 11-d layout."""
    if path in NAMED_MODELS:
        path = str(shipped_model_path(NAMED_MODELS[path]))
    model = load_shipped_model() if path is None else load_model(Path(path))
    if model.feature_layout != FEATURE_LAYOUT:
        source = path if path is not None else SHIPPED_MODEL
        raise UserError(
            f"{source}: feature_layout is {list(model.feature_layout)}; expected the 11-d"
            f" layout {list(FEATURE_LAYOUT)}."
        )
    return model


class SvmParams(StageParams):
    """Parameters of the ``svm`` classifier."""

    model: str | None = Field(
        default=None,
        description="Path of a trackfw-infoless-svm JSON model (trackfw train classifier);"
        " 'yolox' for the shipped model trained on the yolox detector's outputs; empty for"
        " the model shipped with trackfw (trained on oracle detections).",
    )
    threshold: float | None = Field(
        default=None,
        ge=0.0,
        le=1.0,
        description="Outside an interval, a frame is info-less when the Platt probability is at"
        " least this; empty for the model's own enter_probability (0.5 if it records none).",
    )
    leave_threshold: float | None = Field(
        default=None,
        ge=0.0,
        le=1.0,
        description="Inside an interval, a frame stays info-less while the probability is at"
        " least this (hysteresis, OURS); empty for the model's own leave_probability, or for"
        " threshold when threshold is given.",
    )
    reanchor_after: int | None = Field(
        default=None,
        ge=0,
        description="After this many consecutive info-less decisions on a steady camera, the"
        " current frame becomes the reference of C_t (OURS; 0 never); empty for the model's own.",
    )
    reanchor_max_motion: float | None = Field(
        default=None,
        ge=0.0,
        description="Re-anchor only when every M in the feature's history is at most this"
        " (working-resolution pixels); empty for the model's own (no limit if it records none).",
    )
    turn_motion: float | None = Field(
        default=None,
        gt=0.0,
        description="M (working-resolution pixels) from which a frame is part of a camera turn;"
        " an interval begun by a turn stays open until a second turn has ended (OURS); empty"
        " for the model's own (no turn latch if it records none).",
    )
    max_hold: int | None = Field(
        default=None,
        ge=0,
        description="The most frames the turn latch keeps one interval open; empty for the"
        " model's own (300 if it records none).",
    )
    reanchor_on_release: bool | None = Field(
        default=None,
        description="When the turn latch lets go on a frame still info-less that shows people,"
        " make it the reference of C_t; empty for the model's own (true if it records none).",
    )
    latch_late_turns: bool | None = Field(
        default=None,
        description="An interval begun without a turn latches on its first turn; empty for the"
        " model's own (true if it records none).",
    )
    leave_min_detections: int | None = Field(
        default=None,
        ge=0,
        description="An interval is not left on a frame with fewer detections than this (OURS);"
        " empty for the model's own (0, the probability alone, if it records none).",
    )
    reanchor_min_detections: int | None = Field(
        default=None,
        ge=0,
        description="Re-anchor only when every N in the feature's history is at least this;"
        " empty for the model's own (2 if it records none).",
    )
    flow: FlowMethod | None = Field(
        default=None,
        description="Optical flow for M_t: 'dis' or 'farneback'; empty for the model's own"
        " setting (another one changes the scale of M_t the model was trained on).",
    )
    flow_width: int | None = Field(
        default=None,
        ge=16,
        le=4096,
        description="Working width in pixels of the optical flow; empty for the model's own.",
    )
    dis_preset: DisPreset | None = Field(
        default=None,
        description="DIS preset ('ultrafast', 'fast', 'medium'); empty for the model's own.",
    )
    history: int = Field(
        default=HISTORY,
        description="Frames of M and N history in the feature; the paper's 11-d layout fixes 5.",
    )
    c_max: float | None = Field(
        default=None, gt=0.0, description="Clip of C_t; empty for the model's own (10)."
    )
    hindsight_frames: int = Field(
        default=0,
        ge=0,
        le=25,
        description="On leaving an interval, the most frames just before, decided info-less, that"
        " may turn informative: the camera stood still from each to the next and it shows"
        " people (OURS; 0, the paper's, never revises).",
    )
    hindsight_max_motion: float = Field(
        default=4.0,
        ge=0.0,
        description="The largest M (working-resolution pixels) from a revised frame to the next.",
    )
    hindsight_min_detections: int = Field(
        default=1, ge=0, description="The fewest detections on a revised frame."
    )
    onset_frames: int = Field(
        default=0,
        ge=0,
        le=10,
        description="On entering an interval, the most frames just before, decided informative,"
        " that may turn info-less: each scored at least onset_probability (OURS; 0, the"
        " paper's, never revises).",
    )
    onset_probability: float = Field(
        default=0.3,
        ge=0.0,
        le=1.0,
        description="The smallest probability of a frame that the start of an interval revises.",
    )

    @field_validator("history")
    @classmethod
    def _history_is_five(cls, value: int) -> int:
        if value != HISTORY:
            raise ValueError(
                f"must be {HISTORY}: the 11-d feature [M_t-4..M_t, N_t-4..N_t, C_t] fixes it"
            )
        return value


def resolve_online_rules(model: SvmModel, params: Any, source: str = SHIPPED_MODEL) -> OnlineRules:
    """The online rules to use: the parameters where given, else the model's record."""
    recorded = model_rules(model, source)
    enter = recorded.enter_probability if params.threshold is None else params.threshold
    if params.leave_threshold is not None:
        leave = params.leave_threshold
    else:
        leave = recorded.leave_probability if params.threshold is None else params.threshold
    overrides = {
        name: getattr(params, name)
        for name in (
            "reanchor_after",
            "reanchor_max_motion",
            "reanchor_min_detections",
            "turn_motion",
            "max_hold",
            "reanchor_on_release",
            "latch_late_turns",
            "leave_min_detections",
        )
        if getattr(params, name) is not None
    }
    try:
        return replace(recorded, enter_probability=enter, leave_probability=leave, **overrides)
    except ValueError as error:
        raise UserError(f"svm classifier parameters: {error}.") from None


def resolve_feature_settings(model: SvmModel, params: Any) -> dict[str, Any]:
    """The feature settings to use: the parameters where given, else the model's record.

    A parameter that contradicts the model is allowed (for ablations) but logged as a warning.
    """
    settings: dict[str, Any] = {}
    for key, default in _FEATURE_DEFAULTS.items():
        recorded = model.features.get(key, default)
        requested = getattr(params, key)
        if requested is not None and requested != recorded:
            logger.warning(
                "svm classifier: %s=%r differs from the model's %r; its decisions may degrade",
                key,
                requested,
                recorded,
            )
        settings[key] = recorded if requested is None else requested
    return settings


class SvmClassifier(Classifier[SvmParams]):
    """Info-less frames from the 11-d motion/detection feature and an RBF SVM (paper §3.2)."""

    name = "svm"
    uses_pixels = True

    @classmethod
    def resource_files(cls, params: SvmParams) -> list[Path]:
        """The shipped model when no ``model`` is given or ``model`` names a shipped one."""
        if params.model in NAMED_MODELS:
            return [shipped_model_path(NAMED_MODELS[params.model])]
        return [] if params.model else [shipped_model_path()]

    def __init__(self, params: SvmParams | None = None) -> None:
        super().__init__(params)
        self.model = load_classifier_model(self.params.model)
        settings = resolve_feature_settings(self.model, self.params)
        self.extractor = InfolessFeatureExtractor(
            flow=settings["flow"],
            flow_width=int(settings["flow_width"]),
            dis_preset=settings["dis_preset"],
            c_max=float(settings["c_max"]),
        )
        self.rules = resolve_online_rules(
            self.model, self.params, self.params.model or SHIPPED_MODEL
        )
        self.decider = OnlineDecider(self.rules, self.extractor.assembler)
        self.hindsight = EndHindsight(
            self.params.hindsight_frames,
            self.params.hindsight_max_motion,
            self.params.hindsight_min_detections,
        )
        self.onset = OnsetHindsight(self.params.onset_frames, self.params.onset_probability)

    @property
    def hindsight_frames(self) -> int:
        """``hindsight_frames``: how far back leaving an interval may revise decisions."""
        return self.params.hindsight_frames

    @property
    def onset_frames(self) -> int:
        """``onset_frames``: how far back entering an interval may revise decisions."""
        return self.params.onset_frames

    def start(self, video: VideoContext) -> None:
        """Forget the previous video's frames, reference and interval state."""
        self.extractor.reset()
        self.decider.reset()
        self.hindsight.reset()
        self.onset.reset()

    def decision(
        self, frame: FrameData, probability: float, infoless: bool, features: FloatArray
    ) -> ClassifierDecision:
        """The decision on ``frame``, with both hindsight revisions (end and start)."""
        revises = self.hindsight.push(infoless, latest_motion(features), latest_count(features))
        onset = self.onset.push(infoless, probability, frame.first or revises > 0)
        return ClassifierDecision(
            probability=probability,
            infoless=infoless,
            features=features,
            revises=revises,
            onset=onset,
        )

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """Probability and label of ``frame``; needs its pixels."""
        if frame.image is None:
            raise ValueError("the svm classifier needs frame pixels (uses_pixels is True)")
        features = self.extractor.update(frame.t, frame.image, detections.points)
        probability = float(self.model.probability(features)[0])
        # The decider runs on the first frame too (its turn latch sees the motion), but the
        # first frame is informative: it sets the reference of C_t.
        infoless = self.decider.decide(probability, features) and not frame.first
        self.decider.settle(frame.t, infoless, features)
        return self.decision(frame, probability, infoless, features)

"""The ``svm`` classifier: the paper's 11-d feature and RBF SVM (ALGORITHMS.md §6) [PAPER §3.2].

Each frame, the classifier measures ``M_t``, ``N_t`` and ``S_t``, builds ``x_t`` and maps the SVM's
decision value through the Platt sigmoid stored in the model to a probability; the frame is
info-less when the probability reaches ``threshold``. It only labels frames: turning labels into
intervals (§6.4) is the engine's job. The reference frame ``a`` of ``C_t`` follows the decisions:
the classifier's own decision is used provisionally and the engine's final one, given through
:meth:`SvmClassifier.feedback`, replaces it.

The shipped model (``models/infoless_svm.json``) was trained with ``trackfw train classifier
--reference replay --seed 0`` on the synthetic ``paper`` dataset (30 videos, generator seed 2018)
with oracle detections, DIS ultrafast flow at 320 pixels; its ``training`` field records the
details. Retrain it for another detector or real footage: ``N_t`` depends on the detector.
"""

from __future__ import annotations

import logging
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

from pydantic import Field, field_validator

from trackfw.errors import UserError
from trackfw.records import ClassifierDecision, Detections, FrameData, VideoContext
from trackfw.stages import Classifier, StageParams
from trackfw_plugins.classifiers.infoless_features import (
    DEFAULT_C_MAX,
    FEATURE_LAYOUT,
    HISTORY,
    DisPreset,
    FlowMethod,
    InfolessFeatureExtractor,
)
from trackfw_plugins.classifiers.svm_model import SvmModel, load_model

logger = logging.getLogger(__name__)

#: File name of the model shipped inside the package (``trackfw_plugins/classifiers/models``).
SHIPPED_MODEL = "infoless_svm.json"

#: Feature settings used when a model file does not record them.
_FEATURE_DEFAULTS: dict[str, Any] = {
    "flow": "dis",
    "flow_width": 320,
    "dis_preset": "ultrafast",
    "c_max": DEFAULT_C_MAX,
}


def load_shipped_model() -> SvmModel:
    """The model shipped with trackfw, read through :mod:`importlib.resources`."""
    resource = resources.files("trackfw_plugins.classifiers").joinpath("models", SHIPPED_MODEL)
    with resources.as_file(resource) as path:
        return load_model(path)


def load_classifier_model(path: str | None) -> SvmModel:
    """Load ``path`` (or the shipped model when None) and check it holds the 11-d layout."""
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
        " empty for the model shipped with trackfw.",
    )
    threshold: float = Field(
        default=0.5,
        ge=0.0,
        le=1.0,
        description="A frame is info-less when the Platt probability is at least this.",
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

    @field_validator("history")
    @classmethod
    def _history_is_five(cls, value: int) -> int:
        if value != HISTORY:
            raise ValueError(
                f"must be {HISTORY}: the 11-d feature [M_t-4..M_t, N_t-4..N_t, C_t] fixes it"
            )
        return value


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


class SvmClassifier(Classifier):
    """Info-less frames from the 11-d motion/detection feature and an RBF SVM (paper §3.2)."""

    name = "svm"
    Params: ClassVar[type[StageParams]] = SvmParams
    uses_pixels = True

    def __init__(self, params: StageParams | None = None, **nested: Any) -> None:
        super().__init__(params, **nested)
        assert isinstance(self.params, SvmParams)
        self.model = load_classifier_model(self.params.model)
        settings = resolve_feature_settings(self.model, self.params)
        self.extractor = InfolessFeatureExtractor(
            flow=settings["flow"],
            flow_width=int(settings["flow_width"]),
            dis_preset=settings["dis_preset"],
            c_max=float(settings["c_max"]),
        )

    def start(self, video: VideoContext) -> None:
        """Forget the previous video's frames and reference."""
        self.extractor.reset()

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        """Probability and label of ``frame``; needs its pixels."""
        if frame.image is None:
            raise ValueError("the svm classifier needs frame pixels (uses_pixels is True)")
        assert isinstance(self.params, SvmParams)
        features = self.extractor.update(frame.t, frame.image, detections.points)
        probability = float(self.model.probability(features)[0])
        infoless = probability >= self.params.threshold
        # Provisional: feedback() replaces it with the engine's final decision.
        self.extractor.mark_informative(frame.t, not infoless)
        return ClassifierDecision(probability=probability, infoless=infoless, features=features)

    def feedback(self, t: int, infoless: bool) -> None:
        """The engine's final decision for frame ``t``: it sets the reference of ``C_t``."""
        self.extractor.mark_informative(t, not infoless)

"""Typed stages: a stage class is generic in its parameter model and holds a validated instance."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from pydantic import Field

from trackfw.errors import UserError
from trackfw.pipeline import load_pipeline
from trackfw.records import Detections, FrameData
from trackfw.registry import load_registry
from trackfw.stages import Detector, StageParams


class CountParams(StageParams):
    """Parameters of the toy detector."""

    count: int = Field(2, ge=0, description="how many points")


class OtherParams(StageParams):
    """Another model."""


class CountDetector(Detector[CountParams]):
    """Detects ``count`` points at the origin."""

    name = "count"

    def detect(self, frame: FrameData) -> Detections:
        return Detections.empty()


def test_params_model_comes_from_the_type_argument() -> None:
    assert CountDetector.Params is CountParams
    assert CountDetector().params == CountParams()
    assert CountDetector(CountParams(count=5)).params.count == 5


def test_a_stage_refuses_another_model_than_its_own() -> None:
    with pytest.raises(TypeError, match="takes CountParams, got OtherParams"):
        CountDetector(OtherParams())  # type: ignore[arg-type]


def test_a_class_whose_params_disagree_with_its_type_argument_is_refused() -> None:
    with pytest.raises(TypeError, match="generic in CountParams"):

        class Confused(Detector[CountParams]):
            """Says CountParams twice, differently."""

            name = "confused"
            Params = OtherParams

            def detect(self, frame: FrameData) -> Detections:
                return Detections.empty()


def test_pipeline_keeps_validated_models_and_builds_fresh_stages_from_them(
    pipeline_file: Callable[..., Path],
) -> None:
    pipeline = load_pipeline(pipeline_file(), load_registry())
    first, second = pipeline.build(), pipeline.build()
    assert first.tracker is not second.tracker
    # One validated model per stage, shared by every video's instance (it is frozen).
    assert first.tracker.params is pipeline.stages["tracker"].params is second.tracker.params
    predictor = first.gap_matcher.predictor
    assert predictor is not second.gap_matcher.predictor
    assert predictor.params is pipeline.stages["gap_matcher"].nested["predictor"].params


def test_nested_stage_is_written_and_read_back_like_any_stage(
    pipeline_file: Callable[..., Path],
) -> None:
    registry = load_registry()
    pipeline = load_pipeline(
        pipeline_file(),
        registry,
        ["stages.gap_matcher.params.predictor={type: ar, params: {orders: [2, 1]}}"],
    )
    data = pipeline.stages["gap_matcher"].as_data()["params"]["predictor"]
    assert data["type"] == "ar" and data["params"]["orders"] == [2, 1]
    assert pipeline.build().gap_matcher.predictor.params.orders == [2, 1]


def test_registry_build_stage_reports_bad_specs_as_user_errors() -> None:
    registry = load_registry()
    with pytest.raises(UserError, match="unknown detector 'orcale'"):
        registry.build_stage("detector", {"type": "orcale"})
    with pytest.raises(UserError, match=r"predictor\.params\.orders"):
        registry.build_stage(
            "gap_matcher",
            {
                "type": "assignment",
                "params": {"predictor": {"type": "ar", "params": {"orders": []}}},
            },
        )

"""Stage parameters: finite numbers and integers in range, for every stage and nested settings."""

from __future__ import annotations

import json
import math
import types
import typing
from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel, ValidationError

from trackfw.cli import main
from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.formats.run import write_run
from trackfw.pipeline import load_pipeline
from trackfw.registry import load_registry
from trackfw.stages import StageParams

REPO = Path(__file__).resolve().parents[2]
PROPOSED = REPO / "pipelines" / "proposed.yaml"


def _nested_models(annotation: Any) -> list[type[BaseModel]]:
    """Pydantic models inside a field's annotation (``Settings``, ``Settings | None``, ...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    origin = typing.get_origin(annotation)
    if origin is None:
        return []
    if origin not in (typing.Union, types.UnionType, list, tuple, dict, typing.Annotated):
        return []
    return [model for arg in typing.get_args(annotation) for model in _nested_models(arg)]


def _all_parameter_models() -> list[type[BaseModel]]:
    registry = load_registry()
    found: list[type[BaseModel]] = []
    pending: list[type[BaseModel]] = [entry.cls.Params for entry in registry.stages.values()]
    while pending:
        model = pending.pop()
        if model in found:
            continue
        found.append(model)
        for field in model.model_fields.values():
            pending.extend(_nested_models(field.annotation))
    return found


def _scalar_kind(annotation: Any) -> str | None:
    """``"float"`` or ``"int"`` when the field holds such a number (possibly optional)."""
    args = [a for a in typing.get_args(annotation) if a is not type(None)] or [annotation]
    if float in args:
        return "float"
    if int in args and bool not in args:
        return "int"
    return None


def test_every_stage_and_nested_settings_model_forbids_inf_and_nan() -> None:
    models = _all_parameter_models()
    for model in models:
        model()  # the defaults themselves are valid (finite)
    names = {model.__name__ for model in models}
    # The nested maths settings are part of the walk, not only the stages' own Params.
    assert {"TpsRpmSettings", "ShapeDistanceSettings"} <= names, names
    lenient = [model.__name__ for model in models if model.model_config.get("allow_inf_nan", True)]
    assert lenient == []


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan, 10**23, -(10**23)])
def test_no_numeric_parameter_accepts_non_finite_or_huge_values(value: float) -> None:
    accepted = []
    for model in _all_parameter_models():
        for name, field in model.model_fields.items():
            kind = _scalar_kind(field.annotation)
            # Non-finite values go to float fields, huge integers to integer fields.
            if kind != ("float" if isinstance(value, float) else "int"):
                continue
            try:
                model(**{name: value})
            except ValidationError:
                continue
            accepted.append(f"{model.__name__}.{name}")
    assert accepted == []


def test_stage_params_base_is_finite() -> None:
    assert StageParams.model_config.get("allow_inf_nan") is False


@pytest.mark.parametrize(
    ("override", "fragment"),
    [
        ("stages.gap_matcher.params.lambda2=inf", "lambda2"),
        ("stages.gap_matcher.params.lambda2=1e400", "lambda2"),
        ("stages.gap_matcher.params.lambda1=.nan", "lambda1"),
        ("stages.detector.params.max_boxes=1.0e+23", "max_boxes"),
        ("stages.detector.params.max_boxes=100000000000000000000000", "max_boxes"),
        ("stages.tracker.params.rpm.sinkhorn_maxit=100000000000", "sinkhorn_maxit"),
        ("engine.box_size=inf", "box_size"),
    ],
)
def test_set_with_non_finite_or_huge_values_is_a_validation_error(
    override: str, fragment: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["validate", str(PROPOSED), "--set", override]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and str(PROPOSED) in lines[0], lines


def test_gaps_json_never_holds_infinity_or_nan(tmp_path: Path) -> None:
    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(tmp_path / "v", n_frames=60, intervals=[(20, 30)], n_others=0)
    pipeline_path = tmp_path / "p.yaml"
    pipeline_path.write_text(
        "name: p\nstages:\n  detector: {type: oracle}\n  classifier: {type: oracle}\n"
        "  tracker: {type: kalman}\n  gap_matcher: {type: assignment}\n"
    )
    registry = load_registry()
    pipeline = load_pipeline(pipeline_path, registry)
    run = Engine(pipeline, registry).run_video(load_video(video))
    assert run.gaps
    # A gap matcher may well report an infinite cost (no admissible candidate) or NaN figures.
    solution = run.gaps[0].solution
    assert solution is not None
    solution.cost = math.inf
    solution.diagnostics = {"spread": math.nan, "costs": [1.0, -math.inf]}
    out = write_run(run, pipeline, tmp_path / "out")

    def refuse(constant: str) -> None:
        raise AssertionError(f"gaps.json holds {constant}")

    gaps = json.loads((out / "gaps.json").read_text(), parse_constant=refuse)
    assert gaps[0]["cost"] is None
    assert gaps[0]["diagnostics"] == {"spread": None, "costs": [1.0, None]}
    json.loads((out / "summary.json").read_text(), parse_constant=refuse)

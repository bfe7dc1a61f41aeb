"""Pipeline loading: every malformed pipeline gives exit 2, one line with file and YAML path, no output."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from trackfw.cli import main
from trackfw.errors import UserError
from trackfw.pipeline import load_pipeline, parse_assignments
from trackfw.registry import load_registry

from .conftest import PIPELINE

# (name, pipeline text, expected fragments of the error line)
MALFORMED = [
    ("syntax", "name: x\nstages: [\n", ["line", "invalid YAML"]),
    ("empty", "", ["empty pipeline"]),
    ("not-a-mapping", "- a\n- b\n", ["expected a mapping"]),
    (
        "unknown-kind",
        PIPELINE.replace(
            "detector:    {type: oracle}", "detector:    {type: oracle}\n  detetor: {type: oracle}"
        ),
        ["stages.detetor", "did you mean 'detector'"],
    ),
    (
        "misspelled-type",
        PIPELINE.replace("detector:    {type: oracle}", "detector:    {type: orcale}"),
        ["stages.detector.type", "did you mean 'oracle'"],
    ),
    (
        "unknown-param",
        PIPELINE.replace("{association: hungarian}", "{asociation: hungarian}"),
        ["stages.tracker.params.asociation", "did you mean 'association'"],
    ),
    (
        "wrong-type",
        PIPELINE.replace(
            "detector:    {type: oracle}", "detector:    {type: oracle, params: {miss_rate: lots}}"
        ),
        ["stages.detector.params.miss_rate", "number"],
    ),
    (
        "out-of-range",
        PIPELINE.replace(
            "detector:    {type: oracle}", "detector:    {type: oracle, params: {miss_rate: 2}}"
        ),
        ["stages.detector.params.miss_rate", "less than or equal to 1"],
    ),
    (
        "bad-choice",
        PIPELINE.replace("{association: hungarian}", "{association: hungry}"),
        ["stages.tracker.params.association", "hungarian"],
    ),
    (
        "duplicate-stage",
        PIPELINE.replace(
            "classifier:  {type: oracle}",
            "classifier:  {type: oracle}\n  classifier: {type: oracle}",
        ),
        ["duplicate key 'classifier'", "line"],
    ),
    (
        "missing-stage",
        PIPELINE.replace(
            "  gap_matcher: {type: assignment, params: {method: hungarian, predictor: {type: kalman}}}\n",
            "",
        ),
        ["stages.gap_matcher", "missing"],
    ),
    ("unknown-top-level", PIPELINE + "stagse: {}\n", ["stagse", "did you mean 'stages'"]),
    (
        "nested-predictor",
        PIPELINE.replace("predictor: {type: kalman}", "predictor: {type: arr}"),
        ["stages.gap_matcher.params.predictor.type", "did you mean 'ar'"],
    ),
    (
        "nested-param",
        PIPELINE.replace(
            "predictor: {type: kalman}", "predictor: {type: ar, params: {orders: [0]}}"
        ),
        ["stages.gap_matcher.params.predictor.params.orders"],
    ),
    (
        # Before issue 15 a predictor's parameters sat beside its type; the message says where
        # they go now.
        "nested-old-shape",
        PIPELINE.replace("predictor: {type: kalman}", "predictor: {type: ar, orders: [1]}"),
        ["stages.gap_matcher.params.predictor.orders: unknown key", "go under 'params'"],
    ),
]


@pytest.mark.parametrize(
    ("case", "text", "fragments"), MALFORMED, ids=[case for case, _, _ in MALFORMED]
)
def test_malformed_pipeline_exits_2_with_one_line_and_writes_nothing(
    case: str,
    text: str,
    fragments: list[str],
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = pipeline_file(text)
    video = points_video()
    output = tmp_path / "out"
    code = main(["run", str(path), "--input", str(video), "--output", str(output), "--quiet"])
    error = capsys.readouterr().err.strip()
    assert code == 2, error
    lines = error.splitlines()
    assert len(lines) == 1, error
    assert str(path) in lines[0]
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    assert not output.exists()


def test_all_problems_are_reported_at_once(pipeline_file: Callable[..., Path]) -> None:
    text = (
        PIPELINE.replace("{type: orcale}", "")
        .replace("detector:    {type: oracle}", "detector:    {type: orcale}")
        .replace("{association: hungarian}", "{association: hungarian, gate_px_at_1080: -1}")
    )
    with pytest.raises(UserError) as caught:
        load_pipeline(pipeline_file(text), load_registry())
    assert len(caught.value.lines) == 2
    assert any("stages.detector.type" in line for line in caught.value.lines)
    assert any("stages.tracker.params.gate_px_at_1080" in line for line in caught.value.lines)


def test_missing_input_exits_2_and_writes_nothing(
    pipeline_file: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    output = tmp_path / "out"
    code = main(
        ["run", str(pipeline_file()), "--input", str(tmp_path / "nowhere"), "--output", str(output)]
    )
    error = capsys.readouterr().err
    assert code == 2
    assert "--input" in error and "does not exist" in error
    assert not output.exists()


def test_missing_pipeline_input_field(
    pipeline_file: Callable[..., Path], capsys: pytest.CaptureFixture[str]
) -> None:
    path = pipeline_file()
    assert main(["run", str(path)]) == 2
    assert f"{path}: input: missing" in capsys.readouterr().err


def test_set_overrides_values_and_reports_bad_paths(pipeline_file: Callable[..., Path]) -> None:
    registry = load_registry()
    pipeline = load_pipeline(
        pipeline_file(),
        registry,
        ["stages.tracker.params.association=nearest", "stages.detector.params.jitter_px=2.5"],
    )
    assert pipeline.stages["tracker"].as_data()["params"]["association"] == "nearest"
    assert pipeline.stages["detector"].as_data()["params"]["jitter_px"] == 2.5
    with pytest.raises(UserError, match="expected PATH=VALUE"):
        load_pipeline(pipeline_file(), registry, ["stages.tracker.params.association"])
    with pytest.raises(UserError, match=r"stages\.tracker\.params\.gate_px_at_1080"):
        load_pipeline(pipeline_file(), registry, ["stages.tracker.params.gate_px_at_1080=abc"])


def test_params_are_fully_defaulted_and_hash_is_stable(pipeline_file: Callable[..., Path]) -> None:
    registry = load_registry()
    first = load_pipeline(pipeline_file(), registry)
    second = load_pipeline(pipeline_file(), registry)
    assert first.stages["tracker"].as_data()["params"]["P0"] == 1000.0
    assert first.stages["gap_matcher"].as_data()["params"]["predictor"] == {
        "type": "kalman",
        "params": {},
    }
    assert first.content_hash == second.content_hash
    changed = load_pipeline(pipeline_file(), registry, ["stages.tracker.params.Q=0.01"])
    assert changed.content_hash != first.content_hash


def test_shipped_pipelines_validate(capsys: pytest.CaptureFixture[str]) -> None:
    pipelines = sorted((Path(__file__).resolve().parents[2] / "pipelines").glob("*.yaml"))
    assert pipelines
    for path in pipelines:
        assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def test_parse_assignments() -> None:
    assert parse_assignments(["a=1", "b=true", "c=x y"], "--p") == {"a": 1, "b": True, "c": "x y"}
    with pytest.raises(UserError, match="KEY=VALUE"):
        parse_assignments(["novalue"], "--p")

"""Bad input to ``trackfw train detector`` and detector model files: one error line, exit 2."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

EDGEBOX = ["validate", "pipeline.yaml", "--set", "stages.detector.type=edgebox-cnn", "--set"]

CASES = [
    (["train", "detector", "--out", "d.onnx"], ["give at least one --dataset or --mot"]),
    (["train", "detector", "--out", "emptydir", "--dataset", "data"], ["--out: emptydir is a"]),
    (
        ["train", "detector", "--out", "d.onnx", "--dataset", "data", "--dense-out", "emptydir"],
        ["--dense-out: emptydir is a folder"],
    ),
    ([*EDGEBOX, "stages.detector.params.model=missing.onnx"], ["missing.onnx", "not found"]),
    ([*EDGEBOX, "stages.detector.params.model=bad.onnx"], ["bad.onnx", "valid ONNX"]),
]


@pytest.mark.parametrize(("arguments", "fragments"), CASES, ids=lambda v: "-".join(v)[:60])
def test_detector_training_and_models_refuse_bad_input_in_one_line(
    arguments: list[str],
    fragments: list[str],
    in_bad_input_workspace: Path,
    bad_input: Callable[..., str],
) -> None:
    bad_input(arguments, *fragments)

"""Bad input to ``trackfw train detector`` and detector model files: one error line, exit 2."""

from __future__ import annotations

from collections.abc import Callable

EDGEBOX = ["validate", "pipeline.yaml", "--set", "stages.detector.type=edgebox-cnn", "--set"]

BAD_INPUT_CASES = [
    (["train", "detector", "--out", "d.onnx"], ["give at least one --dataset or --mot"]),
    (["train", "detector", "--out", "emptydir", "--dataset", "data"], ["--out: emptydir is a"]),
    (
        ["train", "detector", "--out", "d.onnx", "--dataset", "data", "--dense-out", "emptydir"],
        ["--dense-out: emptydir is a folder"],
    ),
    ([*EDGEBOX, "stages.detector.params.model=missing.onnx"], ["missing.onnx", "not found"]),
    ([*EDGEBOX, "stages.detector.params.model=bad.onnx"], ["bad.onnx", "valid ONNX"]),
]


def test_detector_training_and_models_refuse_bad_input_in_one_line(
    bad_input_case: Callable[[], str],
) -> None:
    bad_input_case()

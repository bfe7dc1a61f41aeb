"""Bad input to ``trackfw train classifier`` and svm model files: one error line, exit 2."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

TRAIN = ["train", "classifier", "--dataset", "data"]
SVM = ["validate", "pipeline.yaml", "--set", "stages.classifier.type=svm", "--set"]

CASES = [
    (["train", "classifier", "--dataset", "missing", "--out", "m.json"], ["missing"]),
    (["train", "classifier", "--dataset", "emptydir", "--out", "m.json"], ["no video found"]),
    ([*TRAIN, "--out", "emptydir"], ["--out: emptydir is a folder"]),
    ([*TRAIN, "--out", "file.txt/m.json"], ["--out", "file.txt is a file"]),
    ([*TRAIN, "--out", "m.json", "--report", "emptydir"], ["--report: emptydir is a folder"]),
    ([*TRAIN, "--out", "m.json", "--flow", "nope"], ["--flow 'nope'"]),
    ([*TRAIN, "--out", "m.json", "--videos-from", "missing.txt"], ["missing.txt"]),
    ([*SVM, "stages.classifier.params.model=missing.json"], ["missing.json: no such model"]),
    ([*SVM, "stages.classifier.params.model=notmodel.json"], ["notmodel.json", "format"]),
    ([*SVM, "stages.classifier.params.model=file.txt"], ["file.txt", "invalid JSON"]),
]


@pytest.mark.parametrize(("arguments", "fragments"), CASES, ids=lambda v: "-".join(v)[:60])
def test_classifier_training_and_models_refuse_bad_input_in_one_line(
    arguments: list[str],
    fragments: list[str],
    in_bad_input_workspace: Path,
    bad_input: Callable[..., str],
) -> None:
    bad_input(arguments, *fragments)

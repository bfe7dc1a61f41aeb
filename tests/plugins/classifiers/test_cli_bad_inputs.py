"""Bad input to ``trackfw train classifier`` and svm model files: one error line, exit 2."""

from __future__ import annotations

from collections.abc import Callable

TRAIN = ["train", "classifier", "--dataset", "data"]
SVM = ["validate", "pipeline.yaml", "--set", "stages.classifier.type=svm", "--set"]

BAD_INPUT_CASES = [
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


def test_classifier_training_and_models_refuse_bad_input_in_one_line(
    bad_input_case: Callable[[], str],
) -> None:
    bad_input_case()

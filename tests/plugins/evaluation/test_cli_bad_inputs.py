"""Bad input to ``trackfw eval``: one error line, exit 2, nothing written."""

from __future__ import annotations

from collections.abc import Callable

BAD_INPUT_CASES = [
    (["eval", "--dataset", "missing", "--runs", "runs"], ["missing: no such file or folder"]),
    (["eval", "--dataset", "data", "--runs", "missing"], ["missing: no such folder"]),
    (["eval", "--dataset", "data", "--runs", "file.txt"], ["file.txt", "runs folder"]),
    (["eval", "--dataset", "fake.mp4", "--runs", "runs"], ["fake.mp4: not a video"]),
    (["eval", "--dataset", "data", "--runs", "emptydir"], ["no run for video(s) v1, v2"]),
    (["eval", "--dataset", "data", "--runs", "runs", "--dist", "-5"], ["--dist is -5.0"]),
    (["eval", "--dataset", "data", "--runs", "runs", "--dist", "nan"], ["--dist is nan"]),
    (["eval", "--dataset", "data", "--runs", "runs", "--out", "file.txt"], ["--out", "file.txt"]),
    (
        ["eval", "--dataset", "data", "--runs", "runs", "--out", "file.txt/x"],
        ["--out", "not a folder"],
    ),
]


def test_eval_refuses_bad_input_in_one_line(bad_input_case: Callable[[], str]) -> None:
    bad_input_case()

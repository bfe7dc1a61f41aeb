"""Bad input to ``trackfw render``: one error line, exit 2, nothing written."""

from __future__ import annotations

from collections.abc import Callable

BAD_INPUT_CASES = [
    (["render", "missing"], ["missing: no such folder"]),
    (["render", "file.txt"], ["file.txt", "expected a run folder"]),
    (["render", "emptydir"], ["emptydir: no summary.json"]),
    (["render", "runs", "--video", "nope"], ["'nope'", "v1, v2"]),
    (["render", "runs/v1", "--out", "emptydir"], ["--out emptydir", ".mp4"]),
    (["render", "runs/v1", "--out", "file.txt/x.mp4"], ["--out", "file.txt is a file"]),
    (["render", "runs/v1", "--out", "x.avi"], ["--out x.avi", ".mp4"]),
    (["render", "runs/v1", "--dataset", "missing"], ["video_path", "--dataset"]),
    (["render", "runs/v1", "--png-frames", "0,abc"], ["--png-frames", "'0'"]),
    (["render", "runs/v1", "--trail", "-1"], ["--trail", "greater than or equal to 0"]),
]


def test_render_refuses_bad_input_in_one_line(bad_input_case: Callable[[], str]) -> None:
    bad_input_case()

"""benchmarks/checks_at_b.py: the gap matcher's proposals and the tracker's check at b, judged."""

from __future__ import annotations

import doctest
import json
from pathlib import Path
from types import ModuleType

import pytest

from trackfw.dataset import load_video, write_meta
from trackfw.errors import UserError
from trackfw.formats.annotations import write_annotations
from trackfw.formats.run import FRAMES_FILE, GAPS_FILE, TRACKS_FILE, frames_header
from trackfw.records import Interval

from .conftest import load_script


def _script() -> ModuleType:
    return load_script("checks_at_b")


def _video(root: Path, at_b: dict[str, dict[str, object]]) -> tuple[Path, Path]:
    """Targets 1 (x=100) and 2 (x=300) and a bystander (x=500) on frames 0-5, an interval a=2,
    b=4; frame b's detections are at x = 100, 500, 300 (stable indices 0, 1, 2)."""
    video, run = root / "dataset" / "v", root / "runs" / "v"
    video.mkdir(parents=True)
    run.mkdir(parents=True)
    truth = {t: {1: (100.0, 50.0), 2: (300.0, 50.0)} for t in (0, 1, 2, 4, 5)}
    heads = [(t, k, x, y, 20.0) for t, points in truth.items() for k, (x, y) in points.items()]
    heads += [(t, 9, 500.0, 50.0, 20.0) for t in truth]
    write_annotations(video, truth, heads, [Interval(a=2, b=4)])
    write_meta(video / "meta.json", {"n_frames": 6, "width": 640, "height": 480, "fps": 25})
    (run / TRACKS_FILE).write_text("", encoding="utf-8")
    rows = [",".join(frames_header())]
    for t in range(6):
        points = "100 50;500 50;300 50" if t == 4 else ""
        count = 3 if t == 4 else 0
        rows.append(f"{t + 1},ok,0.1,{int(t == 3)},{count},{points},,2,0,0,0,1,1,1,")
    (run / FRAMES_FILE).write_text("\n".join(rows) + "\n", encoding="utf-8")
    gaps = [{"a": 3, "b": 5, "resolved": True, "at_b": at_b}]
    (run / GAPS_FILE).write_text(json.dumps(gaps), encoding="utf-8")
    return video, run


def test_each_check_at_b_is_judged_before_and_after(tmp_path: Path) -> None:
    at_b = {
        "1": {"proposed": 0, "refused": None, "detection": 0, "by": "gap matcher"},  # right
        # the bystander's, then its own by continuity
        "2": {"proposed": 1, "refused": "look", "detection": 2, "by": "continuity"},
        "3": {"proposed": None, "refused": None, "detection": 1, "by": "look"},  # not in view
    }
    video, run = _video(tmp_path, at_b)
    counts = _script().video_checks(load_video(video), run, near=22.0)
    assert dict(counts) == {
        ("kept", "right", "right", "gap matcher"): 1,
        ("look", "wrong", "right", "continuity"): 1,
        ("kept", "none, out of view", "absent", "look"): 1,
    }


def test_the_table_counts_the_held_detections_by_who_gave_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = _script()
    counts = script.Counter(
        {("look", "wrong", "right", "continuity"): 2, ("kept", "right", "right", "gap matcher"): 1}
    )
    script.print_table(counts)
    table = capsys.readouterr().out.split("by who gave it:")[1].splitlines()
    rows = {line.split()[0]: line.split()[1:] for line in table[2:] if line.strip()}
    assert rows["continuity"][0] == "2" and rows["gap"][1] == "1" and rows["all"][0] == "3"


def test_a_detection_that_frame_b_does_not_list_is_a_clear_error(tmp_path: Path) -> None:
    video, run = _video(tmp_path, {"1": {"proposed": 7, "refused": None, "detection": 7}})
    with pytest.raises(UserError, match="names detection 7 on frame b"):
        _script().video_checks(load_video(video), run, near=22.0)


def test_the_scripts_examples_hold() -> None:
    result = doctest.testmod(_script())
    assert result.failed == 0 and result.attempted > 0

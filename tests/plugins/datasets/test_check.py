"""``trackfw dataset check``: every crafted problem is reported, one line each, exit code 2."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from trackfw.dataset import write_meta
from trackfw.formats.annotations import write_heads, write_intervals, write_targets
from trackfw.records import Interval
from trackfw_plugins.datasets import check as check_module
from trackfw_plugins.datasets.check import check_dataset

N_FRAMES, WIDTH, HEIGHT = 10, 32, 24


def make_video(folder: Path) -> Path:
    """A valid 10-frame video: targets 1 and 2, a sky interval on frames 4..6 (1-based)."""
    (folder / "img1").mkdir(parents=True)
    for frame in range(1, N_FRAMES + 1):
        cv2.imwrite(
            str(folder / "img1" / f"{frame:06d}.jpg"), np.full((HEIGHT, WIDTH, 3), 99, np.uint8)
        )
    informative = [0, 1, 2, 6, 7, 8, 9]
    write_targets(
        folder / "gt.csv", {t: {1: (5.0 + t, 6.0), 2: (20.0, 10.0 + t)} for t in informative}
    )
    write_heads(folder / "heads.csv", [(t, 1, 5.0 + t, 6.0, 4.0) for t in range(N_FRAMES)])
    write_intervals(folder / "intervals.csv", [Interval(a=2, b=6, kind="sky")])
    write_meta(
        folder / "meta.json",
        {"fps": 25.0, "width": WIDTH, "height": HEIGHT, "n_frames": N_FRAMES, "source": "test"},
    )
    return folder


def _app() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test group."""

    check_module.register(app)
    return app


def test_a_valid_dataset_has_no_problem_and_its_statistics(tmp_path: Path) -> None:
    make_video(tmp_path / "data" / "v1")
    make_video(tmp_path / "data" / "v2")
    report = check_dataset(tmp_path / "data")
    assert report.problems == [] and report.ok
    stats = report.stats
    assert stats["videos"] == 2
    assert stats["frames"] == {"total": 20, "min": 10, "max": 10}
    assert stats["intervals"]["count"] == 2
    assert stats["intervals"]["by_kind"]["sky"]["length"] == {"min": 3, "mean": 3.0, "max": 3}
    assert stats["targets_per_video"]["mean"] == 2
    assert stats["heads_per_frame"] == {"min": 1, "mean": 1.0, "max": 1}
    result = CliRunner().invoke(_app(), ["check", str(tmp_path / "data")])
    assert result.exit_code == 0, result.output


def test_all_crafted_problems_are_reported_at_once(tmp_path: Path) -> None:
    video = make_video(tmp_path / "data" / "v1")
    (video / "gt.csv").write_text(
        "frame,id,x,y\n"
        "1,1,5,6\n"
        "1,2,20,10\n"
        "2,1,6,6\n"
        "2,1,7,6\n"  # line 5: duplicate id
        "99,2,20,10\n"  # line 6: beyond the video
        "2,2,nan,10\n"  # line 7: NaN
        "3,1,5,6\n"  # line 8: inside the interval 3..4
        "7,7,5,6\n"  # line 9: id 7 not on frame 1
        "9,2,500,10\n"  # line 10: outside the image
    )
    # Line 3 overlaps line 2; line 4 has an unknown kind.
    (video / "intervals.csv").write_text("start,end,kind\n3,4,sky\n4,5,path\n8,8,cloud\n")
    report = check_dataset(tmp_path / "data")
    gt, intervals = video / "gt.csv", video / "intervals.csv"
    expected = [
        f"{gt}: line 5: id 1 appears twice in frame 2",
        f"{gt}: line 6: frame 99 is outside the video",
        f"{gt}: line 7: x is 'nan'; expected a finite number",
        f"{gt}: line 8: frame 3 is inside the info-less interval 3..4",
        f"{gt}: line 9: id 7 is not on frame 1",
        f"{gt}: line 10: point (500, 10) is outside",
        f"{intervals}: line 3: interval 4..5 overlaps or touches 3..4",
        f"{intervals}: line 4: kind 'cloud'",
    ]
    # One line per problem, sorted by file and line.
    assert len(report.problems) == len(expected)
    for problem, start in zip(report.problems, expected, strict=True):
        assert problem.startswith(start), (problem, start)
    result = CliRunner().invoke(_app(), ["check", str(tmp_path / "data")])
    assert result.exit_code == 2
    assert "id 1 appears twice in frame 2" in result.output


def test_frames_meta_and_headers(tmp_path: Path) -> None:
    first = make_video(tmp_path / "data" / "v1")
    second = make_video(tmp_path / "data" / "v2")
    (first / "img1" / "000004.jpg").unlink()
    (first / "heads.csv").write_text("frame,id,x,y,head_size\n1,1,5,6,-2\n1,1,5,6,3\n")
    (second / "meta.json").write_text('{"fps": 25, "width": 32, "height": 24}')
    (second / "intervals.csv").write_text("begin,end,kind\n")
    (second / "poses.csv").write_text(
        "frame,pan,tilt,roll,scale,tx,ty\n1,0,0,0,1,0,0\n1,0,0,0,1,0,0\n"
    )
    report = check_dataset(tmp_path / "data")
    joined = "\n".join(report.problems)
    assert f"{first / 'meta.json'}: n_frames is 10 but img1 holds 9 frames" in joined
    assert f"{first / 'img1'}: frame numbers are not 1..9; missing 4" in joined
    assert f"{first / 'heads.csv'}: line 2: head_size is -2; expected a positive size" in joined
    assert f"{first / 'heads.csv'}: line 3: id 1 appears twice in frame 1" in joined
    assert f"{second / 'meta.json'}: n_frames is None; expected a positive integer" in joined
    assert f"{second / 'intervals.csv'}: line 1: header is 'begin,end,kind'" in joined
    assert f"{second / 'poses.csv'}: line 3: frame 1 appears twice" in joined
    # Without intervals the gt rows on frames 4..6 of v2 are no longer flagged.
    assert not any("info-less" in problem for problem in report.problems)


def test_missing_folder_and_missing_files(tmp_path: Path) -> None:
    report = check_dataset(tmp_path / "absent")
    assert len(report.problems) == 1 and "no such file or folder" in report.problems[0]
    video = make_video(tmp_path / "data" / "v1")
    (video / "gt.csv").unlink()
    (video / "intervals.csv").unlink()
    problems = check_dataset(tmp_path / "data").problems
    assert problems == [
        f"{video / 'gt.csv'}: missing; expected frame,id,x,y of the people of interest.",
        f"{video / 'intervals.csv'}: missing; expected the header start,end,kind (even if empty).",
    ]


@pytest.mark.parametrize("bad_id", [-1, 0])
def test_target_ids_must_be_positive_integers(tmp_path: Path, bad_id: int) -> None:
    video = make_video(tmp_path / "data" / "v1")
    text = (video / "gt.csv").read_text().replace("\n1,2,", f"\n1,{bad_id},")
    (video / "gt.csv").write_text(text)
    report = check_dataset(tmp_path / "data")
    line = (
        text.splitlines().index(
            next(row for row in text.splitlines() if row.startswith(f"1,{bad_id},"))
        )
        + 1
    )
    assert any(
        f"gt.csv: line {line}: id {bad_id} is not a positive integer" in problem
        for problem in report.problems
    ), report.problems
    # The reader every command uses refuses it too, so tracks.txt can never carry it.
    from trackfw.dataset import load_video
    from trackfw.errors import UserError

    with pytest.raises(UserError, match=f"id {bad_id} is not a positive integer"):
        load_video(video)

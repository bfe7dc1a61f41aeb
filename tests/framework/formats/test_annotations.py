"""gt.csv, heads.csv and intervals.csv: what is written reads back; bad lines are named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.formats.annotations import (
    read_heads,
    read_intervals,
    read_targets,
    write_heads,
    write_intervals,
    write_targets,
)
from trackfw.records import Interval


def test_written_annotations_read_back(tmp_path: Path) -> None:
    targets = {0: {1: (10.0, 20.5), 2: (30.25, 40.0)}, 4: {1: (11.0, 21.0)}}
    write_targets(tmp_path / "gt.csv", targets)
    assert read_targets(tmp_path / "gt.csv", n_frames=5) == targets
    write_heads(tmp_path / "heads.csv", [(0, 1, 10.0, 20.0, 8.0), (2, 3, 1.5, 2.5, 9.0)])
    heads = read_heads(tmp_path / "heads.csv", n_frames=5)
    assert sorted(heads) == [0, 2] and np.array_equal(heads[2], [[1.5, 2.5, 9.0]])
    write_intervals(tmp_path / "intervals.csv", [Interval(a=1, b=4, kind="sky")])
    assert (tmp_path / "intervals.csv").read_text() == "start,end,kind\n3,4,sky\n"
    assert read_intervals(tmp_path / "intervals.csv", n_frames=5) == [
        Interval(a=1, b=4, kind="sky")
    ]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("frame,id,x\n", "line 1: header is 'frame,id,x'; expected it to start with"),
        ("frame,id,x,y\n1,1,2\n", "line 2: 3 values; expected 4"),
        ("frame,id,x,y\n1,one,2,3\n", "line 2: id is 'one'; expected an integer"),
        ("frame,id,x,y\n1,1,inf,3\n", "line 2: x is 'inf'; expected a finite number"),
        ("frame,id,x,y\n7,1,2,3\n", "line 2: frame 7 is outside the video; expected 1..5"),
        ("frame,id,x,y\n1,1,2,3\n1,1,2,3\n", "line 3: id 1 appears twice in frame 1"),
    ],
)
def test_bad_gt_lines_are_named(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "gt.csv"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(UserError) as error:
        read_targets(path, n_frames=5)
    assert f"{path}: {message}" in str(error.value)

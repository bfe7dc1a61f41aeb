"""MOTChallenge text: one reader for tracks, ground truth and detections, one track writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.formats import mot


def _write(tmp_path: Path, content: str, name: str = "mot.txt") -> Path:
    path = tmp_path / name
    path.write_text(content, encoding="utf-8")
    return path


def test_tracks_are_box_centres_on_0_based_frames(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "1,3,60.0,160.0,80.0,80.0,1,-1,-1,-1\n\n2,3,62.0,160.0,80.0,80.0,1,-1,-1,-1\n",
    )
    rows = mot.read_mot_text(path, n_frames=2)
    assert rows.lines.tolist() == [1, 3]
    assert mot.rows_by_frame(rows) == {0: {3: (100.0, 200.0)}, 1: {3: (102.0, 200.0)}}
    assert mot.rows_by_frame(rows, "box", frame_offset=0)[1][3] == (60.0, 160.0, 80.0, 80.0)


def test_six_value_lines_have_confidence_one_and_no_extra_values(tmp_path: Path) -> None:
    rows = mot.read_mot_text(_write(tmp_path, "1,3,60,160,80,80\n1,4,0,0,8,8,0.25,7\n"))
    assert rows.confidences.tolist() == [1.0, 0.25]
    assert rows.n_values.tolist() == [6, 8]
    assert np.isnan(rows.extra[0]).all() and rows.extra[1, 0] == 7.0


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("1,3,60.0,160.0\n", "line 1: 4 values; expected at least 6"),
        ("1,3,60,160,80,80\n1,x,60,160,80,80\n", "line 2: id is 'x'; expected a number"),
        ("1,3,60,160,80,80\n1.5,3,60,160,80,80\n", "line 2: frame is '1.5'; expected an integer"),
        ("1,3,nan,160,80,80\n", "line 1: left is 'nan'; expected a finite number"),
        ("1,3,1,1,80,80,inf\n", "line 1: conf is 'inf'; expected a finite number"),
        ("9,3,60,160,80,80\n", "line 1: frame 9 is outside the video; expected 1..5"),
        ("0,3,60,160,80,80\n", "line 1: frame 0 is outside the video"),
        ("1,3,60,160,80,80\n1,3,61,160,80,80\n", "line 2: id 3 appears twice in frame 1"),
    ],
)
def test_malformed_lines_name_file_and_line(tmp_path: Path, content: str, message: str) -> None:
    path = _write(tmp_path, content)
    with pytest.raises(UserError) as error:
        mot.read_mot_text(path, n_frames=5)
    assert str(path) in str(error.value)
    assert message in str(error.value)


def test_missing_and_non_utf8_files_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match=r"absent\.txt: file not found; expected MOTChallenge"):
        mot.read_mot_text(tmp_path / "absent.txt")
    path = tmp_path / "latin.txt"
    path.write_bytes(b"1,1,0,0,\xe9,1\n")
    with pytest.raises(UserError, match="not UTF-8"):
        mot.read_mot_text(path)


def test_mot15_ground_truth_keeps_every_row_sorted_by_id(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "1,2,10,5,4,10,1,-1,-1,-1\n1,1,0,0,4,10,0,-1,-1,-1\n3,1,1,1,2,2,1,-1,-1,-1\n",
    )
    boxes = mot.boxes_by_frame(mot.read_mot_ground_truth(path, n_frames=3))
    # MOT15's 7th value is a confidence: the row with 0 there is kept.
    assert sorted(boxes) == [0, 2]
    assert boxes[0][:, 0].tolist() == [1.0, 2.0]
    assert boxes[2].tolist() == [[1.0, 1.0, 1.0, 2.0, 2.0]]
    in_file_order = mot.boxes_by_frame(mot.read_mot_ground_truth(path), sort_ids=False)
    assert in_file_order[0][:, 0].tolist() == [2.0, 1.0]


def test_mot17_ground_truth_keeps_only_considered_pedestrians(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "1,1,0,0,4,10,1,1,0.9\n"  # kept
        "1,2,0,0,4,10,0,1,0.9\n"  # flag 0: ignored
        "1,3,0,0,4,10,1,3,0.9\n"  # class 3 (car): ignored
        "1,3,5,5,4,10,0,3,0.9\n"  # the same id again, but ignored: no clash
        "2,4,0,0,4,10,1,1,0.1\n",
    )
    boxes = mot.boxes_by_frame(mot.read_mot_ground_truth(path))
    assert sorted(boxes) == [0, 1]
    assert boxes[0][:, 0].tolist() == [1.0]
    assert boxes[1][:, 0].tolist() == [4.0]


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        ("1,1,0,0,4,10,1,1,1\n1,2,0,0,4\n", "line 2: 5 values; expected at least 6"),
        ("1,1,0,0,4,10,1,1,1\n1,2,0,0,4,10\n", "line 2: 6 values; expected 9 like the first line"),
        ("1,1,0,0,4,10,1,-1,-1,-1\n1,1,5,5,4,10,1,-1,-1,-1\n", "line 2: id 1 appears twice"),
        ("1,1,0,zero,4,10,1,-1,-1,-1\n", "line 1: top is 'zero'; expected a number"),
        ("9,1,0,0,4,10,1,-1,-1,-1\n", "line 1: frame 9 is outside the video"),
        ("1,1,0,0,-4,10,1,-1,-1,-1\n", "line 1: box -4x10; expected a positive size"),
        ("1,1,0,nan,4,10,1,-1,-1,-1\n", "line 1: top is 'nan'; expected a finite number"),
        ("1,1,0,0,4,10,1,1,1,1,1\n", "line 1: 11 values; expected 6 to 10"),
    ],
)
def test_malformed_ground_truth_names_file_and_line(
    tmp_path: Path, content: str, expected: str
) -> None:
    path = _write(tmp_path, content, "gt.txt")
    with pytest.raises(UserError, match=expected) as error:
        mot.read_mot_ground_truth(path, n_frames=3)
    assert str(path) in str(error.value)


def test_detections_share_ids_and_keep_file_order(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "1,-1,10,20,40,100,0.9,-1,-1,-1\n3,-1,0,0,10,10,5.0,-1,-1,-1\n"
        "1,-1,100,50,20,50,0.2,-1,-1,-1\n",
        "det.txt",
    )
    table = mot.detections_by_frame(mot.read_mot_detections(path))
    assert sorted(table) == [0, 2]
    assert table[0][0].tolist() == [[10.0, 20.0, 40.0, 100.0], [100.0, 50.0, 20.0, 50.0]]
    assert table[0][1].tolist() == [0.9, 0.2]
    assert table[2][1].tolist() == [5.0]


def test_written_tracks_read_back(tmp_path: Path) -> None:
    text = mot.mot_track_text([(1, 2, 50.0, 60.0), (0, 7, 10.5, 20.25), (0, 2, 100.0, 40.0)], 80.0)
    assert text.splitlines()[0] == "1,2,60.00,0.00,80,80,1,-1,-1,-1"
    rows = mot.read_mot_text(_write(tmp_path, text, "tracks.txt"))
    assert mot.rows_by_frame(rows) == {
        0: {2: (100.0, 40.0), 7: (10.5, 20.25)},
        1: {2: (50.0, 60.0)},
    }
    assert mot.mot_track_text([], 80.0) == ""


def test_real_mot15_files(shared_data: Path) -> None:
    sequence = shared_data / "TUD-Stadtmitte"
    truth = mot.read_mot_ground_truth(sequence / "gt" / "gt.txt", n_frames=179)
    assert len(truth) > 1000 and (truth.n_values == 10).all()
    detections = mot.read_mot_detections(sequence / "det" / "det_mot15_official.txt")
    assert (detections.ids == -1).all() and detections.confidences.max() > 1.0

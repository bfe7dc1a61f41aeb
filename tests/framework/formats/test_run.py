"""Run-folder readers: formats, 0-based frames, and one clear UserError per bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.formats import mot_track_text
from trackfw.formats.run import FRAMES_COLUMNS, frames_header, read_frames_csv, read_run

HEADER = "frame,status,infoless_probability,infoless,n_detections,detections,ms_detector,ms_classifier,ms_tracker,ms_gap_matcher"


def test_frames_csv(tmp_path: Path) -> None:
    path = tmp_path / "frames.csv"
    path.write_text(
        HEADER + "\n"
        "2,ok,0.9,1,0,,1,1,1,0\n"
        "1,ok,0.1,0,2,10.5 20.0;30.0 40.5,1,1,1,0\n"
        "3,unread,,,0,,0,0,0,0\n",
        encoding="utf-8",
    )
    records = read_frames_csv(path, n_frames=3)
    assert records.frames.tolist() == [0, 1, 2]
    assert records.infoless.tolist() == [False, True, False]
    assert records.ok.tolist() == [True, True, False]
    assert np.isnan(records.infoless_probability[2])
    assert records.detections[0].tolist() == [[10.5, 20.0], [30.0, 40.5]]
    assert records.detections[1].shape == (0, 2)


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("1,done,0.1,0,0,,1,1,1,0", "status is 'done'"),
        ("1,ok,0.1,2,0,,1,1,1,0", "infoless is '2'; expected 0 or 1"),
        ("1,ok,0.1,0,3,1 2,1,1,1,0", "n_detections is 3 but detections lists 1 points"),
        ("1,ok,0.1,0,1,1 nan,1,1,1,0", "detections is 'nan'; expected a finite number"),
        ("1,ok,0.1,0,1,1 2 3,1,1,1,0", "detections item '1 2 3'"),
        ("7,ok,0.1,0,0,,1,1,1,0", "frame 7 is outside the video"),
        ("1,ok,0.1,0,0,,1,1,1", "9 values; expected 10"),
    ],
)
def test_malformed_frames_csv(tmp_path: Path, row: str, message: str) -> None:
    path = tmp_path / "frames.csv"
    path.write_text(HEADER + "\n" + row + "\n", encoding="utf-8")
    with pytest.raises(UserError) as error:
        read_frames_csv(path, n_frames=5)
    assert f"{path}: line 2:" in str(error.value)
    assert message in str(error.value)


def test_frames_csv_header_is_checked(tmp_path: Path) -> None:
    path = tmp_path / "frames.csv"
    path.write_text("frame,infoless\n1,0\n", encoding="utf-8")
    with pytest.raises(UserError, match="line 1: header"):
        read_frames_csv(path)


def _run_folder(folder: Path) -> Path:
    """A three-frame run: one track point on frame 1, frame 2 info-less."""
    folder.mkdir(parents=True)
    (folder / "tracks.txt").write_text(mot_track_text([(0, 1, 100.0, 200.0)], 80.0))
    rows = [f"{t + 1},ok,0.5,{int(t == 1)},0,,1,1,1,0" for t in range(3)]
    (folder / "frames.csv").write_text("\n".join([HEADER, *rows]) + "\n", encoding="utf-8")
    (folder / "summary.json").write_text('{"video": "v1", "n_frames": 3}\n', encoding="utf-8")
    (folder / "gaps.json").write_text("[]\n", encoding="utf-8")
    return folder


def test_the_header_is_defined_once() -> None:
    # HEADER (used above) is the layout of runs written before detection sizes were recorded;
    # those runs stay readable.
    with_sizes = HEADER.replace(
        ",detections,",
        ",detections,detection_sizes,n_tracked,n_lost,n_out_of_view,n_tentative,",
    )
    assert ",".join(frames_header()) == with_sizes
    assert frames_header()[: len(FRAMES_COLUMNS)] == FRAMES_COLUMNS


def test_detection_sizes_are_read_per_detection(tmp_path: Path) -> None:
    path = tmp_path / "frames.csv"
    path.write_text(
        ",".join(frames_header()) + "\n"
        "1,ok,0.1,0,2,10 20;30 40,12.0 14.0;8 8,6,0,0,0,1,1,1,0\n"
        "2,ok,0.1,0,1,10 20,,6,0,0,0,1,1,1,0\n",
        encoding="utf-8",
    )
    records = read_frames_csv(path)
    assert records.detection_sizes[0].tolist() == [[12.0, 14.0], [8.0, 8.0]]
    assert records.detection_sizes[1].shape == (1, 2) and np.isnan(records.detection_sizes[1]).all()


@pytest.mark.parametrize(
    ("sizes", "message"),
    [("12 14", "lists 1 sizes; expected one per detection (2)"), ("12 14;0 3", "positive")],
)
def test_malformed_detection_sizes(tmp_path: Path, sizes: str, message: str) -> None:
    path = tmp_path / "frames.csv"
    path.write_text(
        ",".join(frames_header()) + f"\n1,ok,0.1,0,2,10 20;30 40,{sizes},6,0,0,0,1,1,1,0\n",
        encoding="utf-8",
    )
    with pytest.raises(UserError) as error:
        read_frames_csv(path)
    assert f"{path}: line 2: detection_sizes" in str(error.value) and message in str(error.value)


def test_read_run(tmp_path: Path) -> None:
    folder = _run_folder(tmp_path / "v1")
    run = read_run(folder, n_frames=3)
    assert run.name == "v1"
    assert run.tracks == {0: {1: (100.0, 200.0)}}
    assert run.frames.infoless.tolist() == [False, True, False]
    assert run.summary["video"] == "v1" and run.gaps == []
    (folder / "gaps.json").write_text("{oops", encoding="utf-8")
    with pytest.raises(UserError, match=r"gaps\.json: line 1: invalid JSON"):
        read_run(folder, n_frames=3)
    (folder / "frames.csv").unlink()
    with pytest.raises(UserError, match=r"frames\.csv: file not found"):
        read_run(folder, n_frames=3)
    with pytest.raises(UserError, match="no run for this video"):
        read_run(tmp_path / "absent")

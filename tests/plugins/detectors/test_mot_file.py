"""Tests of the mot-file detector (MOTChallenge det.txt)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.records import FrameData, VideoContext
from trackfw_plugins.detectors.mot_file import MotFileDetector, MotFileParams

ROWS = (
    "1,-1,10,20,40,100,0.9,-1,-1,-1\n1,-1,100,50,20,50,0.2,-1,-1,-1\n3,-1,0,0,10,10,5.0,-1,-1,-1\n"
)


def _video(folder: Path) -> VideoContext:
    return VideoContext(name=folder.name, path=str(folder), n_frames=3, width=640, height=480)


def _frame(video: VideoContext, t: int) -> FrameData:
    return FrameData(t=t, image=None, video=video)


def test_reads_rows_by_frame_with_body_head_points(tmp_path: Path) -> None:
    folder = tmp_path / "seq"
    (folder / "det").mkdir(parents=True)
    (folder / "det" / "det.txt").write_text(ROWS)
    detector = MotFileDetector()
    assert not detector.needs_pixels
    video = _video(folder)
    detector.start(video)
    first = detector.detect(_frame(video, 0))
    assert first.points.tolist() == [[30.0, 28.0], [110.0, 54.0]]
    assert first.scores.tolist() == [0.9, 0.2]
    assert len(detector.detect(_frame(video, 1))) == 0
    assert detector.detect(_frame(video, 2)).scores.tolist() == [1.0]  # clipped


def test_template_threshold_point_and_sigmoid(tmp_path: Path) -> None:
    folder = tmp_path / "seq"
    folder.mkdir()
    (tmp_path / "dets").mkdir()
    (tmp_path / "dets" / "seq.txt").write_text(ROWS)
    params = MotFileParams(
        path=str(tmp_path / "dets" / "{name}.txt"),
        point="centre",
        score_threshold=0.5,
        score_transform="sigmoid",
    )
    detector = MotFileDetector(params)
    video = _video(folder)
    detector.start(video)
    first = detector.detect(_frame(video, 0))
    assert first.points.tolist() == [[30.0, 70.0]]
    assert first.scores == pytest.approx([1 / (1 + np.exp(-0.9))])
    relative = MotFileDetector(MotFileParams(path="../dets/{name}.txt"))
    relative.start(video)
    assert len(relative.detect(_frame(video, 0))) == 2


def test_missing_file_and_bad_rows_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="not found"):
        MotFileDetector().start(_video(tmp_path))
    (tmp_path / "det").mkdir()
    bad = tmp_path / "det" / "det.txt"
    bad.write_text("1,-1,10,20,40,100,0.9\n2,-1,ten,20,40,100,0.9\n")
    with pytest.raises(UserError, match=r"det\.txt: line 2: left is 'ten'"):
        MotFileDetector().start(_video(tmp_path))
    bad.write_text("0,-1,10,20,40,100,0.9\n")
    with pytest.raises(UserError, match="line 1: frame 0 is outside the video"):
        MotFileDetector().start(_video(tmp_path))


def test_real_mot15_detections(shared_data: Path) -> None:
    sequence = shared_data / "TUD-Stadtmitte"
    detector = MotFileDetector(MotFileParams(path="det/det_frcnn_from_abewley_sort.txt"))
    video = _video(sequence)
    detector.start(video)
    detections = detector.detect(_frame(video, 0))
    assert len(detections) > 3 and detections.boxes is not None
    # Head points lie inside the upper fifth of their body boxes.
    relative = (detections.points[:, 1] - detections.boxes[:, 1]) / detections.boxes[:, 3]
    assert ((relative > 0) & (relative < 0.2)).all()

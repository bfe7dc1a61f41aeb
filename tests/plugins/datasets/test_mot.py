"""MOTChallenge sequence reader: seqinfo.ini, gt.txt layouts and their errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.datasets.mot import (
    load_mot_sequence,
    read_frame,
    trim_edges,
)


def _sequence(folder: Path, gt_lines: list[str], n_images: int = 3, seqinfo: bool = True) -> Path:
    (folder / "img1").mkdir(parents=True)
    (folder / "gt").mkdir()
    for index in range(1, n_images + 1):
        cv2.imwrite(str(folder / "img1" / f"{index:06d}.jpg"), np.full((24, 32, 3), 90, np.uint8))
    (folder / "gt" / "gt.txt").write_text("\n".join(gt_lines) + "\n")
    if seqinfo:
        (folder / "seqinfo.ini").write_text(
            "[Sequence]\nname=Fake\nimDir=img1\nframeRate=30\nseqLength=3\n"
            "imWidth=32\nimHeight=24\nimExt=.jpg\n"
        )
    return folder


def test_mot15_rows_are_all_kept_and_sorted_by_id(tmp_path: Path) -> None:
    folder = _sequence(
        tmp_path / "s",
        ["1,2,10,5,4,10,1,-1,-1,-1", "1,1,0,0,4,10,0,-1,-1,-1", "3,1,1,1,2,2,1,-1,-1,-1"],
    )
    sequence = load_mot_sequence(folder)
    assert (sequence.name, sequence.width, sequence.height, sequence.fps) == ("Fake", 32, 24, 30.0)
    assert sequence.n_frames == 3
    # MOT15's 7th column is a confidence: the row with 0 there is kept.
    assert sequence.boxes_at(0)[:, 0].tolist() == [1.0, 2.0]
    assert sequence.boxes_at(1).shape == (0, 5)
    assert sequence.boxes_at(2).tolist() == [[1.0, 1.0, 1.0, 2.0, 2.0]]


def test_without_seqinfo_the_size_comes_from_the_images(tmp_path: Path) -> None:
    folder = _sequence(tmp_path / "Plain", ["2,7,1,2,3,4,1,-1,-1,-1"], n_images=4, seqinfo=False)
    sequence = load_mot_sequence(folder)
    assert (sequence.name, sequence.width, sequence.height, sequence.n_frames) == (
        "Plain",
        32,
        24,
        4,
    )
    assert read_frame(sequence, 3).shape == (24, 32, 3)


def test_missing_pieces_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such folder"):
        load_mot_sequence(tmp_path / "absent")
    folder = _sequence(tmp_path / "s", ["1,1,0,0,4,10,1,-1,-1,-1"])
    (folder / "gt" / "gt.txt").unlink()
    with pytest.raises(UserError, match=r"gt\.txt: file not found"):
        load_mot_sequence(folder)
    (folder / "seqinfo.ini").write_text("[Sequence]\nseqLength=10\n")
    with pytest.raises(UserError, match="seqLength is 10"):
        load_mot_sequence(folder)


def test_edges_are_trimmed_and_the_inside_kept() -> None:
    rng = np.random.default_rng(0)
    image = rng.integers(80, 160, size=(20, 30, 3), dtype=np.uint8)
    image[:2] = 0
    image[:, -1] = 10
    trimmed = trim_edges(image, 3)
    assert np.array_equal(trimmed[3:-3, 3:-3], image[3:-3, 3:-3])
    for row in (0, 1, 2):
        assert np.array_equal(trimmed[row, 3:-3], image[3, 3:-3])
    for column in (27, 28, 29):
        assert np.array_equal(trimmed[3:-3, column], image[3:-3, 26])
    assert trimmed.min() >= 80


def test_read_frame_trims_unless_raw(tmp_path: Path) -> None:
    folder = _sequence(tmp_path / "s", ["1,1,0,0,4,10,1,-1,-1,-1"])
    image = np.full((24, 32, 3), 120, np.uint8)
    image[0] = 0
    cv2.imwrite(str(folder / "img1" / "000001.png"), image)
    (folder / "img1" / "000001.jpg").unlink()
    (folder / "seqinfo.ini").write_text("[Sequence]\nseqLength=3\nimExt=.png\n")
    (folder / "img1" / "000002.jpg").rename(folder / "img1" / "000002.png")
    (folder / "img1" / "000003.jpg").rename(folder / "img1" / "000003.png")
    sequence = load_mot_sequence(folder)
    assert int(read_frame(sequence, 0, raw=True)[0].max()) == 0
    assert int(read_frame(sequence, 0)[0].min()) == 120

"""Tests of training-crop sampling and of the MOT head proxy."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trackfw_plugins.detectors.proposals import HeadProposer
from trackfw_plugins.detectors.training.sampling import (
    MOT_HEAD_SIZE_RATIO,
    AnnotatedFrame,
    SamplingSettings,
    candidate_boxes,
    head_boxes,
    iter_mot_frames,
    label_boxes,
    mot_heads,
    sample_crops,
)


def test_mot_heads_uses_the_body_box_proxy_and_skips_ignored_rows(tmp_path: Path) -> None:
    gt = tmp_path / "gt.txt"
    gt.write_text(
        "1,1,10,20,40,100,1,1,1.0\n1,2,0,0,10,10,0,1,1.0\n"
        "2,1,0,0,20,50,1,2,1.0\n2,3,0,0,20,50,1,1,1.0\n"
    )
    heads = mot_heads(gt)
    assert sorted(heads) == [0, 1]
    assert heads[0].tolist() == [[30.0, 28.0, MOT_HEAD_SIZE_RATIO * 100]]  # flag 0 left out
    assert heads[1].tolist() == [[10.0, 4.0, MOT_HEAD_SIZE_RATIO * 50]]  # class 2 left out


def test_labels_follow_distance_and_size_rules() -> None:
    heads = np.array([[100.0, 100.0, 20.0]])
    labels = label_boxes(
        np.array(
            [
                [90.0, 90.0, 20.0, 20.0],  # the head box
                [93.0, 90.0, 20.0, 20.0],  # shifted by 0.15 s: still a head
                [100.0, 90.0, 20.0, 20.0],  # shifted by 0.5 s: ambiguous
                [120.0, 90.0, 20.0, 20.0],  # shifted by 1.5 s: background
                [75.0, 75.0, 50.0, 50.0],  # 2.5 times too large: background
                [93.5, 93.5, 13.0, 13.0],  # 0.65 times the size: still a head
                [95.0, 95.0, 10.0, 10.0],  # half the size: ambiguous
            ]
        ),
        heads,
    )
    assert labels.tolist() == [1, 1, -1, 0, 0, 1, -1]
    assert label_boxes(np.zeros((2, 4)), np.zeros((0, 3))).tolist() == [0, 0]


def test_sampled_crops_are_labelled_consistently() -> None:
    rng = np.random.default_rng(0)
    image = np.random.default_rng(1).integers(0, 255, (180, 320, 3), dtype=np.uint8)
    heads = np.array([[80.0, 60.0, 20.0], [200.0, 100.0, 30.0], [10.0, 10.0, 3.0]])
    frame = AnnotatedFrame(image=image, heads=heads, source="test")
    settings = SamplingSettings(input_size=32, positives_per_head=5, random_per_frame=10)
    boxes = candidate_boxes(frame, rng, settings)
    labels = label_boxes(boxes, heads)
    # Jittered copies of the two large heads are positives; the 3 px head is too small to sample.
    assert np.count_nonzero(labels == 1) >= 2 * settings.positives_per_head
    crops, crop_labels = sample_crops(frame, rng, settings, HeadProposer())
    assert crops.shape[1:] == (32, 32, 3) and len(crops) == len(crop_labels)
    positives = int(crop_labels.sum())
    assert positives >= 2 * settings.positives_per_head
    assert len(crop_labels) - positives <= max(10, 3 * positives)


def test_smallest_sampled_head_is_scaled_by_the_frame_height() -> None:
    # 6 px at 720p is 9 px at 1080p: above the 8 px (at 1080p) smallest head, so it is sampled
    # at 720p; at 1080p the same 6 px head is below it and gets no jittered positives.
    heads = np.array([[200.0, 200.0, 6.0]])
    settings = SamplingSettings(positives_per_head=5, near_misses_per_head=0, random_per_frame=0)
    for height, expected in ((720, 5), (1080, 0)):
        frame = AnnotatedFrame(np.zeros((height, 400, 3), np.uint8), heads, "test")
        boxes = candidate_boxes(frame, np.random.default_rng(0), settings)
        assert np.count_nonzero(label_boxes(boxes, heads) == 1) == expected


def test_head_boxes_are_squares_around_heads() -> None:
    boxes = head_boxes(np.array([[50.0, 40.0, 10.0]]))
    assert boxes.tolist() == [[45.0, 35.0, 10.0, 10.0]]


def test_real_sequence_frames(shared_data: Path) -> None:
    frame = next(iter_mot_frames(shared_data / "TUD-Stadtmitte", frame_step=50))
    assert frame.image.shape == (480, 640, 3) and len(frame.heads) >= 5
    assert (frame.heads[:, 2] > 5).all() and (frame.heads[:, 1] < 240).all()


def test_dataset_frames_inside_an_interval_are_not_informative(tmp_path: Path) -> None:
    import cv2

    from trackfw.dataset import write_meta
    from trackfw.formats.annotations import write_heads, write_intervals
    from trackfw.records import Interval
    from trackfw_plugins.detectors.training.sampling import iter_dataset_frames

    video = tmp_path / "data" / "video0"
    (video / "img1").mkdir(parents=True)
    for t in range(10):
        cv2.imwrite(str(video / "img1" / f"{t + 1:06d}.png"), np.full((36, 64, 3), t, np.uint8))
    write_heads(video / "heads.csv", [(t, 1, 20.0, 20.0, 8.0) for t in range(10)])
    write_intervals(video / "intervals.csv", [Interval(2, 6, "sky")])  # frames 3..5 info-less
    write_meta(video / "meta.json", {"width": 64, "height": 36, "fps": 30, "n_frames": 10})
    frames = list(iter_dataset_frames(tmp_path / "data", frame_step=1))
    assert [frame.informative for frame in frames] == [t not in (3, 4, 5) for t in range(10)]
    assert all(len(frame.heads) == 1 for frame in frames)

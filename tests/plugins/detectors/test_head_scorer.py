"""Tests of crop extraction and of the onnxruntime head scorer (model checks, output forms)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.detectors.head_scorer import (
    HeadScorer,
    context_fraction,
    crops_to_tensor,
    extract_crops,
)


def test_extract_crops_shapes_context_and_border() -> None:
    image = np.zeros((100, 100, 3), dtype=np.uint8)
    image[40:60, 40:60] = 255
    boxes = np.array([[40.0, 40.0, 20.0, 20.0], [-10.0, -10.0, 20.0, 20.0]])
    crops = extract_crops(image, boxes, (32, 32), context=0.0)
    assert crops.shape == (2, 32, 32, 3) and crops.dtype == np.uint8
    assert crops[0].min() == 255  # exactly the white square
    assert crops[1].max() == 0  # outside the frame: the black border is replicated
    with_context = extract_crops(image, boxes[:1], (32, 32), context=32.0)
    grow = context_fraction(32.0)
    margin = 32 * grow / (1 + 2 * grow)  # the dark margin inside the crop, in crop pixels
    assert with_context[0, 0, 0].max() == 0 and with_context[0, 16, 16].min() == 255
    assert with_context[0, 16, round(margin) + 2].min() > 200
    assert with_context[0, 16, max(round(margin) - 2, 0)].max() < 60


def test_no_boxes_give_no_crops() -> None:
    crops = extract_crops(np.zeros((10, 10, 3), np.uint8), np.zeros((0, 4)), (48, 48))
    assert crops.shape == (0, 48, 48, 3)


def test_crops_to_tensor_swaps_channels_and_normalises() -> None:
    crop = np.zeros((1, 2, 2, 3), dtype=np.uint8)
    crop[..., 0] = 255  # blue in BGR
    tensor = crops_to_tensor(crop, mean=(0.5, 0.5, 0.5), std=(0.25, 0.25, 0.25), rgb=True)
    assert tensor.shape == (1, 3, 2, 2)
    assert np.allclose(tensor[0, 2], 2.0) and np.allclose(tensor[0, 0], -2.0)


def test_scorer_prefers_a_centred_bright_square(tmp_path: Path, make_scorer) -> None:
    scorer = HeadScorer(make_scorer(tmp_path / "scorer.onnx"), batch_size=2)
    assert scorer.input_size == (32, 32) and scorer.output_form == "logit"
    centred = np.zeros((32, 32, 3), dtype=np.uint8)
    centred[8:24, 8:24] = 255
    crops = np.stack([centred, 255 - centred, np.zeros_like(centred)])
    scores = scorer.score_crops(crops)  # three crops in batches of two
    assert scores.shape == (3,)
    assert scores[0] > 0.99 and scores[1] < 0.01 and scores[2] == pytest.approx(0.5, abs=1e-3)


def test_output_forms() -> None:
    scorer = HeadScorer.__new__(HeadScorer)
    scorer.output_form = "logits2"
    assert scorer.to_probability(np.array([[0.0, 0.0], [0.0, 10.0]])) == pytest.approx(
        [0.5, 1 / (1 + np.exp(-10))]
    )
    scorer.output_form = "probability"
    assert scorer.to_probability(np.array([[0.2], [1.3]])).tolist() == [0.2, 1.0]
    scorer.output_form = "logit"
    assert scorer.to_probability(np.array([0.0])).tolist() == [0.5]


def test_missing_model_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="not found"):
        HeadScorer(tmp_path / "absent.onnx")


def test_damaged_model_is_a_user_error(tmp_path: Path) -> None:
    damaged = tmp_path / "damaged.onnx"
    damaged.write_bytes(b"\x08\x01garbage" * 10)
    with pytest.raises(UserError, match="cannot be loaded"):
        HeadScorer(damaged)


def test_unexpected_inputs_and_outputs_are_user_errors(tmp_path: Path, make_constant_model) -> None:
    rank_two = make_constant_model(tmp_path / "a.onnx", {"logit": np.zeros((1, 1))}, ["N", 8])
    with pytest.raises(UserError, match="rank 4"):
        HeadScorer(rank_two)
    grey = make_constant_model(tmp_path / "b.onnx", {"logit": np.zeros((1, 1))}, ["N", 1, 32, 32])
    with pytest.raises(UserError, match="channels"):
        HeadScorer(grey)
    wide = make_constant_model(tmp_path / "c.onnx", {"logit": np.zeros((1, 5))}, ["N", 3, 32, 32])
    with pytest.raises(UserError, match="output shape"):
        HeadScorer(wide)
    dynamic = make_constant_model(
        tmp_path / "d.onnx", {"logit": np.zeros((1, 1))}, ["N", 3, "h", "w"]
    )
    with pytest.raises(UserError, match="dynamic"):
        HeadScorer(dynamic)
    fixed = make_constant_model(tmp_path / "e.onnx", {"logit": np.zeros((1, 1))}, ["N", 3, 32, 32])
    with pytest.raises(UserError, match="height"):
        HeadScorer(fixed, input_size=(48, 48))
    assert HeadScorer(dynamic, input_size=(40, 40)).input_size == (40, 40)


def test_automatic_threads_follow_omp_num_threads(monkeypatch) -> None:
    from trackfw_plugins.detectors.head_scorer import resolve_threads

    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert resolve_threads(0) == 1
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert 1 <= resolve_threads(0) <= 4
    assert resolve_threads(3) == 3


def test_min_side_widens_small_crops_about_their_centre() -> None:
    image = np.zeros((100, 100, 3), dtype=np.uint8)
    image[45:55, 45:55] = 255  # a 10-px square
    box = np.array([[45.0, 45.0, 10.0, 10.0]])
    tight = extract_crops(image, box, (20, 20), context=0.0)
    # 216 px at 1080p is 20 px on this 100-px-high frame.
    wide = extract_crops(image, box, (20, 20), context=0.0, min_crop=216.0)
    assert tight.min() == 255  # the box alone: all square
    # Twice the side: the square fills the middle half, ground around it, centred.
    assert wide[0, 10, 10, 0] == 255 and wide[0, 0, 0, 0] == 0 and wide[0, 19, 19, 0] == 0
    assert np.array_equal(wide[0], wide[0, ::-1, ::-1])
    large = np.array([[20.0, 20.0, 40.0, 40.0]])
    np.testing.assert_array_equal(
        extract_crops(image, large, (20, 20), context=0.0, min_crop=216.0),
        extract_crops(image, large, (20, 20), context=0.0),
    )

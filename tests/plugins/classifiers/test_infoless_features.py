"""Tests of the online 11-d info-less feature.

See docs/algorithms/infoless-classifier.md#feature-vector.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from trackfw_plugins.classifiers.infoless_features import (
    FEATURE_LAYOUT,
    FeatureAssembler,
    InfolessFeatureExtractor,
    OpticalFlowMeter,
    assemble_features,
    relative_change,
    spread,
    to_working_grey,
)


def textured_scene(width: int = 800, height: int = 500, seed: int = 0) -> np.ndarray:
    """A smooth random texture larger than the frames cut from it (grey uint8)."""
    noise = np.random.default_rng(seed).random((height, width)).astype(np.float32)
    blurred = cv2.GaussianBlur(noise, (0, 0), 3.0)
    blurred = (blurred - blurred.min()) / (blurred.max() - blurred.min())
    return (255 * blurred).astype(np.uint8)


def frame_at(scene: np.ndarray, dx: int, width: int = 640, height: int = 360) -> np.ndarray:
    """The ``(height, width, 3)`` BGR crop of ``scene`` shifted right by ``dx`` pixels."""
    crop = scene[40 : 40 + height, 40 + dx : 40 + dx + width]
    return np.ascontiguousarray(np.repeat(crop[:, :, None], 3, axis=2))


def test_spread_is_mean_distance_to_centroid() -> None:
    points = np.array([[0.0, 0.0], [6.0, 0.0], [3.0, 4.0]])
    centroid = points.mean(axis=0)
    expected = np.mean(np.linalg.norm(points - centroid, axis=1))
    assert spread(points) == pytest.approx(expected)
    assert spread(np.zeros((0, 2))) == 0.0


def test_relative_change_rules() -> None:
    assert relative_change(2.0, 4.0) == pytest.approx(0.5)
    assert relative_change(6.0, 4.0) == pytest.approx(0.5)
    assert relative_change(0.0, 0.0) == 0.0
    assert relative_change(3.0, 0.0, c_max=7.0) == 7.0
    assert relative_change(1000.0, 1.0, c_max=7.0) == 7.0


def test_warm_up_repeats_the_first_values() -> None:
    assembler = FeatureAssembler()
    first = assembler.push(0, 0.0, 3.0, 10.0)
    assert first.shape == (len(FEATURE_LAYOUT),) == (11,)
    assert first.tolist() == [0.0] * 5 + [3.0] * 5 + [0.0]
    assembler.mark_informative(0, True)
    second = assembler.push(1, 2.5, 4.0, 15.0)
    assert second[:5].tolist() == [0.0, 0.0, 0.0, 0.0, 2.5]
    assert second[5:10].tolist() == [3.0, 3.0, 3.0, 3.0, 4.0]
    assert second[10] == pytest.approx(0.5)


def test_history_shifts_after_five_frames() -> None:
    assembler = FeatureAssembler()
    for t in range(7):
        features = assembler.push(t, float(t), float(10 + t), 1.0)
        assembler.mark_informative(t, True)
    assert features[:5].tolist() == [2.0, 3.0, 4.0, 5.0, 6.0]
    assert features[5:10].tolist() == [12.0, 13.0, 14.0, 15.0, 16.0]


def test_reference_is_the_last_informative_frame() -> None:
    assembler = FeatureAssembler(c_max=10.0)
    assembler.push(0, 0.0, 2.0, 10.0)
    assembler.mark_informative(0, True)
    assembler.push(1, 0.0, 2.0, 40.0)
    assembler.mark_informative(1, False)  # info-less: frame 0 stays the reference
    assert assembler.push(2, 0.0, 2.0, 20.0)[10] == pytest.approx(1.0)
    assembler.mark_informative(2, True)  # informative: frame 2 becomes the reference
    assert assembler.push(3, 0.0, 2.0, 30.0)[10] == pytest.approx(0.5)


def test_a_decision_can_be_replaced() -> None:
    assembler = FeatureAssembler()
    assembler.push(0, 0.0, 2.0, 10.0)
    assembler.push(1, 0.0, 2.0, 20.0)
    assembler.mark_informative(1, True)
    assembler.mark_informative(1, False)  # the engine overrides the provisional label
    assert assembler.push(2, 0.0, 2.0, 20.0)[10] == pytest.approx(1.0)


def test_order_and_marking_are_checked() -> None:
    assembler = FeatureAssembler()
    assembler.push(3, 0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="increasing"):
        assembler.push(3, 0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="must follow"):
        assembler.mark_informative(2, True)


def test_assemble_features_matches_the_online_recursion() -> None:
    rng = np.random.default_rng(1)
    motion, counts, spreads = rng.random(20), rng.integers(0, 5, 20).astype(float), rng.random(20)
    informative = rng.random(20) > 0.3
    batch = assemble_features(motion, counts, spreads, informative, c_max=3.0)
    assembler = FeatureAssembler(c_max=3.0)
    for t in range(20):
        assert np.array_equal(batch[t], assembler.push(t, motion[t], counts[t], spreads[t]))
        assembler.mark_informative(t, bool(informative[t]))
    assert batch[:, 10].max() <= 3.0


def test_to_working_grey_keeps_the_aspect_ratio() -> None:
    image = np.zeros((720, 1280, 3), dtype=np.uint8)
    assert to_working_grey(image, 320).shape == (180, 320)
    assert to_working_grey(image[:, :, 0], 2560).shape == (1440, 2560)


@pytest.mark.parametrize(("method", "width"), [("dis", 320), ("farneback", 160)])
def test_flow_measures_a_known_shift(method: str, width: int) -> None:
    scene = textured_scene()
    meter = OpticalFlowMeter(method, width)
    assert meter.measure(frame_at(scene, 0)) == 0.0  # M_0 = 0
    still = meter.measure(frame_at(scene, 0))
    moved = meter.measure(frame_at(scene, 8))
    expected = 8 * width / 640  # the 8-pixel shift in working pixels
    assert still < 0.1 * expected
    assert moved == pytest.approx(expected, rel=0.35)


def test_extractor_gives_the_same_features_for_grey_and_colour() -> None:
    scene = textured_scene()
    frames = [frame_at(scene, dx) for dx in (0, 3, 9)]
    points = np.array([[10.0, 10.0], [30.0, 10.0]])
    colour, grey = InfolessFeatureExtractor(), InfolessFeatureExtractor()
    for t, frame in enumerate(frames):
        a = colour.update(t, frame, points)
        b = grey.update(t, frame[:, :, 0], points)
        colour.mark_informative(t, True)
        grey.mark_informative(t, True)
        assert np.array_equal(a, b)
    assert a[4] > a[3] > 0.0  # M_2 (shift 6) > M_1 (shift 3)
    assert a[9] == 2.0
    colour.reset()
    assert colour.update(0, frames[2], points)[:5].tolist() == [0.0] * 5

"""Tests of the onnx detector's input checks and output decodings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.detectors.onnx_detector import OnnxDetector, OnnxDetectorParams

FRAME = np.zeros((240, 320, 3), dtype=np.uint8)


def test_yolo_rows_are_decoded_letterboxed_and_suppressed(
    tmp_path: Path, make_constant_model
) -> None:
    # Input 320x320; a 320x240 frame is letterboxed with 40 px bands at the top and bottom.
    rows = np.array(
        [
            [[100.0, 140.0, 20.0, 40.0, 0.9, 0.9, 0.1]],  # kept
        ]
    )
    rows = np.concatenate(
        [
            rows,
            [[[102.0, 141.0, 20.0, 40.0, 0.9, 0.8, 0.1]]],  # overlaps the first: suppressed
            [[[200.0, 100.0, 30.0, 30.0, 0.4, 0.9, 0.1]]],  # 0.36 < 0.5: dropped
            [[[250.0, 200.0, 10.0, 10.0, 1.0, 0.1, 0.95]]],  # another class: dropped
        ],
        axis=1,
    )
    model = make_constant_model(tmp_path / "yolo.onnx", {"rows": rows}, [1, 3, 320, 320])
    detector = OnnxDetector(OnnxDetectorParams(model=str(model), decoding="yolo"))
    detections = detector.detect_image(FRAME)
    assert len(detections) == 1
    assert detections.boxes is not None
    assert detections.boxes[0].tolist() == pytest.approx([90.0, 80.0, 20.0, 40.0])
    assert detections.points[0].tolist() == pytest.approx([100.0, 100.0])
    assert detections.scores[0] == pytest.approx(0.81)


def test_yolov8_transposed_rows_without_objectness(tmp_path: Path, make_constant_model) -> None:
    rows = np.array([[[50.0], [60.0], [10.0], [20.0], [0.7]]])  # (1, 4 + C, N) with C = 1
    model = make_constant_model(tmp_path / "v8.onnx", {"rows": rows}, [1, 3, 240, 320])
    params = OnnxDetectorParams(model=str(model), objectness=False, point="body", transposed=True)
    detections = OnnxDetector(params).detect_image(FRAME)
    assert detections.points.ravel().tolist() == pytest.approx([50.0, 50.0 + 0.08 * 20.0])
    # Many anchors: the layout is recognised without the flag.
    many = np.zeros((1, 5, 40))
    many[0, :, 7] = [50.0, 60.0, 10.0, 20.0, 0.7]
    model = make_constant_model(tmp_path / "v8b.onnx", {"rows": many}, [1, 3, 240, 320])
    params = OnnxDetectorParams(model=str(model), objectness=False)
    detections = OnnxDetector(params).detect_image(FRAME)
    assert detections.points.ravel().tolist() == pytest.approx([50.0, 60.0])


def test_boxes_and_scores_tensors(tmp_path: Path, make_constant_model) -> None:
    outputs = {
        "boxes": np.array([[[0.1, 0.1, 0.2, 0.3], [0.5, 0.5, 0.6, 0.6]]]),
        "scores": np.array([[0.0, 3.0]]),
    }
    model = make_constant_model(tmp_path / "bs.onnx", outputs, [1, 240, 320, 3])
    params = OnnxDetectorParams(
        model=str(model),
        layout="NHWC",
        decoding="boxes_scores",
        normalised_boxes=True,
        resize="stretch",
        logits=True,
        scores_output="scores",
        boxes_output="boxes",
    )
    detections = OnnxDetector(params).detect_image(FRAME)
    assert len(detections) == 1
    assert detections.points[0].tolist() == pytest.approx([0.55 * 320, 0.55 * 240])
    assert detections.scores[0] == pytest.approx(1 / (1 + np.exp(-3.0)))


def test_score_map_decoding(tmp_path: Path, make_constant_model) -> None:
    grid = np.full((1, 1, 4, 5), -5.0)
    grid[0, 0, 2, 3] = 4.0
    model = make_constant_model(tmp_path / "map.onnx", {"map": grid}, [1, 3, "h", "w"])
    params = OnnxDetectorParams(
        model=str(model), decoding="score_map", logits=True, stride=8, window=32, scales=(0.5,)
    )
    detections = OnnxDetector(params).detect_image(FRAME)
    assert len(detections) == 1
    # Cell (row 2, column 3) at stride 8 and window 32, on a half-size image.
    assert detections.points[0].tolist() == pytest.approx([(3 * 8 + 16) / 0.5, (2 * 8 + 16) / 0.5])


def test_construction_errors(tmp_path: Path, make_constant_model) -> None:
    with pytest.raises(UserError, match="model"):
        OnnxDetector(OnnxDetectorParams())
    with pytest.raises(UserError, match="not found"):
        OnnxDetector(OnnxDetectorParams(model=str(tmp_path / "absent.onnx")))
    damaged = tmp_path / "damaged.onnx"
    damaged.write_bytes(b"nonsense")
    with pytest.raises(UserError, match="cannot be loaded"):
        OnnxDetector(OnnxDetectorParams(model=str(damaged)))
    dynamic = make_constant_model(
        tmp_path / "d.onnx", {"rows": np.zeros((1, 1, 6))}, [1, 3, "h", "w"]
    )
    with pytest.raises(UserError, match="dynamic"):
        OnnxDetector(OnnxDetectorParams(model=str(dynamic)))
    one = make_constant_model(tmp_path / "o.onnx", {"rows": np.zeros((1, 1, 6))}, [1, 3, 32, 32])
    with pytest.raises(UserError, match="outputs"):
        OnnxDetector(OnnxDetectorParams(model=str(one), decoding="boxes_scores"))
    with pytest.raises(UserError, match="no output named"):
        OnnxDetector(OnnxDetectorParams(model=str(one), boxes_output="boxes"))


def test_shipped_dense_model_runs_as_a_score_map_detector() -> None:
    from trackfw_plugins.detectors.edgebox_cnn import shipped_model_path

    dense = shipped_model_path().with_name("head_cnn_dense.onnx")
    params = OnnxDetectorParams(
        model=str(dense),
        decoding="score_map",
        logits=True,
        mean=(0.5, 0.5, 0.5),
        std=(0.25, 0.25, 0.25),
        scales=(1.0, 0.5),
    )
    detections = OnnxDetector(params).detect_image(np.full((120, 160, 3), 128, np.uint8))
    assert len(detections) == 0  # a flat grey frame has no head


def test_model_input_shape_is_checked_at_validation(
    tmp_path: Path, make_constant_model, capsys: pytest.CaptureFixture[str]
) -> None:
    from trackfw.cli import main

    # A 1-channel 7x5 model: before, validate passed and frame 1 failed with a traceback.
    model = make_constant_model(tmp_path / "grey.onnx", {"rows": np.zeros((1, 1, 6))}, [1, 1, 7, 5])
    pipeline = tmp_path / "onnx.yaml"
    pipeline.write_text(
        "name: onnx\nstages:\n"
        f"  detector: {{type: onnx, params: {{model: {str(model)!r}}}}}\n"
        "  classifier: {type: flow-threshold}\n  tracker: {type: kalman}\n"
        "  gap_matcher: {type: assignment}\n"
    )
    assert main(["validate", str(pipeline)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and str(model) in lines[0], lines
    assert "[1, 1, 7, 5]" in lines[0] and "3 channels" in lines[0], lines[0]
    nhwc = make_constant_model(tmp_path / "nhwc.onnx", {"rows": np.zeros((1, 1, 6))}, [1, 7, 5, 1])
    with pytest.raises(UserError, match=r"\[1, 7, 5, 1\].*expected \(1, H, W, 3\)"):
        OnnxDetector(OnnxDetectorParams(model=str(nhwc), layout="NHWC"))
    fixed = make_constant_model(
        tmp_path / "fixed.onnx", {"rows": np.zeros((1, 1, 6))}, [1, 3, 64, 64]
    )
    with pytest.raises(UserError, match=r"input_width 32.*64"):
        OnnxDetector(OnnxDetectorParams(model=str(fixed), input_width=32))
    # A model that fits runs on a frame.
    good = OnnxDetector(OnnxDetectorParams(model=str(fixed)))
    assert len(good.detect_image(FRAME)) == 0

"""Tests of the yolox detector: decoding, letterbox geometry, tiles, shipped models, bad models."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.cli import main
from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, HEAD_SIZE_FRACTION
from trackfw_plugins.detectors.yolox import (
    SHIPPED_MODELS,
    YoloxDetector,
    YoloxParams,
    anchor_grid,
    shipped_model_path,
    tile_boxes,
)

MODELS = Path(__file__).resolve().parents[3] / "plugins" / "detectors" / "models"


def _rows_model(tmp_path: Path, make_constant_model, rows: np.ndarray, side: int = 64) -> Path:
    return make_constant_model(tmp_path / "rows.onnx", {"output": rows[None]}, [1, 3, side, side])


def test_a_row_is_decoded_on_its_grid_cell_and_mapped_back_through_the_letterbox(
    tmp_path: Path, make_constant_model
) -> None:
    cells, strides = anchor_grid(64)
    rows = np.zeros((len(cells), 6))
    # The stride-16 cell (column 1, row 2): centre ((0.5 + 1) * 16, (0.25 + 2) * 16) = (24, 36),
    # size (exp(0) * 16, exp(log 2) * 16) = (16, 32) in input pixels; score 0.9 * 0.8.
    index = 64 + 2 * 4 + 1
    assert cells[index].tolist() == [1.0, 2.0] and strides[index] == 16
    rows[index] = [0.5, 0.25, 0.0, np.log(2.0), 0.9, 0.8]
    rows[0] = [0.0, 0.0, 0.0, 0.0, 0.5, 0.5]  # 0.25 < threshold 0.3
    model = _rows_model(tmp_path, make_constant_model, rows)
    detector = YoloxDetector(YoloxParams(model=str(model), score_threshold=0.3))
    # A 128x96 frame letterboxed into 64x64: scale 0.5, image at the top-left, no offset.
    frame = np.zeros((96, 128, 3), dtype=np.uint8)
    bodies, scores = detector.detect_bodies(frame)
    assert bodies.ravel().tolist() == pytest.approx([32.0, 40.0, 32.0, 64.0])
    assert scores.tolist() == pytest.approx([0.72])
    detections = detector.detect_image(frame)
    assert detections.points.ravel().tolist() == pytest.approx([48.0, 40.0 + HEAD_FRACTION * 64])
    side = HEAD_SIZE_FRACTION * 64
    assert detections.boxes is not None
    assert detections.boxes[0, 2:].tolist() == pytest.approx([side, side])
    assert (detections.boxes[0, :2] + side / 2).tolist() == pytest.approx(
        detections.points[0].tolist()
    )


def test_overlapping_rows_are_suppressed_and_other_classes_ignored(
    tmp_path: Path, make_constant_model
) -> None:
    cells, _ = anchor_grid(64)
    rows = np.zeros((len(cells), 7))
    rows[10] = [0.5, 0.5, 1.0, 1.0, 0.9, 0.9, 0.0]
    rows[11] = [-0.5, 0.5, 1.0, 1.0, 0.9, 0.8, 0.0]  # the same box one cell left: suppressed
    rows[40] = [0.5, 0.5, 0.0, 0.0, 0.9, 0.0, 0.9]  # class 1 only
    model = _rows_model(tmp_path, make_constant_model, rows)
    bodies, scores = YoloxDetector(YoloxParams(model=str(model))).detect_bodies(
        np.zeros((64, 64, 3), np.uint8)
    )
    assert len(bodies) == 1 and scores[0] == pytest.approx(0.81)
    other = YoloxDetector(YoloxParams(model=str(model), class_index=1))
    assert len(other.detect_bodies(np.zeros((64, 64, 3), np.uint8))[0]) == 1


def test_tiles_cover_the_frame_with_the_requested_overlap() -> None:
    tiles = tile_boxes(1920, 1080, 3, 2, 0.2)
    assert len(tiles) == 6
    covered = np.zeros((1080, 1920), dtype=bool)
    for left, top, width, height in tiles:
        assert left + width <= 1920 and top + height <= 1080
        covered[top : top + height, left : left + width] = True
    assert covered.all()
    (l0, _, w0, _), (l1, _, _, _) = tiles[0], tiles[1]
    assert (l0 + w0 - l1) / w0 == pytest.approx(0.2, abs=0.01)


@pytest.mark.parametrize(
    ("content", "message"),
    [(None, "model file not found"), (b"\x00\x01 not onnx", "not a loadable ONNX model")],
)
def test_missing_or_damaged_model_is_one_line_naming_the_file(
    tmp_path: Path, content: bytes | None, message: str
) -> None:
    path = tmp_path / "person.onnx"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(UserError) as error:
        YoloxDetector(YoloxParams(model=str(path)))
    assert len(error.value.lines) == 1
    assert str(path) in error.value.lines[0] and message in error.value.lines[0]


@pytest.mark.parametrize(
    ("outputs", "input_shape", "message"),
    [
        ({"output": np.zeros((1, 84, 6))}, [1, 3, 64], r"inputs are \[\[1, 3, 64\]\]"),
        ({"output": np.zeros((84, 6))}, [1, 3, 64, 64], r"outputs are \[\[84, 6\]\]"),
        ({"output": np.zeros((1, 84, 4))}, [1, 3, 64, 64], "4 columns"),
        ({"output": np.zeros((1, 84, 6))}, [1, 3, 64, 96], "square"),
    ],
)
def test_model_of_the_wrong_shape_fails_at_construction(
    tmp_path: Path, make_constant_model, outputs, input_shape, message: str
) -> None:
    model = make_constant_model(tmp_path / "wrong.onnx", outputs, input_shape)
    with pytest.raises(UserError, match=message):
        YoloxDetector(YoloxParams(model=str(model)))


def test_anchor_count_that_does_not_fit_the_strides_is_reported(
    tmp_path: Path, make_constant_model
) -> None:
    model = make_constant_model(
        tmp_path / "few.onnx", {"output": np.zeros((1, 50, 6))}, [1, 3, 64, 64]
    )
    detector = YoloxDetector(YoloxParams(model=str(model)))
    with pytest.raises(UserError, match=r"few\.onnx: output is \[1, 50, 6\]; expected \(1, 84"):
        detector.detect_image(np.zeros((64, 64, 3), np.uint8))


def test_bad_model_in_a_pipeline_fails_validation_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pipeline = tmp_path / "p.yaml"
    pipeline.write_text(
        "name: p\nstages:\n"
        f"  detector: {{type: yolox, params: {{model: {tmp_path / 'none.onnx'}}}}}\n"
        "  classifier: {type: oracle}\n  tracker: {type: kalman}\n"
        "  gap_matcher: {type: window-tps-rpm}\n"
    )
    assert main(["validate", str(pipeline)]) == 2
    err = capsys.readouterr().err
    assert "none.onnx" in err and "model file not found" in err
    pipeline.write_text(pipeline.read_text().replace("model: ", "tiles: 3by2, model: "))
    assert main(["validate", str(pipeline)]) == 2
    assert "tiles" in capsys.readouterr().err


def test_shipped_models_are_the_files_the_notice_names() -> None:
    notice = (MODELS / "NOTICE").read_text()
    for name in SHIPPED_MODELS:
        path = shipped_model_path(name)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        block = notice.split(path.name, 1)[1]
        assert re.search(r"SHA256: ([0-9a-f]{64})", block).group(1) == digest  # type: ignore[union-attr]
        licence = re.search(r"Licence: (\S+)", block).group(1)  # type: ignore[union-attr]
        assert "Apache License" in (MODELS / licence).read_text()


def _iou(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    a0, a1 = first[:, None, :2], first[:, None, :2] + first[:, None, 2:]
    b0, b1 = second[None, :, :2], second[None, :, :2] + second[None, :, 2:]
    overlap = np.clip(np.minimum(a1, b1) - np.maximum(a0, b0), 0, None).prod(axis=2)
    union = first[:, None, 2:].prod(axis=2) + second[None, :, 2:].prod(axis=2) - overlap
    return overlap / union


@pytest.mark.parametrize(
    ("model", "input_size"), [("yolox-nano", 0), ("light-person-192", 0), ("yolox-nano", 640)]
)
def test_shipped_models_find_the_people_of_a_real_frame(
    shared_data: Path, model: str, input_size: int
) -> None:
    sequence = shared_data / "TUD-Stadtmitte"
    image = cv2.imread(str(sequence / "img1" / "000001.jpg"))
    gt = np.loadtxt(sequence / "gt" / "gt.txt", delimiter=",")
    truth = gt[gt[:, 0] == 1][:, 2:6]
    detector = YoloxDetector(YoloxParams(model=model, input_size=input_size, threads=1))
    bodies, _ = detector.detect_bodies(image)
    matched = (_iou(truth, bodies) >= 0.5).any(axis=1) if len(bodies) else np.zeros(len(truth))
    assert matched.mean() >= 0.6, (model, input_size, matched)
    assert len(bodies) <= len(truth) + 2


def test_a_wide_frame_runs_on_a_stride_padded_input_and_maps_back(
    tmp_path: Path, make_constant_model
) -> None:
    # A 128x64 frame at input 64: scale 0.5, 64x32 of image. 'stride' runs the network on
    # 64 columns x 32 rows (42 anchors), 'square' on 64x64 (84 anchors).
    cells, strides = anchor_grid(32, 64)
    rows = np.zeros((len(cells), 6))
    index = 32 + 7  # stride 16, column 3, row 1: centre (3.5 * 16, 1.5 * 16) = (56, 24)
    assert cells[index].tolist() == [3.0, 1.0] and strides[index] == 16
    rows[index] = [0.5, 0.5, 0.0, 0.0, 0.9, 0.9]
    model = _rows_model(tmp_path, make_constant_model, rows)
    frame = np.zeros((64, 128, 3), dtype=np.uint8)
    bodies, _ = YoloxDetector(YoloxParams(model=str(model))).detect_bodies(frame)
    # Input pixels (48, 16, 16, 16) at scale 0.5 -> frame pixels.
    assert bodies.ravel().tolist() == pytest.approx([96.0, 32.0, 32.0, 32.0])
    square = YoloxDetector(YoloxParams(model=str(model), padding="square"))
    with pytest.raises(UserError, match=r"expected \(1, 84, 5 \+ C\) rows .* at input 64x64"):
        square.detect_bodies(frame)


def test_an_export_with_a_fixed_size_graph_asks_for_square_padding(tmp_path: Path) -> None:
    import onnx
    from onnx import helper

    # The rows reshaped to a fixed (1, 2048, 6): the graph runs only at its 64x64 input.
    shape = helper.make_tensor("shape", onnx.TensorProto.INT64, [3], [1, 2048, 6])
    graph = helper.make_graph(
        [helper.make_node("Reshape", ["image", "shape"], ["output"])],
        "fixed",
        [helper.make_tensor_value_info("image", onnx.TensorProto.FLOAT, [1, 3, 64, 64])],
        [helper.make_tensor_value_info("output", onnx.TensorProto.FLOAT, [1, 2048, 6])],
        [shape],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    path = tmp_path / "fixed.onnx"
    onnx.save(model, str(path))
    frame = np.zeros((64, 128, 3), dtype=np.uint8)  # runs at 64x32 with stride padding
    with pytest.raises(UserError, match=r"fixed\.onnx: the model does not run at input 64x32 \(width x height.*padding: square"):
        YoloxDetector(YoloxParams(model=str(path))).detect_bodies(frame)
    # At its own square input it runs (and its 2048 rows are then refused as not YOLOX's grid).
    with pytest.raises(UserError, match=r"expected \(1, 84, 5 \+ C\) rows"):
        YoloxDetector(YoloxParams(model=str(path), padding="square")).detect_bodies(frame)


def test_stride_padding_finds_the_people_square_padding_finds(shared_data: Path) -> None:
    image = cv2.imread(str(shared_data / "TUD-Stadtmitte" / "img1" / "000001.jpg"))
    wide = cv2.copyMakeBorder(image, 0, 0, 160, 160, cv2.BORDER_REFLECT)  # 960x480: 416x224
    square = YoloxDetector(YoloxParams(padding="square", threads=1)).detect_bodies(wide)[0]
    stride = YoloxDetector(YoloxParams(padding="stride", threads=1)).detect_bodies(wide)[0]
    assert len(square) >= 4
    assert (_iou(square, stride) >= 0.8).any(axis=1).mean() >= 0.9


def test_tiled_detection_keeps_each_person_once(shared_data: Path) -> None:
    image = cv2.imread(str(shared_data / "TUD-Stadtmitte" / "img1" / "000001.jpg"))
    large = cv2.resize(image, None, fx=2.0, fy=2.0)
    plain = YoloxDetector(YoloxParams(threads=1)).detect_bodies(large)[0]
    tiled = YoloxDetector(YoloxParams(tiles="2x2", threads=1)).detect_bodies(large)[0]
    assert len(plain) >= 4
    # Every person of the whole-frame pass is still there, and no one is found twice.
    assert (_iou(plain, tiled) >= 0.5).any(axis=1).all()
    overlap = _iou(tiled, tiled)
    np.fill_diagonal(overlap, 0.0)
    assert overlap.max() < 0.45

"""The person-reid descriptor: shipped embedders, body boxes from head points, bad models."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.formats import HEAD_SIZE_FRACTION
from trackfw.records import Detections
from trackfw_plugins.maths.person_reid import (
    PERSON_REID_MODELS,
    PersonReidEmbedder,
    body_boxes,
    cosine_distance_matrix,
    person_reid_model_path,
)

MODELS = Path(__file__).resolve().parents[3] / "plugins" / "maths" / "models"


def test_shipped_embedders_are_the_files_the_notice_names() -> None:
    notice = (MODELS / "NOTICE").read_text()
    for name in PERSON_REID_MODELS:
        path = person_reid_model_path(name)
        block = notice.split(path.name + "\n", 1)[1]
        digest = re.search(r"SHA256: ([0-9a-f]{64})", block).group(1)  # type: ignore[union-attr]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == digest
        licence = re.search(r"Licence: (\S+)", block).group(1)  # type: ignore[union-attr]
        assert "Apache License" in (MODELS / licence).read_text()


def test_embeddings_have_unit_length_and_identical_crops_distance_zero() -> None:
    embedder = PersonReidEmbedder("0248", threads=1)
    crops = np.random.default_rng(0).integers(0, 255, (3, 256, 128, 3)).astype(np.uint8)
    crops[2] = crops[0]
    embeddings = embedder.embed(crops)
    assert embeddings.shape == (3, 256)
    assert np.linalg.norm(embeddings, axis=1) == pytest.approx(np.ones(3))
    distances = cosine_distance_matrix(embeddings, embeddings)
    assert distances[0, 2] == pytest.approx(0.0, abs=1e-6)
    assert distances[0, 1] > 0.01
    assert embedder.embed(np.zeros((0, 256, 128, 3), np.uint8)).shape == (0, 256)


def test_crops_embedded_side_by_side_are_those_embedded_one_by_one() -> None:
    crops = np.random.default_rng(1).integers(0, 255, (4, 256, 128, 3)).astype(np.uint8)
    alone = PersonReidEmbedder("0248", threads=1).embed(crops)
    np.testing.assert_array_equal(PersonReidEmbedder("0248", threads=3).embed(crops), alone)


def test_body_boxes_from_head_boxes_body_boxes_and_fallbacks() -> None:
    points = np.array([[100.0, 50.0], [300.0, 60.0], [500.0, 70.0]])
    detections = Detections(
        points=points[:2],
        scores=np.ones(2),
        boxes=np.array([[94.0, 44.0, 12.0, 12.0], [280.0, 40.0, 40.0, 120.0]]),
    )
    boxes = body_boxes(points, detections, np.array([0, 1, -1]), fallback_size=99.0)
    # A square head box of side 12 gives a body 12 / HEAD_SIZE_FRACTION tall, 1:2 wide, centred on the head.
    height = 12.0 / HEAD_SIZE_FRACTION
    assert boxes[0, 3] == pytest.approx(height) and boxes[0, 2] == pytest.approx(height / 2)
    assert boxes[0, 0] + boxes[0, 2] / 2 == pytest.approx(100.0)
    # A tall box is already a body box.
    assert boxes[1].tolist() == [280.0, 40.0, 40.0, 120.0]
    # No detection: the median head size of the frame (12 and HEAD_SIZE_FRACTION * 120).
    assert boxes[2, 3] == pytest.approx(
        np.median([12.0, HEAD_SIZE_FRACTION * 120.0]) / HEAD_SIZE_FRACTION
    )
    alone = body_boxes(points[:1], None, np.array([-1]), fallback_size=HEAD_SIZE_FRACTION * 100)
    assert alone[0, 3] == pytest.approx(100.0)


def _nchw_model(path: Path) -> Path:
    """A valid ONNX model with an NCHW (1, 3, 256, 128) input: the wrong layout."""
    onnx = pytest.importorskip("onnx")
    helper = onnx.helper
    graph = helper.make_graph(
        [helper.make_node("ReduceMean", ["image"], ["e"], axes=[2, 3], keepdims=0)],
        "nchw",
        [helper.make_tensor_value_info("image", onnx.TensorProto.FLOAT, [1, 3, 256, 128])],
        [helper.make_tensor_value_info("e", onnx.TensorProto.FLOAT, [1, 3])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return path


def test_missing_or_misshapen_embedder_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(UserError, match=r"nothing\.onnx: model file not found"):
        PersonReidEmbedder(str(tmp_path / "nothing.onnx"))
    (tmp_path / "text.onnx").write_text("hello")
    with pytest.raises(UserError, match=r"text\.onnx: not a loadable ONNX model"):
        PersonReidEmbedder(str(tmp_path / "text.onnx"))
    wrong = _nchw_model(tmp_path / "nchw.onnx")
    with pytest.raises(UserError, match=r"nchw\.onnx: model inputs are \[\[1, 3, 256, 128\]\]"):
        PersonReidEmbedder(str(wrong))


@pytest.mark.parametrize("model", sorted(PERSON_REID_MODELS))
def test_same_person_is_closer_than_others_on_real_frames(shared_data: Path, model: str) -> None:
    sequence = shared_data / "TUD-Stadtmitte"
    gt = np.loadtxt(sequence / "gt" / "gt.txt", delimiter=",")
    embedder = PersonReidEmbedder(model, threads=1)
    embeddings, identities = [], []
    for frame in (1, 40, 80):
        image = cv2.imread(str(sequence / "img1" / f"{frame:06d}.jpg"))
        rows = gt[gt[:, 0] == frame]
        boxes = rows[:, 2:6].copy()
        # The gt boxes are tight; the embedders take 1:2 crops around the person.
        boxes[:, 0] += boxes[:, 2] / 2 - boxes[:, 3] / 4
        boxes[:, 2] = boxes[:, 3] / 2
        embeddings.append(embedder.describe(image, boxes))
        identities.append(rows[:, 1])
    vectors, ids = np.concatenate(embeddings), np.concatenate(identities)
    distances = cosine_distance_matrix(vectors, vectors)
    same = ids[:, None] == ids[None, :]
    off_diagonal = ~np.eye(len(ids), dtype=bool)
    assert distances[same & off_diagonal].mean() < 0.75 * distances[~same].mean()

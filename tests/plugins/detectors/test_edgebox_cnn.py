"""Tests of the edgebox-cnn detector: construction checks and detection on synthetic frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from trackfw.errors import UserError
from trackfw.records import FrameData, VideoContext
from trackfw_plugins.detectors.edgebox_cnn import (
    EdgeBoxCnnDetector,
    EdgeBoxCnnParams,
    shipped_model_path,
)

CENTRES = [(100.0, 100.0), (300.0, 200.0), (500.0, 120.0)]


def test_params_have_defaults_and_reject_unknown_keys() -> None:
    params = EdgeBoxCnnParams()
    assert params.score_threshold == 0.7 and params.nms_iou == 0.3
    assert params.context is None and params.min_crop is None  # read from the model
    assert params.intra_op_threads == 0
    with pytest.raises(ValidationError):
        EdgeBoxCnnParams(unknown=1)


def test_shipped_model_loads() -> None:
    assert shipped_model_path().is_file()
    detector = EdgeBoxCnnDetector()
    assert detector.scorer.input_size[0] in (32, 48) and detector.needs_pixels
    # The shipped model records the crops it was trained on (models/README.md).
    assert detector.scorer.crop_settings == {"context": 16.0, "min_crop": 16.0}
    assert (detector.context, detector.min_crop) == (16.0, 16.0)


def _with_crop_metadata(path: Path, source: Path, **values: str) -> Path:
    onnx = pytest.importorskip("onnx")
    model = onnx.load(str(source))
    for name, value in values.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = f"trackfw.{name}", value
    onnx.save(model, str(path))
    return path


def test_crop_settings_come_from_the_model_unless_configured(tmp_path: Path, make_scorer) -> None:
    plain = make_scorer(tmp_path / "plain.onnx")
    detector = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(plain)))
    assert (detector.context, detector.min_crop) == (16.0, 0.0)  # no record: the defaults
    configured = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(plain), min_crop=12, context=8))
    assert (configured.context, configured.min_crop) == (8.0, 12.0)
    recorded = _with_crop_metadata(tmp_path / "r.onnx", plain, context="10.0", min_crop="24.0")
    detector = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(recorded)))
    assert (detector.context, detector.min_crop) == (10.0, 24.0)
    same = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(recorded), min_crop=24))
    assert same.min_crop == 24.0


def test_crop_setting_that_contradicts_the_model_fails_at_construction(
    tmp_path: Path, make_scorer
) -> None:
    plain = make_scorer(tmp_path / "plain.onnx")
    recorded = _with_crop_metadata(tmp_path / "r.onnx", plain, min_crop="16.0")
    with pytest.raises(UserError, match=r"r\.onnx: the model was trained with min_crop 16"):
        EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(recorded), min_crop=0))
    damaged = _with_crop_metadata(tmp_path / "d.onnx", plain, context="wide")
    with pytest.raises(UserError, match=r"d\.onnx: metadata trackfw.context is 'wide'"):
        EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(damaged)))


@pytest.mark.parametrize("content", [None, b"", b"\x00\x01 not onnx"])
def test_missing_or_damaged_model_fails_at_construction(tmp_path: Path, content) -> None:
    path = tmp_path / "model.onnx"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(UserError, match=str(path.name)):
        EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(path)))


def test_model_with_unexpected_input_fails_at_construction(
    tmp_path: Path, make_constant_model
) -> None:
    model = make_constant_model(tmp_path / "m.onnx", {"logit": np.zeros((1, 1))}, [1, 3, 64])
    with pytest.raises(UserError, match="rank 4"):
        EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(model)))


def test_detects_each_disc_once_near_its_centre(
    tmp_path: Path, make_scorer, make_disc_image
) -> None:
    model = make_scorer(tmp_path / "scorer.onnx")
    # EdgeBoxes alone (the paper's proposals): the toy scorer is not discriminative enough to
    # sort out the many blob boxes around each disc.
    detector = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(model), work_width=640, blob_width=0))
    video = VideoContext(name="discs", path=str(tmp_path), n_frames=1, width=640, height=360)
    detections = detector.detect(FrameData(t=0, image=make_disc_image(CENTRES), video=video))
    assert detections.boxes is not None and len(detections) >= len(CENTRES)
    assert ((detections.scores >= 0.5) & (detections.scores <= 1)).all()
    centres = np.asarray(CENTRES)
    distance = np.linalg.norm(detections.points[:, None] - centres[None], axis=2)
    assert (distance.min(axis=0) < 4).all()  # every disc (diameter 24) found near its centre
    assert (distance.min(axis=1) < 12 + 2).all()  # and nothing off the discs (radius 12)
    box_centres = detections.boxes[:, :2] + detections.boxes[:, 2:] / 2
    assert np.allclose(box_centres, detections.points)
    assert detector.last_timing["proposed"] > 0


def test_frame_without_pixels_is_a_user_error(tmp_path: Path, make_scorer) -> None:
    detector = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(make_scorer(tmp_path / "s.onnx"))))
    video = VideoContext(name="v", path=str(tmp_path), n_frames=1, width=640, height=360)
    with pytest.raises(UserError, match="pixels"):
        detector.detect(FrameData(t=0, image=None, video=video))


def test_blank_frame_gives_no_detection(tmp_path: Path, make_scorer) -> None:
    detector = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=str(make_scorer(tmp_path / "s.onnx"))))
    detections = detector.detect_image(np.full((360, 640, 3), 80, dtype=np.uint8))
    assert len(detections) == 0 and detections.points.shape == (0, 2)


def test_overlapped_proposals_give_the_sequential_result(
    tmp_path: Path, make_scorer, make_disc_image
) -> None:
    image = make_disc_image(CENTRES)
    model = str(make_scorer(tmp_path / "scorer.onnx"))
    overlapped = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=model, overlap_proposals=True))
    sequential = EdgeBoxCnnDetector(EdgeBoxCnnParams(model=model, overlap_proposals=False))
    first, second = overlapped.detect_image(image), sequential.detect_image(image)
    assert len(first) > 0
    np.testing.assert_array_equal(first.points, second.points)
    np.testing.assert_array_equal(first.scores, second.scores)
    timing = overlapped.last_timing
    assert timing["proposed"] == len(overlapped.proposals(image)) > 0
    assert timing["edge_boxes"] > 0 and timing["blobs"] > 0 and timing["scoring"] > 0

"""The ``onnx`` detector: a user's own ONNX detection model, with configurable decoding.

See docs/algorithms/detectors.md#onnx-detector.

The frame is resized (stretched or letterboxed) to the model's input, scaled, normalised and laid
out as NCHW or NHWC. Outputs are decoded as one of:

* ``boxes_scores``: a boxes tensor ``(1, N, 4)`` / ``(N, 4)`` and a scores tensor ``(1, N)`` /
  ``(N,)`` / ``(N, C)`` (the class column ``class_index`` is used);
* ``yolo``: one tensor of rows ``(cx, cy, w, h, objectness, class scores...)``, ``(1, N, 5+C)``
  (YOLOv5 style); with ``objectness = false`` rows are ``(cx, cy, w, h, class scores...)``
  (YOLOv8 style, ``(1, 4+C, N)`` is transposed automatically);
* ``score_map``: a dense classifier map ``(1, 1, H', W')`` of logits, one window of
  ``window`` px every ``stride`` px, run over an image pyramid (``scales``); for a fully
  convolutional head classifier.

Then score threshold, ``cv2.dnn.NMSBoxes``, and the head point of each box (``point``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from trackfw.arrays import FloatArray
from trackfw.errors import UserError
from trackfw.records import Detections, FrameData
from trackfw.stages import Detector, StageParams
from trackfw_plugins.detectors.boxes import (
    detections_from_boxes,
    frame_pixels,
    non_maximum_suppression,
)
from trackfw_plugins.detectors.head_scorer import context_fraction, open_onnx_session


class OnnxDetectorParams(StageParams):
    """Parameters of the ``onnx`` detector."""

    model: str = Field("", description="Path of the ONNX detection model (required).")
    input_width: int = Field(0, ge=0, description="Model input width (px); 0 = from the model.")
    input_height: int = Field(0, ge=0, description="Model input height (px); 0 = from the model.")
    layout: Literal["NCHW", "NHWC"] = Field("NCHW", description="Input tensor layout.")
    rgb: bool = Field(True, description="Feed RGB (true) or BGR (false) channels.")
    resize: Literal["stretch", "letterbox"] = Field(
        "letterbox", description="Fit the frame by stretching or by letterboxing (pad 114)."
    )
    pixel_scale: float = Field(1 / 255, gt=0, description="Pixels are multiplied by this first.")
    mean: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="Per-channel mean subtracted after scaling."
    )
    std: tuple[float, float, float] = Field(
        (1.0, 1.0, 1.0), description="Per-channel std divided by after the mean."
    )
    decoding: Literal["boxes_scores", "yolo", "score_map"] = Field(
        "yolo", description="Output form: boxes_scores, yolo rows, or a dense score_map."
    )
    boxes_output: str = Field(
        "", description="boxes_scores: name of the boxes output; empty = the first output."
    )
    scores_output: str = Field(
        "", description="boxes_scores: name of the scores output; empty = the second output."
    )
    box_format: Literal["xyxy", "xywh", "cxcywh"] = Field(
        "xyxy", description="boxes_scores: box coordinates (yolo rows are always cxcywh)."
    )
    normalised_boxes: bool = Field(
        False, description="Box coordinates are in [0, 1] of the input size."
    )
    objectness: bool = Field(True, description="yolo: rows carry an objectness column.")
    transposed: bool | None = Field(
        None,
        description="yolo: output is (attributes, N) as YOLOv8 exports it; None = guess"
        " (transposed when it has more columns than rows).",
    )
    class_index: int = Field(0, ge=0, description="Class whose score is used (person/head).")
    logits: bool = Field(False, description="Apply a sigmoid to the scores.")
    scales: tuple[float, ...] = Field(
        (1.0,), description="score_map: image pyramid scales (input size is then ignored)."
    )
    stride: int = Field(8, ge=1, description="score_map: output cell stride in input px.")
    window: int = Field(32, ge=1, description="score_map: window side in input px.")
    context: float = Field(
        16.0, ge=0, lt=112, description="score_map: R-CNN context inside the window (224-px px)."
    )
    point: Literal["centre", "body", "top"] = Field(
        "centre",
        description="Head point of a box: centre, body (the head-point rule, top + 0.08 h) or top.",
    )
    score_threshold: float = Field(0.5, ge=0, le=1, description="Score threshold.")
    nms_iou: float = Field(0.3, gt=0, le=1, description="IoU threshold of cv2.dnn.NMSBoxes.")
    intra_op_threads: int = Field(
        0,
        ge=0,
        description="onnxruntime intra-op threads; 0 = OMP_NUM_THREADS if set (1 in bench"
        " workers), else the CPU count (at most 4).",
    )


class OnnxDetector(Detector[OnnxDetectorParams]):
    """A user-supplied ONNX detector (YOLO-style rows, boxes+scores tensors, or a score map)."""

    name = "onnx"
    uses_pixels = True

    def __init__(self, params: OnnxDetectorParams | None = None) -> None:
        super().__init__(params)
        settings = self.params
        if not settings.model:
            raise UserError("onnx detector: field 'model' is empty; expected an ONNX file path.")
        path = Path(settings.model).expanduser()
        self.session = open_onnx_session(path, settings.intra_op_threads, "an ONNX detector")
        inputs = self.session.get_inputs()
        if len(inputs) != 1 or len(inputs[0].shape) != 4:
            raise UserError(
                f"{path}: model inputs are {[list(i.shape) for i in inputs]}; expected one"
                " image input of rank 4."
            )
        self.input_name = inputs[0].name
        shape = inputs[0].shape
        height_axis, width_axis = (2, 3) if settings.layout == "NCHW" else (1, 2)
        _check_input_shape(path, list(shape), settings)
        self.input_height = settings.input_height or _static(shape[height_axis])
        self.input_width = settings.input_width or _static(shape[width_axis])
        if settings.decoding != "score_map" and not (self.input_height and self.input_width):
            raise UserError(
                f"{path}: model input size is dynamic; set input_width and input_height."
            )
        self.output_names = [output.name for output in self.session.get_outputs()]
        wanted = 2 if settings.decoding == "boxes_scores" else 1
        if len(self.output_names) < wanted:
            raise UserError(
                f"{path}: model has {len(self.output_names)} outputs; decoding"
                f" {settings.decoding!r} expects at least {wanted}."
            )
        for name in (settings.boxes_output, settings.scores_output):
            if name and name not in self.output_names:
                raise UserError(
                    f"{path}: no output named {name!r}; the model has {self.output_names}."
                )
        self.path = path

    # ------------------------------------------------------------------ input
    def _tensor(self, image: np.ndarray) -> NDArray[np.float32]:
        pixels = image[..., ::-1] if self.params.rgb else image
        scaled = pixels.astype(np.float32) * np.float32(self.params.pixel_scale)
        normalised = (scaled - np.asarray(self.params.mean, np.float32)) / np.asarray(
            self.params.std, np.float32
        )
        tensor = normalised[None]
        if self.params.layout == "NCHW":
            tensor = tensor.transpose(0, 3, 1, 2)
        return np.ascontiguousarray(tensor, dtype=np.float32)

    def _fit(self, image: np.ndarray) -> tuple[np.ndarray, float, float, float, float]:
        """Resize to the input; returns the image and (scale_x, scale_y, pad_x, pad_y)."""
        height, width = image.shape[:2]
        target_w, target_h = self.input_width, self.input_height
        if self.params.resize == "stretch":
            resized = cv2.resize(image, (target_w, target_h), interpolation=cv2.INTER_LINEAR)
            return resized, target_w / width, target_h / height, 0.0, 0.0
        scale = min(target_w / width, target_h / height)
        new_w, new_h = round(width * scale), round(height * scale)
        resized = cv2.resize(image, (new_w, new_h), interpolation=cv2.INTER_LINEAR)
        pad_x, pad_y = (target_w - new_w) // 2, (target_h - new_h) // 2
        canvas = np.full((target_h, target_w, 3), 114, dtype=np.uint8)
        canvas[pad_y : pad_y + new_h, pad_x : pad_x + new_w] = resized
        return canvas, scale, scale, float(pad_x), float(pad_y)

    # ----------------------------------------------------------------- decode
    def _scores(self, values: FloatArray) -> FloatArray:
        if self.params.logits:
            return np.asarray(1.0 / (1.0 + np.exp(-values)), dtype=np.float64)
        return values

    def _decode_boxes_scores(self, outputs: dict[str, np.ndarray]) -> tuple[FloatArray, FloatArray]:
        boxes_name = self.params.boxes_output or self.output_names[0]
        scores_name = self.params.scores_output or self.output_names[1]
        boxes = np.asarray(outputs[boxes_name], dtype=np.float64).reshape(-1, 4)
        scores = np.asarray(outputs[scores_name], dtype=np.float64)
        scores = scores.reshape(len(boxes), -1) if scores.size else scores.reshape(0, 1)
        column = min(self.params.class_index, scores.shape[1] - 1) if scores.shape[1] else 0
        return _to_xywh(boxes, self.params.box_format), self._scores(scores[:, column])

    def _decode_yolo(self, outputs: dict[str, np.ndarray]) -> tuple[FloatArray, FloatArray]:
        rows = np.asarray(outputs[self.output_names[0]], dtype=np.float64)
        rows = rows.reshape(rows.shape[-2], rows.shape[-1]) if rows.ndim == 3 else rows
        first = 5 if self.params.objectness else 4
        transposed = self.params.transposed
        if transposed is None:
            # YOLOv8 exports (4 + C, N) with N (thousands of anchors) much larger than 4 + C.
            transposed = rows.shape[1] > rows.shape[0] and rows.shape[0] >= first
        if transposed:
            rows = rows.T
        if rows.shape[1] <= first + self.params.class_index:
            raise UserError(
                f"{self.path}: output rows have {rows.shape[1]} columns; expected"
                f" {first} + classes (class_index {self.params.class_index})."
            )
        class_scores = self._scores(rows[:, first + self.params.class_index])
        if self.params.objectness:
            class_scores = class_scores * self._scores(rows[:, 4])
        return _to_xywh(rows[:, :4], "cxcywh"), class_scores

    def _score_map(self, image: NDArray[np.uint8]) -> tuple[FloatArray, FloatArray]:
        all_boxes: list[FloatArray] = []
        all_scores: list[FloatArray] = []
        grow = context_fraction(self.params.context)
        head_side = self.params.window / (1.0 + 2.0 * grow)
        for scale in self.params.scales:
            resized = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
            (logit_map, *_rest) = self.session.run(
                [self.output_names[0]], {self.input_name: self._tensor(resized)}
            )
            grid = np.asarray(logit_map, dtype=np.float64).reshape(logit_map.shape[-2:])
            rows, columns = np.nonzero(self._scores(grid) >= self.params.score_threshold)
            centre_x = (columns * self.params.stride + self.params.window / 2) / scale
            centre_y = (rows * self.params.stride + self.params.window / 2) / scale
            side = np.full(len(rows), head_side / scale)
            all_boxes.append(
                np.stack([centre_x - side / 2, centre_y - side / 2, side, side], axis=1)
            )
            all_scores.append(self._scores(grid[rows, columns]))
        return np.concatenate(all_boxes), np.concatenate(all_scores)

    def detect_image(self, image: NDArray[np.uint8]) -> Detections:
        """Detect heads on a ``(H, W, 3)`` uint8 BGR image."""
        if self.params.decoding == "score_map":
            boxes, scores = self._score_map(image)
        else:
            fitted, scale_x, scale_y, pad_x, pad_y = self._fit(image)
            values = self.session.run(self.output_names, {self.input_name: self._tensor(fitted)})
            outputs = dict(zip(self.output_names, values, strict=True))
            if self.params.decoding == "yolo":
                boxes, scores = self._decode_yolo(outputs)
            else:
                boxes, scores = self._decode_boxes_scores(outputs)
            if self.params.normalised_boxes:
                boxes = boxes * np.array(
                    [self.input_width, self.input_height, self.input_width, self.input_height]
                )
            boxes = (boxes - np.array([pad_x, pad_y, 0.0, 0.0])) / np.array(
                [scale_x, scale_y, scale_x, scale_y]
            )
        kept = non_maximum_suppression(
            boxes, scores, self.params.score_threshold, self.params.nms_iou
        )
        return detections_from_boxes(boxes[kept], np.clip(scores[kept], 0, 1), self.params.point)

    def detect(self, frame: FrameData) -> Detections:
        """Detect heads on ``frame`` (its image must be decoded)."""
        return self.detect_image(frame_pixels(frame, self.name))


def _check_input_shape(path: Path, shape: list[Any], settings: OnnxDetectorParams) -> None:
    """The model's declared input must take what :meth:`OnnxDetector._tensor` feeds it.

    That is one float image of 3 colour channels laid out as ``settings.layout``, of the size
    ``input_width`` x ``input_height`` when those are set; a dynamic dimension takes anything.
    Checked when the pipeline is validated, not on the first frame.
    """
    nchw = settings.layout == "NCHW"
    expected = "(1, 3, H, W)" if nchw else "(1, H, W, 3)"
    channels = shape[1] if nchw else shape[3]
    height, width = (shape[2], shape[3]) if nchw else (shape[1], shape[2])

    # Only positive integers are static dimensions (names, None or -1 are dynamic).
    def static(value: Any) -> bool:
        return isinstance(value, int) and value >= 1

    for declared, wanted, name in (
        (height, settings.input_height, "input_height"),
        (width, settings.input_width, "input_width"),
    ):
        if static(declared) and wanted and wanted != declared:
            raise UserError(
                f"{path}: model input is {shape}; {name} {wanted} does not match its"
                f" {declared}; expected {expected} with layout {settings.layout}."
            )
    wrong = (static(channels) and channels != 3) or (static(shape[0]) and shape[0] != 1)
    if wrong:
        raise UserError(
            f"{path}: model input is {shape}; expected {expected} (layout {settings.layout},"
            " 3 channels)."
        )


def _static(value: object) -> int:
    return value if isinstance(value, int) and value > 0 else 0


def _to_xywh(boxes: FloatArray, box_format: str) -> FloatArray:
    """``(N, 4)`` boxes in ``box_format`` -> ``(left, top, width, height)``.

    >>> _to_xywh(np.array([[10.0, 20.0, 30.0, 60.0]]), "xyxy").tolist()
    [[10.0, 20.0, 20.0, 40.0]]
    >>> _to_xywh(np.array([[20.0, 40.0, 20.0, 40.0]]), "cxcywh").tolist()
    [[10.0, 20.0, 20.0, 40.0]]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if box_format == "xyxy":
        return np.stack(
            [boxes[:, 0], boxes[:, 1], boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]],
            axis=1,
        )
    if box_format == "cxcywh":
        return np.stack(
            [
                boxes[:, 0] - boxes[:, 2] / 2,
                boxes[:, 1] - boxes[:, 3] / 2,
                boxes[:, 2],
                boxes[:, 3],
            ],
            axis=1,
        )
    return boxes.copy()

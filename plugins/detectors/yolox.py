"""The ``yolox`` detector: pretrained YOLOX person detectors for real footage.

Two models ship with trackfw (``models/NOTICE`` names their origin; Apache-2.0):

* ``yolox-nano``: YOLOX-nano trained on COCO (80 classes, person is class 0), 416x416 input;
* ``light-person-192``: a YOLOX-style person-only detector with a 192x192 input (fast, but it
  loses small people).

A user's own YOLOX export works too (``model: path/to/model.onnx``) when it takes one
``(1, 3, H, W)`` BGR image and gives one ``(1, N, 5 + C)`` tensor of raw rows.

Per frame: letterbox into ``input_size`` (resize keeping the aspect ratio, image at the top-left,
pad value 114, BGR 0-255 as YOLOX was trained; with ``padding: stride`` the shorter side is padded
only up to the next multiple of 32, not to a square), run, decode the anchor-free rows on the grids of
strides 8, 16 and 32 (centre = (dx + column) · stride, size = exp(log w) · stride, score =
objectness · person score), threshold, NMS. With ``tiles`` a large frame is also cut into
overlapping tiles, each detected at ``input_size``; tile boxes touching an inner tile edge are
dropped (the overlap or the whole-frame pass holds that person whole) and all boxes are merged by
one NMS. Each person box gives a head point by the one rule of :mod:`trackfw.formats.head_point`;
the detections
carry square head boxes (side HEAD_SIZE_FRACTION of the body height), as head detectors do, so downstream
stages read a head size from them, and :meth:`YoloxDetector.detect_bodies` returns the body boxes.
Where a box puts the head depends on how the model draws boxes, so the fraction of the rule is a
property of the model (see :data:`SHIPPED_MODELS`).
"""

from __future__ import annotations

import math
import re
from contextlib import ExitStack
from importlib import resources
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator

from trackfw.arrays import FloatArray
from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, body_head_points
from trackfw.records import Detections, FrameData
from trackfw.stages import Detector, StageParams
from trackfw_plugins.detectors.boxes import (
    frame_pixels,
    head_boxes_from_bodies,
    non_maximum_suppression,
)
from trackfw_plugins.detectors.head_scorer import cpu_session_options

#: Shipped models by name: file in ``trackfw_plugins/detectors/models``, native input side, and
#: where the model's boxes put the head centre (share of the box height below its top). Measured
#: on TUD-Stadtmitte against the ground truth's head proxy (benchmarks/detector_accuracy.py): the
#: head-point precision/recall peak at 0.065-0.095 for YOLOX-nano, whose boxes end at the top of
#: the hair like the annotations, and at 0.095-0.11 for the 192 px model, whose boxes leave a
#: margin above the head (TUD-Campus agrees). Other models get the project's HEAD_FRACTION.
SHIPPED_MODELS = {
    "yolox-nano": ("yolox_nano_416_coco.onnx", 416, 0.08),
    "light-person-192": ("light_person_detector_192.onnx", 192, 0.10),
}
#: Strides of the YOLOX heads (P3, P4, P5).
STRIDES = (8, 16, 32)
#: Letterbox pad value YOLOX was trained with.
PAD_VALUE = 114
#: A tile box closer than this to an inner tile edge (px) is cut by the tile.
EDGE_MARGIN = 2.0
_TILES = re.compile(r"^(none|auto|[1-9][0-9]?x[1-9][0-9]?)$")


def shipped_model_path(name: str) -> Path:
    """Path of a shipped model (a real file in both wheel and editable installs)."""
    resource = resources.files("trackfw_plugins.detectors") / "models" / SHIPPED_MODELS[name][0]
    with ExitStack() as stack:
        return Path(stack.enter_context(resources.as_file(resource)))


class YoloxParams(StageParams):
    """Parameters of the ``yolox`` detector."""

    model: str = Field(
        "yolox-nano",
        description="'yolox-nano' (COCO, 416 px), 'light-person-192' (person-only, fast) or the"
        " path of a YOLOX ONNX export ((1, 3, H, W) BGR input, (1, N, 5 + C) raw rows).",
    )
    input_size: int = Field(
        0,
        ge=0,
        multiple_of=32,
        description="Square network input side (px, a multiple of 32); 0 = the model's own (416"
        " for yolox-nano). 640 and above find small, far people.",
    )
    padding: Literal["stride", "square"] = Field(
        "stride",
        description="'stride': the resized frame padded only up to the next multiple of 32 (a"
        " 1280x720 frame runs at 416x256, 38% fewer pixels than 416x416; the network is fully"
        " convolutional); 'square': padded to input_size x input_size, as the models were"
        " exported.",
    )
    tiles: str = Field(
        "none",
        description="Also detect on overlapping tiles of large frames, merged by NMS: 'none',"
        " 'auto' (tiles of about 2x input_size when the frame is larger) or 'NxM' (columns x"
        " rows).",
    )
    tile_overlap: float = Field(
        0.2, ge=0, lt=0.5, description="Overlap of neighbouring tiles, as a share of a tile."
    )
    class_index: int = Field(0, ge=0, description="Class scored (COCO person = 0).")
    score_threshold: float = Field(
        0.5,
        ge=0,
        le=1,
        description="Keep boxes whose objectness x class score reaches this (0.5: best box"
        " F1 on TUD-Stadtmitte with precision to spare).",
    )
    nms_iou: float = Field(0.45, gt=0, le=1, description="IoU threshold of the NMS.")
    head_fraction: float = Field(
        0.0,
        ge=0,
        lt=1,
        description="Head centre below the box top, as a share of the box height; 0 = the"
        " model's own (0.08 yolox-nano, 0.10 light-person-192, 0.08 (trackfw.formats.HEAD_FRACTION) for other models).",
    )
    threads: int = Field(
        0,
        ge=0,
        description="onnxruntime intra-op threads; 0 = OMP_NUM_THREADS if set, else the CPU"
        " count (at most 4).",
    )

    @field_validator("tiles")
    @classmethod
    def _tiles_form(cls, value: str) -> str:
        if not _TILES.match(value):
            raise ValueError("expected 'none', 'auto' or 'NxM' such as '3x2'")
        return value


def resolve_model(model: str) -> tuple[Path, int, float]:
    """The model file, its native input side (0 = read from the file) and head fraction."""
    if model in SHIPPED_MODELS:
        _, side, fraction = SHIPPED_MODELS[model]
        return shipped_model_path(model), side, fraction
    return Path(model).expanduser(), 0, HEAD_FRACTION


def _dimension(value: object) -> int:
    return value if isinstance(value, int) and value > 0 else 0


def load_yolox_session(
    path: Path, input_size: int, threads: int, any_shape: bool = False
) -> tuple[object, int, int]:
    """An onnxruntime session for a YOLOX export, checked before any frame is read.

    Args:
        path: the ONNX file.
        input_size: wanted square input side; 0 = the model's own.
        threads: onnxruntime intra-op threads (0 = :func:`resolve_threads`'s choice).
        any_shape: make the input's height and width symbolic even at the native size (for
            inputs that are not square).

    Returns:
        ``(session, input side, number of row columns 5 + C)``.

    Raises:
        UserError: one line naming the file and what was expected.
    """
    import onnxruntime

    expected = "expected a YOLOX ONNX export with input (1, 3, H, W) and output (1, N, 5 + C)"
    if not path.is_file():
        raise UserError(f"{path}: model file not found; {expected}.")
    data = path.read_bytes()
    options = cpu_session_options(threads)

    def session_of(model_bytes: bytes) -> onnxruntime.InferenceSession:
        try:
            return onnxruntime.InferenceSession(
                model_bytes, sess_options=options, providers=["CPUExecutionProvider"]
            )
        except Exception as error:  # onnxruntime raises several private exception types
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise UserError(f"{path}: not a loadable ONNX model ({first}); {expected}.") from None

    session = session_of(data)
    inputs, outputs = session.get_inputs(), session.get_outputs()
    if len(inputs) != 1 or len(inputs[0].shape) != 4 or inputs[0].shape[1] not in (3, "3"):
        shapes = [list(item.shape) for item in inputs]
        raise UserError(f"{path}: model inputs are {shapes}; {expected}.")
    if len(outputs) != 1 or len(outputs[0].shape) != 3:
        shapes = [list(item.shape) for item in outputs]
        raise UserError(f"{path}: model outputs are {shapes}; {expected}.")
    height, width = (_dimension(value) for value in inputs[0].shape[2:])
    columns = _dimension(outputs[0].shape[2])
    if height != width and height and width:
        raise UserError(f"{path}: model input is {height}x{width}; expected a square input.")
    if columns and columns < 6:
        raise UserError(f"{path}: output rows have {columns} columns; {expected} (C >= 1).")
    native = height or width
    side = input_size or native
    if not side:
        raise UserError(f"{path}: model input size is dynamic; set input_size.")
    if native and (side != native or any_shape):
        # The exports fix the input and output sizes, but the network is fully convolutional:
        # renaming the fixed dimensions to symbolic ones lets onnxruntime run other sizes.
        session = session_of(_symbolic_dimensions(path, data))
    return session, side, columns


def _symbolic_dimensions(path: Path, data: bytes) -> bytes:
    """The model with its input height/width and output anchor count made symbolic."""
    import onnx

    model = onnx.load_from_string(data)
    input_shape = model.graph.input[0].type.tensor_type.shape.dim
    input_shape[2].dim_param, input_shape[3].dim_param = "height", "width"
    output_shape = model.graph.output[0].type.tensor_type.shape.dim
    output_shape[1].dim_param = "anchors"
    for info in model.graph.value_info:
        # Intermediate shapes recorded at export time would contradict the new size.
        info.type.tensor_type.ClearField("shape")
    return bytes(model.SerializeToString())


def anchor_grid(side: int, width: int | None = None) -> tuple[FloatArray, FloatArray]:
    """Grid cells and strides of a ``side`` (rows) x ``width`` (columns, default ``side``)
    input, in YOLOX's output order.

    Returns:
        ``(N, 2)`` cell ``(column, row)`` and ``(N,)`` stride, N = sum over strides of
        ``(side / stride) * (width / stride)``, rows in raster order per stride, strides 8,
        16, 32.

    >>> cells, strides = anchor_grid(64)
    >>> cells.shape, cells[:3].tolist(), strides[[0, 64, 80]].tolist()
    ((84, 2), [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], [8.0, 16.0, 32.0])
    >>> cells, strides = anchor_grid(32, 64)
    >>> cells.shape, cells[[7, 8]].tolist(), strides[[32, 40]].tolist()
    ((42, 2), [[7.0, 0.0], [0.0, 1.0]], [16.0, 32.0])
    """
    width = side if width is None else width
    cells, strides = [], []
    for stride in STRIDES:
        rows, columns = np.meshgrid(
            np.arange(side // stride), np.arange(width // stride), indexing="ij"
        )
        cells.append(np.stack([columns.ravel(), rows.ravel()], axis=1))
        strides.append(np.full(rows.size, stride))
    return (
        np.concatenate(cells).astype(np.float64),
        np.concatenate(strides).astype(np.float64),
    )


def decode_rows(
    rows: FloatArray, cells: FloatArray, strides: FloatArray, class_index: int
) -> tuple[FloatArray, FloatArray]:
    """Raw YOLOX rows to boxes and scores in input pixels.

    Args:
        rows: ``(N, 5 + C)`` raw rows ``(dx, dy, log w, log h, objectness, class scores...)``;
            objectness and class scores already pass a sigmoid in these exports.
        cells: ``(N, 2)`` grid cells (see :func:`anchor_grid`).
        strides: ``(N,)`` strides.
        class_index: the class scored.

    Returns:
        ``(N, 4)`` boxes ``(left, top, width, height)`` and ``(N,)`` scores.

    >>> rows = np.array([[0.5, 0.5, 0.0, np.log(2.0), 0.8, 0.5]])
    >>> boxes, scores = decode_rows(rows, np.array([[2.0, 1.0]]), np.array([8.0]), 0)
    >>> boxes.tolist(), scores.tolist()
    ([[16.0, 4.0, 8.0, 16.0]], [0.4])
    """
    centres = (rows[:, :2] + cells) * strides[:, None]
    # Clipped: a garbage row must not overflow to inf and poison the NMS.
    sizes = np.exp(np.minimum(rows[:, 2:4], 10.0)) * strides[:, None]
    scores = rows[:, 4] * rows[:, 5 + class_index]
    return np.concatenate([centres - sizes / 2, sizes], axis=1), scores


def letterbox(
    image: NDArray[np.uint8], side: int, square: bool = True
) -> tuple[NDArray[np.float32], float]:
    """YOLOX input: ``(1, 3, H, W)`` float32 BGR 0-255, image at the top-left, pad 114.

    The frame is resized to fit ``side`` x ``side``; ``square`` pads it to that square, else
    each side only up to the next multiple of the largest stride (32).

    Returns:
        The tensor and the scale from frame pixels to input pixels.

    >>> letterbox(np.zeros((720, 1280, 3), np.uint8), 416, square=False)[0].shape
    (1, 3, 256, 416)
    """
    height, width = image.shape[:2]
    scale = min(side / height, side / width)
    new_w, new_h = max(1, round(width * scale)), max(1, round(height * scale))
    step = STRIDES[-1]
    shape = (side, side) if square else (-(-new_h // step) * step, -(-new_w // step) * step)
    canvas = np.full((*shape, 3), PAD_VALUE, dtype=np.uint8)
    canvas[:new_h, :new_w] = cv2.resize(image, (new_w, new_h), interpolation=cv2.INTER_LINEAR)
    tensor = canvas.transpose(2, 0, 1)[None].astype(np.float32)
    return np.ascontiguousarray(tensor), scale


def tile_grid(tiles: str, width: int, height: int, side: int) -> tuple[int, int]:
    """``(columns, rows)`` of tiles for a frame; (1, 1) means no tiling.

    ``auto`` tiles a frame whose longer side exceeds twice the input side, with tiles of about
    twice the input side (people then appear at least half their native size).

    >>> tile_grid("auto", 1920, 1080, 416), tile_grid("auto", 640, 480, 416), tile_grid("3x2", 9, 9, 32)
    ((3, 2), (1, 1), (3, 2))
    """
    if tiles == "none":
        return 1, 1
    if tiles == "auto":
        if max(width, height) <= 2 * side:
            return 1, 1
        return max(1, math.ceil(width / (2 * side))), max(1, math.ceil(height / (2 * side)))
    columns, rows = (int(value) for value in tiles.split("x"))
    return columns, rows


def tile_boxes(
    width: int, height: int, columns: int, rows: int, overlap: float
) -> list[tuple[int, int, int, int]]:
    """Overlapping tiles ``(left, top, width, height)`` covering a ``width`` x ``height`` frame.

    >>> tile_boxes(100, 50, 2, 1, 0.2)
    [(0, 0, 56, 50), (44, 0, 56, 50)]
    """

    def spans(total: int, count: int) -> list[tuple[int, int]]:
        if count == 1:
            return [(0, total)]
        # count tiles of length L overlapping by overlap·L cover L·(count - overlap·(count - 1)).
        length = math.ceil(total / (count - overlap * (count - 1)))
        step = (total - length) / (count - 1)
        return [(round(index * step), length) for index in range(count)]

    return [
        (left, top, tile_w, tile_h)
        for top, tile_h in spans(height, rows)
        for left, tile_w in spans(width, columns)
    ]


class YoloxDetector(Detector):
    """Pretrained YOLOX person detector; head points from the person boxes (real footage)."""

    name = "yolox"
    Params = YoloxParams
    uses_pixels = True

    @classmethod
    def resource_files(cls, params: StageParams) -> list[Path]:
        """The shipped model a named ``model`` stands for."""
        assert isinstance(params, YoloxParams)
        return [shipped_model_path(params.model)] if params.model in SHIPPED_MODELS else []

    def __init__(self, params: YoloxParams | None = None) -> None:
        super().__init__(params)
        assert isinstance(self.params, YoloxParams)
        self.settings: YoloxParams = self.params
        path, native, fraction = resolve_model(self.settings.model)
        self.head_fraction = self.settings.head_fraction or fraction
        session, side, columns = load_yolox_session(
            path,
            self.settings.input_size or native,
            self.settings.threads,
            any_shape=self.settings.padding == "stride",
        )
        if columns and self.settings.class_index >= columns - 5:
            raise UserError(
                f"{path}: the model scores {columns - 5} classes; class_index"
                f" {self.settings.class_index} is out of range."
            )
        self.path = path
        self.session = session
        self.side = side
        self.input_name = session.get_inputs()[0].name  # type: ignore[attr-defined]
        # Grid cells and strides per input shape (one shape per frame size and tile size).
        self._grids: dict[tuple[int, int], tuple[FloatArray, FloatArray]] = {}

    def _grid(self, height: int, width: int) -> tuple[FloatArray, FloatArray]:
        """The anchor grid of a ``height`` x ``width`` input (made once per shape)."""
        if (height, width) not in self._grids:
            self._grids[(height, width)] = anchor_grid(height, width)
        return self._grids[(height, width)]

    def _detect_once(self, image: NDArray[np.uint8]) -> tuple[FloatArray, FloatArray]:
        tensor, scale = letterbox(image, self.side, self.settings.padding == "square")
        try:
            (output,) = self.session.run(None, {self.input_name: tensor})  # type: ignore[attr-defined]
        except Exception as error:  # onnxruntime raises several private exception types
            if self.settings.padding == "square":
                raise
            # An export with sizes baked into its graph runs only at its own square input.
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise UserError(
                f"{self.path}: the model does not run at input {tensor.shape[3]}x"
                f"{tensor.shape[2]} (width x height; {first}); expected a fully convolutional"
                " YOLOX export, or set padding: square."
            ) from None
        rows = np.asarray(output, dtype=np.float64).reshape(-1, np.shape(output)[-1])
        height, width = tensor.shape[2:]
        cells, strides = self._grid(height, width)
        if len(rows) != len(cells) or rows.shape[1] <= 5 + self.settings.class_index:
            raise UserError(
                f"{self.path}: output is {list(np.shape(output))}; expected (1,"
                f" {len(cells)}, 5 + C) rows for strides 8/16/32 at input {width}x{height}."
            )
        # Threshold before decoding: most of the thousands of anchors score near zero.
        scores = rows[:, 4] * rows[:, 5 + self.settings.class_index]
        keep = scores >= self.settings.score_threshold
        boxes, scores = decode_rows(
            rows[keep], cells[keep], strides[keep], self.settings.class_index
        )
        return boxes / scale, scores

    def detect_bodies(self, image: NDArray[np.uint8]) -> tuple[FloatArray, FloatArray]:
        """Person boxes on a ``(H, W, 3)`` uint8 BGR image.

        Returns:
            ``(K, 4)`` body boxes ``(left, top, width, height)`` in frame pixels and ``(K,)``
            scores, best first.
        """
        height, width = image.shape[:2]
        boxes, scores = self._detect_once(image)
        all_boxes, all_scores = [boxes], [scores]
        columns, rows = tile_grid(self.settings.tiles, width, height, self.side)
        if columns * rows > 1:
            for left, top, tile_w, tile_h in tile_boxes(
                width, height, columns, rows, self.settings.tile_overlap
            ):
                found, found_scores = self._detect_once(
                    image[top : top + tile_h, left : left + tile_w]
                )
                cut = np.zeros(len(found), dtype=bool)
                if left > 0:
                    cut |= found[:, 0] < EDGE_MARGIN
                if top > 0:
                    cut |= found[:, 1] < EDGE_MARGIN
                if left + tile_w < width:
                    cut |= found[:, 0] + found[:, 2] > tile_w - EDGE_MARGIN
                if top + tile_h < height:
                    cut |= found[:, 1] + found[:, 3] > tile_h - EDGE_MARGIN
                all_boxes.append(found[~cut] + np.array([left, top, 0.0, 0.0]))
                all_scores.append(found_scores[~cut])
        boxes, scores = np.concatenate(all_boxes), np.concatenate(all_scores)
        kept = non_maximum_suppression(
            boxes, scores, self.settings.score_threshold, self.settings.nms_iou
        )
        return boxes[kept], np.clip(scores[kept], 0.0, 1.0)

    def detect_image(self, image: NDArray[np.uint8]) -> Detections:
        """Head detections (points and square head boxes) of the people on a BGR image."""
        bodies, scores = self.detect_bodies(image)
        return Detections(
            points=body_head_points(bodies, self.head_fraction),
            scores=scores,
            boxes=head_boxes_from_bodies(bodies, self.head_fraction),
        )

    def detect(self, frame: FrameData) -> Detections:
        """Detect people on ``frame`` (its image must be decoded)."""
        return self.detect_image(frame_pixels(frame, self.name))

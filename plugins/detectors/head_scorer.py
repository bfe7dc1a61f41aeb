"""Scores head candidates with an ONNX classifier through onnxruntime.

See docs/algorithms/detectors.md#cnn-scoring.

R-CNN style: each box is grown by a context margin, cut out of the frame (replicating the border),
warped to the network's input size and scored in batches. The network's input size, channel order,
normalisation and output form are configurable; the model's declared inputs and outputs are
checked when it is loaded so that a wrong file fails before any frame is read.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.errors import UserError

if TYPE_CHECKING:
    import onnxruntime

OutputForm = Literal["auto", "logit", "logits2", "probability"]

#: The network frame in which R-CNN (Girshick et al. 2014) measures its 16 px context.
RCNN_FRAME = 224.0

#: ONNX metadata keys under which ``trackfw train detector`` records how its crops were cut, so
#: that the detector cuts them the same way (a model scores badly on crops it was not trained on).
CROP_METADATA = {"context": "trackfw.context", "min_crop": "trackfw.min_crop"}


def context_fraction(context: float) -> float:
    """The share of the box size added on each side for R-CNN-style ``context`` pixels.

    R-CNN warps a box to 224 px with ``context`` px of surrounding image on each side, so the
    box covers ``224 - 2 * context`` px and grows by ``context / (224 - 2 * context)`` of its size.

    >>> round(context_fraction(16.0), 4)
    0.0833
    >>> context_fraction(0.0)
    0.0
    """
    return context / (RCNN_FRAME - 2.0 * context)


def extract_crops(
    image: NDArray[np.uint8],
    boxes: NDArray[np.float64],
    size: tuple[int, int],
    context: float = 16.0,
    min_crop: float = 0.0,
) -> NDArray[np.uint8]:
    """Cut boxes (grown by their context) out of a frame and warp them to ``size``.

    Args:
        image: ``(H, W, 3)`` uint8 frame.
        boxes: ``(N, 4)`` boxes as ``(left, top, width, height)`` in pixels.
        size: ``(height, width)`` of the crops.
        context: R-CNN context in pixels of a 224-px frame (see :func:`context_fraction`).
        min_crop: smallest crop side in px at 1080p (scaled by the frame height / 1080): a
            smaller grown box is widened about its centre, so that a tiny head comes with its
            shoulders and surroundings.

    Returns:
        ``(N, height, width, 3)`` uint8 crops; outside the frame the border is replicated.
    """
    crop_height, crop_width = size
    count = len(boxes)
    crops = np.zeros((count, crop_height, crop_width, 3), dtype=np.uint8)
    if count == 0:
        return crops
    grow = context_fraction(context)
    min_side = min_crop * image.shape[0] / 1080.0
    widths = np.maximum((1.0 + 2.0 * grow) * boxes[:, 2], min_side)
    heights = np.maximum((1.0 + 2.0 * grow) * boxes[:, 3], min_side)
    centre_x = boxes[:, 0] + 0.5 * boxes[:, 2]
    centre_y = boxes[:, 1] + 0.5 * boxes[:, 3]
    lefts, rights = centre_x - 0.5 * widths, centre_x + 0.5 * widths
    tops, bottoms = centre_y - 0.5 * heights, centre_y + 0.5 * heights
    height, width = image.shape[:2]
    # One padded copy of the frame lets every crop be a plain slice.
    overflow = max(0.0, -lefts.min(), -tops.min(), rights.max() - width, bottoms.max() - height)
    pad = math.ceil(overflow) + 1
    padded = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    # Corners as Python ints up front and resize into the output: the per-box loop was a third
    # of the scoring time on 1500 boxes. np.rint rounds half to even, like round().
    x0 = np.rint(lefts).astype(np.int64) + pad
    y0 = np.rint(tops).astype(np.int64) + pad
    x1 = np.maximum(np.rint(rights).astype(np.int64) + pad, x0 + 1)
    y1 = np.maximum(np.rint(bottoms).astype(np.int64) + pad, y0 + 1)
    shrinking = ((y1 - y0) > crop_height) | ((x1 - x0) > crop_width)
    output_size = (crop_width, crop_height)
    for index, (left, top, right, bottom, shrink) in enumerate(
        zip(x0.tolist(), y0.tolist(), x1.tolist(), y1.tolist(), shrinking.tolist(), strict=True)
    ):
        cv2.resize(
            padded[top:bottom, left:right],
            output_size,
            dst=crops[index],
            interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR,
        )
    return crops


def crops_to_tensor(
    crops_bgr: NDArray[np.uint8],
    mean: Sequence[float] = (0.5, 0.5, 0.5),
    std: Sequence[float] = (0.25, 0.25, 0.25),
    rgb: bool = True,
) -> NDArray[np.float32]:
    """``(N, h, w, 3)`` uint8 BGR crops -> ``(N, 3, h, w)`` float32 tensor ``(x/255 - mean)/std``.

    >>> crops_to_tensor(np.full((1, 2, 2, 3), 255, dtype=np.uint8)).shape
    (1, 3, 2, 2)
    >>> float(crops_to_tensor(np.full((1, 1, 1, 3), 255, dtype=np.uint8)).max())
    2.0
    """
    planar = crops_bgr.transpose(0, 3, 1, 2)
    if rgb:
        planar = planar[:, ::-1]
    # Reorder while still uint8 (a quarter of the bytes), then scale in place: 4x faster than
    # converting first on 1500 crops.
    tensor = np.ascontiguousarray(planar).astype(np.float32)
    std_array = np.asarray(std, dtype=np.float32).reshape(1, 3, 1, 1)
    mean_array = np.asarray(mean, dtype=np.float32).reshape(1, 3, 1, 1)
    tensor *= np.float32(1.0 / 255.0) / std_array
    tensor -= mean_array / std_array
    return tensor


def _sigmoid(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (1.0 + np.tanh(0.5 * values))


def resolve_threads(requested: int) -> int:
    """Threads for one onnxruntime operator: ``requested``, or for 0 what this process may use.

    0 follows ``OMP_NUM_THREADS`` when it is set (``trackfw bench`` sets it to 1 in each worker
    process), else the CPU count, at most 4 (the small head CNN gains nothing beyond).

    >>> resolve_threads(3)
    3
    """
    if requested > 0:
        return requested
    allowed = os.environ.get("OMP_NUM_THREADS", "")
    if allowed.isdigit() and int(allowed) > 0:
        return int(allowed)
    return max(1, min(4, os.cpu_count() or 1))


def cpu_session_options(intra_op_threads: int) -> onnxruntime.SessionOptions:
    """onnxruntime options for one of trackfw's CPU sessions.

    ``intra_op_threads`` threads per operator (0 = :func:`resolve_threads`'s choice), one
    operator at a time, warnings only, and threads that sleep between runs: onnxruntime's
    default keeps them spinning for work, on the cores the other stages of the same frame (the
    tracker's embedder, NumPy) then wait for. On the 2-core development machine
    ``pipelines/real.yaml`` used a fifth less CPU time for the same outputs.
    """
    import onnxruntime

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = resolve_threads(intra_op_threads)
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return options


def open_onnx_session(
    path: Path, intra_op_threads: int, expected: str
) -> onnxruntime.InferenceSession:
    """A CPU onnxruntime session for ``path``; a missing or unloadable file is one UserError.

    Args:
        path: the ONNX file.
        intra_op_threads: threads for one operator; 0 = :func:`resolve_threads`'s choice.
        expected: what the file should be, for the error sentence ("an ONNX head classifier").
    """
    import onnxruntime

    if not path.is_file():
        raise UserError(f"{path}: model file not found; expected {expected}.")
    options = cpu_session_options(int(intra_op_threads))
    try:
        return onnxruntime.InferenceSession(
            str(path), sess_options=options, providers=["CPUExecutionProvider"]
        )
    except Exception as error:  # onnxruntime raises several private exception types
        raise UserError(
            f"{path}: model cannot be loaded by onnxruntime ({str(error).splitlines()[0]});"
            " expected a valid ONNX file."
        ) from error


def _crop_metadata(path: Path, session: onnxruntime.InferenceSession) -> dict[str, float]:
    """The crop settings a model records in its metadata (see :data:`CROP_METADATA`)."""
    stored = session.get_modelmeta().custom_metadata_map
    settings: dict[str, float] = {}
    for name, key in CROP_METADATA.items():
        if key in stored:
            try:
                settings[name] = float(stored[key])
            except ValueError:
                raise UserError(
                    f"{path}: metadata {key} is {stored[key]!r}; expected a number."
                ) from None
    return settings


def _crop_setting(
    path: Path, name: str, configured: float | None, recorded: float | None, default: float
) -> float:
    """A crop setting: the configured value, else the model's record, else ``default``.

    Raises:
        UserError: the configured value differs from the one the model was trained with.
    """
    if configured is None:
        return recorded if recorded is not None else default
    if recorded is not None and not math.isclose(configured, recorded):
        raise UserError(
            f"{path}: the model was trained with {name} {recorded:g}, but the detector sets"
            f" {name} {configured:g}; leave {name} unset to use the model's value."
        )
    return configured


class HeadScorer:
    """An onnxruntime session that maps head crops to head probabilities.

    Args:
        model_path: the ``.onnx`` file: one NCHW float32 input, one output of shape ``(N,)``,
            ``(N, 1)`` or ``(N, 2)``.
        input_size: ``(height, width)``; None takes it from the model (it must then be static).
        mean: per-channel mean subtracted from pixels scaled to [0, 1], in model channel order.
        std: per-channel standard deviation the pixels are divided by.
        rgb: whether the model expects RGB (frames are BGR).
        output_form: ``logit`` (one value, sigmoid), ``logits2`` (two classes, softmax, index 1 is
            head), ``probability`` (already in [0, 1]) or ``auto`` (one value -> logit, two ->
            logits2).
        intra_op_threads: onnxruntime threads inside one operator (0: see :func:`resolve_threads`).
        batch_size: crops per onnxruntime call.
        context: R-CNN context of :meth:`score_boxes` (see :func:`extract_crops`); None = the
            value the model records, 16 when it records none.
        min_crop: smallest crop side of :meth:`score_boxes`, px at 1080p; None = the value the
            model records, 0 when it records none.

    Attributes:
        crop_settings: ``context`` and ``min_crop`` as the model's metadata records them (empty
            for a model that records none, e.g. one not trained by trackfw).
        context: the context :meth:`score_boxes` cuts crops with.
        min_crop: the smallest crop side :meth:`score_boxes` cuts crops with.

    Raises:
        UserError: the file is missing or damaged, or its inputs/outputs are not as expected.
    """

    def __init__(
        self,
        model_path: str | Path,
        input_size: tuple[int, int] | None = None,
        mean: Sequence[float] = (0.5, 0.5, 0.5),
        std: Sequence[float] = (0.25, 0.25, 0.25),
        rgb: bool = True,
        output_form: OutputForm = "auto",
        intra_op_threads: int = 0,
        batch_size: int = 64,
        context: float | None = None,
        min_crop: float | None = None,
    ) -> None:
        path = Path(model_path)
        self.session = open_onnx_session(path, intra_op_threads, "an ONNX head classifier")
        inputs = self.session.get_inputs()
        outputs = self.session.get_outputs()
        if len(inputs) != 1 or len(inputs[0].shape) != 4:
            shapes = [list(item.shape) for item in inputs]
            raise UserError(
                f"{path}: model inputs are {shapes}; expected one NCHW input of rank 4."
            )
        if inputs[0].type != "tensor(float)":
            raise UserError(f"{path}: model input type is {inputs[0].type}; expected float32.")
        channels, model_height, model_width = inputs[0].shape[1:]
        if isinstance(channels, int) and channels != 3:
            raise UserError(f"{path}: model input has {channels} channels; expected 3.")
        if input_size is None:
            if not (isinstance(model_height, int) and isinstance(model_width, int)):
                raise UserError(
                    f"{path}: model input size is dynamic; set input_size to (height, width)."
                )
            input_size = (model_height, model_width)
        for declared, wanted, axis in (
            (model_height, input_size[0], "height"),
            (model_width, input_size[1], "width"),
        ):
            if isinstance(declared, int) and declared != wanted:
                raise UserError(
                    f"{path}: model input {axis} is {declared}; expected input_size {axis}"
                    f" {wanted}."
                )
        if len(outputs) < 1:
            raise UserError(f"{path}: model has no output; expected head scores.")
        last = outputs[0].shape[-1] if len(outputs[0].shape) >= 2 else 1
        if len(outputs[0].shape) > 2 or (isinstance(last, int) and last not in (1, 2)):
            raise UserError(
                f"{path}: model output shape is {list(outputs[0].shape)}; expected (N,), (N, 1)"
                " or (N, 2) head scores."
            )
        if output_form == "auto":
            output_form = "logits2" if last == 2 else "logit"
        self.path = path
        self.crop_settings = _crop_metadata(path, self.session)
        recorded = self.crop_settings
        self.context = _crop_setting(path, "context", context, recorded.get("context"), 16.0)
        self.min_crop = _crop_setting(path, "min_crop", min_crop, recorded.get("min_crop"), 0.0)
        self.input_name = inputs[0].name
        self.output_name = outputs[0].name
        self.input_size = (int(input_size[0]), int(input_size[1]))
        self.mean = np.asarray(mean, dtype=np.float32).reshape(1, 3, 1, 1)
        self.std = np.asarray(std, dtype=np.float32).reshape(1, 3, 1, 1)
        self.rgb = rgb
        self.output_form: OutputForm = output_form
        self.batch_size = max(1, int(batch_size))

    def preprocess(self, crops_bgr: NDArray[np.uint8]) -> NDArray[np.float32]:
        """``(N, h, w, 3)`` uint8 BGR crops -> ``(N, 3, h, w)`` normalised float32 tensor."""
        return crops_to_tensor(
            crops_bgr, self.mean.ravel().tolist(), self.std.ravel().tolist(), self.rgb
        )

    def to_probability(self, raw: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map the model's raw ``(N,)``/``(N, 1)``/``(N, 2)`` output to head probabilities."""
        raw = np.asarray(raw, dtype=np.float64)
        if self.output_form == "logits2":
            two = raw.reshape(len(raw), 2)
            return _sigmoid(two[:, 1] - two[:, 0])
        values = raw.reshape(len(raw), -1)[:, -1]
        if self.output_form == "probability":
            return np.clip(values, 0.0, 1.0)
        return _sigmoid(values)

    def score_crops(self, crops_bgr: NDArray[np.uint8]) -> NDArray[np.float64]:
        """Head probability of each ``(N, h, w, 3)`` uint8 BGR crop (already at input size)."""
        count = len(crops_bgr)
        scores = np.zeros(count, dtype=np.float64)
        for start in range(0, count, self.batch_size):
            batch = self.preprocess(crops_bgr[start : start + self.batch_size])
            (raw, *_rest) = self.session.run([self.output_name], {self.input_name: batch})
            scores[start : start + len(batch)] = self.to_probability(raw)
        return scores

    def score_boxes(
        self, image: NDArray[np.uint8], boxes: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Head probability of each ``(N, 4)`` box of ``image``, cut as the model was trained."""
        return self.score_crops(
            extract_crops(image, boxes, self.input_size, self.context, self.min_crop)
        )

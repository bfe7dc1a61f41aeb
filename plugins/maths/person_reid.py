"""The ``person-reid`` descriptor: a pretrained deep person re-identification embedder.

Two Intel Open Model Zoo embedders ship with trackfw (``models/NOTICE``; Apache-2.0):
``person-reidentification-retail-0287`` (default) and the smaller ``-0248``. Each takes one
256x128 (rows x columns) BGR crop of a whole person, pixel values 0-255, laid out NHWC, and
gives a 256-d embedding; two people are compared by the cosine distance of their L2-normalised
embeddings (0 = same direction, 2 = opposite).

The tracker knows a head point, and a detector a head box; the body crop is the box of a person
whose head has that centre and size (:func:`~trackfw_plugins.detectors.boxes.body_boxes_from_heads`,
the inverse of the detectors' head-point rule), 1:2 wide as the networks expect. A tall detection
box (a body box, as ``hog`` gives) is used as the body box itself.

The exports fix the batch size at 1 (their reshapes carry it), so the crops of one call are run
one per session call, side by side on a few threads of one session (each call on one onnxruntime
thread); a frame's crops are cut once and embedded together.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from trackfw.arrays import FloatArray, IntArray
from trackfw.errors import UserError
from trackfw.formats import HEAD_SIZE_FRACTION
from trackfw.records import Detections
from trackfw_plugins.detectors.boxes import body_boxes_from_heads
from trackfw_plugins.detectors.head_scorer import cpu_session_options, resolve_threads
from trackfw_plugins.maths.assignment import distance_matrix
from trackfw_plugins.maths.reid_crop import crop_box

#: Shipped embedders by name.
PERSON_REID_MODELS = {
    "0287": "person-reidentification-retail-0287.onnx",
    "0248": "person-reidentification-retail-0248.onnx",
}
#: Crop the embedders take: rows, columns.
CROP_SHAPE = (256, 128)
#: A box taller than this many times its width is a body box, not a head box.
BODY_BOX_ASPECT = 1.5


def person_reid_model_path(model: str) -> Path:
    """The file of a shipped embedder (``0287``, ``0248``) or ``model`` as a path."""
    if model not in PERSON_REID_MODELS:
        return Path(model).expanduser()
    resource = resources.files("trackfw_plugins.maths") / "models" / PERSON_REID_MODELS[model]
    with ExitStack() as stack:
        return Path(stack.enter_context(resources.as_file(resource)))


def _is_body(boxes: FloatArray) -> NDArray[np.bool_]:
    return np.asarray(boxes[:, 3] > BODY_BOX_ASPECT * boxes[:, 2])


def head_sizes_of(boxes: FloatArray) -> FloatArray:
    """Head size of each ``(N, 4)`` detection box: its side, or HEAD_SIZE_FRACTION h for a tall body box.

    >>> head_sizes_of(np.array([[0.0, 0.0, 10.0, 12.0], [0.0, 0.0, 40.0, 100.0]])).round(3).tolist()
    [11.0, 13.0]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    return np.where(_is_body(boxes), HEAD_SIZE_FRACTION * boxes[:, 3], boxes[:, 2:4].mean(axis=1))


def detection_rows(detections: Detections | None, indices: ArrayLike) -> IntArray:
    """Row of each stable detection index in ``detections`` (-1 where absent)."""
    wanted = np.asarray(indices, dtype=np.int64).reshape(-1)
    if detections is None:
        return np.full(len(wanted), -1, dtype=np.int64)
    position = {int(index): row for row, index in enumerate(detections.index)}
    return np.array([position.get(int(index), -1) for index in wanted], dtype=np.int64)


def nearest_rows(points: ArrayLike, detections: Detections | None) -> IntArray:
    """Row of the detection nearest each ``(P, 2)`` point, -1 where none lies within its own
    head size of it (or where there are no detection boxes).

    >>> from trackfw.records import Detections
    >>> boxes = np.array([[95.0, 95.0, 10.0, 10.0], [195.0, 95.0, 10.0, 10.0]])
    >>> points = np.array([[100.0, 100.0], [200.0, 100.0]])
    >>> detections = Detections(points, np.ones(2), boxes=boxes)
    >>> nearest_rows(np.array([[104.0, 103.0], [150.0, 100.0]]), detections).tolist()
    [0, -1]
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if detections is None or detections.boxes is None or len(detections) == 0:
        return np.full(len(points), -1, dtype=np.int64)
    distances = distance_matrix(points, detections.points)
    nearest = distances.argmin(axis=1) if len(points) else np.zeros(0, dtype=np.int64)
    within = distances[np.arange(len(points)), nearest] <= head_sizes_of(detections.boxes)[nearest]
    return np.where(within, nearest, -1).astype(np.int64)


def body_boxes(
    points: ArrayLike,
    detections: Detections | None,
    rows: ArrayLike,
    fallback_size: float,
) -> FloatArray:
    """Body boxes ``(P, 4)`` for ``(P, 2)`` head points.

    Args:
        points: head points.
        detections: the detections of the frame, or None.
        rows: per point, its row in ``detections`` (-1: none); a point with a detection box
            takes its head size (or the box itself when it is a body box), the others the median
            head size of the frame's detections, else ``fallback_size``.
        fallback_size: head size (px) when the frame has no detection box at all.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    rows = np.asarray(rows, dtype=np.int64).reshape(-1)
    boxes = None if detections is None else detections.boxes
    if boxes is None or len(boxes) == 0:
        return body_boxes_from_heads(points, np.full(len(points), fallback_size))
    sizes = head_sizes_of(boxes)
    has = (rows >= 0) & (rows < len(boxes))
    chosen = np.where(has, sizes[np.where(has, rows, 0)], float(np.median(sizes)))
    result = body_boxes_from_heads(points, chosen)
    bodies = has & _is_body(boxes)[np.where(has, rows, 0)]
    result[bodies] = boxes[rows[bodies]]
    return result


def body_crops(image: NDArray[np.uint8], boxes: ArrayLike, angle: float = 0.0) -> NDArray[np.uint8]:
    """``(P, 256, 128, 3)`` uint8 BGR crops of ``(P, 4)`` body boxes (borders replicated), each
    cut from the image turned by ``angle`` degrees about its centre (:func:`.crop_box`;
    0: as the image stands)."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if len(boxes) == 0:
        return np.zeros((0, *CROP_SHAPE, 3), dtype=np.uint8)
    return np.stack(
        [
            crop_box(image, left, top, width, height, CROP_SHAPE, angle)
            for left, top, width, height in boxes
        ]
    )


def cosine_distance_matrix(first: ArrayLike, second: ArrayLike) -> FloatArray:
    """``(K, N)`` cosine distances ``1 - a·b`` between L2-normalised ``(K, D)`` and ``(N, D)`` rows.

    >>> cosine_distance_matrix([[1.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]]).tolist()
    [[0.0, 1.0]]
    """
    a = np.asarray(first, dtype=np.float64)
    b = np.asarray(second, dtype=np.float64)
    return np.clip(1.0 - a.reshape(len(a), -1) @ b.reshape(len(b), -1).T, 0.0, 2.0)


class PersonReidEmbedder:
    """An onnxruntime session of a person re-ID embedder, checked when it is opened.

    Args:
        model: ``"0287"``, ``"0248"`` or the path of an ONNX embedder with an NHWC
            ``(1, 256, 128, 3)`` input and a ``(1, D)`` output.
        threads: crops embedded at once, each on one onnxruntime thread; 0 =
            :func:`resolve_threads`'s choice. The embedder gains nothing from a second
            intra-op thread on one crop (16.5 against 16.2 ms on two cores), so a frame's crops
            run side by side instead; the embeddings are the same bit for bit.

    Raises:
        UserError: a missing, unloadable or wrongly shaped model, in one line naming the file.
    """

    def __init__(self, model: str = "0287", threads: int = 0) -> None:
        import onnxruntime

        path = person_reid_model_path(model)
        expected = (
            "expected an ONNX person re-ID embedder with input (1, 256, 128, 3) and output (1, D)"
        )
        if not path.is_file():
            raise UserError(f"{path}: model file not found; {expected}.")
        options = cpu_session_options(1)
        try:
            session = onnxruntime.InferenceSession(
                str(path), sess_options=options, providers=["CPUExecutionProvider"]
            )
        except Exception as error:  # onnxruntime raises several private exception types
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise UserError(f"{path}: not a loadable ONNX model ({first}); {expected}.") from None
        inputs, outputs = session.get_inputs(), session.get_outputs()
        if len(inputs) != 1 or list(inputs[0].shape[1:]) != [*CROP_SHAPE, 3]:
            shapes = [list(item.shape) for item in inputs]
            raise UserError(f"{path}: model inputs are {shapes}; {expected}.")
        if len(outputs) != 1 or len(outputs[0].shape) != 2:
            shapes = [list(item.shape) for item in outputs]
            raise UserError(f"{path}: model outputs are {shapes}; {expected}.")
        self.path = path
        self.session = session
        self.input_name = inputs[0].name
        self.workers = resolve_threads(threads)
        self._pool: ThreadPoolExecutor | None = None

    def _embed_one(self, crop: NDArray[np.uint8]) -> FloatArray:
        """One ``(256, 128, 3)`` crop's raw ``(D,)`` embedding (onnxruntime sessions may run
        concurrently)."""
        output = self.session.run(None, {self.input_name: crop[None].astype(np.float32)})[0]
        return np.asarray(output, dtype=np.float64).reshape(-1)

    def embed(self, crops: NDArray[np.uint8]) -> FloatArray:
        """``(P, 256, 128, 3)`` uint8 BGR crops -> ``(P, D)`` unit-length embeddings."""
        crops = np.asarray(crops).reshape(-1, *CROP_SHAPE, 3)
        if len(crops) > 1 and self.workers > 1:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="trackfw-reid")
            rows = list(self._pool.map(self._embed_one, crops))
        else:
            rows = [self._embed_one(crop) for crop in crops]
        if not rows:
            width = self.session.get_outputs()[0].shape[1]
            return np.zeros((0, width if isinstance(width, int) else 0))
        embeddings = np.stack(rows)
        norms = np.linalg.norm(embeddings, axis=1, keepdims=True)
        return embeddings / np.where(norms > 0, norms, 1.0)

    def describe(
        self, image: NDArray[np.uint8], boxes: ArrayLike, angle: float = 0.0
    ) -> FloatArray:
        """Embeddings ``(P, D)`` of the people in ``(P, 4)`` body boxes of a BGR frame, cut from
        the frame turned by ``angle`` degrees (:func:`body_crops`; the upright angle of a rolled
        camera, :func:`.upright_angle`)."""
        return self.embed(body_crops(image, boxes, angle))

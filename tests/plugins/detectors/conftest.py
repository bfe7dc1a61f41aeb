"""Fixtures of the detector tests: tiny ONNX models built with onnx.helper (so that tests do not
depend on a trained network) and synthetic frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


def _save(graph: object, path: Path) -> Path:
    onnx = pytest.importorskip("onnx")
    model = onnx.helper.make_model(graph, opset_imports=[onnx.helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def centre_surround_scorer(path: Path, size: int = 32, gain: float = 5.0) -> Path:
    """``(N, 3, s, s)`` -> ``(N, 1)`` logit = gain · (mean of the central half - mean outside)."""
    onnx = pytest.importorskip("onnx")
    helper, numpy_helper = onnx.helper, onnx.numpy_helper
    mask = np.zeros((size, size), dtype=bool)
    mask[size // 4 : 3 * size // 4, size // 4 : 3 * size // 4] = True
    weights = np.where(mask, 1.0 / mask.sum(), -1.0 / (~mask).sum()) * gain / 3.0
    weight = np.tile(weights.ravel(), 3).astype(np.float32).reshape(-1, 1)
    graph = helper.make_graph(
        [
            helper.make_node("Flatten", ["crops"], ["flat"], axis=1),
            helper.make_node("MatMul", ["flat", "weight"], ["logit"]),
        ],
        "centre_surround",
        [helper.make_tensor_value_info("crops", onnx.TensorProto.FLOAT, ["N", 3, size, size])],
        [helper.make_tensor_value_info("logit", onnx.TensorProto.FLOAT, ["N", 1])],
        [numpy_helper.from_array(weight, "weight")],
    )
    return _save(graph, path)


def constant_outputs(
    path: Path, outputs: dict[str, np.ndarray], input_shape: list[int | str]
) -> Path:
    """A model whose input is ignored (summed times 0) and whose outputs are constants."""
    onnx = pytest.importorskip("onnx")
    helper, numpy_helper = onnx.helper, onnx.numpy_helper
    nodes = [
        helper.make_node("ReduceSum", ["image"], ["total"], keepdims=0),
        helper.make_node("Mul", ["total", "zero"], ["nothing"]),
    ]
    initialisers = [numpy_helper.from_array(np.zeros((), np.float32), "zero")]
    value_infos = []
    for name, value in outputs.items():
        initialisers.append(numpy_helper.from_array(value.astype(np.float32), f"{name}_value"))
        nodes.append(helper.make_node("Add", [f"{name}_value", "nothing"], [name]))
        value_infos.append(
            helper.make_tensor_value_info(name, onnx.TensorProto.FLOAT, list(value.shape))
        )
    graph = helper.make_graph(
        nodes,
        "constant",
        [helper.make_tensor_value_info("image", onnx.TensorProto.FLOAT, input_shape)],
        value_infos,
        initialisers,
    )
    return _save(graph, path)


def disc_image(
    centres: list[tuple[float, float]], radius: int = 12, size: tuple[int, int] = (360, 640)
) -> np.ndarray:
    """A dark ``(H, W, 3)`` uint8 frame with light discs ("heads") at ``centres``."""
    import cv2

    image = np.full((*size, 3), 30, dtype=np.uint8)
    for x, y in centres:
        cv2.circle(image, (round(x), round(y)), radius, (220, 220, 220), -1, cv2.LINE_AA)
    return image


@pytest.fixture
def make_disc_image():
    """:func:`disc_image`."""
    return disc_image


@pytest.fixture
def make_scorer():
    """:func:`centre_surround_scorer`."""
    return centre_surround_scorer


@pytest.fixture
def make_constant_model():
    """:func:`constant_outputs`."""
    return constant_outputs

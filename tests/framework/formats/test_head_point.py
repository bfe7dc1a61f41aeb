"""The one head-point rule: a body box's head centre and size, a head box's point."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw.formats import (
    HEAD_FRACTION,
    HEAD_SIZE_FRACTION,
    MEASURED_HEAD_FRACTION,
    body_head_points,
    body_heads,
    box_points,
)

BOXES = np.array([[100.0, 50.0, 60.0, 200.0], [0.0, 0.0, 10.0, 30.0]])


def test_body_heads_follow_the_documented_formula() -> None:
    heads = body_heads(BOXES)
    assert heads[:, 0].tolist() == [130.0, 5.0]
    assert np.allclose(heads[:, 1], [50 + HEAD_FRACTION * 200, HEAD_FRACTION * 30])
    assert np.allclose(heads[:, 2], [HEAD_SIZE_FRACTION * 200, HEAD_SIZE_FRACTION * 30])
    assert body_heads(np.zeros((0, 4))).shape == (0, 3)


def test_the_fraction_is_the_one_parameter() -> None:
    default = body_head_points(BOXES)
    measured = body_head_points(BOXES, MEASURED_HEAD_FRACTION)
    assert np.array_equal(default, box_points(BOXES, "body"))
    assert np.array_equal(measured[:, 0], default[:, 0])
    assert np.allclose(measured[:, 1] - default[:, 1], (0.116 - 0.08) * BOXES[:, 3])
    assert np.allclose(body_heads(BOXES, size_fraction=0.12)[:, 2], 0.12 * BOXES[:, 3])


def test_head_boxes_give_their_centre_or_top() -> None:
    assert box_points(BOXES[:1], "centre").tolist() == [[130.0, 150.0]]
    assert box_points(BOXES[:1], "top").tolist() == [[130.0, 50.0]]
    with pytest.raises(ValueError, match="anchor"):
        box_points(BOXES, "feet")

"""The head of a person from a box: one rule for datasets, detectors, training and evaluation.

A whole-body box ``(left, top, width, height)`` gives the head centre

    ``(left + width / 2, top + fraction * height)``

and the head size ``size_fraction * height``. The height is used rather than the width because a
box's width varies with the stride and the arms while its height does not.

``fraction`` is the one parameter of the head point. Its default, :data:`HEAD_FRACTION` = 0.08, is
the proxy every benchmark of this project was built and measured with (the MOTChallenge-derived
datasets' ground truth, the ``body`` point of the box detectors). On real elevated street footage
the head centre sits lower: in the Oxford Town Centre annotations (head and body box of 47,746
people) it is about :data:`MEASURED_HEAD_FRACTION` = 0.116 of the body height below the box's
top, with a head box about 0.118 of the body height (``../shared/models/README.md``). A caller
that wants the measured value passes it; changing the default would move the ground truth of the
existing datasets and so every benchmark figure.

A head box (a detector that outlines heads) gives its centre (``anchor="centre"``); ``"top"``
gives the middle of the box's top edge.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Head centre below a body box's top, as a share of the box height (the default rule).
HEAD_FRACTION = 0.08
#: The same share measured on real elevated footage (Oxford Town Centre); see the module docstring.
MEASURED_HEAD_FRACTION = 0.116
#: Head size as a share of the body box's height: an adult head is about 1/7.5 of the body.
HEAD_SIZE_FRACTION = 0.13

#: Where a box's head point is: a body box's head, a head box's centre, or its top edge.
BoxAnchor = Literal["body", "centre", "top"]


def body_head_points(boxes: ArrayLike, fraction: float = HEAD_FRACTION) -> NDArray[np.float64]:
    """The head centre of each body box.

    Args:
        boxes: ``(N, 4)`` body boxes ``(left, top, width, height)``.
        fraction: head centre below the box's top, as a share of its height.

    Returns:
        ``(N, 2)`` head centres ``(x, y)``.

    >>> body_head_points([[10.0, 20.0, 40.0, 100.0]]).tolist()
    [[30.0, 28.0]]
    """
    return box_points(boxes, "body", fraction)


def body_heads(
    boxes: ArrayLike,
    fraction: float = HEAD_FRACTION,
    size_fraction: float = HEAD_SIZE_FRACTION,
) -> NDArray[np.float64]:
    """Head centre and size of each body box.

    Args:
        boxes: ``(N, 4)`` body boxes ``(left, top, width, height)``.
        fraction: head centre below the box's top, as a share of its height.
        size_fraction: head size as a share of the box's height.

    Returns:
        ``(N, 3)`` rows ``(x, y, head_size)`` in the boxes' pixels.

    >>> body_heads([[10.0, 20.0, 40.0, 100.0]]).tolist()
    [[30.0, 28.0, 13.0]]
    """
    boxes = _boxes(boxes)
    sizes = size_fraction * boxes[:, 3:4]
    return np.concatenate([body_head_points(boxes, fraction), sizes], axis=1)


def box_points(
    boxes: ArrayLike, anchor: BoxAnchor | str = "body", fraction: float = HEAD_FRACTION
) -> NDArray[np.float64]:
    """The head point of each box, by what the box outlines.

    Args:
        boxes: ``(N, 4)`` boxes ``(left, top, width, height)``.
        anchor: ``body`` (a whole-body box: the head rule above), ``centre`` (a head box) or
            ``top`` (the middle of the top edge).
        fraction: for ``body``, the head centre below the box's top as a share of its height.

    Returns:
        ``(N, 2)`` points ``(x, y)``.

    >>> box_points([[10.0, 20.0, 40.0, 100.0]], "centre").tolist()
    [[30.0, 70.0]]
    """
    boxes = _boxes(boxes)
    x = boxes[:, 0] + 0.5 * boxes[:, 2]
    if anchor == "body":
        y = boxes[:, 1] + fraction * boxes[:, 3]
    elif anchor == "top":
        y = boxes[:, 1]
    elif anchor == "centre":
        y = boxes[:, 1] + 0.5 * boxes[:, 3]
    else:
        raise ValueError(f"anchor is {anchor!r}; expected 'body', 'centre' or 'top'.")
    return np.stack([x, y], axis=1)


def _boxes(boxes: ArrayLike) -> NDArray[np.float64]:
    return np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
